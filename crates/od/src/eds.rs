//! CiA 306 electronic data sheet of exactly what a description implements.
//! Writes to any `fmt::Write`, so it needs no allocation.

use core::fmt::{self, Write};

use crate::{DataType, DeviceDescription, Entry, Limit, Object, ObjectKind, Value};

/// Writes the EDS of `desc`. `date` is `mm-dd-yyyy` (kept out of the function so the output
/// is reproducible).
pub fn write_eds(w: &mut impl Write, desc: &DeviceDescription, date: &str) -> fmt::Result {
    writeln!(w, "[FileInfo]")?;
    writeln!(w, "FileName={}.eds", desc.name)?;
    writeln!(w, "FileVersion=1")?;
    writeln!(w, "FileRevision=0")?;
    writeln!(w, "EDSVersion=4.0")?;
    writeln!(w, "Description={}", desc.description)?;
    writeln!(w, "CreationTime=12:00PM")?;
    writeln!(w, "CreationDate={date}")?;
    writeln!(w, "CreatedBy=drivetwin")?;
    writeln!(w, "ModificationTime=12:00PM")?;
    writeln!(w, "ModificationDate={date}")?;
    writeln!(w, "ModifiedBy=drivetwin")?;
    writeln!(w)?;
    writeln!(w, "[DeviceInfo]")?;
    writeln!(w, "VendorName={}", desc.vendor_name)?;
    writeln!(w, "VendorNumber=0x{:X}", desc.vendor_id)?;
    writeln!(w, "ProductName={}", desc.product_name)?;
    writeln!(w, "ProductNumber=0x{:X}", desc.product_code)?;
    writeln!(w, "RevisionNumber=0x{:X}", desc.revision)?;
    writeln!(w, "OrderCode={}", desc.order_code)?;
    for rate in [10u16, 20, 50, 125, 250, 500, 800, 1000] {
        writeln!(
            w,
            "BaudRate_{rate}={}",
            desc.baud_rates.contains(&rate) as u8
        )?;
    }
    writeln!(w, "SimpleBootUpMaster=0")?;
    writeln!(w, "SimpleBootUpSlave=1")?;
    writeln!(w, "Granularity=8")?;
    writeln!(w, "DynamicChannelsSupported=0")?;
    writeln!(w, "GroupMessaging=0")?;
    let count = |lo: u16, hi: u16| {
        desc.objects
            .iter()
            .filter(|o| (lo..=hi).contains(&o.index))
            .count()
    };
    writeln!(w, "NrOfRXPDO={}", count(0x1400, 0x15FF))?;
    writeln!(w, "NrOfTXPDO={}", count(0x1800, 0x19FF))?;
    writeln!(w, "LSS_Supported=0")?;
    writeln!(w)?;
    writeln!(w, "[DummyUsage]")?;
    // CiA 306: a dummy is announced here, not as an object section. A device lists the
    // dummy objects it offers (Nanotec §9.44–9.50) with their mapping flag.
    for i in 1..=7u16 {
        let usable = match desc.cia301.dummy_usage {
            Some(usage) => usage & (1 << i) != 0,
            None => desc.entry(i, 0).is_some_and(|e| e.pdo_mappable),
        };
        writeln!(w, "Dummy000{i}={}", usable as u8)?;
    }
    writeln!(w)?;
    writeln!(w, "[Comments]")?;
    writeln!(w, "Lines=0")?;
    writeln!(w)?;

    let mandatory = |o: &&Object| matches!(o.index, 0x1000 | 0x1001 | 0x1018);
    let optional =
        |o: &&Object| !mandatory(o) && ((0x1000..0x2000).contains(&o.index) || o.index >= 0x6000);
    let manufacturer = |o: &&Object| (0x2000..0x6000).contains(&o.index);
    write_list(w, "MandatoryObjects", desc.objects.iter().filter(mandatory))?;
    write_list(w, "OptionalObjects", desc.objects.iter().filter(optional))?;
    write_list(
        w,
        "ManufacturerObjects",
        desc.objects.iter().filter(manufacturer),
    )?;

    for o in desc.objects.iter().filter(|o| !is_dummy(o)) {
        write_object(w, o)?;
    }
    Ok(())
}

/// The dummy objects 0001h–0007h (data type indices), announced in `[DummyUsage]` only.
fn is_dummy(o: &Object) -> bool {
    (0x0001..=0x0007).contains(&o.index)
}

