//! The Nanotec power state machine (Nanotec ch. 3; the extract's §9 item 4): the §2.4 power-up
//! sequence frame by frame through the CANopen node, the statusword values with bit 9 remote, the
//! only multi-step jump (Ready to Switch On → Operation Enabled), quick stop into Switch On
//! Disabled and the fault reset edge.

mod nanotec_rig;

use drive::device_control::State;
use nanotec_rig::Rig;

const SDO_WRITE_OK: [u8; 8] = [0x60, 0x40, 0x60, 0x00, 0x00, 0x00, 0x00, 0x00];

/// Controlword `cw` as the manual's short download frame; then the statusword upload. Returns
/// both answers.
fn write_cw_read_sw(r: &mut Rig, cw: u8) -> (Vec<u8>, Vec<u8>) {
    let w = r.sdo(&[0x2B, 0x40, 0x60, 0x00, cw, 0x00]);
    r.run_ms(10);
    let s = r.sdo(&[0x40, 0x41, 0x60, 0x00]);
    (w, s)
}

/// NT-CW-01: controlword 0 → Switch On Disabled, statusword 0260h (bits 5, 6, 9).
#[test]
fn nt_cw_01_controlword_0_switch_on_disabled_0260h() {
    let mut r = Rig::new();
    let (w, s) = write_cw_read_sw(&mut r, 0x00);
    assert_eq!(w, SDO_WRITE_OK);
    assert_eq!(s, [0x4B, 0x41, 0x60, 0x00, 0x60, 0x02, 0x00, 0x00]);
    assert_eq!(r.d.state(), State::SwitchOnDisabled);
}

/// NT-CW-02: 06h → Ready to Switch On, 0221h.
#[test]
fn nt_cw_02_shutdown_ready_to_switch_on_0221h() {
    let mut r = Rig::new();
    write_cw_read_sw(&mut r, 0x00);
    let (w, s) = write_cw_read_sw(&mut r, 0x06);
    assert_eq!(w, SDO_WRITE_OK);
    assert_eq!(s, [0x4B, 0x41, 0x60, 0x00, 0x21, 0x02, 0x00, 0x00]);
}

/// NT-CW-03: 07h → Switched On, 0233h: voltage enabled (bit 4), the motor energised.
#[test]
fn nt_cw_03_switch_on_switched_on_0233h() {
    let mut r = Rig::new();
    write_cw_read_sw(&mut r, 0x00);
    write_cw_read_sw(&mut r, 0x06);
    let (w, s) = write_cw_read_sw(&mut r, 0x07);
    assert_eq!(w, SDO_WRITE_OK);
    assert_eq!(s, [0x4B, 0x41, 0x60, 0x00, 0x33, 0x02, 0x00, 0x00]);
    assert!(
        !r.d.axis().motor().brake(),
        "the brake is released from Switched On"
    );
}

/// NT-CW-04: 0Fh → Operation Enabled, 0237h.
#[test]
fn nt_cw_04_enable_operation_0237h() {
    let mut r = Rig::new();
    for cw in [0x00, 0x06, 0x07] {
        write_cw_read_sw(&mut r, cw);
    }
    let (w, s) = write_cw_read_sw(&mut r, 0x0F);
    assert_eq!(w, SDO_WRITE_OK);
    assert_eq!(s, [0x4B, 0x41, 0x60, 0x00, 0x37, 0x02, 0x00, 0x00]);
}

/// NT-CW-05: 0Fh in Switch On Disabled is refused ("a multiple transition when switching on
/// is not possible"): the write is answered, the statusword stays 0260h.
#[test]
fn nt_cw_05_enable_from_switch_on_disabled_refused() {
    let mut r = Rig::new();
    write_cw_read_sw(&mut r, 0x00);
    let (w, s) = write_cw_read_sw(&mut r, 0x0F);
    assert_eq!(w, SDO_WRITE_OK);
    assert_eq!(s, [0x4B, 0x41, 0x60, 0x00, 0x60, 0x02, 0x00, 0x00]);
    assert_eq!(r.d.state(), State::SwitchOnDisabled);
}

/// NT-CW-06: 0Fh in Ready to Switch On jumps to Operation Enabled (0237h).
#[test]
fn nt_cw_06_enable_from_ready_to_switch_on() {
    let mut r = Rig::new();
    write_cw_read_sw(&mut r, 0x06);
    assert_eq!(r.sw(), 0x0221);
    let (_, s) = write_cw_read_sw(&mut r, 0x0F);
    assert_eq!(s, [0x4B, 0x41, 0x60, 0x00, 0x37, 0x02, 0x00, 0x00]);
}

