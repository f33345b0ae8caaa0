//! A confirmed write has been taken (DESIGN "never faster, never stricter than the device"):
//! controlwords written back to back, each after its SDO answer, all reach the state machine
//! in order, whatever their spacing against the drive's cycle, on every CiA 402 personality.
//! A demo for the Nanotec writes 00h, 80h, 06h, 07h, 0Fh with no pause; on the real bus each
//! write is taken before it is answered, so the drive ends in OPERATION ENABLED.

mod drive_rig;

use std::time::Duration;

use drive::device_control::State;
use drive::drive::DriveSettings;
use drive_rig::Rig;

/// The drives of the CiA 402 device files, set up as a bus master sets them up.
fn drives() -> Vec<(&'static str, Rig)> {
    let mut kinco = Rig::device("kinco-fd3", 1, DriveSettings::default());
    // As a bus master sets the Kinco up (EA02 = 8): no DIN owns the controlword or the mode.
    kinco.w16(0x2010, 0x03, 0);
    kinco.w16(0x2010, 0x05, 0);
    kinco.run_ms(2);
    vec![
        (
            "cmmp-as",
            Rig::device("cmmp-as", 1, DriveSettings::default()),
        ),
        (
            "nanotec-smci47s",
            Rig::device("nanotec-smci47s", 34, DriveSettings::default()),
        ),
        (
            "nanotec-pd4n",
            Rig::device("nanotec-pd4n", 1, DriveSettings::default()),
        ),
        ("kinco-fd3", kinco),
        ("kinco-cd3", {
            let mut r = Rig::device("kinco-cd3", 1, DriveSettings::default());
            r.w16(0x2010, 0x03, 0);
            r.w16(0x2010, 0x05, 0);
            r.run_ms(2);
            r
        }),
    ]
}

/// 6040h written as an expedited SDO download of two bytes; the answer must confirm it.
fn write_cw(r: &mut Rig, cw: u16) {
    let [lo, hi] = cw.to_le_bytes();
    let answer = r.sdo(&[0x2B, 0x40, 0x60, 0x00, lo, hi, 0x00, 0x00]);
    assert_eq!(answer.first(), Some(&0x60), "6040h = {cw:04X}h confirmed");
}

/// The words, `gap` apart on the drive's clock, then 20 ms for the drive to settle.
fn write_all(r: &mut Rig, words: &[u16], gap: Duration) {
    for &cw in words {
        write_cw(r, cw);
        if !gap.is_zero() {
            r.now = r.now + gap;
            r.d.step(r.now);
        }
    }
    r.run_ms(20);
}

#[test]
fn shutdown_switch_on_enable_back_to_back_reach_operation_enabled_at_any_spacing() {
    for gap_us in [0, 10, 100, 250, 1000] {
        for (name, mut r) in drives() {
            write_all(&mut r, &[0x06, 0x07, 0x0F], Duration::from_micros(gap_us));
            assert_eq!(
                r.d.state(),
                State::OperationEnabled,
                "{name}: 06h, 07h, 0Fh {gap_us} µs apart"
            );
        }
    }
}

/// The Nanotec demo's sequence: 00h, a fault-reset edge 80h, then 06h, 07h, 0Fh.
#[test]
fn the_nanotec_demo_sequence_with_fault_reset_reaches_operation_enabled() {
    for gap_us in [0, 100, 1000] {
        for (name, mut r) in drives() {
            write_all(
                &mut r,
                &[0x00, 0x80, 0x06, 0x07, 0x0F],
                Duration::from_micros(gap_us),
            );
            assert_eq!(
                r.d.state(),
                State::OperationEnabled,
                "{name}: 00h, 80h, 06h, 07h, 0Fh {gap_us} µs apart"
            );
        }
    }
}

/// Transitions in the middle of a burst take effect too: enabled, disabled and enabled again
/// within one cycle ends enabled; enabled then shut down within one cycle ends in READY TO
/// SWITCH ON with the output stage off.
#[test]
fn every_word_of_a_burst_counts_not_only_the_last() {
    for (name, mut r) in drives() {
        write_all(&mut r, &[0x06, 0x0F, 0x06], Duration::ZERO);
        assert_eq!(r.d.state(), State::ReadyToSwitchOn, "{name}: 06h, 0Fh, 06h");
        write_all(&mut r, &[0x07, 0x0F, 0x07, 0x0F], Duration::ZERO);
        assert_eq!(
            r.d.state(),
            State::OperationEnabled,
            "{name}: 07h, 0Fh, 07h, 0Fh"
        );
        // Disable voltage and straight back: 00h leaves for SWITCH ON DISABLED, so 0Fh after it
        // is not a valid command there and the drive stays disabled, as on the device.
        write_all(&mut r, &[0x00, 0x0F], Duration::ZERO);
        assert_eq!(r.d.state(), State::SwitchOnDisabled, "{name}: 00h, 0Fh");
    }
}

/// A fault acknowledged and the drive enabled again in one burst: the reset edge clears the
/// fault before 06h, 07h, 0Fh run.
#[test]
fn fault_reset_then_enable_in_one_burst() {
    let mut r = Rig::device("cmmp-as", 1, DriveSettings::default());
    write_all(&mut r, &[0x06, 0x0F], Duration::ZERO);
    assert_eq!(r.d.state(), State::OperationEnabled);
    r.d.inject_fault(0x5114, 0x05);
    r.run_ms(200);
    assert_eq!(r.d.state(), State::Fault);
    r.d.clear_fault(0x5114);
    write_all(&mut r, &[0x80, 0x06, 0x07, 0x0F], Duration::ZERO);
    assert_eq!(r.d.state(), State::OperationEnabled);
}
