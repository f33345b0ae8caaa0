//! FHPP telegrams (8 or 16 bytes: control bytes and the parameter channel with its file
//! transfer) into a CMMO-ST, each held for some 1 ms cycles, open or closed loop: no panic,
//! the 16-byte input image starts with the 8-byte one.
//!
//! Speed (about 450 executions/s with a device built per input): a device of each loop mode is
//! built and run through its first cycle (parameters and record table read) once, and copied
//! for every input; an input runs at most [`MAX_CYCLES`] cycles (a telegram held 1…16 of them;
//! a longer input stops there).
#![no_main]

use drive::vendors::festo_cmmo_st::device::{FhppDevice, FhppSettings};
use drive::stepper::StepperMode;
use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use od::{Instant, ObjectDictionary};
use std::sync::OnceLock;

/// At most this many 1 ms cycles per input.
const MAX_CYCLES: u64 = 128;

/// A CMMO-ST in `mode` after its first cycle, built once per mode.
fn device(mode: StepperMode) -> Option<FhppDevice<Vec<u8>>> {
    static DEVICES: OnceLock<Option<[FhppDevice<Vec<u8>>; 2]>> = OnceLock::new();
    let [open, closed] = DEVICES
        .get_or_init(|| {
            let desc = &devices::CMMO_ST;
            let od = ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]).ok()?;
            let build = |mode| {
                let mut dev = FhppDevice::new(
                    od.clone(),
                    FhppSettings {
                        mode,
                        ..FhppSettings::default()
                    },
                );
                dev.step(Instant::ZERO);
                dev
            };
            Some([build(StepperMode::OpenLoop), build(StepperMode::ClosedLoop)])
        })
        .as_ref()?;
    Some(match mode {
        StepperMode::OpenLoop => open.clone(),
        StepperMode::ClosedLoop => closed.clone(),
    })
}

fn run(u: &mut Unstructured) -> Result<()> {
    let mode = if u.arbitrary::<bool>()? {
        StepperMode::OpenLoop
    } else {
        StepperMode::ClosedLoop
    };
    let Some(mut dev) = device(mode) else {
        return Ok(());
    };
    let mut t_ms = 1u64;
    while !u.is_empty() && t_ms < MAX_CYCLES {
        let len = if u.arbitrary::<bool>()? { 16 } else { 8 };
        let mut telegram = [0u8; 16];
        u.fill_buffer(&mut telegram[..len])?;
        // CCON.ENABLE most of the time, so the states behind it are reached.
        if u.ratio(3u8, 4)? {
            telegram[0] |= 0x01;
        }
        assert!(
            dev.set_outputs(&telegram[..len]).is_ok(),
            "8 or 16 bytes are taken"
        );
        for _ in 0..u.int_in_range(1u64..=16)? {
            dev.step(Instant::from_millis(t_ms));
            t_ms += 1;
        }
        assert_eq!(&dev.inputs_fpc()[..8], &dev.inputs()[..]);
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let _ = run(&mut Unstructured::new(data));
});