fn write_list<'a>(
    w: &mut impl Write,
    section: &str,
    objs: impl Iterator<Item = &'a Object> + Clone,
) -> fmt::Result {
    writeln!(w, "[{section}]")?;
    writeln!(w, "SupportedObjects={}", objs.clone().count())?;
    for (i, o) in objs.enumerate() {
        writeln!(w, "{}=0x{:04X}", i + 1, o.index)?;
    }
    writeln!(w)
}

fn write_object(w: &mut impl Write, o: &Object) -> fmt::Result {
    match o.kind {
        ObjectKind::Var => {
            if let Some(e) = o.entries.first() {
                writeln!(w, "[{:04X}]", o.index)?;
                write_entry_body(w, o.name, e)?;
            }
        }
        ObjectKind::Array | ObjectKind::Record => {
            writeln!(w, "[{:04X}]", o.index)?;
            writeln!(w, "ParameterName={}", o.name)?;
            writeln!(w, "ObjectType=0x{:X}", o.kind.object_code())?;
            writeln!(w, "SubNumber={}", o.entries.len())?;
            writeln!(w)?;
            for e in o.entries {
                writeln!(w, "[{:04X}sub{:X}]", o.index, e.sub)?;
                write_entry_body(w, e.name, e)?;
            }
        }
    }
    Ok(())
}

fn write_entry_body(w: &mut impl Write, name: &str, e: &Entry) -> fmt::Result {
    writeln!(w, "ParameterName={name}")?;
    writeln!(w, "ObjectType=0x7")?;
    writeln!(w, "DataType=0x{:04X}", e.data_type.code())?;
    writeln!(w, "AccessType={}", e.access.eds_name())?;
    if e.data_type != DataType::Domain {
        write!(w, "DefaultValue=")?;
        write_default(w, e)?;
        writeln!(w)?;
    }
    if let Some(min) = e.min {
        write!(w, "LowLimit=")?;
        write_limit(w, e.data_type, min)?;
        writeln!(w)?;
    }
    if let Some(max) = e.max {
        write!(w, "HighLimit=")?;
        write_limit(w, e.data_type, max)?;
        writeln!(w)?;
    }
    writeln!(w, "PDOMapping={}", e.pdo_mappable as u8)?;
    writeln!(w)
}

fn write_default(w: &mut impl Write, e: &Entry) -> fmt::Result {
    match e.data_type {
        DataType::VisibleString => {
            for &b in e.default {
                w.write_char(char::from(b))?;
            }
            Ok(())
        }
        DataType::OctetString => {
            for b in e.default {
                write!(w, "{b:02X}")?;
            }
            Ok(())
        }
        // REAL values as their IEEE 754 bit pattern, as Lely's dcfchk requires (python-canopen
        // reads a default it cannot parse as "no default").
        DataType::Real32 | DataType::Real64 => {
            let mut b = [0u8; 8];
            let n = e.default.len().min(8);
            if let (Some(d), Some(s)) = (b.get_mut(..n), e.default.get(..n)) {
                d.copy_from_slice(s);
            }
            write!(w, "0x{:X}", u64::from_le_bytes(b))
        }
        t => {
            let v = Value::decode(t, e.default).unwrap_or(Value::Unsigned(0));
            match v {
                Value::Unsigned(u) if e.default_plus_node_id => write!(w, "$NODEID+0x{u:X}"),
                Value::Unsigned(u) => write!(w, "0x{u:X}"),
                Value::Bool(b) => write!(w, "{}", b as u8),
                Value::Signed(s) => write!(w, "{s}"),
                Value::Real(r) => write!(w, "{r}"),
            }
        }
    }
}

fn write_limit(w: &mut impl Write, t: DataType, l: Limit) -> fmt::Result {
    if t.is_real() {
        let mut b = [0u8; 8];
        // A limit that does not fit the type leaves 0, which the description check prevents.
        let _ = Value::from_limit(l).encode(t, &mut b);
        return write!(w, "0x{:X}", u64::from_le_bytes(b));
    }
    match (l, t.is_signed()) {
        (Limit::Unsigned(u), false) => write!(w, "0x{u:X}"),
        (Limit::Unsigned(u), true) => write!(w, "{u}"),
        (Limit::Signed(s), _) => write!(w, "{s}"),
        (Limit::Real(r), _) => write!(w, "{r}"),
    }
}
