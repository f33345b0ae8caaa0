//! Kinco digital inputs and outputs (manual §5.5 Tab. 5-2 / 5-3, §6.1 L1287), the following-error
//! limit and the error words (§7): through the drive, with the inputs simulated by Din_Simulate
//! 2010h:02 and the travel's switches.

mod kinco_rig;

use drive::drive::DriveEvent;
use kinco_rig::{dec_rpm, dec_rps2, Rig};
use od::ObjectAccess;

const DIN1: i64 = 1 << 0;
const DIN2: i64 = 1 << 1;
const DIN3: i64 = 1 << 2;
const DIN5: i64 = 1 << 4;

/// KINCO-CW-06: the Enable input (DIN1, factory) sets the controlword to Din_Controlword
/// 2020h:0F (2Fh) when it goes active and to 06h when it goes inactive; meanwhile a bus write
/// to the controlword does not take effect (L1287).
#[test]
fn kinco_cw_06_enable_input_owns_the_controlword() {
    let mut r = Rig::factory();
    r.w16(0x2010, 0x02, DIN1);
    r.run_ms(10);
    assert_eq!(r.i(0x6040, 0), 0x2F);
    assert_eq!(r.sw() & 0x6F, 0x27, "enabled (mode −4: holds)");
    assert!(r.try_cw(0x06).is_err(), "the bus cannot disable");
    assert_eq!(r.i(0x6040, 0), 0x2F);
    r.w16(0x2010, 0x02, 0);
    r.run_ms(10);
    assert_eq!(r.i(0x6040, 0), 0x06);
    assert_eq!(r.sw() & 0x6F, 0x21, "ready to switch on");
    r.w16(0x2020, 0x0F, 0x0F);
    r.w16(0x2010, 0x02, DIN1);
    r.run_ms(10);
    assert_eq!(r.i(0x6040, 0), 0x0F, "Din_Controlword 0Fh");
}

/// Operation Mode Sel (DIN3, factory): Din_Mode1 2020h:0E (−3) while active, Din_Mode0
/// 2020h:0D (−4) while not.
#[test]
fn operation_mode_sel_input_switches_the_mode() {
    let mut r = Rig::factory();
    assert_eq!(r.i(0x6061, 0), -4);
    r.w16(0x2010, 0x02, DIN3);
    r.run_ms(5);
    assert_eq!(r.i(0x6061, 0), -3);
    r.w16(0x2010, 0x02, 0);
    r.run_ms(5);
    assert_eq!(r.i(0x6061, 0), -4);
}

/// KINCO-SC-03 (§6.2.2 Tab. 6-9): DIN1 Enable, DIN2 Reset Errors, DIN3 Operation Mode Sel
/// active, DIN4…6 Din Vel Index0…2 = 0, 1, 0, Din_Mode1 = −3, Din_Speed[2] = 500 rpm: DIN1
/// going active runs the motor at 500 rpm in mode −3.
#[test]
fn kinco_sc_03_din_speed() {
    let mut r = Rig::factory();
    r.w16(0x2010, 0x06, 0x0100);
    r.w16(0x2010, 0x07, 0x0200);
    r.w16(0x2010, 0x08, 0x8001);
    r.w16(0x2020, 0x0B, 500);
    r.w16(0x2010, 0x02, DIN3 | DIN5);
    r.run_ms(5);
    assert_eq!(r.i(0x6061, 0), -3);
    assert!(r.rpm().abs() < 1.0, "not enabled yet");
    r.w16(0x2010, 0x02, DIN1 | DIN3 | DIN5);
    r.run_ms(300);
    assert_eq!(r.sw() & 0x6F, 0x27);
    assert!((r.rpm() - 500.0).abs() < 10.0, "{} rpm", r.rpm());
    // Invert Direction (0080h) on DIN7 turns it round.
    r.w16(0x2010, 0x09, 0x0080);
    r.w16(0x2010, 0x02, DIN1 | DIN3 | DIN5 | (1 << 6));
    r.run_ms(300);
    assert!((r.rpm() + 500.0).abs() < 10.0, "{} rpm", r.rpm());
}

