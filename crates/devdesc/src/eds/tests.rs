//! The EDS reader on small files written here: each test names what CiA 306 says.

use super::*;

/// A minimal CiA 402 EDS; `extra` is appended (more sections), `optional` lists more objects.
fn eds(optional: &[u16], extra: &str) -> String {
    let mut s = String::from(
        "[FileInfo]\nFileName=t.eds\nDescription=test drive\n\n\
         [DeviceInfo]\nVendorName=V\nVendorNumber=0x1234\nProductName=P\nProductNumber=7\n\
         RevisionNumber=0x10002\nBaudRate_125=1\nBaudRate_500=1\nLSS_Supported=1\n\n\
         [MandatoryObjects]\nSupportedObjects=3\n1=0x1000\n2=0x1001\n3=0x1018\n\n\
         [1000]\nParameterName=Device type\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\n\
         DefaultValue=0x00020192\nPDOMapping=0\n\n\
         [1001]\nParameterName=Error register\nDataType=0x0005\nAccessType=ro\nDefaultValue=0\n\
         PDOMapping=1\n\n\
         [1018]\nParameterName=Identity\nObjectType=0x9\nSubNumber=2\n\n\
         [1018sub0]\nParameterName=Highest sub-index supported\nDataType=0x0005\nAccessType=ro\n\
         DefaultValue=1\n\n\
         [1018sub1]\nParameterName=Vendor-ID\nDataType=0x0007\nAccessType=ro\nDefaultValue=0x1234\n\n",
    );
    s.push_str(&format!(
        "[OptionalObjects]\nSupportedObjects={}\n",
        optional.len()
    ));
    for (i, o) in optional.iter().enumerate() {
        s.push_str(&format!("{}=0x{o:04X}\n", i + 1));
    }
    s.push('\n');
    s.push_str(extra);
    s
}

fn err(optional: &[u16], extra: &str) -> String {
    match parse(&eds(optional, extra), "dir/t.eds") {
        Ok(_) => panic!("accepted: {extra}"),
        Err(e) => e.to_string(),
    }
}

/// The line `needle` is on in the file `eds(optional, extra)`.
fn line_of(optional: &[u16], extra: &str, needle: &str) -> usize {
    eds(optional, extra)
        .lines()
        .position(|l| l == needle)
        .map(|i| i + 1)
        .unwrap()
}

const CONTROLWORD: &str = "[6040]\nParameterName=Controlword\nObjectType=0x7\nDataType=0x0006\n\
                           AccessType=rww\nDefaultValue=0\nPDOMapping=1\n\n";

#[test]
fn identity_types_access_and_profile() {
    let e = parse(&eds(&[0x6040], CONTROLWORD), "dir/EPOS4 like.eds").unwrap();
    let d = &e.device;
    assert_eq!(d.name, "epos4-like");
    assert_eq!(
        (d.vendor_id, d.product_code, d.revision),
        (0x1234, 7, 0x10002)
    );
    assert_eq!(d.baud_rates, [125, 500]);
    assert!(!d.cia301.lss_unsupported);
    assert_eq!(d.profile, od::Profile::Cia402);
    // A drive without its statusword is refused at the list of the profile's objects.
    let line = line_of(&[0x6040], CONTROLWORD, "[OptionalObjects]") + 1;
    assert_eq!(
        e.require_cia402().unwrap_err().to_string(),
        format!(
            "dir/EPOS4 like.eds:{line}: [OptionalObjects] SupportedObjects: missing: object \
             6041h, which every CiA 402 drive has (CiA 402 §6)"
        )
    );
    let cw = &d
        .objects
        .iter()
        .find(|o| o.index == 0x6040)
        .unwrap()
        .entries[0];
    assert_eq!(cw.data_type, DataType::Unsigned16);
    assert_eq!(cw.access, Access::ReadWrite);
    assert!(cw.pdo);
    assert!(!cw.storable, "RPDO-mappable process data is not saved");
    let id = d.objects.iter().find(|o| o.index == 0x1018).unwrap();
    assert_eq!(id.kind, ObjectKind::Record);
    assert_eq!(id.entries.len(), 2);
    assert_eq!(id.entries[1].name, "Vendor-ID");
}

