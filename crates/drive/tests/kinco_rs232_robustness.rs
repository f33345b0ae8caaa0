//! Whatever arrives on a Kinco RS232 line (short telegrams, bad checksums, other stations,
//! garbage at any pace), the port goes on: no panic, only whole checksum-valid 10-byte
//! telegrams go out, everything else is counted, and a valid telegram after a silence is
//! answered.

use drive::vendors::kinco::rs232::{
    checksum, checksum_ok, KincoRs232, Request, Telegram, DEFAULT_GAP,
};
use od::{Instant, ObjectDictionary};
use proptest::prelude::*;

#[derive(Debug, Clone)]
enum Event {
    Bytes(Vec<u8>),
    /// A telegram to station 1 or 2 with any command and data, checksum valid or not.
    Telegram([u8; 9], bool),
    Pause(u64),
}

fn event() -> impl Strategy<Value = Event> {
    prop_oneof![
        3 => prop::collection::vec(any::<u8>(), 0..25).prop_map(Event::Bytes),
        3 => (any::<[u8; 9]>(), 1u8..=2, any::<bool>()).prop_map(|(mut b, id, ok)| {
            b[0] = id;
            Event::Telegram(b, ok)
        }),
        1 => (0u64..50).prop_map(Event::Pause),
    ]
}

proptest! {
    #[test]
    fn any_bytes_leave_the_port_answering(events in prop::collection::vec(event(), 0..60), ring in any::<bool>()) {
        let d = &devices::KINCO_FD3;
        let mut od = ObjectDictionary::new(d, 1, vec![0; d.storage_size]).unwrap();
        let mut port = KincoRs232::new(1, ring);
        let mut now = Instant::ZERO;
        let mut out: Vec<Vec<u8>> = Vec::new();
        for e in events {
            match e {
                Event::Bytes(b) => port.on_bytes(now, &b, &mut od, &mut |a| out.push(a.to_vec())),
                Event::Telegram(body, ok) => {
                    let mut t = [0u8; 10];
                    t[..9].copy_from_slice(&body);
                    t[9] = checksum(&body).wrapping_add(u8::from(!ok));
                    port.on_bytes(now, &t, &mut od, &mut |a| out.push(a.to_vec()));
                }
                Event::Pause(ms) => now = now + std::time::Duration::from_millis(ms),
            }
            now = now + std::time::Duration::from_micros(100);
        }
        for a in &out {
            prop_assert_eq!(a.len(), 10);
            if !ring {
                let t: Telegram = a.as_slice().try_into().unwrap();
                prop_assert!(checksum_ok(&t));
                prop_assert_eq!(t[0], 1);
            }
        }
        // After a silence the line is in step again: a read of 1018h:02 is answered.
        now = now + DEFAULT_GAP + std::time::Duration::from_millis(1);
        let req = Request::Read { index: 0x1018, sub: 2 }.emit(1);
        let mut answer = Vec::new();
        port.on_bytes(now, &req, &mut od, &mut |a| answer.extend_from_slice(a));
        let tail = &answer[answer.len() - 10..];
        prop_assert_eq!(&tail[..5], &[0x01, 0x43, 0x18, 0x10, 0x02][..]);
    }
}