/// Reset Errors (DIN2, factory): its rising edge resets a fault whose cause is gone.
#[test]
fn reset_errors_input() {
    let mut r = Rig::new();
    r.enable_in(3);
    r.d.inject_fault(0x3210, 0x05);
    r.run_ms(5);
    assert_eq!(r.sw() & 0x4F, 0x08);
    assert_eq!(r.i(0x2601, 0), 1 << 5, "Error_State bit 5 Overvoltage");
    r.d.clear_fault(0x3210);
    r.w16(0x2010, 0x02, DIN2);
    r.run_ms(5);
    assert_eq!(r.sw() & 0x4F, 0x40, "switch on disabled");
    assert_eq!(r.i(0x2601, 0), 0);
}

/// P limit± (DIN5 / DIN6, factory, normally closed): at the positive switch the direction
/// is blocked, the other one is free; Din_Real shows the open contact, the Position Limit
/// output follows it.
#[test]
fn limit_switch_blocks_its_direction() {
    let mut r = Rig::new();
    r.w16(0x2010, 0x0F, 0x0200); // OUT1: Position Limit
    r.enable_in(-3);
    assert_eq!(r.i(0x2010, 0x0A) & 0x30, 0x30, "both contacts closed");
    assert_eq!(r.i(0x2010, 0x14) & 1, 0);
    // The positive switch is at +64 revolutions of the travel: 640 000 increments.
    r.w32(0x60FF, 0, dec_rpm(3000.0));
    r.run_ms(14_000);
    assert!(
        r.rpm().abs() < 1.0,
        "stopped at the switch: {} rpm",
        r.rpm()
    );
    let at = r.position();
    assert!((640_000..660_000).contains(&at), "at {at}");
    assert_eq!(r.i(0x2010, 0x0A) & 0x10, 0, "DIN5 open");
    assert_eq!(r.i(0x2010, 0x14) & 1, 1, "OUT1 Position Limit");
    assert_eq!(
        r.sw() & 0x6F,
        0x27,
        "no fault: the direction is blocked only"
    );
    r.w32(0x60FF, 0, dec_rpm(-300.0));
    r.run_ms(500);
    assert!(r.position() < at - 10_000, "away from the switch");
}

/// The outputs (Tab. 5-3) of the factory set-up: OUT1 Ready, OUT2 Motor Brake, OUT3 Pos
/// Reached, OUT4 Zero Speed, OUT5 Error; Dout_Simulate 2010h:0E forces one, Dout_Polarity
/// 2010h:0D = 0 inverts one.
#[test]
fn outputs_follow_their_functions() {
    let mut r = Rig::new();
    let out = |r: &Rig| r.i(0x2010, 0x14);
    assert_eq!(out(&r), 0b01001, "ready, zero speed");
    r.w8(0x6060, 0, 1);
    r.cw(0x06);
    r.cw(0x2F);
    r.w32(0x607A, 0, 20_000);
    r.cw(0x3F);
    r.run_ms(20);
    assert_eq!(out(&r), 0b00011, "ready, brake released, moving");
    assert!(r.until_sw(0x0400, 5000));
    assert_eq!(out(&r), 0b01111, "position reached, zero speed");
    r.w16(0x2010, 0x0E, 0b10000);
    r.run_ms(2);
    assert_eq!(out(&r), 0b11111, "OUT5 simulated");
    r.w16(0x2010, 0x0E, 0);
    r.w16(0x2010, 0x0D, 0xFFFF & !1);
    r.run_ms(2);
    assert_eq!(out(&r), 0b01110, "OUT1 normally closed");
    r.w16(0x2010, 0x0D, 0xFFFF);
    r.d.inject_fault(0x2320, 0x03);
    r.run_ms(5);
    assert_eq!(out(&r), 0b11000, "error, zero speed");
}

/// KINCO-SC-09 / KINCO-DIAG-03 through the drive: Max_Following_Error_16 2FF0h:0E = 5
/// makes 6065h = 500; a load the motor cannot hold pulls the shaft beyond it: Error_State
/// bit 9, EMCY 8611h, the output stage off.
#[test]
fn kinco_diag_03_following_error() {
    let mut r = Rig::new();
    assert_eq!(r.i(0x6065, 0), 524_200, "KINCO-SC-09: 100 × 5242");
    r.w16(0x2FF0, 0x0E, 5);
    assert_eq!(r.i(0x6065, 0), 500);
    r.enable_in(1);
    r.events();
    r.d.axis_mut().motor_mut().set_load_torque(20.0);
    r.run_ms(200);
    assert_eq!(r.sw() & 0x4F, 0x08, "fault");
    assert_eq!(r.i(0x2601, 0), 1 << 9);
    let events = r.events();
    assert!(
        events.contains(&DriveEvent::Error {
            code: 0x8611,
            register: 0x01
        }),
        "{events:?}"
    );
}

