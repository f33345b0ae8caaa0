//! Every transition of the CiA 402 state machine as the CMMP-AS manual (ch. 6) gives it, and
//! the statusword state values of Tab. 6.6.

use drive::device_control::{DeviceControl, Reaction, State};
use drive::vendors::festo_cmmp_as::manufacturer_bit_14;

fn at(state: State) -> DeviceControl {
    let mut dc = DeviceControl::default();
    dc.initialised();
    let path: &[u16] = match state {
        State::SwitchOnDisabled => &[],
        State::ReadyToSwitchOn => &[0x06],
        State::SwitchedOn => &[0x06, 0x07],
        State::OperationEnabled => &[0x06, 0x07, 0x0F],
        State::QuickStopActive => &[0x06, 0x07, 0x0F, 0x02],
        _ => unreachable!(),
    };
    for cw in path {
        dc.controlword(*cw, false, true);
    }
    assert_eq!(dc.state(), state);
    dc
}

/// CMMP-CW-11 (with the Tab. 6.6 masks and values the other CW vectors use): FAULT reads
/// 000Fh with 6510h:F0 bit 7 = 0, 0008h with bit 7 = 1.
#[test]
fn statusword_values_of_tab_6_6() {
    let cases = [
        (State::NotReadyToSwitchOn, 0x004F, 0x0000),
        (State::SwitchOnDisabled, 0x004F, 0x0040),
        (State::ReadyToSwitchOn, 0x006F, 0x0021),
        (State::SwitchedOn, 0x006F, 0x0023),
        (State::OperationEnabled, 0x006F, 0x0027),
        (State::QuickStopActive, 0x006F, 0x0007),
        (State::FaultReactionActive, 0x004F, 0x000F),
    ];
    for (s, mask, value) in cases {
        assert_eq!(s.statusword_bits(false) & mask, value, "{s:?}");
        assert_eq!(s.statusword_bits(true) & mask, value, "{s:?}");
    }
    // FAULT: 000Fh by default, 0008h with 6510h:F0 bit 7 (CiA 402).
    assert_eq!(State::Fault.statusword_bits(false) & 0x4F, 0x000F);
    assert_eq!(State::Fault.statusword_bits(true) & 0x4F, 0x0008);
}

/// CMMP-CW-01, CMMP-CW-02, CMMP-CW-03: 0006h → 0021h, 0007h → 0023h, 000Fh → 0027h; for
/// transition 2 bit 3 is don't-care (000Eh is Shutdown as well).
#[test]
fn enable_sequence_transitions_0_to_4() {
    // CMMP-AS §8.1: 0006h → 0021h, 0007h → 0023h, 000Fh → 0027h.
    let mut dc = DeviceControl::default();
    assert_eq!(dc.state(), State::NotReadyToSwitchOn);
    dc.initialised();
    assert_eq!(dc.state().statusword_bits(false) & 0x4F, 0x40);
    assert_eq!(dc.controlword(0x06, false, true), Reaction::None);
    assert_eq!(dc.state().statusword_bits(false) & 0x6F, 0x21);
    let mut with_bit_3 = DeviceControl::default();
    with_bit_3.initialised();
    with_bit_3.controlword(0x0E, false, true);
    assert_eq!(
        with_bit_3.state(),
        State::ReadyToSwitchOn,
        "bit 3 don't-care"
    );
    assert_eq!(dc.controlword(0x07, false, true), Reaction::Enable);
    assert_eq!(dc.state().statusword_bits(false) & 0x6F, 0x23);
    assert_eq!(dc.controlword(0x0F, false, true), Reaction::Enable);
    assert_eq!(dc.state().statusword_bits(false) & 0x6F, 0x27);
}

/// CMMP-CW-04: READY_TO_SWITCH_ON, 000Fh → OPERATION_ENABLE.
#[test]
fn transitions_3_and_4_combined() {
    let mut dc = at(State::ReadyToSwitchOn);
    assert_eq!(dc.controlword(0x0F, false, true), Reaction::Enable);
    assert_eq!(dc.state(), State::OperationEnabled);
}

#[test]
fn transition_2_needs_the_hardware_enables() {
    let mut dc = at(State::SwitchOnDisabled);
    dc.controlword(0x06, false, false);
    assert_eq!(dc.state(), State::SwitchOnDisabled);
}

/// CMMP-CW-06, CMMP-CW-07, CMMP-CW-08, CMMP-CW-09: quick stop (0002h), disable voltage (0000h),
/// shutdown (0006h), disable operation (0007h) from OPERATION_ENABLE.
#[test]
fn every_transition_out_of_operation_enabled() {
    // 5: disable operation → SWITCHED ON, braking with the quick-stop deceleration (605Ch = −1).
    let mut dc = at(State::OperationEnabled);
    assert_eq!(dc.controlword(0x07, false, true), Reaction::QuickStopRamp);
    assert_eq!(dc.state(), State::SwitchedOn);
    // 8: shutdown → READY TO SWITCH ON, coasting (605Bh = 0).
    let mut dc = at(State::OperationEnabled);
    assert_eq!(dc.controlword(0x06, false, true), Reaction::Coast);
    assert_eq!(dc.state(), State::ReadyToSwitchOn);
    // 9: disable voltage → SWITCH ON DISABLED.
    let mut dc = at(State::OperationEnabled);
    assert_eq!(dc.controlword(0x00, false, true), Reaction::Coast);
    assert_eq!(dc.state(), State::SwitchOnDisabled);
    // 11: quick stop → QUICK STOP ACTIVE, then 12 when stopped (605Ah = 2).
    let mut dc = at(State::OperationEnabled);
    assert_eq!(dc.controlword(0x02, false, true), Reaction::QuickStopRamp);
    assert_eq!(dc.state().statusword_bits(false) & 0x6F, 0x07);
    assert_eq!(dc.stopped(), Reaction::Coast);
    assert_eq!(dc.state().statusword_bits(false) & 0x4F, 0x40);
}

