//! EtherCAT Slave Information (ESI, ETG.2000) XML of a device description: what TwinCAT and
//! other configurators import. The same description and the same [`SiiConfig`] give the SII
//! image (`ethercat::sii`), so the ESI and the EEPROM agree on SM addresses, PDOs and names.
//!
//! Structure and naming follow the Festo CMMP-AS ESI excerpt (the manual's extract kept beside the
//! project, `cmmp-as-1-communication.md` §2.13): vendor `#x1D`, group type "Festo Electric-Drives"
//! / name "Festo Electric-Drive", `Device Physics="YY"`, RxPDO entries with
//! Index/SubIndex/BitLen/Name/DataType, the PDO assigned to SM2 named "Outputs" and the one
//! assigned to SM3 "Inputs". Decisions:
//! * Element names are ETG.2000's `RxPdo` / `TxPdo` (the manual prints `<RxPDO>`, which the
//!   ETG schema and TwinCAT do not know; its `<Index#>x6060</Index>` typo is not copied either).
//! * The vendor name is the description's `vendor_name` ("Festo AG & Co. KG"), not the
//!   excerpt's "Festo SE": the description is the single source of truth; masters match the Id.
//! * PDOs are not `Fixed`: the CMMP-AS mapping objects are writable (the manual's extract,
//!   part 1 §3.2); only the default assignment (1C12h/1C13h of [`SiiConfig`]) carries `Sm`.
//! * Records and arrays are both described as `DTxxxx` data types with one `SubItem` per
//!   present sub-index (arrays with gaps, e.g. 1010h with only sub 1, stay exact that way);
//!   sub 0 takes 16 bits (8 + 8 padding) as in Beckhoff's files, the rest follow packed.
//! * Every object of the description is listed, including 1008h–100Ah and 6089h–608Eh which
//!   the CMMP-AS rejects under CoE (Tab. 4.9): the description has no
//!   per-protocol flag; that is for the CoE front end to refuse.
//! * Defaults are `DefaultData` (little-endian hex, as on the wire), strings `DefaultString`;
//!   `$NODEID` defaults are given for the description's default node ID. Limits are
//!   `MinData`/`MaxData`.
//! * `PdoMapping` is `R` for a mappable writable entry, `T` for a mappable read-only one.
//! * `Dc` lists the synchronisation modes the slave runs ([`ethercat::SYNC_MODES`]: the
//!   frame as time base, and DC SYNC0 at the master's cycle, which must equal the
//!   interpolation period 60C2h), so that a configurator offers DC; the SII keeps no DC
//!   category (ETG.2010 has none that SOEM or ethercrab read), so the EEPROM is unchanged.
//! * No InitCmds: with `PdoAssign="true"` the configurator writes 1C12h/1C13h itself.

use std::collections::BTreeMap;
use std::fmt::{self, Display, Write};

use ethercat::sii::{self, coe_details, PdoDir, PdoName, SiiConfig};
use ethercat::SYNC_MODES;
use od::{Access, DataType, DeviceDescription, Entry, Limit, Object, ObjectKind, Value};

/// What the ESI says beyond the description: the SII layout and the group's display name.
#[derive(Debug, Clone, Copy)]
pub struct EsiConfig<'a> {
    pub sii: SiiConfig<'a>,
    /// `<Group><Name>`; the group type is `sii.group_type`.
    pub group_name: &'a str,
    /// `<Eeprom><ByteSize>`.
    pub eeprom_size: usize,
}

impl EsiConfig<'static> {
    /// What `desc`'s device file says (`[device.ethercat]`, on the SII baseline of
    /// the ESC reference kept beside the project, §3.5 without it).
    pub fn from_description(desc: &DeviceDescription) -> Self {
        EsiConfig {
            sii: SiiConfig::from_description(desc),
            group_name: desc.ethercat.map_or("Drives", |e| e.group_name),
            eeprom_size: sii::DEFAULT_IMAGE_SIZE,
        }
    }
}

/// Writes the ESI XML of `desc` as its device file describes it
/// ([`EsiConfig::from_description`]).
pub fn write_esi(desc: &DeviceDescription, w: &mut impl Write) -> fmt::Result {
    write_esi_with(desc, &EsiConfig::from_description(desc), w)
}

/// XML text or attribute value with `& < > " '` escaped and control characters replaced.
pub struct Xml<'a>(pub &'a str);

impl Display for Xml<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for c in self.0.chars() {
            match c {
                '&' => f.write_str("&amp;")?,
                '<' => f.write_str("&lt;")?,
                '>' => f.write_str("&gt;")?,
                '"' => f.write_str("&quot;")?,
                '\'' => f.write_str("&apos;")?,
                '\t' | '\n' | '\r' => f.write_char(c)?,
                c if (c as u32) < 0x20 || c == '\u{FFFE}' || c == '\u{FFFF}' => {
                    f.write_char('?')?
                }
                c => f.write_char(c)?,
            }
        }
        Ok(())
    }
}