/// Error_Mask 2605h:01 bit = 0: that error is ignored (§7).
#[test]
fn masked_error_is_ignored() {
    let mut r = Rig::new();
    r.w16(0x2605, 0x01, 0xFFFF & !(1 << 9));
    r.w16(0x2FF0, 0x0E, 5);
    r.enable_in(1);
    r.d.axis_mut().motor_mut().set_load_torque(0.5);
    r.run_ms(100);
    r.d.axis_mut().motor_mut().set_load_torque(0.0);
    r.run_ms(100);
    assert_eq!(r.sw() & 0x6F, 0x27, "still enabled");
    assert_eq!(r.i(0x2601, 0), 0);
}

/// KINCO-DIAG-06 (Error_State2 in Error_State bit 0): Pre Enable (8200h) on DIN4, inactive,
/// and an enable: "External enable" 5443h, Error_State2 bit 8, Error_State bit 0.
#[test]
fn pre_enable_refuses_the_enable() {
    let mut r = Rig::new();
    r.w16(0x2010, 0x06, 0x8200);
    r.w8(0x6060, 0, 3);
    r.cw(0x06);
    let _ = r.try_cw(0x0F);
    r.run_ms(5);
    assert_ne!(r.sw() & 0x6F, 0x27, "not enabled");
    assert_eq!(r.i(0x2602, 0), 1 << 8);
    assert_eq!(r.i(0x2601, 0), 1, "extended error");
    r.w16(0x2010, 0x02, 1 << 3);
    r.cw(0x86);
    r.cw(0x06);
    r.cw(0x0F);
    r.run_ms(5);
    assert_eq!(r.sw() & 0x6F, 0x27, "enabled with Pre Enable active");
}

/// Fast capture (§5.5.5): the first rising edge of Fast_Capture1 latches 6063h into
/// 2010h:24 and sets 2010h:20; a later edge does not until the flag is cleared.
#[test]
fn fast_capture_latches_the_first_edge() {
    let mut r = Rig::new();
    r.w16(0x2010, 0x06, 0x8400);
    r.enable_in(-3);
    r.w32(0x60FF, 0, dec_rpm(600.0));
    r.run_ms(100);
    r.w16(0x2010, 0x02, 1 << 3);
    r.run_ms(2);
    let first = r.i(0x2010, 0x24);
    assert_eq!(r.i(0x2010, 0x20), 1);
    assert!(first > 0 && (first - r.position()).abs() < 500, "{first}");
    r.w16(0x2010, 0x02, 0);
    r.run_ms(50);
    r.w16(0x2010, 0x02, 1 << 3);
    r.run_ms(2);
    assert_eq!(r.i(0x2010, 0x24), first, "only the first edge");
    assert_eq!(r.i(0x2010, 0x21), 1, "the falling edge has its own flag");
    r.w8(0x2010, 0x20, 0);
    r.w16(0x2010, 0x02, 0);
    r.run_ms(50);
    r.w16(0x2010, 0x02, 1 << 3);
    r.run_ms(2);
    assert!(r.i(0x2010, 0x24) > first + 1000, "armed again");
}

/// Homing method 17 on the negative limit switch (DIN6) and 19 on the home switch (DIN7):
/// the position is the home offset at the switch edge, bit 15 reference found.
#[test]
fn homing_on_the_switches() {
    for (method, edge) in [(17i8, -200_000i64), (19, 6_104)] {
        let mut r = Rig::new();
        r.w32(0x6099, 1, dec_rpm(1200.0));
        r.w32(0x6099, 2, dec_rpm(60.0));
        r.w32(0x609A, 0, dec_rps2(200.0));
        r.w8(0x6098, 0, method);
        r.enable_in(6);
        r.cw(0x1F);
        assert!(
            r.until_sw(0x1000, 30_000),
            "method {method}: {:04X}",
            r.sw()
        );
        assert_ne!(r.sw() & 0x8000, 0);
        let p = r.d.plant_position() * 10_000 / 65_536;
        assert!((p - edge).abs() < 200, "method {method}: edge at {p}");
        assert!(r.position().abs() < 200, "home offset 0: {}", r.position());
    }
}

