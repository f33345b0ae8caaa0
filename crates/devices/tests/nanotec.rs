//! The two Nanotec personalities (the Nanotec "Referenzhandbuch CANopen" V2.5, kept beside the
//! project): what each device has, and the dictionary values the manual prints.

use od::{ObjectDictionary, Profile, Value};

fn od(d: &'static od::DeviceDescription) -> ObjectDictionary<Vec<u8>> {
    ObjectDictionary::new(d, 34, vec![0; d.storage_size]).unwrap()
}

#[test]
fn smci47s_has_brake_and_analog_input_pd4n_has_dspdrive_current_controller() {
    let smci = &devices::NANOTEC_SMCI47S;
    let pd4n = &devices::NANOTEC_PD4N;
    for d in [smci, pd4n] {
        assert_eq!(d.profile, Profile::Cia402);
        assert!(d.object(0x1008).is_none(), "the manual lists no 1008h");
        for i in (0x0001..=0x0007).chain([0x1000, 0x1003, 0x1A03, 0x2000, 0x2021, 0x6502]) {
            assert!(d.object(i).is_some(), "{}: {i:04X}h", d.name);
        }
    }
    for i in [
        0x2007, 0x6401, 0x6423, 0x6424, 0x6425, 0x6426, 0x6427, 0x6428,
    ] {
        assert!(smci.object(i).is_some(), "SMCI47-S {i:04X}h");
        assert!(pd4n.object(i).is_none(), "PD4-N {i:04X}h");
    }
    assert!(smci.object(0x200E).is_none());
    assert!(pd4n.object(0x200E).is_some());
}

/// The values the manual prints: 1000h (§9.6), default mappings (§3.2, §3.3), TPDO inhibit
/// 1000 × 100 µs (§9.18), node-relative COB-IDs, 6502h = 6Bh (NT-SC-10), 2004h:0C (NT-SC-07),
/// 604Ch 60/2000 (NT-SC-05, the decision in the file), 6092h 2000/1 (NT-SC-01).
#[test]
fn printed_defaults() {
    let od = od(&devices::NANOTEC_SMCI47S);
    let u = |i, s| od.get_unsigned(i, s);
    assert_eq!(u(0x1000, 0), Some(0x0000_0008));
    assert_eq!(u(0x1600, 0), Some(1));
    assert_eq!(u(0x1600, 1), Some(0x6040_0010));
    assert_eq!(u(0x1A00, 1), Some(0x6041_0010));
    assert_eq!(u(0x1800, 3), Some(1000));
    assert_eq!(u(0x1800, 1), Some(0x1A2));
    assert_eq!(u(0x1403, 1), Some(0x522));
    assert_eq!(u(0x1014, 0), Some(0xA2));
    assert_eq!(u(0x6502, 0), Some(0x6B));
    assert_eq!(u(0x2004, 12), Some(0x243015));
    assert_eq!(u(0x2005, 0), Some(135));
    assert_eq!(u(0x6092, 1), Some(2000));
    assert_eq!(od.value(0x604C, 1), Some(Value::Signed(60)));
    assert_eq!(od.value(0x604C, 2), Some(Value::Signed(2000)));
    assert_eq!(od.value(0x605A, 0), Some(Value::Signed(3)));
    assert_eq!(od.value(0x607B, 1), Some(Value::Signed(-100_000_000)));
    assert_eq!(u(0x200C, 0), Some(10));
    assert_eq!(u(0x2002, 0), Some(24));
    assert_eq!(u(0x2004, 0), Some(14));
}