#[test]
fn a_device_that_is_not_a_drive_is_refused_at_its_device_type() {
    let text = eds(&[], "").replace("DefaultValue=0x00020192", "DefaultValue=0x00000191");
    let e = parse(&text, "io.eds").unwrap();
    let msg = e.require_cia402().unwrap_err().to_string();
    let line = line_of(&[], "", "DefaultValue=0x00020192");
    assert!(
        msg.starts_with(&format!("io.eds:{line}: [1000] DefaultValue: ")),
        "{msg}"
    );
}

/// CiA 306 §4.6.3: `$NODEID+constant`; the dictionary adds the node-ID.
#[test]
fn node_relative_defaults() {
    let tpdo = "[1800]\nParameterName=TPDO1\nObjectType=0x9\nSubNumber=2\n\n\
                [1800sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\nDefaultValue=1\n\n\
                [1800sub1]\nParameterName=COB-ID\nDataType=0x0007\nAccessType=rw\n\
                DefaultValue=$NODEID+0x40000180\n\n";
    let d = parse(&eds(&[0x1800], tpdo), "t.eds").unwrap().device;
    let e = &d
        .objects
        .iter()
        .find(|o| o.index == 0x1800)
        .unwrap()
        .entries[1];
    assert!(e.default_plus_node_id);
    assert_eq!(e.default, 0x4000_0180u32.to_le_bytes());
    assert_eq!(e.behaviour, Behaviour::PdoCobId);
    let bad = tpdo.replace("$NODEID+0x40000180", "$NODEID*2");
    let msg = err(&[0x1800], &bad);
    let line = line_of(&[0x1800], &bad, "DefaultValue=$NODEID*2");
    assert!(
        msg.starts_with(&format!(
            "dir/t.eds:{line}: [1800sub1] DefaultValue: not supported"
        )),
        "{msg}"
    );
}

#[test]
fn limits_and_defaults_are_checked() {
    let var = |extra: &str| {
        format!(
            "[607A]\nParameterName=Target position\nDataType=0x0004\nAccessType=rww\n\
             PDOMapping=1\n{extra}\n"
        )
    };
    let d = parse(
        &eds(
            &[0x607A],
            &var("LowLimit=0x80000000\nHighLimit=0x7FFFFFFF\nDefaultValue=-5"),
        ),
        "t.eds",
    )
    .unwrap()
    .device;
    let e = &d
        .objects
        .iter()
        .find(|o| o.index == 0x607A)
        .unwrap()
        .entries[0];
    assert_eq!(e.min, Some(Limit::Signed(i64::from(i32::MIN))));
    assert_eq!(e.max, Some(Limit::Unsigned(i32::MAX as u64)));
    assert_eq!(e.default, (-5i32).to_le_bytes());
    let outside = var("LowLimit=0\nDefaultValue=-5");
    let line = line_of(&[0x607A], &outside, "DefaultValue=-5");
    assert_eq!(
        err(&[0x607A], &outside),
        format!("dir/t.eds:{line}: [607A] DefaultValue: -5 is outside LowLimit / HighLimit")
    );
    assert!(err(&[0x607A], &var("LowLimit=5\nHighLimit=4")).contains("[607A] HighLimit: below"));
    assert!(err(&[0x607A], &var("DefaultValue=0x100000000")).contains("does not fit INTEGER32"));
    assert!(err(&[0x607A], &var("DefaultValue=ten")).contains("[607A] DefaultValue:"));
}