/// Start Homing (2000h): its rising edge homes in mode 6 and then returns to the mode the
/// drive was in (Tab. 5-2).
#[test]
fn start_homing_input_returns_to_the_previous_mode() {
    let mut r = Rig::new();
    r.w16(0x2010, 0x05, 0x2000);
    r.w8(0x6098, 0, 19);
    r.w32(0x6099, 1, dec_rpm(300.0));
    r.w32(0x6099, 2, dec_rpm(60.0));
    r.w32(0x609A, 0, dec_rps2(100.0));
    r.w8(0x6099, 0x05, 1);
    r.w32(0x607C, 0, 777);
    r.enable_in(3);
    r.w16(0x2010, 0x02, DIN3);
    r.run_ms(2);
    let mut seen_homing = r.i(0x6061, 0) == 6;
    for _ in 0..1000 {
        r.run_ms(5);
        seen_homing |= r.i(0x6061, 0) == 6;
        if r.i(0x6061, 0) == 3 && seen_homing {
            break;
        }
    }
    assert!(seen_homing, "ran in mode 6");
    assert_eq!(r.i(0x6061, 0), 3, "back in mode 3");
    assert_ne!(r.sw() & 0x8000, 0, "home found");
    let p = r.position();
    // The edge reads 777; the motor stops past it: 50 inc at 60 rpm and 100 rps/s, and the
    // settling of the default loop (stiffness 12: 38 Hz / 10 Hz, kinco_loops.rs).
    assert!(
        (p - 777).abs() <= 100,
        "the home switch's edge reads 777: {p}"
    );
    assert_eq!(r.i(0x6040, 0) & 0x10, 0, "bit 4 back");
}

/// The error history (§7): the last 8 errors, each stored where the store mask of the
/// drive's state has its bit: Store_Mask_ON 2605h:02 = FBFFh keeps Following Error while
/// enabled, Store_Mask_OFF 2605h:03 = 0 keeps nothing while disabled.
#[test]
fn error_history_follows_the_store_masks() {
    let mut r = Rig::new();
    r.d.inject_fault(0x4210, 0x09); // disabled: not stored (Store_Mask_OFF = 0)
    r.run_ms(5);
    r.d.clear_fault(0x4210);
    r.cw(0x86);
    r.cw(0x06);
    assert_eq!(r.d.error_history().count(), 0);
    for _ in 0..10 {
        r.enable_in(3);
        r.d.inject_fault(0x3210, 0x05);
        r.run_ms(5);
        r.d.clear_fault(0x3210);
        r.cw(0x86);
        r.cw(0x06);
    }
    assert_eq!(r.d.error_history().collect::<Vec<_>>(), vec![0x3210; 8]);
    r.w16(0x2605, 0x03, 1 << 4);
    r.d.inject_fault(0x4210, 0x09);
    r.run_ms(5);
    assert_eq!(
        r.d.error_history().last(),
        Some(0x4210),
        "now stored while disabled"
    );
}

/// Quick Stop (1000h): the controlword's quick stop; afterwards 06h before 0Fh (Tab. 5-2).
#[test]
fn quick_stop_input() {
    let mut r = Rig::new();
    r.w16(0x2010, 0x06, 0x1000);
    r.enable_in(3);
    r.w32(0x60FF, 0, dec_rpm(600.0));
    r.run_ms(300);
    r.w16(0x2010, 0x02, 1 << 3);
    r.run_ms(500);
    assert!(r.rpm().abs() < 1.0, "stopped: {}", r.rpm());
    assert_ne!(r.sw() & 0x6F, 0x27, "no longer enabled: {:04X}", r.sw());
    r.w16(0x2010, 0x02, 0);
    r.cw(0x0F);
    assert_ne!(r.sw() & 0x6F, 0x27, "0Fh alone does not enable");
    r.cw(0x06);
    r.cw(0x0F);
    r.run_ms(5);
    assert_eq!(r.sw() & 0x6F, 0x27, "06h then 0Fh");
}

