//! Each personality's tables agree with the device files it serves: the device exists and is
//! a CiA 402 drive, 6502h says the modes 6060h accepts, the option codes read as the
//! personality has them, and every homing method fits 6098h.

use drive::drive::DriveSettings;
use drive::personality::Personality;
use drive::vendors::AnyDrive;
use od::{ObjectDictionary, Value};

/// Every vendor's personality, by the vendor's name.
const ALL: [(&str, &Personality); 3] = [
    ("CMMP-AS", &drive::vendors::festo_cmmp_as::CMMP_AS),
    ("Nanotec", &drive::vendors::nanotec::NANOTEC),
    ("Kinco", &drive::vendors::kinco::KINCO),
];

#[test]
fn tables_agree_with_the_device_files() {
    for (vendor, p) in ALL {
        assert!(!p.devices.is_empty(), "{vendor} serves no device file");
        for name in p.devices {
            let desc = devices::by_name(name).expect("a device file of this name");
            assert_eq!(desc.profile, od::Profile::Cia402, "{name}");
            let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).unwrap();
            let any = AnyDrive::new(od, DriveSettings::default());
            assert_eq!(
                any.personality().devices,
                p.devices,
                "{name} runs as {vendor}"
            );
            let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).unwrap();
            assert_eq!(
                od.get_unsigned(0x6502, 0),
                Some(u64::from(p.supported_drive_modes(false))),
                "{name}: 6502h"
            );
            for o in p.option_codes {
                assert_eq!(
                    od.value(o.index, 0),
                    Some(Value::Signed(i64::from(o.value))),
                    "{name}: {:04X}h",
                    o.index
                );
            }
            // Negative methods need a signed 6098h (Nanotec §9: "typed u8, really s8").
            let e = desc.entry(0x6098, 0).expect("6098h");
            assert_eq!(e.data_type, od::DataType::Integer8, "{name}: 6098h");
            assert!(!p.homing_methods.is_empty(), "{name}");
        }
    }
}

/// The CMMP-AS reached over EtherCAT adds CSP (6502h bit 7, mode 8); otherwise it refuses mode 8.
#[test]
fn cmmp_as_csp_over_ethercat_only() {
    let p = &drive::vendors::festo_cmmp_as::CMMP_AS;
    assert_eq!(p.supported_drive_modes(false), 0x6D);
    assert_eq!(p.supported_drive_modes(true), 0xED);
    assert!(!p.accepts_mode(8, false));
    assert!(p.accepts_mode(8, true));
}

/// Only the CMMP-AS has the 7-segment display (App. B); the Nanotec's and the Kinco's manuals
/// name none of that kind (the Kinco's LED panel is its own), nor does CiA 402 for a drive
/// from its EDS.
#[test]
fn only_the_cmmp_as_has_the_seven_segment_display() {
    let any = |name: &str| {
        let desc = devices::by_name(name).expect("a device file of this name");
        let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).unwrap();
        AnyDrive::new(od, DriveSettings::default())
    };
    assert!(any("cmmp-as").display().is_some());
    for name in ["nanotec-smci47s", "nanotec-pd4n", "kinco-fd3", "kinco-cd3"] {
        assert_eq!(any(name).display(), None, "{name}");
    }
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/interop/data/eds/lexium32_like.eds");
    let desc = devdesc::runtime::leak(&devdesc::eds::load_file(&path).unwrap().device);
    let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).unwrap();
    let generic = AnyDrive::new(od, DriveSettings::default());
    assert!(matches!(generic, AnyDrive::Cia402(_)));
    assert_eq!(generic.display(), None);
}