/// ETG.2000 type name and bit size of an entry.
fn esi_type(e: &Entry) -> (String, u32) {
    let bits = e.bit_len();
    let name = match e.data_type {
        DataType::Boolean => return ("BOOL".into(), 1),
        DataType::Integer8 => "SINT",
        DataType::Integer16 => "INT",
        DataType::Integer32 => "DINT",
        DataType::Integer64 => "LINT",
        DataType::Unsigned8 => "USINT",
        DataType::Unsigned16 => "UINT",
        DataType::Unsigned32 => "UDINT",
        DataType::Unsigned64 => "ULINT",
        DataType::Real32 => "REAL",
        DataType::Real64 => "LREAL",
        DataType::VisibleString => return (format!("STRING({})", e.capacity), bits),
        DataType::OctetString | DataType::Domain => {
            return (byte_array(e.capacity), bits);
        }
    };
    (name.into(), bits)
}

fn byte_array(n: u32) -> String {
    format!("ARRAY [0..{}] OF BYTE", n.saturating_sub(1))
}

fn access(a: Access) -> &'static str {
    match a {
        Access::ReadOnly | Access::Const => "ro",
        Access::WriteOnly => "wo",
        Access::ReadWrite => "rw",
    }
}

fn pdo_mapping(e: &Entry) -> Option<&'static str> {
    match (e.pdo_mappable, e.access.writable()) {
        (false, _) => None,
        (true, true) => Some("R"),
        (true, false) => Some("T"),
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect()
}

/// The default value as the device stores it, with `$NODEID` resolved.
fn default_bytes(desc: &DeviceDescription, e: &Entry) -> Vec<u8> {
    let mut v = e.default.to_vec();
    if e.default_plus_node_id && e.data_type.is_numeric() {
        let mut b = [0u8; 8];
        for (dst, src) in b.iter_mut().zip(&v) {
            *dst = *src;
        }
        let sum = u64::from_le_bytes(b).wrapping_add(u64::from(desc.default_node_id));
        for (dst, src) in v.iter_mut().zip(sum.to_le_bytes()) {
            *dst = src;
        }
    }
    v
}

fn limit_bytes(e: &Entry, l: Limit) -> Option<Vec<u8>> {
    let size = e.data_type.fixed_size()?;
    let mut b = [0u8; 8];
    Value::from_limit(l).encode(e.data_type, &mut b)?;
    b.get(..size).map(<[u8]>::to_vec)
}

/// Name of the data type of an object: the entry's type for a VAR, `DTxxxx` otherwise.
fn object_type(o: &Object) -> (String, u32) {
    match o.kind {
        ObjectKind::Var => o
            .entries
            .first()
            .map(esi_type)
            .unwrap_or(("USINT".into(), 8)),
        ObjectKind::Array | ObjectKind::Record => (format!("DT{:04X}", o.index), sub_offsets(o).1),
    }
}

/// Bit offsets of the entries of a record/array, and the total size.
fn sub_offsets(o: &Object) -> (Vec<u32>, u32) {
    let mut offs = Vec::with_capacity(o.entries.len());
    let mut pos = 0u32;
    for e in o.entries {
        offs.push(pos);
        let bits = esi_type(e).1;
        // Sub 0 takes 16 bits: 8 + 8 padding (ETG convention).
        pos += if e.sub == 0 { 16 } else { bits };
    }
    (offs, pos)
}