/// KINCO-SC-05 (§5.5.4): Gain Switch0 on DIN3 active, Gain Switch1 on DIN4 inactive: PI_Pointer
/// 60F9h:28 = 1, and the controller runs with set 1 (Kvp[1] = 2 × Kvp[0]: twice the velocity
/// gain); the bus cannot write PI_Pointer meanwhile.
#[test]
fn kinco_sc_05_gain_switch() {
    let mut r = Rig::new();
    let base = r.d.axis().gains().vel_kp;
    // Twice the gain, within the controller's 1/256 steps (kinco_loops.rs).
    let twice = |g: f64, b: f64| (g / b - 2.0).abs() < 0.03;
    r.w16(0x2340, 0x04, 2280);
    r.w16(0x2010, 0x05, 0x8020);
    r.w16(0x2010, 0x06, 0x8040);
    r.w16(0x2010, 0x02, DIN3);
    r.run_ms(5);
    assert_eq!(r.i(0x60F9, 0x28), 1);
    assert!(twice(r.d.axis().gains().vel_kp, base));
    assert!(r.d.write(0x60F9, 0x28, &[0, 0]).is_err());
    r.w16(0x2010, 0x02, 0);
    r.run_ms(5);
    assert_eq!(r.i(0x60F9, 0x28), 0);
    assert_eq!(r.d.axis().gains().vel_kp, base);
}

/// Kvi Off (0008h, DIN4 in the factory set-up): without the velocity integral a load leaves
/// a speed error that the integral otherwise removes.
#[test]
fn kvi_off_input_leaves_a_speed_error_under_load() {
    let error_with = |kvi_off: bool| {
        let mut r = Rig::new();
        if kvi_off {
            r.w16(0x2010, 0x02, 1 << 3);
        }
        r.enable_in(-3);
        r.w32(0x60FF, 0, dec_rpm(300.0));
        r.d.axis_mut().motor_mut().set_load_torque(0.3);
        r.run_ms(1000);
        (r.rpm() - 300.0).abs()
    };
    let with_integral = error_with(false);
    let without = error_with(true);
    assert!(with_integral < 2.0, "integral: {with_integral} rpm off");
    assert!(
        without > 5.0 * with_integral.max(0.5),
        "Kvi Off: {without} rpm off"
    );
}

/// Motor Error (8100h): an active input is "Motor Temperature" (Error_State bit 13, EMCY
/// 4310h with the temperature bit of 1001h); the fault resets once the input is gone.
#[test]
fn motor_error_input() {
    let mut r = Rig::new();
    r.w16(0x2010, 0x06, 0x8100);
    r.enable_in(3);
    r.events();
    r.w16(0x2010, 0x02, 1 << 3);
    r.run_ms(5);
    assert_eq!(r.sw() & 0x4F, 0x08);
    assert_eq!(r.i(0x2601, 0), 1 << 13);
    assert!(r.events().contains(&DriveEvent::Error {
        code: 0x4310,
        register: 0x09
    }));
    r.cw(0x86);
    r.cw(0x06);
    assert_eq!(r.sw() & 0x4F, 0x08, "still there");
    r.w16(0x2010, 0x02, 0);
    r.run_ms(5);
    r.cw(0x86);
    r.cw(0x06);
    assert_eq!(r.sw() & 0x6F, 0x21);
}

/// Warnings (§7): Warning_Word 2680h bit 0 (battery low) shows on the Enc Warning output
/// (8002h) and in statusword bit 7; the drive stays enabled.
#[test]
fn warning_word() {
    let mut r = Rig::new();
    r.w16(0x2010, 0x13, 0x8002); // OUT5: Enc Warning
    r.enable_in(3);
    r.d.set_warnings(0x0001);
    r.run_ms(5);
    assert_eq!(r.i(0x2680, 0), 1);
    assert_ne!(r.sw() & 0x0080, 0);
    assert_eq!(r.sw() & 0x6F, 0x27);
    assert_eq!(r.i(0x2010, 0x14) & 0x10, 0x10);
    r.d.set_warnings(0);
    r.run_ms(5);
    assert_eq!(r.sw() & 0x0080, 0);
    assert_eq!(r.i(0x2010, 0x14) & 0x10, 0);
}