/// NT-CW-07: bit 2 = 0 in Operation Enabled: "the motor brakes with the ramp set in 6085h,
/// then goes to Switch On Disabled" (§4.2 L769); (SW & 004Fh) = 0040h; 605Ah = 3 is the only
/// option (§4.4). The ramp is measured: from 2000 units/s, 6085h = 1000 and 4000 units/s²
/// brake in v / a = 2 s and 0.5 s over v² / 2a = 2000 and 500 units of the position demand.
#[test]
fn nt_cw_07_quick_stop_ends_in_switch_on_disabled() {
    for (decel, stop_ms, distance) in [(1000i64, 2000i64, 2000i64), (4000, 500, 500)] {
        let mut r = Rig::new();
        r.enable_pp();
        assert_eq!(r.i(0x605A, 0), 3);
        r.w32(0x6081, 0, 2000);
        r.w32(0x6083, 0, 100_000);
        r.w32(0x6085, 0, decel);
        // A long move at 2000 units/s, so the quick stop has something to brake.
        r.w32(0x607A, 0, 1_000_000);
        r.cw(0x001F);
        r.cw(0x000F);
        r.run_ms(300);
        let from = r.i(0x6062, 0);
        assert!(from > 0, "moving: {from}");
        r.cw(0x000B);
        assert_eq!(r.sw() & 0x006F, 0x0007, "Quick Stop Active while braking");
        let mut ms = 0;
        while r.d.state() != State::SwitchOnDisabled && ms < 5000 {
            r.run_ms(1);
            ms += 1;
        }
        assert_eq!(r.d.state(), State::SwitchOnDisabled);
        assert_eq!(r.sw() & 0x004F, 0x0040);
        let braked = r.i(0x6062, 0) - from;
        assert!(
            (ms - stop_ms).abs() <= stop_ms / 20,
            "NT-CW-07: 6085h = {decel}: stopped after {ms} ms, v / a = {stop_ms} ms"
        );
        assert!(
            (braked - distance).abs() <= distance / 20,
            "NT-CW-07: 6085h = {decel}: braked over {braked} units, v² / 2a = {distance}"
        );
    }
}

/// NT-CW-08: in Fault a permanent 1 in bit 7 is not enough; the 0 → 1 edge resets.
#[test]
fn nt_cw_08_fault_reset_needs_a_rising_edge() {
    let mut r = Rig::new();
    r.enable();
    r.cw(0x0080);
    r.d.inject_fault(0x0080, 0x01); // overcurrent (§13.3)
    r.run_ms(10);
    r.d.clear_fault(0x0080);
    r.run_ms(200);
    assert_eq!(r.d.state(), State::Fault);
    assert_eq!(r.sw() & 0x004F, 0x0008);
    r.cw(0x0080); // still 1: no edge
    r.run_ms(10);
    assert_eq!(r.d.state(), State::Fault);
    r.cw(0x0000);
    r.cw(0x0080);
    assert_eq!(r.d.state(), State::SwitchOnDisabled);
    assert_eq!(r.sw(), 0x0260);
}

/// NT-NODE-07, the drive's side: switch = node + 128 with a 2005h outside 130…135 leaves a
/// controller that "answers on CAN but accepts no motion commands" (§1.1.3 step 7, L333;
/// `drive::vendors::nanotec::rotary_switches` decides it from the switches). The cell gives
/// such a drive no hardware enables (`DriveSettings::enables_present`): SDO answers, the statusword reads
/// Switch On Disabled, and neither Shutdown nor the §2.4 power-up nor a PP start moves it.
///
/// Decision: the manual names no object or state for the refusal; a power stage that cannot
/// be switched on (transition 2 not taken) refuses every motion command at once, whatever
/// the mode, and leaves the bus side (SDO, NMT, PDO) as it is.
#[test]
fn nt_node_07_no_motion_commands_without_a_valid_bit_rate_code() {
    let mut r = Rig::with(drive::drive::DriveSettings {
        enables_present: false,
        ..Default::default()
    });
    for cw in [0x00, 0x06, 0x07, 0x0F] {
        let (w, s) = write_cw_read_sw(&mut r, cw);
        assert_eq!(w, SDO_WRITE_OK, "the controlword is taken over SDO");
        assert_eq!(
            s,
            [0x4B, 0x41, 0x60, 0x00, 0x60, 0x02, 0x00, 0x00],
            "CW {cw:02X}h"
        );
    }
    assert_eq!(
        r.sdo(&[0x2F, 0x60, 0x60, 0x00, 0x01]),
        [0x60, 0x60, 0x60, 0, 0, 0, 0, 0]
    );
    r.sdo(&[0x23, 0x7A, 0x60, 0x00, 0x45, 0x23, 0x01, 0x00]);
    let before = r.d.plant_position();
    for cw in [0x1F, 0x0F] {
        write_cw_read_sw(&mut r, cw);
    }
    r.run_ms(500);
    assert_eq!(r.d.state(), State::SwitchOnDisabled);
    assert_eq!(r.d.plant_position(), before, "the shaft does not move");
}
