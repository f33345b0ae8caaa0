//! Whatever a master writes, the Nanotec goes on: any sequence of writes to any entry of
//! the SMCI47-S (right-sized most of the time, any bytes), controlwords, SYNCs and time
//! steps never panics, every refused write answers an SDO abort code, and afterwards the
//! drive still takes the enable sequence (fault reset, 06h, 07h, 0Fh) or reports its fault.

mod nanotec_rig;

use drive::device_control::State;
use nanotec_rig::Rig;
use od::ObjectAccess;
use proptest::prelude::*;

#[derive(Debug, Clone)]
enum Step {
    /// A write to the `n`th entry of the description (modulo their number).
    Write(usize, Vec<u8>),
    Controlword(u16),
    Mode(i8),
    Sync,
    Run(u64),
}

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        6 => (any::<usize>(), prop_oneof![
                4 => prop::collection::vec(any::<u8>(), 1..=4),
                1 => prop::collection::vec(any::<u8>(), 0..12),
            ]).prop_map(|(n, v)| Step::Write(n, v)),
        2 => any::<u16>().prop_map(Step::Controlword),
        1 => (-3i8..9).prop_map(Step::Mode),
        1 => Just(Step::Sync),
        2 => (1u64..200).prop_map(Step::Run),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    #[test]
    fn any_writes_leave_the_nanotec_working(steps in prop::collection::vec(step(), 1..40)) {
        let mut r = Rig::new();
        let entries: Vec<_> = devices::NANOTEC_SMCI47S.entries().collect();
        for s in &steps {
            match s {
                Step::Write(n, bytes) => {
                    let e = entries[n % entries.len()];
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
                Step::Mode(m) => {
                    let _ = r.d.write(0x6060, 0, &[*m as u8]);
                }
                Step::Sync => {
                    let now = r.now;
                    r.d.sync(now);
                }
                Step::Run(ms) => r.run_ms(*ms),
            }
        }
        r.run_ms(100);
        // Fault reset, then the enable sequence.
        for cw in [0x0000u16, 0x0080, 0x0000, 0x0006, 0x0007, 0x000F] {
            let _ = r.d.write(0x6040, 0, &cw.to_le_bytes());
            r.run_ms(20);
        }
        // A brake wait time the sequence wrote (2007h) delays the motion, not the state.
        let state = r.d.state();
        prop_assert!(
            state == State::OperationEnabled || state == State::Fault,
            "neither enabled nor in a fault it reports: {:?}",
            state
        );
    }
}
