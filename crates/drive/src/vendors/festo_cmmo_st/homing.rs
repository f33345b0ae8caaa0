//! The homing methods of PNU 1011 (CMMO-ST §6.2.2 Tab. 6.2, after CiA 402) as data: what
//! each searches, in which direction, and where Tab. 6.2 permits it. The device
//! ([`super::device`]) runs the search; this module only says which one and refuses the rest.

use crate::stepper::StepperMode;

/// App. D 22h: homing to the switch failed, switch not found.
pub const SWITCH_NOT_FOUND: u8 = 0x22;
/// App. D 23h: no index pulse found.
pub const NO_INDEX_PULSE: u8 = 0x23;
/// App. D 2Eh: index pulse too close to the (reference) proximity switch.
pub const INDEX_TOO_CLOSE: u8 = 0x2E;
/// App. D 3Ah: homing timeout (open loop: switch not found within the time).
pub const HOMING_TIMEOUT: u8 = 0x3A;
/// App. D 3Bh: homing method invalid; 24h: drive function not supported in open loop.
pub use super::diagnostics::code::{HOMING_METHOD_INVALID as METHOD_INVALID, NOT_IN_OPEN_LOOP};

/// What a method searches for REF.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// −35: REF = the actual position, no motion.
    CurrentPosition,
    /// 33 / 34: the next index pulse in the direction.
    IndexPulse,
    /// −17 / −18: the fixed stop (block detection PNU 1015…1017).
    FixedStop,
    /// 23 / 27: the edge of the reference switch (closed loop: the next index pulse behind it).
    ReferenceSwitch,
}

/// One method: PNU 1011 value, search target, search direction (+1 / −1, 0 for none).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Method {
    pub number: i8,
    pub target: Target,
    pub direction: i8,
    /// Tab. 6.2 permits it in open loop (motor without encoder or open-loop operation).
    pub open_loop: bool,
}

/// Tab. 6.2. Decision for 23 / 27: the manual prints "27 positive, 23 negative" in the
/// closed-loop rows and "27 negative, 23 positive" in the open-loop rows; CiA 402 (on which
/// §6.2.2 says the methods are based) has 23 = home switch, positive start and 27 = home
/// switch, negative start, so the open-loop row is taken for both.
pub const METHODS: [Method; 7] = [
    m(-35, Target::CurrentPosition, 0, true),
    m(33, Target::IndexPulse, -1, false),
    m(34, Target::IndexPulse, 1, false),
    m(-17, Target::FixedStop, -1, false),
    m(-18, Target::FixedStop, 1, false),
    m(23, Target::ReferenceSwitch, 1, true),
    m(27, Target::ReferenceSwitch, -1, true),
];

const fn m(number: i8, target: Target, direction: i8, open_loop: bool) -> Method {
    Method {
        number,
        target,
        direction,
        open_loop,
    }
}

/// The method PNU 1011 = `number` selects with this motor mode and wiring, or the diagnostic
/// of the refusal. Decisions: a number outside Tab. 6.2, a fixed stop in open loop (App. D 3Bh
/// names it) and a switch method without a switch wired are 3Bh; the index methods in open
/// loop are 24h (the index is evaluated by the closed-loop encoder function).
pub fn select(number: i64, mode: StepperMode, switch_wired: bool) -> Result<Method, u8> {
    let method = METHODS
        .iter()
        .find(|m| i64::from(m.number) == number)
        .ok_or(METHOD_INVALID)?;
    if mode == StepperMode::OpenLoop && !method.open_loop {
        return Err(match method.target {
            Target::IndexPulse => NOT_IN_OPEN_LOOP,
            _ => METHOD_INVALID,
        });
    }
    if method.target == Target::ReferenceSwitch && !switch_wired {
        return Err(METHOD_INVALID);
    }
    Ok(*method)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tab_6_2_per_mode() {
        let cl = StepperMode::ClosedLoop;
        let ol = StepperMode::OpenLoop;
        for n in [-35, 33, 34, -17, -18, 23, 27] {
            assert_eq!(select(n, cl, true).map(|m| i64::from(m.number)), Ok(n));
        }
        assert_eq!(select(-17, ol, true), Err(METHOD_INVALID));
        assert_eq!(select(34, ol, true), Err(NOT_IN_OPEN_LOOP));
        assert_eq!(select(23, ol, false), Err(METHOD_INVALID));
        assert_eq!(select(1, cl, true), Err(METHOD_INVALID));
        assert_eq!(select(23, ol, true).map(|m| m.direction), Ok(1));
        assert_eq!(select(27, cl, true).map(|m| m.direction), Ok(-1));
    }
}
