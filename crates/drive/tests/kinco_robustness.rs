//! Whatever a master writes, the Kinco goes on: any sequence of writes to any entry of the
//! FD3 (right-sized most of the time, any bytes), controlwords, modes, simulated inputs
//! (digital, analog, pulses) and time steps never panics, every refused write answers an SDO
//! abort code, and once the inputs are the bus's again (no DIN function) the drive takes the
//! enable sequence or reports its fault.

mod kinco_rig;

use drive::device_control::State;
use kinco_rig::Rig;
use od::ObjectAccess;
use proptest::prelude::*;

#[derive(Debug, Clone)]
enum Step {
    /// A write to the `n`th entry of the description (modulo their number).
    Write(usize, Vec<u8>),
    Controlword(u16),
    Mode(i8),
    Inputs(u16),
    Analog(u8, f64),
    Pulses(f64),
    Run(u64),
}

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        6 => (any::<usize>(), prop_oneof![
                4 => prop::collection::vec(any::<u8>(), 1..=4),
                1 => prop::collection::vec(any::<u8>(), 0..12),
            ]).prop_map(|(n, v)| Step::Write(n, v)),
        2 => any::<u16>().prop_map(Step::Controlword),
        1 => (-5i8..8).prop_map(Step::Mode),
        1 => any::<u16>().prop_map(Step::Inputs),
        1 => (0u8..4, -20.0f64..20.0).prop_map(|(n, v)| Step::Analog(n, v)),
        1 => (-1e6f64..1e6).prop_map(Step::Pulses),
        2 => (1u64..200).prop_map(Step::Run),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

    #[test]
    fn any_writes_leave_the_kinco_working(steps in prop::collection::vec(step(), 1..40)) {
        let mut r = Rig::new();
        let desc = devices::by_name("kinco-fd3").expect("the FD3");
        let entries: Vec<_> = desc.entries().collect();
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
                Step::Inputs(levels) => r.d.force_inputs(0x7F, *levels),
                Step::Analog(n, v) => r.d.set_analog_input(*n, *v),
                Step::Pulses(f) => r.d.set_pulse_input(*f),
                Step::Run(ms) => r.run_ms(*ms),
            }
        }
        r.run_ms(100);
        // The inputs back to the bus: no functions, no simulation, no pulses.
        for sub in 0x02..=0x09u8 {
            let _ = r.d.write(0x2010, sub, &[0, 0]);
        }
        r.d.force_inputs(0, 0);
        r.d.set_pulse_input(0.0);
        let _ = r.d.write(0x6060, 0, &[3]);
        r.run_ms(20);
        for cw in [0x0000u16, 0x0080, 0x0000, 0x0006, 0x000F] {
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