#[test]
fn types_access_and_flags_are_named_when_wrong() {
    let var = |t: &str, a: &str, p: &str| {
        format!("[2000]\nParameterName=x\nDataType={t}\nAccessType={a}\nPDOMapping={p}\n\n")
    };
    assert!(err(&[], &var("0x0007", "rw", "0")).contains("[2000]: object 2000h is in none of"));
    let e = |t: &str, a: &str, p: &str| {
        let mut text = eds(&[], &var(t, a, p));
        text = text.replace(
            "[OptionalObjects]\nSupportedObjects=0\n",
            "[ManufacturerObjects]\nSupportedObjects=1\n1=0x2000\n",
        );
        parse(&text, "m.eds").map(|_| ()).unwrap_err().to_string()
    };
    assert!(
        e("0x000C", "rw", "0").contains("[2000] DataType: not supported: data type TIME_OF_DAY")
    );
    assert!(e("0x0099", "rw", "0").contains("[2000] DataType: 0x0099 is no CiA 301 data type"));
    assert!(e("0x0007", "readwrite", "0").contains("[2000] AccessType: \"readwrite\""));
    assert!(e("0x0007", "rw", "2").contains("[2000] PDOMapping: 2: 0 or 1"));
}

#[test]
fn structure_mistakes_are_named() {
    // A listed object without its section: named at the list's line.
    let msg = err(&[0x6041], "");
    assert!(
        msg.contains("[OptionalObjects] 1: missing: the section [6041]"),
        "{msg}"
    );
    // SubNumber disagrees with the sub-sections.
    let rec = "[2001]\nParameterName=r\nObjectType=0x9\nSubNumber=3\n\n\
               [2001sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\nDefaultValue=1\n\n\
               [2001sub1]\nParameterName=a\nDataType=0x0007\nAccessType=rw\n\n";
    assert!(err(&[0x2001], rec).contains("[2001] SubNumber: SubNumber=3 but the file has 2"));
    let no_sub0 = "[2001]\nParameterName=r\nObjectType=0x9\nSubNumber=1\n\n\
                   [2001sub1]\nParameterName=a\nDataType=0x0007\nAccessType=rw\n\n";
    assert!(err(&[0x2001], no_sub0).contains("missing: [2001sub0]"));
    // A VAR with sub-indices, a missing name, an unknown object code.
    let var_subs = format!("{CONTROLWORD}[6040sub1]\nParameterName=x\n\n");
    assert!(err(&[0x6040], &var_subs).contains("[6040sub1]: 6040h is a VAR"));
    assert!(err(
        &[0x6040],
        &CONTROLWORD.replace("ParameterName=Controlword\n", "")
    )
    .contains("[6040] ParameterName: missing"));
    assert!(err(&[0x6040], &CONTROLWORD.replace("0x7", "0x3")).contains("no object code"));
    // A sub-index of an object no list names.
    let orphan = "[2002sub1]\nParameterName=x\nDataType=0x0007\nAccessType=rw\n\n";
    assert!(err(&[], orphan).contains("[2002sub1]: object 2002h is in none of"));
    // A byte-order mark is not part of the first line.
    assert!(parse(&format!("\u{feff}{}", eds(&[], "")), "t.eds").is_ok());
    // SupportedObjects and its numbered keys agree.
    let text = eds(&[0x6040], CONTROLWORD).replace("1=0x6040\n", "1=0x6040\n2=0x6041\n");
    let msg = parse(&text, "t.eds").unwrap_err().to_string();
    assert!(
        msg.contains("[OptionalObjects] 2: beyond SupportedObjects=1"),
        "{msg}"
    );
}

