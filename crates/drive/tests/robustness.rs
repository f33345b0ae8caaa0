//! Whatever a master writes, a CiA 402 drive goes on — the CMMP-AS, the Nanotec SMCI47-S and
//! the Kinco FD3 on one rig (`drive_rig`, by device name): any sequence of writes to any entry
//! of the device file (the value's own size most of the time, any length now and then, any
//! bytes), controlwords, modes, the device's own inputs (SYNC; digital, analog and pulse
//! inputs) and time steps never panics, every refused write answers an SDO abort code, and
//! afterwards the drive still takes the CiA 402 enable sequence once its faults are reset
//! (CMMP-AS ch. 6, CiA 402 transitions 15, 2, 3, 4), or reports its fault.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod drive_rig;

use drive::device_control::State;
use drive::drive::DriveSettings;
use drive_rig::Rig;
use od::ObjectAccess;
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

#[derive(Debug, Clone)]
enum Step {
    /// A write to the `n`th entry of the description (modulo their number).
    Write(usize, Vec<u8>),
    Controlword(u16),
    Mode(i8),
    /// Nanotec: a SYNC.
    Sync,
    /// Kinco: the seven DINs' wires, an analog input, the pulse input.
    Inputs(u16),
    Analog(u8, f64),
    Pulses(f64),
    Run(u64),
}

fn write() -> impl Strategy<Value = Step> {
    (
        any::<usize>(),
        prop_oneof![
            4 => prop::collection::vec(any::<u8>(), 1..=4),
            1 => prop::collection::vec(any::<u8>(), 0..12),
        ],
    )
        .prop_map(|(n, v)| Step::Write(n, v))
}

fn cmmp_step() -> impl Strategy<Value = Step> {
    prop_oneof![
        6 => write(),
        2 => any::<u16>().prop_map(Step::Controlword),
        2 => (1u64..200).prop_map(Step::Run),
    ]
}

fn nanotec_step() -> impl Strategy<Value = Step> {
    prop_oneof![
        6 => write(),
        2 => any::<u16>().prop_map(Step::Controlword),
        1 => (-3i8..9).prop_map(Step::Mode),
        1 => Just(Step::Sync),
        2 => (1u64..200).prop_map(Step::Run),
    ]
}

fn kinco_step() -> impl Strategy<Value = Step> {
    prop_oneof![
        6 => write(),
        2 => any::<u16>().prop_map(Step::Controlword),
        1 => (-5i8..8).prop_map(Step::Mode),
        1 => any::<u16>().prop_map(Step::Inputs),
        1 => (0u8..4, -20.0f64..20.0).prop_map(|(n, v)| Step::Analog(n, v)),
        1 => (-1e6f64..1e6).prop_map(Step::Pulses),
        2 => (1u64..200).prop_map(Step::Run),
    ]
}

/// Runs `steps` on `r` (device file `device`): a refused write must answer an abort code of
/// classes 05h, 06h or 08h. Then 100 ms.
fn run_steps(r: &mut Rig, device: &str, steps: &[Step]) -> Result<(), TestCaseError> {
    let desc = devices::by_name(device).expect("the device file");
    let entries: Vec<_> = desc.entries().collect();
    for s in steps {
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
                    prop_assert!(
                        abort.0 >> 24 == 0x05 || abort.0 >> 24 == 0x06 || abort.0 >> 24 == 0x08,
                        "{:04X}h:{}: abort {:08X}",
                        e.index,
                        e.sub,
                        abort.0
                    );
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
            Step::Inputs(levels) => r.d.force_inputs(0x7F, *levels),
            Step::Analog(n, v) => {
                // The analog inputs are the Kinco's.
                if let Some(k) = r.d.as_kinco_mut() {
                    k.set_analog_input(*n, *v);
                }
            }
            Step::Pulses(f) => {
                // The pulse input is the Kinco's.
                if let Some(k) = r.d.as_kinco_mut() {
                    k.set_pulse_input(*f);
                }
            }
            Step::Run(ms) => r.run_ms(*ms),
        }
    }
    r.run_ms(100);
    Ok(())
}

/// The controlwords `sequence` 20 ms apart; then the drive is enabled or in a fault it
/// reports.
fn enables_or_reports(r: &mut Rig, sequence: &[u16]) -> Result<(), TestCaseError> {
    for cw in sequence {
        let _ = r.d.write(0x6040, 0, &cw.to_le_bytes());
        r.run_ms(20);
    }
    let state = r.d.state();
    prop_assert!(
        state == State::OperationEnabled || state == State::Fault,
        "neither enabled nor in a fault it reports: {:?}",
        state
    );
    Ok(())
}

/// Fault reset, shutdown, switch on, enable operation.
const ENABLE: [u16; 6] = [0x0000, 0x0080, 0x0000, 0x0006, 0x0007, 0x000F];

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// The CMMP-AS (node 1): back to the defaults of the control objects the sequence may
    /// have spoiled, then the enable sequence.
    #[test]
    fn any_writes_leave_the_drive_working(steps in prop::collection::vec(cmmp_step(), 1..40)) {
        let mut r = Rig::device("cmmp-as", 1, DriveSettings::default());
        run_steps(&mut r, "cmmp-as", &steps)?;
        enables_or_reports(&mut r, &ENABLE)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    /// The Nanotec SMCI47-S (node 34): a brake wait time the sequence wrote (2007h) delays the
    /// motion, not the state.
    #[test]
    fn any_writes_leave_the_nanotec_working(steps in prop::collection::vec(nanotec_step(), 1..40)) {
        let mut r = Rig::device("nanotec-smci47s", 34, DriveSettings::default());
        run_steps(&mut r, "nanotec-smci47s", &steps)?;
        enables_or_reports(&mut r, &ENABLE)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

    /// The Kinco FD3 (node 1) as a bus master sets it up (no DIN owns the controlword or the
    /// mode); at the end the inputs are the bus's again (no functions, no simulation, no
    /// pulses), mode 3, then 06h → 0Fh after a fault reset.
    #[test]
    fn any_writes_leave_the_kinco_working(steps in prop::collection::vec(kinco_step(), 1..40)) {
        let mut r = Rig::device("kinco-fd3", 1, DriveSettings::default());
        for sub in [0x03u8, 0x05] {
            r.w16(0x2010, sub, 0);
        }
        // Profile_Speed 600 rpm, Profile_Acc / Dec 100 rps/s in the Kinco DEC.
        r.w32(0x6081, 0, 1_638_400);
        r.w32(0x6083, 0, 16_384);
        r.w32(0x6084, 0, 16_384);
        r.run_ms(2);
        run_steps(&mut r, "kinco-fd3", &steps)?;
        for sub in 0x02..=0x09u8 {
            let _ = r.d.write(0x2010, sub, &[0, 0]);
        }
        r.d.force_inputs(0, 0);
        if let Some(k) = r.d.as_kinco_mut() {
            k.set_pulse_input(0.0);
        }
        let _ = r.d.write(0x6060, 0, &[3]);
        r.run_ms(20);
        enables_or_reports(&mut r, &[0x0000, 0x0080, 0x0000, 0x0006, 0x000F])?;
    }
}
