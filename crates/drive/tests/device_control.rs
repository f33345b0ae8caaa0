//! Every transition of the CiA 402 state machine as the CMMP-AS manual (ch. 6) gives it, and
//! the statusword state values of Tab. 6.6 (spec cmmp-as-2 §4, §8.1–8.3).

use drive::device_control::{DeviceControl, Reaction, State};

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

#[test]
fn enable_sequence_transitions_0_to_4() {
    // CMMP-AS §8.1: 0006h → 0021h, 0007h → 0023h, 000Fh → 0027h.
    let mut dc = DeviceControl::default();
    assert_eq!(dc.state(), State::NotReadyToSwitchOn);
    dc.initialised();
    assert_eq!(dc.state().statusword_bits(false) & 0x4F, 0x40);
    assert_eq!(dc.controlword(0x06, false, true), Reaction::None);
    assert_eq!(dc.state().statusword_bits(false) & 0x6F, 0x21);
    assert_eq!(dc.controlword(0x07, false, true), Reaction::Enable);
    assert_eq!(dc.state().statusword_bits(false) & 0x6F, 0x23);
    assert_eq!(dc.controlword(0x0F, false, true), Reaction::Enable);
    assert_eq!(dc.state().statusword_bits(false) & 0x6F, 0x27);
}

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
