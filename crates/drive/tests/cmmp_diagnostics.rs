//! CMMP-AS diagnostics: the error management 2100h, the last warning 200Fh and the 7-segment
//! display (CMMP-AS §5.17, §5.18, App. B; the vector catalogue kept beside the project, §1.12,
//! §1.13).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use drive::device_control::State;
use drive::drive::DriveEvent;
use drive::vendors::festo_cmmp_as::display::Display;
use drive::vendors::festo_cmmp_as::messages::{self, decode_warning_code, warning_code, Number};
use od::{AbortCode, ObjectAccess};

mod cmmp_rig;

use cmmp_rig::Rig;

impl Rig {
    fn w8(&mut self, index: u16, sub: u8, v: u8) -> Result<(), AbortCode> {
        self.d.write(index, sub, &[v])
    }
    fn u(&self, index: u16, sub: u8) -> u64 {
        self.d.od().get_unsigned(index, sub).unwrap()
    }
    fn reaction(&mut self, main: u8) -> u64 {
        self.w8(0x2100, 1, main).unwrap();
        self.u(0x2100, 2)
    }
    fn text(&self) -> String {
        self.d.display().text().as_str().to_string()
    }
}

/// CMMP-GAIN-12: error 08-2 has main number 8; 2100h:01 := 8 selects it and 2100h:02 takes
/// the reaction codes 0, 1, 3, 5, 7, 8; a value below the manufacturer minimum is clamped.
#[test]
fn cmmp_gain_12_error_management_2100h() {
    let msg = messages::by_code(0x7382).unwrap();
    assert_eq!(msg.number, Number { main: 8, sub: 2 });
    let mut r = Rig::new();
    assert_eq!(r.u(0x2100, 1), 1);
    assert_eq!(r.u(0x2100, 2), 8, "01-0 stack overflow: PS off");
    r.w8(0x2100, 1, msg.number.main).unwrap();
    for code in [0, 1, 3, 5, 7, 8] {
        r.w8(0x2100, 2, code).unwrap();
        assert_eq!(r.u(0x2100, 2), u64::from(code));
    }
    for bad in [2, 4, 6, 9] {
        assert_eq!(r.w8(0x2100, 2, bad), Err(AbortCode::INVALID_VALUE), "{bad}");
    }
    assert_eq!(r.u(0x2100, 2), 8, "a refused write changes nothing");
    // Group 5 (internal voltages) is "PS off" only: 0 is clamped to 8.
    r.w8(0x2100, 1, 5).unwrap();
    r.w8(0x2100, 2, 0).unwrap();
    assert_eq!(r.u(0x2100, 2), 8);
    // Group 3 has 03-0 with "QStop": at least 5.
    r.w8(0x2100, 1, 3).unwrap();
    r.w8(0x2100, 2, 1).unwrap();
    assert_eq!(r.u(0x2100, 2), 5);
    // The selection keeps each group's reaction.
    assert_eq!(r.reaction(8), 8);
    assert_eq!(r.reaction(5), 8);
    // error_number 1 … 96.
    assert!(r.w8(0x2100, 1, 0).is_err());
    assert!(r.w8(0x2100, 1, 97).is_err());
}

/// CMMP-GAIN-12 (the reaction in force): group 34 (fieldbus synchronisation) set to "no
/// action" lets IP mode be enabled without SYNC and without an error; set back to 5 the same
/// start stops the drive with 34-0.
#[test]
fn reaction_none_suppresses_the_error() {
    let mut r = Rig::new();
    r.w8(0x2100, 1, 34).unwrap();
    r.w8(0x2100, 2, 0).unwrap();
    r.d.write(0x6060, 0, &[7]).unwrap();
    r.run_ms(5);
    r.cw(0x06);
    r.cw(0x07);
    r.cw(0x0F);
    // Interpolation enabled without SYNC: 34-0, here with "no action".
    r.cw(0x1F);
    r.run_ms(10);
    assert_eq!(r.d.state(), State::OperationEnabled);
    assert!(r.d.errors().is_empty());
    r.cw(0x0F);
    r.w8(0x2100, 2, 5).unwrap();
    r.cw(0x1F);
    r.run_ms(10);
    assert_eq!(r.d.errors(), &[0x8780]);
}

/// CMMP-GAIN-13: 200Fh = 8082h is warning 08-2, active (bit 15), main number in bits 4 … 11,
/// sub number in bits 0 … 3.
#[test]
fn cmmp_gain_13_last_warning_code_layout() {
    let n = Number { main: 8, sub: 2 };
    assert_eq!(decode_warning_code(0x8082), (n, true));
    assert_eq!(warning_code(n, true), 0x8082);
    assert_eq!(decode_warning_code(0x0082), (n, false));
    // Two-digit main numbers read as displayed (BCD; see messages::warning_code).
    let w = Number { main: 17, sub: 0 };
    assert_eq!(warning_code(w, true), 0x8170);
    assert_eq!(decode_warning_code(0x8170), (w, true));
}

/// CMMP-DIAG-01: error 01-0 active → the display cycles "- E 0 1 0 -".
#[test]
fn cmmp_diag_01_error_01_0_on_the_display() {
    let mut r = Rig::new();
    r.w32(0x6510, 0xC0, 1);
    r.d.inject_fault(0x6180, 0x01);
    r.run_ms(2);
    assert_eq!(r.d.display(), Display::Error(Number { main: 1, sub: 0 }));
    assert_eq!(r.text(), "-E010-");
    assert_eq!(r.d.state(), State::Fault);
    // One diagnostic-memory entry per occurrence, not per cycle.
    r.run_ms(100);
    assert_eq!(r.d.diagnostic_memory().count(), 1);
    r.d.clear_fault(0x6180);
    r.cw(0x00);
    r.cw(0x80);
    assert_eq!(r.text(), "");
    r.d.inject_fault(0x6180, 0x01);
    r.run_ms(2);
    assert_eq!(r.d.diagnostic_memory().count(), 2);
}

