//! Whatever frame reaches the Kinco RTU server (any bytes, any length, a valid CRC or not),
//! it answers without a panic, only to its own station, with a frame whose CRC is right and
//! whose function code is the request's or an error code.

use drive::vendors::kinco::rtu::{ErrorStyle, KincoRtu, RegisterMapping, MAX_FRAME};
use modbus::rtu;
use od::ObjectDictionary;
use proptest::prelude::*;

fn frame() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        prop::collection::vec(any::<u8>(), 0..40),
        // Station 0-2, a Kinco function code, a register near the mapped ones, a valid CRC.
        (
            0u8..=2,
            prop::sample::select(vec![0x03u8, 0x06, 0x10, 0x04]),
            prop::sample::select(vec![
                0x3100u16, 0x3200, 0x3500, 0x6F00, 0x4000, 0x5010, 0x1234
            ]),
            prop::collection::vec(any::<u8>(), 0..12)
        )
            .prop_map(|(st, fc, reg, rest)| {
                let mut f = vec![st, fc];
                f.extend_from_slice(&reg.to_be_bytes());
                f.extend_from_slice(&rest);
                let crc = rtu::crc_bytes(&f);
                f.extend_from_slice(&crc);
                f
            }),
    ]
}

proptest! {
    #[test]
    fn any_frame_gets_a_well_formed_reply_or_none(frames in prop::collection::vec(frame(), 1..40)) {
        let d = &devices::KINCO_FD3;
        let mut od = ObjectDictionary::new(d, 1, vec![0; d.storage_size]).unwrap();
        let map: Vec<RegisterMapping> = devices::addresses("kinco-fd3").unwrap().modbus.iter()
            .map(|r| RegisterMapping { register: r.register, index: r.index, sub: r.sub }).collect();
        let server = KincoRtu { station: 1, map: &map, errors: ErrorStyle::Read81h };
        for f in frames {
            let mut out = [0u8; MAX_FRAME];
            if let Ok(n) = server.handle_frame(&f, &mut od, &mut out) {
                let reply = &out[..n];
                prop_assert!(rtu::check_frame(reply));
                prop_assert_eq!(reply[0], 1);
                prop_assert_eq!(f[0], 1);
                let fc = f[1];
                prop_assert!(reply[1] == fc || reply[1] == fc | 0x80 || (fc == 3 && reply[1] == 0x81));
            }
        }
    }
}