/// CiA 306 §4.6.4: `CompactSubObj` with `[IIIIName]`; a DCF's `[IIIIValue]` and
/// `ParameterValue` set the values the device starts with.
#[test]
fn compact_arrays_and_dcf_values() {
    let array = "[6502]\nParameterName=Supported drive modes\nDataType=0x0007\nAccessType=ro\n\
                 DefaultValue=0x25\n\n\
                 [2100]\nParameterName=Gain\nObjectType=0x8\nCompactSubObj=3\nDataType=0x0006\n\
                 AccessType=rw\nDefaultValue=10\nPDOMapping=0\n\n\
                 [2100Name]\nNrOfEntries=1\n2=Integral gain\n\n\
                 [2100Value]\nNrOfEntries=1\n3=0x20\n\n";
    let mut text = eds(&[0x6502], array);
    text = text.replace(
        "[OptionalObjects]",
        "[ManufacturerObjects]\nSupportedObjects=1\n1=0x2100\n\n[OptionalObjects]",
    );
    text = text.replace(
        "DefaultValue=0x25\n",
        "DefaultValue=0x25\nParameterValue=0x21\n",
    );
    text.push_str("[DeviceComissioning]\nNodeID=5\n");
    let e = parse(&text, "drive.dcf").unwrap();
    assert_eq!(e.node_id, Some(5));
    assert_eq!(e.device.default_node_id, 5);
    let o = e.device.objects.iter().find(|o| o.index == 0x2100).unwrap();
    assert_eq!(o.kind, ObjectKind::Array);
    let subs: Vec<(u8, &str, Vec<u8>)> = o
        .entries
        .iter()
        .map(|e| (e.sub, e.name.as_str(), e.default.clone()))
        .collect();
    assert_eq!(
        subs,
        [
            (0, "Number of entries", vec![3]),
            (1, "Gain1", vec![10, 0]),
            (2, "Integral gain", vec![10, 0]),
            (3, "Gain3", vec![0x20, 0]),
        ]
    );
    let modes = e.device.objects.iter().find(|o| o.index == 0x6502).unwrap();
    assert_eq!(modes.entries[0].default, 0x21u32.to_le_bytes());
}

/// CiA 301 §7.5.2.38: a default mapping names mappable objects, whole, at most 64 bits.
#[test]
fn default_pdo_mappings_are_checked() {
    let map = |count: u8, first: &str| {
        format!(
            "{CONTROLWORD}[1600]\nParameterName=RPDO1 mapping\nObjectType=0x9\nSubNumber=3\n\n\
             [1600sub0]\nParameterName=n\nDataType=0x0005\nAccessType=rw\nDefaultValue={count}\n\n\
             [1600sub1]\nParameterName=1\nDataType=0x0007\nAccessType=rw\nDefaultValue={first}\n\n\
             [1600sub2]\nParameterName=2\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x00050008\n\n"
        )
    };
    let d = parse(&eds(&[0x1600, 0x6040], &map(2, "0x60400010")), "t.eds")
        .unwrap()
        .device;
    let o = d.objects.iter().find(|o| o.index == 0x1600).unwrap();
    assert_eq!(o.entries[0].behaviour, Behaviour::PdoMapCount);
    assert_eq!(o.entries[1].behaviour, Behaviour::PdoMapEntry);
    let wrong_len = map(1, "0x60400008");
    let line = line_of(&[0x1600, 0x6040], &wrong_len, "DefaultValue=0x60400008");
    let msg = err(&[0x1600, 0x6040], &wrong_len);
    assert!(
        msg.starts_with(&format!(
            "dir/t.eds:{line}: [1600sub1] DefaultValue: maps 6040h"
        )),
        "{msg}"
    );
    assert!(err(&[0x1600, 0x6040], &map(1, "0x60410010")).contains("does not define"));
    assert!(err(&[0x1600, 0x6040], &map(3, "0x60400010")).contains("only 2 mapping entries"));
}

