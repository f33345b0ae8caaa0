//! Whatever a master writes, the CMMP-AS goes on: any sequence of writes to any of its
//! entries (the value's own size most of the time, any length now and then, any bytes),
//! controlwords and time steps never panics, every refused write answers an SDO abort code,
//! and afterwards the drive still takes the CiA 402 enable sequence from "switch on
//! disabled" once its faults are reset (spec cmmp-as §6, CiA 402 transitions 15, 2, 3, 4).

mod cmmp_rig;

use cmmp_rig::Rig;
use drive::device_control::State;
use od::ObjectAccess;
use proptest::prelude::*;

#[derive(Debug, Clone)]
enum Step {
    /// A write to the `n`th entry of the description (modulo their number).
    Write(usize, Vec<u8>),
    Controlword(u16),
    Run(u64),
}

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        6 => (any::<usize>(), prop_oneof![
                4 => prop::collection::vec(any::<u8>(), 1..=4),
                1 => prop::collection::vec(any::<u8>(), 0..12),
            ]).prop_map(|(n, v)| Step::Write(n, v)),
        2 => any::<u16>().prop_map(Step::Controlword),
        2 => (1u64..200).prop_map(Step::Run),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn any_writes_leave_the_drive_working(steps in prop::collection::vec(step(), 1..40)) {
        let mut r = Rig::new();
        let entries: Vec<_> = devices::CMMP_AS.entries().collect();
        for s in &steps {
            match s {
                Step::Write(n, bytes) => {
                    let e = entries[n % entries.len()];
                    // Right-sized most of the time, so the checks behind the size are reached.
                    let data = match e.data_type.fixed_size() {
                        Some(size) if bytes.len() <= 4 => {
                            let mut v = bytes.clone();
                            v.resize(size, 0);
                            v
                        }
                        _ => bytes.clone(),
                    };
                    if let Err(abort) = r.d.write(e.index, e.sub, &data) {
                        prop_assert!(abort.0 >> 24 == 0x05 || abort.0 >> 24 == 0x06 || abort.0 >> 24 == 0x08,
                            "{:04X}h:{}: abort {:08X}", e.index, e.sub, abort.0);
                    }
                }
                Step::Controlword(cw) => {
                    let _ = r.d.write(0x6040, 0, &cw.to_le_bytes());
                }
                Step::Run(ms) => r.run_ms(*ms),
            }
        }
        r.run_ms(100);
        // Back to the defaults of the control objects the sequence may have spoiled, then the
        // enable sequence: fault reset, shutdown, switch on, enable operation.
        for cw in [0x0000u16, 0x0080, 0x0000, 0x0006, 0x0007, 0x000F] {
            let _ = r.d.write(0x6040, 0, &cw.to_le_bytes());
            r.run_ms(20);
        }
        let state = r.d.state();
        prop_assert!(
            state == State::OperationEnabled || state == State::Fault,
            "neither enabled nor in a fault it reports: {:?}",
            state
        );
    }
}
