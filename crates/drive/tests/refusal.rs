//! Why a drive does not take a command (`Drive::refusal`): the reason and the manual's rule,
//! for each refusal point of the personalities, checked against what the drive then does.

#[path = "drive_rig/mod.rs"]
mod drive_rig;

use drive::device_control::State;
use drive::drive::refusal::{Refusal, Request};
use drive::drive::DriveSettings;
use drive_rig::Rig;
use od::{AbortCode, ObjectAccess};

/// A factory Kinco FD3: DIN1 has Enable, DIN3 Operation Mode Sel (ch. 9): the enable is
/// refused because DIN1 owns 6040h (L1287), and a bus write of 6040h is refused with it.
#[test]
fn a_factory_kinco_names_din1_as_the_owner_of_the_controlword() {
    let mut r = Rig::device("kinco-fd3", 1, DriveSettings::default());
    let why = r.d.refusal(Request::Enable);
    assert_eq!(
        why.map(|w| match w {
            Refusal::InputOwns {
                input,
                function,
                function_object,
                index,
                ..
            } => (input, function, function_object, index),
            _ => (0, "", (0, 0), 0),
        }),
        Some((1, "Enable", (0x2010, 0x03), 0x6040))
    );
    let why = why.map(|w| (w.kind(), w.to_string(), w.rule()));
    assert!(
        why.as_ref()
            .is_some_and(|(kind, text, rule)| *kind == "input_owns_object"
                && text.starts_with("DIN1 has the function Enable (2010h:03)")
                && text.contains("6040h:00")
                && rule.contains("L1287")),
        "{why:?}"
    );
    // The write the rule refuses is the one the drive refuses.
    assert_eq!(r.try_cw(0x06), Err(AbortCode::LOCAL_CONTROL));
    assert_eq!(
        r.d.refusal(Request::Write {
            index: 0x6040,
            sub: 0
        })
        .map(|w| w.kind()),
        Some("input_owns_object")
    );
    // DIN3 owns the mode.
    assert!(matches!(
        r.d.refusal(Request::Mode(3)),
        Some(Refusal::InputOwns {
            input: 3,
            index: 0x6060,
            ..
        })
    ));
    assert_eq!(
        r.d.write(0x6060, 0, &[3]),
        Err(AbortCode::LOCAL_CONTROL),
        "the drive refuses what the refusal names"
    );
    // Din1_Function := 0 gives the controlword to the bus: nothing refuses it any more.
    r.w16(0x2010, 0x03, 0);
    assert_eq!(r.d.refusal(Request::Enable), None);
    assert_eq!(r.try_cw(0x06), Ok(()));
}

/// A Kinco whose Pre Enable input (8200h) is configured and inactive cannot be enabled
/// (Tab. 6-1): the refusal names the input.
#[test]
fn a_kinco_without_pre_enable_names_that_input() {
    let mut r = Rig::device("kinco-fd3", 1, DriveSettings::default());
    r.w16(0x2010, 0x03, 0);
    r.w16(0x2010, 0x06, 0x8200);
    r.run_ms(2);
    assert!(matches!(
        r.d.refusal(Request::Enable),
        Some(Refusal::InputInactive {
            input: 4,
            function: "Pre Enable",
            ..
        })
    ));
    // Din_Simulate DIN4: active, the enable is free.
    r.w16(0x2010, 0x02, 1 << 3);
    r.run_ms(2);
    assert_eq!(r.d.refusal(Request::Enable), None);
}

/// CMMP-AS transition 2 needs DIN4 and DIN5 (§6.1.3 Tab. 6.4): without them the refusal
/// says so, and the drive stays in SWITCH ON DISABLED.
#[test]
fn a_cmmp_as_without_its_hardware_enables_says_which() {
    let mut r = Rig::device(
        "cmmp-as",
        1,
        DriveSettings {
            enables_present: false,
            ..Default::default()
        },
    );
    let why = r.d.refusal(Request::Enable);
    assert_eq!(why.map(|w| w.kind()), Some("hardware_enable_missing"));
    assert!(why.is_some_and(|w| w.to_string().contains("DIN4") && w.rule().contains("Tab. 6.4")));
    r.cw(0x06);
    r.run_ms(5);
    assert_eq!(r.d.state(), State::SwitchOnDisabled);
    let ok = Rig::device("cmmp-as", 1, DriveSettings::default());
    assert_eq!(ok.d.refusal(Request::Enable), None);
    assert_eq!(
        ok.d.refusal(Request::Mode(2)),
        Some(Refusal::ModeUnsupported { mode: 2 }),
        "the CMMP-AS has no velocity mode (§7.1)"
    );
}