#[test]
fn compact_pdo_and_type_definitions_are_refused() {
    let text = eds(&[], "").replace("LSS_Supported=1\n", "LSS_Supported=1\nCompactPDO=1\n");
    let msg = parse(&text, "c.eds").unwrap_err().to_string();
    assert!(
        msg.contains("[DeviceInfo] CompactPDO: not supported"),
        "{msg}"
    );
    let deftype = "[0007]\nParameterName=UNSIGNED32\nObjectType=0x5\n\n";
    let text = eds(&[0x0007], deftype);
    let msg = parse(&text, "c.eds").unwrap_err().to_string();
    assert!(msg.contains("[0007] ObjectType: not supported"), "{msg}");
}

/// What `drivetwin eds` writes reads back as the description it came from, for every device
/// file.
#[test]
fn a_written_eds_reads_back() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../devices");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 5);
    for path in files {
        let d = crate::load_file(&path).unwrap();
        let desc = crate::runtime::leak(&d);
        let mut text = String::new();
        od::eds::write_eds(&mut text, desc, "01-01-2026").unwrap();
        let back = parse(&text, &format!("{}.eds", d.name))
            .unwrap_or_else(|e| panic!("{}: {e}", d.name))
            .device;
        assert_eq!(back.vendor_id, d.vendor_id);
        assert_eq!(
            back.profile == od::Profile::Cia402,
            desc.entry(0x1000, 0)
                .is_some_and(|e| e.default.first() == Some(&0x92))
        );
        let written: Vec<&Ent> = d
            .objects
            .iter()
            .filter(|o| !(0x0001..=0x0007).contains(&o.index))
            .flat_map(|o| &o.entries)
            .collect();
        let read: Vec<&Ent> = back.objects.iter().flat_map(|o| &o.entries).collect();
        assert_eq!(written.len(), read.len(), "{}", d.name);
        for (w, r) in written.iter().zip(&read) {
            let at = format!("{} {:04X}:{}", d.name, w.index, w.sub);
            assert_eq!((w.index, w.sub), (r.index, r.sub), "{at}");
            assert_eq!(w.data_type, r.data_type, "{at}");
            assert_eq!(w.access.writable(), r.access.writable(), "{at}");
            assert_eq!(w.pdo, r.pdo, "{at}");
            assert_eq!(w.min, r.min, "{at}");
            assert_eq!(w.max, r.max, "{at}");
            assert_eq!(w.default_plus_node_id, r.default_plus_node_id, "{at}");
            if w.data_type != DataType::Domain {
                assert_eq!(w.default, r.default, "{at}");
            }
        }
    }
}

/// CiA 306 §4.7: a DCF's `[DeviceComissioning] Baudrate` (kbit/s) is the bit rate it is
/// commissioned to, with its line; a rate CiA 306 does not name, or one `[DeviceInfo]` does
/// not mark supported, is refused at the key; an EDS has none.
#[test]
fn dcf_bit_rate() {
    assert_eq!(parse(&eds(&[], ""), "t.eds").unwrap().bit_rate, None);
    let extra = "[DeviceComissioning]\nNodeID=3\nBaudrate=500\n";
    let e = parse(&eds(&[], extra), "drive.dcf").unwrap();
    let rate = e.bit_rate.unwrap();
    assert_eq!(rate.kbit, 500);
    assert_eq!(rate.at.line, line_of(&[], extra, "Baudrate=500"));
    assert_eq!(
        rate.at.to_string(),
        format!("drive.dcf:{}: [DeviceComissioning] Baudrate", rate.at.line)
    );
    assert_eq!(e.node_id, Some(3));
    for (bad, says) in [
        ("Baudrate=300", "300 kbit/s: one of"),
        ("Baudrate=1000", "no BaudRate_1000=1"),
        ("Baudrate=fast", "not a number"),
    ] {
        let e = err(&[], &format!("[DeviceComissioning]\n{bad}\n"));
        assert!(
            e.contains("[DeviceComissioning] Baudrate") && e.contains(says),
            "{bad}: {e}"
        );
    }
}