/// CMMP-DIAG-02, CMMP-GAIN-13 end to end: error 17 set to "warning" (2100h reaction 3); a
/// following error beyond 6510h:22 shows "- 1 7 0 -", 200Fh = 8170h and statusword bit 7,
/// and the drive keeps running; the warning ends by itself when the cause is gone.
#[test]
fn cmmp_diag_02_following_error_warning_17_0() {
    let mut r = Rig::new();
    r.w32(0x6510, 0xC0, 1);
    r.w32(0x6510, 0x22, 20_000);
    assert_eq!(r.reaction(17), 8, "6510h:22 > 0: output stage off");
    r.w8(0x2100, 2, 3).unwrap();
    r.d.write(0x6060, 0, &[1]).unwrap();
    r.run_ms(5);
    r.cw(0x06);
    r.cw(0x07);
    r.cw(0x0F);
    r.d.axis_mut().set_blocked(true);
    r.w32(0x607A, 0, 20 * 65536);
    r.cw(0x1F);
    r.cw(0x0F);
    r.run_ms(300);
    assert_eq!(r.text(), "-170-");
    assert_eq!(r.u(0x200F, 0), 0x8170);
    assert_ne!(r.u(0x6041, 0) & 0x0080, 0, "statusword bit 7 warning");
    assert_eq!(
        r.d.state(),
        State::OperationEnabled,
        "a warning does not stop"
    );
    assert!(r.d.errors().is_empty());
    while let Some(e) = r.d.take_event() {
        assert!(!matches!(e, DriveEvent::Error { .. }), "no EMCY: {e:?}");
    }
    // Free again: the axis catches up and the warning goes.
    r.d.axis_mut().set_blocked(false);
    r.run_ms(3000);
    assert_eq!(r.u(0x200F, 0), 0x0170, "last warning, no longer active");
    assert_eq!(r.u(0x6041, 0) & 0x0080, 0);
    assert_eq!(r.d.display(), Display::Operating);
}

/// CMMP-DIAG-04: commissioning_state 6510h:C0 = 0 shows "A"; any bit set suppresses it; the
/// defaults bring it back.
#[test]
fn cmmp_diag_04_not_parameterised_a() {
    let mut r = Rig::new();
    assert_eq!(r.u(0x6510, 0xC0), 0);
    assert_eq!(r.text(), "A");
    r.w32(0x6510, 0xC0, 0x0000_0100);
    assert_eq!(r.d.display(), Display::Operating);
    assert_eq!(r.text(), "");
    // restore_default_parameters (1011h), as the runtime carries it out.
    r.d.od_mut().load_defaults(|_| true);
    r.d.reload();
    assert_eq!(r.text(), "A");
}

/// CMMP-DIAG-05: the safety module reports safe standstill: 2000h:01 bit 8 and "H".
#[test]
fn cmmp_diag_05_safe_standstill_h() {
    let mut r = Rig::new();
    r.w32(0x6510, 0xC0, 1);
    r.d.set_safe_standstill(true);
    r.run_ms(1);
    assert_eq!(r.u(0x2000, 1) & 0x100, 0x100);
    assert_eq!(r.text(), "H");
    r.d.set_safe_standstill(false);
    r.run_ms(1);
    assert_eq!(r.u(0x2000, 1) & 0x100, 0);
    assert_eq!(r.text(), "");
}

/// CMMP-DIAG-03: DC-link undervoltage 02-0 at 560 V (below 6510h:36 with 6510h:37 = 1):
/// EMCY code 3220h, and the diagnostic memory's additional information carries the
/// voltage at approx. 17.1 digits/V in its lower 16 bits (560 × 17.1 = 9576 = 2568h, ±1 %)
/// and a state number in its upper 16 bits.
#[test]
fn cmmp_diag_03_dc_link_undervoltage_additional_information() {
    let mut r = Rig::new();
    r.w32(0x6510, 0x36, 600_000);
    r.d.write(0x6510, 0x37, &1u16.to_le_bytes()).unwrap();
    r.d.set_dc_link_voltage(Some(560_000));
    r.run_ms(2);
    assert_eq!(r.u(0x6510, 0x34), 560_000);
    assert_eq!(r.u(0x6079, 0), 560_000);
    assert_eq!(r.d.errors(), &[0x3220]);
    assert!(std::iter::from_fn(|| r.d.take_event()).any(|e| e
        == DriveEvent::Error {
            code: 0x3220,
            register: 0x04
        }));
    let entry = *r.d.diagnostic_memory().last().unwrap();
    assert_eq!(entry.number, Number { main: 2, sub: 0 });
    assert_eq!(entry.code, 0x3220);
    let volts = f64::from(entry.info & 0xFFFF);
    assert!((volts - 9576.0).abs() <= 95.76, "{volts}");
    assert_eq!(entry.info & 0xFFFF, 0x2568);
    assert_eq!(entry.info >> 16, State::SwitchOnDisabled as u32);
    // The cause stays while the voltage is low: no fault reset.
    r.run_ms(200);
    r.cw(0x00);
    r.cw(0x80);
    assert_eq!(r.d.state(), State::Fault);
    r.d.set_dc_link_voltage(None);
    r.run_ms(2);
    r.cw(0x00);
    r.cw(0x80);
    assert_eq!(r.d.state(), State::SwitchOnDisabled);
    assert_eq!(r.u(0x6510, 0x34), 325_000, "back to the nominal voltage");
}