/// NT-NODE-07: the Nanotec that accepts no motion commands (switch = node + 128, no bit-rate
/// code in 2005h) says why; its torque mode needs the closed loop (§5.5: 2001h = 1 switches it on, 200Ah shows it).
#[test]
fn a_nanotec_says_why_it_takes_no_motion_command_or_no_torque_mode() {
    let r = Rig::device(
        "nanotec-smci47s",
        34,
        DriveSettings {
            enables_present: false,
            ..Default::default()
        },
    );
    let why = r.d.refusal(Request::Enable);
    assert!(
        why.is_some_and(|w| w.to_string().contains("accepts no motion commands")
            && w.rule().contains("§1.1.3 step 7")),
        "{why:?}"
    );
    let mut r = Rig::device("nanotec-smci47s", 34, DriveSettings::default());
    assert_eq!(r.d.refusal(Request::Enable), None);
    assert_eq!(r.i(0x200A, 0), 0, "open loop at delivery");
    let why = r.d.refusal(Request::Mode(4));
    assert!(why.is_some_and(|w| w.kind() == "device_state" && w.rule().contains("§5.5")));
    assert_eq!(r.d.write(0x6060, 0, &[4]), Err(AbortCode::DEVICE_STATE));
    r.w8(0x2001, 0, 1);
    r.run_ms(2);
    assert_eq!(r.d.refusal(Request::Mode(4)), None);
}

/// Parameters the CMMP-AS locks in a state (0800 0022h) say why: 1011h with the output stage
/// on (§5.1, CMMP-SDO-10), 60C1h:01 while the IP buffer is locked (§7.4.2); the Kinco's tuning
/// start without WriteFUN_CTL (§7.1). Each refusal is the one the drive answers the write with.
#[test]
fn locked_parameters_name_their_rule() {
    let mut r = Rig::device("cmmp-as", 1, DriveSettings::default());
    let write = |index, sub| Request::Write { index, sub };
    assert!(matches!(
        r.d.refusal(write(0x60C1, 1)),
        Some(Refusal::State { rule, .. }) if rule.contains("§7.4.2")
    ));
    assert_eq!(
        r.d.write(0x60C1, 1, &0i32.to_le_bytes()),
        Err(AbortCode::DEVICE_STATE)
    );
    assert_eq!(r.d.refusal(write(0x1011, 1)), None, "output stage off");
    for cw in [0x06, 0x07, 0x0F] {
        r.cw(cw);
    }
    r.run_ms(20);
    assert_eq!(r.d.state(), State::OperationEnabled);
    assert!(matches!(
        r.d.refusal(write(0x1011, 1)),
        Some(Refusal::State { rule, .. }) if rule.contains("§5.1")
    ));
    assert_eq!(
        r.d.write(0x1011, 1, b"load"),
        Err(AbortCode::DEVICE_STATE),
        "CMMP-SDO-10"
    );

    let mut k = Rig::device("kinco-fd3", 1, DriveSettings::default());
    assert!(matches!(
        k.d.refusal(write(0x3040, 1)),
        Some(Refusal::State { reason, .. }) if reason.contains("WriteFUN_CTL")
    ));
    assert_eq!(k.d.write(0x3040, 1, &[1]), Err(AbortCode::DEVICE_STATE));
    k.w8(0x3041, 0x05, 1);
    assert_eq!(k.d.refusal(write(0x3040, 1)), None);
}

/// A fault whose cause is still there: the fault reset does not acknowledge it (CiA 402
/// transition 15), and the enable says so until the cause is gone.
#[test]
fn a_present_fault_cause_is_named() {
    let mut r = Rig::device("cmmp-as", 1, DriveSettings::default());
    r.d.inject_fault(0x4310, 0x09);
    r.run_ms(10);
    assert_eq!(r.d.state(), State::Fault);
    assert_eq!(
        r.d.refusal(Request::Enable),
        Some(Refusal::CausePresent { code: 0x4310 })
    );
    r.cw(0x00);
    r.cw(0x80);
    r.run_ms(5);
    assert_eq!(r.d.state(), State::Fault, "the reset does not take");
    r.d.clear_fault(0x4310);
    assert_eq!(r.d.refusal(Request::Enable), None);
}