/// CiA 306 `[DummyUsage]`: `Dummy000n=1` lets 000nh be mapped; a default mapping of a dummy
/// the file does not allow, a value other than 0 / 1 and a key that names no dummy are
/// refused with their line; a file without the section says nothing (`None`).
#[test]
fn dummy_usage_says_which_dummies_map() {
    let usage = "[DummyUsage]\nDummy0001=0\nDummy0002=1\nDummy0005=1\nDummy0007=0\n\n";
    let d = parse(&eds(&[0x6040], &format!("{usage}{CONTROLWORD}")), "t.eds")
        .unwrap()
        .device;
    assert_eq!(d.cia301.dummy_usage, Some(1 << 2 | 1 << 5));
    let d = parse(&eds(&[0x6040], CONTROLWORD), "t.eds").unwrap().device;
    assert_eq!(d.cia301.dummy_usage, None);

    let rpdo = |dummy: &str| {
        format!(
            "{usage}{CONTROLWORD}[1600]\nParameterName=RPDO1 mapping\nObjectType=0x9\nSubNumber=3\n\n\
             [1600sub0]\nParameterName=n\nDataType=0x0005\nAccessType=rw\nDefaultValue=2\n\n\
             [1600sub1]\nParameterName=1\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x60400010\n\n\
             [1600sub2]\nParameterName=2\nDataType=0x0007\nAccessType=rw\nDefaultValue={dummy}\n\n"
        )
    };
    assert!(parse(&eds(&[0x1600, 0x6040], &rpdo("0x00050008")), "t.eds").is_ok());
    let refused = rpdo("0x00060010");
    let line = line_of(&[0x1600, 0x6040], &refused, "DefaultValue=0x00060010");
    let msg = err(&[0x1600, 0x6040], &refused);
    assert!(
        msg.starts_with(&format!(
            "dir/t.eds:{line}: [1600sub2] DefaultValue: maps the dummy 0006h"
        )),
        "{msg}"
    );

    let broken = "[DummyUsage]\nDummy0003=2\n\n";
    let line = line_of(&[], broken, "Dummy0003=2");
    let msg = err(&[], broken);
    assert!(
        msg.starts_with(&format!("dir/t.eds:{line}: [DummyUsage] Dummy0003: ")),
        "{msg}"
    );
    let unknown = "[DummyUsage]\nDummy0008=1\n\n";
    let line = line_of(&[], unknown, "Dummy0008=1");
    let msg = err(&[], unknown);
    assert!(
        msg.starts_with(&format!("dir/t.eds:{line}: [DummyUsage] Dummy0008: ")),
        "{msg}"
    );
}

/// The drive's SDO side: an RPDO mapping entry of a dummy is taken only where `[DummyUsage]`
/// allows it, else 0604 0041h (CiA 301: object cannot be mapped to the PDO); a file without
/// the section takes the dummies 0002h–0007h, as before.
#[test]
fn dummy_mapping_follows_dummy_usage() {
    use od::pdo_rules::check_map_entry;
    let usage = "[DummyUsage]\nDummy0002=1\nDummy0004=0\n\n";
    let d = parse(&eds(&[0x6040], &format!("{usage}{CONTROLWORD}")), "t.eds")
        .unwrap()
        .device;
    let desc = crate::runtime::leak(&d);
    assert_eq!(check_map_entry(desc, false, 0x0002_0008), Ok(()));
    for refused in [0x0004_0020, 0x0001_0008, 0x0007_0020] {
        assert_eq!(
            check_map_entry(desc, false, refused),
            Err(od::AbortCode::NOT_MAPPABLE),
            "{refused:08X}"
        );
    }
    // Never in a TPDO.
    assert_eq!(
        check_map_entry(desc, true, 0x0002_0008),
        Err(od::AbortCode::NOT_MAPPABLE)
    );
    let d = parse(&eds(&[0x6040], CONTROLWORD), "t.eds").unwrap().device;
    let desc = crate::runtime::leak(&d);
    assert_eq!(check_map_entry(desc, false, 0x0004_0020), Ok(()));
}