#[test]
fn transitions_6_7_10_12() {
    let mut dc = at(State::SwitchedOn);
    assert_eq!(dc.controlword(0x06, false, true), Reaction::Coast); // 6
    assert_eq!(dc.state(), State::ReadyToSwitchOn);
    dc.controlword(0x02, false, true); // 7 (quick stop)
    assert_eq!(dc.state(), State::SwitchOnDisabled);
    let mut dc = at(State::ReadyToSwitchOn);
    dc.controlword(0x00, false, true); // 7 (disable voltage, CiA 402)
    assert_eq!(dc.state(), State::SwitchOnDisabled);
    let mut dc = at(State::SwitchedOn);
    assert_eq!(dc.controlword(0x00, false, true), Reaction::Coast); // 10
    assert_eq!(dc.state(), State::SwitchOnDisabled);
    let mut dc = at(State::SwitchedOn);
    dc.controlword(0x02, false, true); // 10 (quick stop, CiA 402)
    assert_eq!(dc.state(), State::SwitchOnDisabled);
    let mut dc = at(State::QuickStopActive);
    assert_eq!(dc.controlword(0x00, false, true), Reaction::Coast); // 12 (disable voltage)
    assert_eq!(dc.state(), State::SwitchOnDisabled);
    // 16 is not offered (605Ah = 2): enable operation does not leave QUICK STOP ACTIVE.
    let mut dc = at(State::QuickStopActive);
    dc.controlword(0x0F, false, true);
    assert_eq!(dc.state(), State::QuickStopActive);
}

/// CMMP-CW-10: the fault reset takes the rising edge of bit 7 (0080h, the manual's "0008h"
/// corrected), once the cause is gone; holding 0080h does not reset again.
#[test]
fn fault_reaction_fault_and_reset_on_the_rising_edge() {
    // 13 → 14: from a powered state through FAULT REACTION ACTIVE.
    let mut dc = at(State::OperationEnabled);
    assert_eq!(dc.fault(), Reaction::QuickStopRamp);
    assert_eq!(dc.state(), State::FaultReactionActive);
    dc.controlword(0x0F, true, true);
    assert_eq!(
        dc.state(),
        State::FaultReactionActive,
        "commands wait for the reaction"
    );
    dc.stopped();
    assert_eq!(dc.state(), State::Fault);
    // 15: bit 7 rising edge, but only once the cause is gone (CMMP-AS §8.2).
    dc.controlword(0x80, true, true);
    assert_eq!(dc.state(), State::Fault);
    dc.controlword(0x80, false, true);
    assert_eq!(dc.state(), State::Fault, "no edge: bit 7 was already set");
    dc.controlword(0x00, false, true);
    dc.controlword(0x80, false, true);
    assert_eq!(dc.state(), State::SwitchOnDisabled);
    // From an unpowered state straight to FAULT.
    let mut dc = at(State::ReadyToSwitchOn);
    assert_eq!(dc.fault(), Reaction::Coast);
    assert_eq!(dc.state(), State::Fault);
}

#[test]
fn python_canopen_fault_reset_sequence() {
    // BaseNode402.reset_from_fault: 0x00 then 0x80 (rising edge), then the enable commands.
    let mut dc = at(State::OperationEnabled);
    dc.fault();
    dc.stopped();
    for cw in [0x00, 0x80, 0x06, 0x07, 0x0F] {
        dc.controlword(cw, false, true);
    }
    assert_eq!(dc.state(), State::OperationEnabled);
}

/// CMMP-CW-05: only Shutdown leads out of SWITCH_ON_DISABLED; 000Fh changes nothing.
#[test]
fn cmmp_cw_05_enable_operation_from_switch_on_disabled_is_ignored() {
    let mut dc = at(State::SwitchOnDisabled);
    for cw in [0x0F, 0x07, 0x1F, 0x02, 0x00] {
        assert_eq!(dc.controlword(cw, false, true), Reaction::None, "{cw:#06x}");
        assert_eq!(dc.state().statusword_bits(false) & 0x4F, 0x40, "{cw:#06x}");
    }
}

/// CMMP-CW-12: invert 0, mask 1: IS_REFERENCED 1 → bit 14 = 1, 0 → 0.
#[test]
fn cmmp_cw_12_bit_14_shows_referenced() {
    assert!(manufacturer_bit_14(0x0000_0001, 0, 1));
    assert!(!manufacturer_bit_14(0x0000_0000, 0, 1));
}

/// CMMP-CW-13: invert 2, mask 2: COMMUTATION_VALID 0 → bit 14 = 1, 1 → 0.
#[test]
fn cmmp_cw_13_bit_14_shows_commutation_not_valid() {
    assert!(manufacturer_bit_14(0x0000_0000, 2, 2));
    assert!(!manufacturer_bit_14(0x0000_0002, 2, 2));
}

/// CMMP-CW-14: invert 4, mask 5 ("not ready for enable OR referenced"): 2000h:01 = 4, 0, 5, 1
/// → bit 14 = 0, 1, 1, 1. Bit 2 is READY_FOR_ENABLE (Tab. 6.10), as the example uses it.
#[test]
fn cmmp_cw_14_bit_14_not_ready_for_enable_or_referenced() {
    for (msw, bit) in [(4, false), (0, true), (5, true), (1, true)] {
        assert_eq!(manufacturer_bit_14(msw, 4, 5), bit, "2000h:01 = {msw}");
    }
}