/// Writes the ESI XML of `desc`.
pub fn write_esi_with(
    desc: &DeviceDescription,
    cfg: &EsiConfig<'_>,
    w: &mut impl Write,
) -> fmt::Result {
    let sii = &cfg.sii;
    let image = sii_image(desc, cfg);
    // ConfigData: the ESC configuration area, words 0–3, as the SII holds it.
    let config_data = image
        .as_deref()
        .and_then(|i| i.get(..8))
        .map(hex)
        .unwrap_or_default();
    let out_bytes = sii::assigned_bits(desc, sii.rx_assigned)
        .unwrap_or(0)
        .div_ceil(8);
    let in_bytes = sii::assigned_bits(desc, sii.tx_assigned)
        .unwrap_or(0)
        .div_ceil(8);
    let long_name = if sii.device_name.is_empty() {
        desc.product_name
    } else {
        sii.device_name
    };

    writeln!(w, r#"<?xml version="1.0" encoding="UTF-8"?>"#)?;
    writeln!(
        w,
        r#"<EtherCATInfo xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" Version="1.2">"#
    )?;
    writeln!(w, "  <Vendor>")?;
    writeln!(w, "    <Id>#x{:X}</Id>", desc.vendor_id)?;
    writeln!(
        w,
        r#"    <Name LcId="1033">{}</Name>"#,
        Xml(desc.vendor_name)
    )?;
    writeln!(w, "  </Vendor>")?;
    writeln!(w, "  <Descriptions>")?;
    writeln!(w, "    <Groups>")?;
    writeln!(w, r#"      <Group SortOrder="1">"#)?;
    writeln!(w, "        <Type>{}</Type>", Xml(sii.group_type))?;
    writeln!(
        w,
        r#"        <Name LcId="1033">{}</Name>"#,
        Xml(cfg.group_name)
    )?;
    writeln!(w, "      </Group>")?;
    writeln!(w, "    </Groups>")?;
    writeln!(w, "    <Devices>")?;
    writeln!(w, r#"      <Device Physics="YY">"#)?;
    writeln!(
        w,
        r##"        <Type ProductCode="#x{:X}" RevisionNo="#x{:X}">{}</Type>"##,
        desc.product_code,
        desc.revision,
        Xml(desc.product_name)
    )?;
    writeln!(w, r#"        <Name LcId="1033">{}</Name>"#, Xml(long_name))?;
    writeln!(w, "        <GroupType>{}</GroupType>", Xml(sii.group_type))?;
    write_profile(desc, w)?;
    writeln!(w, "        <Fmmu>Outputs</Fmmu>")?;
    writeln!(w, "        <Fmmu>Inputs</Fmmu>")?;
    writeln!(w, "        <Fmmu>MBoxState</Fmmu>")?;
    let sms = [
        (
            sii.mailbox_out.0,
            u32::from(sii.mailbox_out.1),
            sii::SM0_CONTROL,
            "MBoxOut",
        ),
        (
            sii.mailbox_in.0,
            u32::from(sii.mailbox_in.1),
            sii::SM1_CONTROL,
            "MBoxIn",
        ),
        (sii.outputs_start, out_bytes, sii::SM2_CONTROL, "Outputs"),
        (sii.inputs_start, in_bytes, sii::SM3_CONTROL, "Inputs"),
    ];
    for (start, size, control, what) in sms {
        writeln!(
            w,
            r##"        <Sm DefaultSize="{size}" StartAddress="#x{start:04X}" ControlByte="#x{control:02X}" Enable="1">{what}</Sm>"##
        )?;
    }
    write_pdos(desc, sii, PdoDir::Rx, w)?;
    write_pdos(desc, sii, PdoDir::Tx, w)?;
    let coe = sii.coe_details;
    let flag = |bit: u8| coe & bit != 0;
    writeln!(w, "        <Mailbox>")?;
    writeln!(
        w,
        r#"          <CoE SdoInfo="{}" PdoAssign="{}" PdoConfig="{}" PdoUpload="{}" CompleteAccess="{}"/>"#,
        flag(coe_details::SDO_INFO),
        flag(coe_details::PDO_ASSIGN),
        flag(coe_details::PDO_CONFIG),
        flag(coe_details::PDO_UPLOAD),
        flag(coe_details::SDO_COMPLETE_ACCESS)
    )?;
    writeln!(w, "        </Mailbox>")?;
    write_dc(w)?;
    writeln!(w, "        <Eeprom>")?;
    writeln!(w, "          <ByteSize>{}</ByteSize>", cfg.eeprom_size)?;
    if !config_data.is_empty() {
        writeln!(w, "          <ConfigData>{config_data}</ConfigData>")?;
    }
    writeln!(w, "        </Eeprom>")?;
    writeln!(w, "      </Device>")?;
    writeln!(w, "    </Devices>")?;
    writeln!(w, "  </Descriptions>")?;
    writeln!(w, "</EtherCATInfo>")
}

/// `<Dc>`: one `OpMode` per synchronisation mode the slave runs. A SYNC0 mode's cycle is the
/// master's (`Factor="1"`, no fixed part) with no shift: the slave takes any SYNC0 cycle
/// equal to its interpolation period and refuses others on Pre-Op → Safe-Op (0x0036).
fn write_dc(w: &mut impl Write) -> fmt::Result {
    writeln!(w, "        <Dc>")?;
    for mode in SYNC_MODES {
        writeln!(w, "          <OpMode>")?;
        writeln!(w, "            <Name>{}</Name>", Xml(mode.name))?;
        writeln!(w, "            <Desc>{}</Desc>", Xml(mode.desc))?;
        writeln!(
            w,
            "            <AssignActivate>#x{:X}</AssignActivate>",
            mode.assign_activate
        )?;
        if mode.sync0 {
            writeln!(
                w,
                r#"            <CycleTimeSync0 Factor="1">0</CycleTimeSync0>"#
            )?;
            writeln!(w, "            <ShiftTimeSync0>0</ShiftTimeSync0>")?;
        }
        writeln!(w, "          </OpMode>")?;
    }
    writeln!(w, "        </Dc>")
}

fn sii_image(desc: &DeviceDescription, cfg: &EsiConfig<'_>) -> Option<Vec<u8>> {
    let mut buf = vec![0u8; cfg.eeprom_size];
    sii::build_sii(desc, &cfg.sii, &mut buf).ok().map(|_| buf)
}

fn write_pdos(
    desc: &DeviceDescription,
    sii: &SiiConfig<'_>,
    dir: PdoDir,
    w: &mut impl Write,
) -> fmt::Result {
    let (tag, assigned) = match dir {
        PdoDir::Rx => ("RxPdo", sii.rx_assigned),
        PdoDir::Tx => ("TxPdo", sii.tx_assigned),
    };
    for obj in sii::pdo_objects(desc, dir) {
        let is_assigned = assigned.contains(&obj.index);
        if is_assigned {
            writeln!(w, r#"        <{tag} Sm="{}">"#, dir.sm())?;
        } else {
            writeln!(w, "        <{tag}>")?;
        }
        writeln!(w, "          <Index>#x{:04X}</Index>", obj.index)?;
        writeln!(
            w,
            "          <Name>{}</Name>",
            Xml(PdoName::new(dir, obj.index, is_assigned).as_str())
        )?;
        // A mapping the description cannot decode is exported without entries.
        let entries: Vec<_> = sii::default_mapping(obj)
            .map(|m| m.collect())
            .unwrap_or_default();
        for m in entries {
            writeln!(w, "          <Entry>")?;
            writeln!(w, "            <Index>#x{:X}</Index>", m.index)?;
            if m.index != 0 {
                writeln!(w, "            <SubIndex>{}</SubIndex>", m.sub)?;
            }
            writeln!(w, "            <BitLen>{}</BitLen>", m.bits)?;
            if let Some(e) = m.entry(desc) {
                writeln!(w, "            <Name>{}</Name>", Xml(e.name))?;
                writeln!(
                    w,
                    "            <DataType>{}</DataType>",
                    Xml(&esi_type(e).0)
                )?;
            }
            writeln!(w, "          </Entry>")?;
        }
        writeln!(w, "        </{tag}>")?;
    }
    Ok(())
}

fn write_profile(desc: &DeviceDescription, w: &mut impl Write) -> fmt::Result {
    // 1000h: low word = profile number, high word = additional information (CiA 301 §7.5.2.1).
    let device_type = desc
        .entry(0x1000, 0)
        .map(|e| u32::from_le_bytes(pad4(e.default)))
        .unwrap_or(0);
    writeln!(w, "        <Profile>")?;
    writeln!(
        w,
        "          <ProfileNo>{}</ProfileNo>",
        device_type & 0xFFFF
    )?;
    writeln!(w, "          <AddInfo>{}</AddInfo>", device_type >> 16)?;
    writeln!(w, "          <Dictionary>")?;
    writeln!(w, "            <DataTypes>")?;
    // Base types, by name, with their bit sizes.
    let mut base: BTreeMap<String, u32> = BTreeMap::new();
    for e in desc.entries() {
        let (name, bits) = esi_type(e);
        if matches!(e.data_type, DataType::OctetString | DataType::Domain) {
            base.insert("BYTE".into(), 8);
        }
        base.insert(name, bits);
    }
    for o in desc.objects.iter().filter(|o| o.kind != ObjectKind::Var) {
        let (offs, size) = sub_offsets(o);
        writeln!(w, "              <DataType>")?;
        writeln!(w, "                <Name>DT{:04X}</Name>", o.index)?;
        writeln!(w, "                <BitSize>{size}</BitSize>")?;
        for (e, off) in o.entries.iter().zip(offs) {
            let (t, bits) = esi_type(e);
            writeln!(w, "                <SubItem>")?;
            writeln!(w, "                  <SubIdx>{}</SubIdx>", e.sub)?;
            writeln!(w, "                  <Name>{}</Name>", Xml(e.name))?;
            writeln!(w, "                  <Type>{}</Type>", Xml(&t))?;
            writeln!(w, "                  <BitSize>{bits}</BitSize>")?;
            writeln!(w, "                  <BitOffs>{off}</BitOffs>")?;
            write_flags(w, e, "                  ")?;
            writeln!(w, "                </SubItem>")?;
        }
        writeln!(w, "              </DataType>")?;
    }
    for (name, bits) in &base {
        writeln!(w, "              <DataType>")?;
        writeln!(w, "                <Name>{}</Name>", Xml(name))?;
        if let Some(n) = name
            .strip_prefix("ARRAY [0..")
            .and_then(|r| r.strip_suffix("] OF BYTE"))
        {
            let elements = n.parse::<u32>().map(|n| n + 1).unwrap_or(0);
            writeln!(w, "                <BaseType>BYTE</BaseType>")?;
            writeln!(w, "                <BitSize>{bits}</BitSize>")?;
            writeln!(w, "                <ArrayInfo>")?;
            writeln!(w, "                  <LBound>0</LBound>")?;
            writeln!(w, "                  <Elements>{elements}</Elements>")?;
            writeln!(w, "                </ArrayInfo>")?;
        } else {
            writeln!(w, "                <BitSize>{bits}</BitSize>")?;
        }
        writeln!(w, "              </DataType>")?;
    }
    writeln!(w, "            </DataTypes>")?;
    writeln!(w, "            <Objects>")?;
    for o in desc.objects {
        write_object(desc, o, w)?;
    }
    writeln!(w, "            </Objects>")?;
    writeln!(w, "          </Dictionary>")?;
    writeln!(w, "        </Profile>")
}

fn pad4(b: &[u8]) -> [u8; 4] {
    let mut a = [0u8; 4];
    for (d, s) in a.iter_mut().zip(b) {
        *d = *s;
    }
    a
}

fn write_flags(w: &mut impl Write, e: &Entry, ind: &str) -> fmt::Result {
    writeln!(w, "{ind}<Flags>")?;
    writeln!(w, "{ind}  <Access>{}</Access>", access(e.access))?;
    if let Some(m) = pdo_mapping(e) {
        writeln!(w, "{ind}  <PdoMapping>{m}</PdoMapping>")?;
    }
    writeln!(w, "{ind}</Flags>")
}

/// The `<Info>` content of one entry (default and limits), if it has any.
fn write_info(desc: &DeviceDescription, e: &Entry, ind: &str, w: &mut impl Write) -> fmt::Result {
    match e.data_type {
        DataType::VisibleString => {
            let s: String = e.default.iter().map(|&b| char::from(b)).collect();
            writeln!(w, "{ind}<DefaultString>{}</DefaultString>", Xml(&s))
        }
        DataType::Domain => Ok(()),
        _ => {
            if let Some(min) = e.min.and_then(|l| limit_bytes(e, l)) {
                writeln!(w, "{ind}<MinData>{}</MinData>", hex(&min))?;
            }
            if let Some(max) = e.max.and_then(|l| limit_bytes(e, l)) {
                writeln!(w, "{ind}<MaxData>{}</MaxData>", hex(&max))?;
            }
            let d = default_bytes(desc, e);
            if !d.is_empty() {
                writeln!(w, "{ind}<DefaultData>{}</DefaultData>", hex(&d))?;
            }
            Ok(())
        }
    }
}

fn write_object(desc: &DeviceDescription, o: &Object, w: &mut impl Write) -> fmt::Result {
    let (t, bits) = object_type(o);
    writeln!(w, "              <Object>")?;
    writeln!(w, "                <Index>#x{:04X}</Index>", o.index)?;
    writeln!(w, "                <Name>{}</Name>", Xml(o.name))?;
    writeln!(w, "                <Type>{}</Type>", Xml(&t))?;
    writeln!(w, "                <BitSize>{bits}</BitSize>")?;
    match o.kind {
        ObjectKind::Var => {
            if let Some(e) = o.entries.first() {
                let mut info = String::new();
                write_info(desc, e, "                  ", &mut info)?;
                if !info.is_empty() {
                    writeln!(w, "                <Info>")?;
                    w.write_str(&info)?;
                    writeln!(w, "                </Info>")?;
                }
                write_flags(w, e, "                ")?;
            }
        }
        ObjectKind::Array | ObjectKind::Record => {
            writeln!(w, "                <Info>")?;
            for e in o.entries {
                writeln!(w, "                  <SubItem>")?;
                writeln!(w, "                    <Name>{}</Name>", Xml(e.name))?;
                let mut info = String::new();
                write_info(desc, e, "                      ", &mut info)?;
                if !info.is_empty() {
                    writeln!(w, "                    <Info>")?;
                    w.write_str(&info)?;
                    writeln!(w, "                    </Info>")?;
                }
                writeln!(w, "                  </SubItem>")?;
            }
            writeln!(w, "                </Info>")?;
            writeln!(w, "                <Flags>")?;
            writeln!(w, "                  <Access>ro</Access>")?;
            writeln!(w, "                </Flags>")?;
        }
    }
    writeln!(w, "              </Object>")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cmmp() -> &'static DeviceDescription {
        devices::by_name("cmmp-as").expect("cmmp-as")
    }

    /// Index, sub, bit length, name, data type.
    type EntryRow = (String, String, String, String, String);
    /// Index, Sm attribute, name, entries.
    type PdoRow = (String, Option<String>, String, Vec<EntryRow>);

    fn xml() -> String {
        let mut s = String::new();
        write_esi(cmmp(), &mut s).unwrap();
        s
    }

    fn child<'a, 'i>(n: roxmltree::Node<'a, 'i>, tag: &str) -> roxmltree::Node<'a, 'i> {
        n.children()
            .find(|c| c.has_tag_name(tag))
            .unwrap_or_else(|| panic!("<{tag}> under <{}>", n.tag_name().name()))
    }

    fn text<'a>(n: roxmltree::Node<'a, '_>, tag: &str) -> &'a str {
        child(n, tag).text().unwrap_or("")
    }

    /// CMMP-ECAT-02: `<Vendor><Id>#x1D</Id>`, the same vendor as identity 1018h:01.
    #[test]
    fn esi_is_well_formed_and_names_the_device() {
        let s = xml();
        let doc = roxmltree::Document::parse(&s).expect("well-formed XML");
        let root = doc.root_element();
        assert_eq!(root.tag_name().name(), "EtherCATInfo");
        let vendor = child(root, "Vendor");
        assert_eq!(text(vendor, "Id"), "#x1D");
        let id = cmmp().entry(0x1018, 1).expect("1018h:01");
        assert_eq!(id.default, &[0x1D, 0, 0, 0], "1018h:01 = 0000001Dh");
        assert_eq!(
            text(vendor, "Name"),
            "Festo AG & Co. KG",
            "escaped and parsed back"
        );
        assert!(s.contains("Festo AG &amp; Co. KG"));
        let descs = child(root, "Descriptions");
        let group = child(child(descs, "Groups"), "Group");
        assert_eq!(text(group, "Type"), "Festo Electric-Drives");
        assert_eq!(text(group, "Name"), "Festo Electric-Drive");
        let dev = child(child(descs, "Devices"), "Device");
        assert_eq!(dev.attribute("Physics"), Some("YY"));
        let ty = child(dev, "Type");
        assert_eq!(ty.attribute("ProductCode"), Some("#x18C375"));
        assert_eq!(ty.attribute("RevisionNo"), Some("#x40000"));
        assert_eq!(ty.text(), Some("CMMP-AS-C2-3A-M3"));
        assert_eq!(text(dev, "GroupType"), "Festo Electric-Drives");

        // ETG.2000 element order of a Device.
        let order: Vec<&str> = dev
            .children()
            .filter(|c| c.is_element())
            .map(|c| c.tag_name().name())
            .collect();
        let first = |t: &str| order.iter().position(|x| *x == t).unwrap();
        let seq = [
            "Type",
            "Name",
            "GroupType",
            "Profile",
            "Fmmu",
            "Sm",
            "RxPdo",
            "TxPdo",
            "Mailbox",
            "Dc",
            "Eeprom",
        ];
        for pair in seq.windows(2) {
            assert!(first(pair[0]) < first(pair[1]), "{pair:?} in {order:?}");
        }

        let sms: Vec<_> = dev.children().filter(|c| c.has_tag_name("Sm")).collect();
        let sm = |i: usize, a: &str| sms[i].attribute(a).unwrap().to_string();
        assert_eq!(sms.len(), 4);
        let expected = [
            ("#x1000", "128", "#x26"),
            ("#x1080", "128", "#x22"),
            ("#x1100", "2", "#x64"),
            ("#x1180", "2", "#x20"),
        ];
        for (i, (start, size, control)) in expected.into_iter().enumerate() {
            assert_eq!(
                (
                    sm(i, "StartAddress"),
                    sm(i, "DefaultSize"),
                    sm(i, "ControlByte")
                ),
                (start.into(), size.into(), control.into()),
                "Sm {i}"
            );
        }
        assert_eq!(
            sms.iter().map(|s| s.text().unwrap()).collect::<Vec<_>>(),
            ["MBoxOut", "MBoxIn", "Outputs", "Inputs"]
        );
        let fmmus: Vec<_> = dev
            .children()
            .filter(|c| c.has_tag_name("Fmmu"))
            .map(|c| c.text().unwrap())
            .collect();
        assert_eq!(fmmus, ["Outputs", "Inputs", "MBoxState"]);

        let coe = child(child(dev, "Mailbox"), "CoE");
        assert_eq!(coe.attribute("PdoAssign"), Some("true"));
        assert_eq!(coe.attribute("PdoConfig"), Some("true"));
        assert_eq!(coe.attribute("SdoInfo"), Some("true"));
        assert_eq!(coe.attribute("CompleteAccess"), Some("false"));
        let eeprom = child(dev, "Eeprom");
        assert_eq!(text(eeprom, "ByteSize"), "2048");
        assert_eq!(text(eeprom, "ConfigData"), "0500000000000000");
    }

    #[test]
    fn esi_pdos_follow_the_default_mappings() {
        let s = xml();
        let doc = roxmltree::Document::parse(&s).unwrap();
        let dev = doc
            .descendants()
            .find(|n| n.has_tag_name("Device"))
            .unwrap();
        let pdos = |tag: &str| -> Vec<PdoRow> {
            dev.children()
                .filter(|c| c.has_tag_name(tag))
                .map(|p| {
                    let entries = p
                        .children()
                        .filter(|c| c.has_tag_name("Entry"))
                        .map(|e| {
                            (
                                text(e, "Index").into(),
                                text(e, "SubIndex").into(),
                                text(e, "BitLen").into(),
                                text(e, "Name").into(),
                                text(e, "DataType").into(),
                            )
                        })
                        .collect();
                    (
                        text(p, "Index").into(),
                        p.attribute("Sm").map(Into::into),
                        text(p, "Name").into(),
                        entries,
                    )
                })
                .collect()
        };
        let e = |i: &str, b: &str, n: &str, t: &str| {
            (
                i.to_string(),
                "0".to_string(),
                b.to_string(),
                n.to_string(),
                t.to_string(),
            )
        };
        let rx = pdos("RxPdo");
        assert_eq!(rx.len(), 4);
        assert_eq!(
            rx[0],
            (
                "#x1600".into(),
                Some("2".into()),
                "Outputs".into(),
                vec![e("#x6040", "16", "controlword", "UINT")]
            )
        );
        assert_eq!(rx[1].1, None);
        assert_eq!(rx[1].2, "RxPDO 2");
        assert_eq!(
            rx[1].3,
            vec![
                e("#x6040", "16", "controlword", "UINT"),
                e("#x6060", "8", "modes_of_operation", "SINT")
            ]
        );
        assert_eq!(rx[3].3[1], e("#x60FF", "32", "target_velocity", "DINT"));
        let tx = pdos("TxPdo");
        assert_eq!(tx.len(), 4);
        assert_eq!(
            tx[0],
            (
                "#x1A00".into(),
                Some("3".into()),
                "Inputs".into(),
                vec![e("#x6041", "16", "statusword", "UINT")]
            )
        );
        assert_eq!(
            tx[2].3[1],
            e("#x6064", "32", "position_actual_value", "DINT")
        );
    }

    #[test]
    fn esi_dictionary_types_and_objects() {
        let s = xml();
        let doc = roxmltree::Document::parse(&s).unwrap();
        let dict = doc
            .descendants()
            .find(|n| n.has_tag_name("Dictionary"))
            .unwrap();
        let profile = dict.parent().unwrap();
        assert_eq!(text(profile, "ProfileNo"), "402");
        assert_eq!(text(profile, "AddInfo"), "2");
        let types: BTreeMap<String, roxmltree::Node> = child(dict, "DataTypes")
            .children()
            .filter(|c| c.has_tag_name("DataType"))
            .map(|t| (text(t, "Name").to_string(), t))
            .collect();
        let objects: Vec<_> = child(dict, "Objects")
            .children()
            .filter(|c| c.has_tag_name("Object"))
            .collect();
        assert_eq!(objects.len(), cmmp().objects.len());
        // Every type an object or sub-item names is defined.
        for o in &objects {
            let t = text(*o, "Type");
            assert!(types.contains_key(t), "type {t} of {}", text(*o, "Index"));
        }
        for t in types.values() {
            for si in t.children().filter(|c| c.has_tag_name("SubItem")) {
                assert!(types.contains_key(text(si, "Type")));
            }
        }
        let obj = |idx: &str| *objects.iter().find(|o| text(**o, "Index") == idx).unwrap();
        // 6041h statusword: UINT, ro, TxPDO-mappable.
        let sw = obj("#x6041");
        assert_eq!(text(sw, "Name"), "statusword");
        assert_eq!(text(sw, "Type"), "UINT");
        assert_eq!(text(sw, "BitSize"), "16");
        let flags = child(sw, "Flags");
        assert_eq!(text(flags, "Access"), "ro");
        assert_eq!(text(flags, "PdoMapping"), "T");
        // 6040h controlword: rw, RxPDO-mappable.
        let cw = child(obj("#x6040"), "Flags");
        assert_eq!((text(cw, "Access"), text(cw, "PdoMapping")), ("rw", "R"));
        // 1000h device type 0x00020192, little-endian.
        assert_eq!(
            text(child(obj("#x1000"), "Info"), "DefaultData"),
            "92010200"
        );
        // 1008h string default.
        assert_eq!(
            text(child(obj("#x1008"), "Info"), "DefaultString"),
            "CMMP-AS-C2-3A-M3"
        );
        assert_eq!(text(obj("#x1008"), "Type"), "STRING(32)");
        // 1600h record: DT1600 with sub-items and offsets, defaults per sub.
        let dt = types["DT1600"];
        let subs: Vec<_> = dt
            .children()
            .filter(|c| c.has_tag_name("SubItem"))
            .collect();
        assert_eq!(subs.len(), 5);
        assert_eq!(text(subs[0], "SubIdx"), "0");
        assert_eq!(text(subs[0], "Type"), "USINT");
        assert_eq!(text(subs[1], "BitOffs"), "16");
        assert_eq!(text(subs[2], "BitOffs"), "48");
        assert_eq!(text(dt, "BitSize"), "144");
        assert_eq!(text(obj("#x1600"), "Type"), "DT1600");
        let info = child(obj("#x1600"), "Info");
        let si: Vec<_> = info
            .children()
            .filter(|c| c.has_tag_name("SubItem"))
            .collect();
        assert_eq!(
            text(si[1], "Name"),
            text(subs[1], "Name"),
            "sub-items matched by name"
        );
        assert_eq!(text(child(si[1], "Info"), "DefaultData"), "10004060");
        // COB-IDs: $NODEID resolved for the default node (1800h:01 = C0000180h + 1).
        let tpdo1 = child(obj("#x1800"), "Info");
        let cob = tpdo1
            .children()
            .filter(|c| c.has_tag_name("SubItem"))
            .nth(1)
            .unwrap();
        assert_eq!(text(child(cob, "Info"), "DefaultData"), "810100C0");
        // Identity 1018h:01 = vendor.
        let id = child(obj("#x1018"), "Info");
        let v = id
            .children()
            .filter(|c| c.has_tag_name("SubItem"))
            .nth(1)
            .unwrap();
        assert_eq!(text(child(v, "Info"), "DefaultData"), "1D000000");
    }

    #[test]
    fn xml_escaping() {
        assert_eq!(
            Xml(r#"a<b>&"c'"#).to_string(),
            "a&lt;b&gt;&amp;&quot;c&apos;"
        );
        assert_eq!(Xml("x\u{1}y").to_string(), "x?y");
        let mut s = String::new();
        let cfg = EsiConfig {
            group_name: "<Drives & \"Motors\">",
            ..EsiConfig::from_description(cmmp())
        };
        write_esi_with(cmmp(), &cfg, &mut s).unwrap();
        let doc = roxmltree::Document::parse(&s).unwrap();
        let g = doc.descendants().find(|n| n.has_tag_name("Group")).unwrap();
        assert_eq!(text(g, "Name"), "<Drives & \"Motors\">");
    }

    /// The modes a configurator offers are the ones the slave runs: SM-synchronous (0x0981 =
    /// 0) and DC with SYNC0 at the master's cycle (0x0981 = 03h, what SOEM's `ecx_dcsync0`
    /// writes; `ethercat_cell.rs` runs the slave in both from these values).
    #[test]
    fn esi_dc_offers_sm_synchronous_and_sync0() {
        let s = xml();
        let doc = roxmltree::Document::parse(&s).unwrap();
        let dc = doc.descendants().find(|n| n.has_tag_name("Dc")).unwrap();
        let modes: Vec<_> = dc
            .children()
            .filter(|c| c.has_tag_name("OpMode"))
            .map(|m| {
                let fields: Vec<(&str, Option<&str>, &str)> = m
                    .children()
                    .filter(|c| c.is_element())
                    .map(|c| {
                        (
                            c.tag_name().name(),
                            c.attribute("Factor"),
                            c.text().unwrap_or(""),
                        )
                    })
                    .collect();
                fields
            })
            .collect();
        assert_eq!(
            modes,
            [
                vec![
                    ("Name", None, "SM-Synchron"),
                    ("Desc", None, "SM-Synchron"),
                    ("AssignActivate", None, "#x0"),
                ],
                vec![
                    ("Name", None, "DC"),
                    ("Desc", None, "DC-Synchron"),
                    ("AssignActivate", None, "#x300"),
                    ("CycleTimeSync0", Some("1"), "0"),
                    ("ShiftTimeSync0", None, "0"),
                ],
            ]
        );
    }

    #[test]
    fn every_personality_exports_well_formed_esi() {
        for d in devices::ALL {
            let mut s = String::new();
            write_esi(d, &mut s).unwrap();
            roxmltree::Document::parse(&s).unwrap_or_else(|e| panic!("{}: {e}", d.name));
        }
    }

    #[test]
    fn esi_passes_xmllint() {
        let Ok(out) = std::process::Command::new("xmllint")
            .arg("--version")
            .output()
        else {
            eprintln!("skipped: xmllint not installed (Debian package libxml2-utils)");
            return;
        };
        assert!(out.status.success() || !out.stderr.is_empty());
        let path = std::env::temp_dir().join(format!("drivetwin-esi-{}.xml", std::process::id()));
        std::fs::write(&path, xml()).unwrap();
        let res = std::process::Command::new("xmllint")
            .arg("--noout")
            .arg(&path)
            .output()
            .unwrap();
        let _ = std::fs::remove_file(&path);
        assert!(
            res.status.success(),
            "xmllint: {}",
            String::from_utf8_lossy(&res.stderr)
        );
    }
}
