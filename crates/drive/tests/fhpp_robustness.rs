//! Whatever a master writes, the CMMO-ST goes on: any sequence of 16-byte telegrams (FHPP bytes and
//! parameter-channel bytes, 8 or 16 at a time), held for any number of cycles, leaves the device
//! stepping without a panic, and taking ENABLE away switches the output stage off (T5 / T6 of
//! Tab. 5.2: SCON.ENABLED = 0) whatever state the sequence left it in, except in S6 "fault", which
//! only RESET leaves: RESET with ENABLE = 0 (T9) then switches it off once the fault is gone.

mod fhpp_bench;

use fhpp_bench::Bench;

use drive::stepper::StepperMode;
use drive::vendors::festo_cmmo_st::fhpp::{InputData, Scon};
use proptest::prelude::*;

/// One step of the master: the telegram (8 or 16 bytes) and how many cycles it stands.
fn step() -> impl Strategy<Value = (Vec<u8>, u64)> {
    (
        prop_oneof![
            prop::collection::vec(any::<u8>(), 8),
            prop::collection::vec(any::<u8>(), 16)
        ],
        1u64..40,
    )
}

/// A telegram that keeps CCON.ENABLE most of the time, so the states behind it are reached.
fn enabling_step() -> impl Strategy<Value = (Vec<u8>, u64)> {
    step().prop_map(|(mut t, n)| {
        if let Some(ccon) = t.first_mut() {
            *ccon |= 0x01;
        }
        (t, n)
    })
}

fn run(mode: StepperMode, steps: &[(Vec<u8>, u64)]) -> Result<(), TestCaseError> {
    let mut b = Bench::with_mode(mode);
    for (telegram, cycles) in steps {
        prop_assert!(
            b.dev.set_outputs(telegram).is_ok(),
            "8 or 16 bytes are taken"
        );
        b.run(*cycles);
        let fpc = b.dev.inputs_fpc();
        prop_assert_eq!(
            &fpc[..8],
            &b.dev.inputs()[..],
            "the 16-byte image starts with the 8"
        );
    }
    // ENABLE away (CCON 00h, nothing else): the output stage goes off (T5 / T6), unless
    // the device is in S6, which ENABLE = 0 does not leave.
    let send = |b: &mut Bench, ccon: u8, cycles: u64| {
        let mut telegram = [0u8; 16];
        telegram[0] = ccon;
        let ok = b.dev.set_outputs(&telegram).is_ok();
        b.run(cycles);
        (ok, InputData::from_bytes(b.dev.inputs()))
    };
    let (ok, i) = send(&mut b, 0x00, 50);
    prop_assert!(ok);
    prop_assert!(
        i.scon.contains(Scon::FAULT) || !i.scon.contains(Scon::ENABLED),
        "enabled without ENABLE and without a fault: {:?}",
        i
    );
    // RESET rising with ENABLE = 0 (T9): once the fault is gone, the output stage is off.
    send(&mut b, 0x08, 5);
    let (_, i) = send(&mut b, 0x00, 50);
    prop_assert!(
        i.scon.contains(Scon::FAULT) || !i.scon.contains(Scon::ENABLED),
        "enabled after T9: {:?}",
        i
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn any_telegrams_closed_loop(steps in prop::collection::vec(enabling_step(), 1..30)) {
        run(StepperMode::ClosedLoop, &steps)?;
    }

    #[test]
    fn any_telegrams_open_loop(steps in prop::collection::vec(step(), 1..30)) {
        run(StepperMode::OpenLoop, &steps)?;
    }
}
