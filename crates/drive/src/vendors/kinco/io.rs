//! Kinco digital inputs and outputs (§5.5, Tab. 5-2 / 6-1, Tab. 5-3 / 6-2): seven DINs and five
//! DOUTs, each with its function codes, polarity and simulation.
//!
//! The manual's rules:
//! - inputs: `Internal = (Real OR Simulate) XOR (NOT Polarity)`, Din_Polarity 2010h:01,
//!   Din_Real 2010h:0A; a function is active while an input that has it is;
//! - outputs: `Real = (Function_Status OR Simulate) XOR (NOT Polarity)`, the status the OR of
//!   the output's functions, Dout_Polarity 2010h:0D, Dout_Real 2010h:14;
//! - a DIN function owns the object it sets (Enable the controlword, Operation Mode Sel the
//!   mode, L1287): Enable 1 → controlword := Din_Controlword 2020h:0F, 0 → 06h; Reset Errors
//!   on its rising edge; Activate Command drives bit 4; Quick Stop the quick-stop command;
//!   the limit switches are normally closed (0 = that direction blocked); Pre Enable 0 refuses
//!   the enable with "External enable"; Motor Error raises "Motor Temperature"; Din Vel Index
//!   selects `Din_Speed[x]` in the velocity modes; Fast_Capture latches 6063h on the first edge.
//!
//! Decisions:
//! - the simulation objects are not printed in this part; the sibling FD manuals' Din_Simulate
//!   2010h:02 and Dout_Simulate 2010h:0E are taken (the extract's §5.11, EXT);
//! - the twin has no cabinet: the travel's switches are wired to the inputs whose function
//!   names them (P limit± as normally closed contacts, the home switch normally open);
//!   [`Drive::force_inputs`] bit n − 1 drives DINn's wire;
//! - the owning functions act when their input changes (and at power-on), so after a Quick
//!   Stop input the Enable input is toggled again, as the manual says;
//! - Ready is "no error and not switch-on disabled" (the manual: "ready to switch on"),
//!   Motor Brake is "brake released".

use super::hooks::Kinco;
use super::{din_has, selected_index, DinFunction, DoutFunction, DOUT_FUNCTIONS};
use crate::axis::Demand;
use crate::controlword::Controlword;
use crate::device_control::State;
use crate::drive::refusal::{Refusal, Request};
use crate::drive::{mode, Drive, HomingRun};
use crate::travel::Inputs;
use od::ObjectAccess;

/// DIN1 … DIN7.
pub const DINS: u8 = 7;
/// OUT1 … OUT5.
pub const DOUTS: u8 = 5;

/// Motor Temperature (Error_State bit 13), raised by the Motor Error DIN.
const MOTOR_TEMPERATURE: u16 = 0x4310;
/// External enable (Error_State2 bit 8), an enable without Pre Enable.
const EXTERNAL_ENABLE: u16 = 0x5443;

/// L1287: "the DIN function has the highest priority".
const DIN_PRIORITY: &str = "Kinco FD/CD §5.5 (L1287): the DIN function has the highest \
    priority; an object a DIN function sets can no longer be changed by hand, e.g. with Enable \
    configured the controlword cannot be changed";

/// Tab. 6-1 (8200h) and Tab. 5-8 bit 8.
const PRE_ENABLE: &str = "Kinco FD/CD Tab. 6-1 (8200h Pre Enable): 0 = the drive cannot be \
    enabled; an enable then raises \"External enable\" (5443h, Tab. 5-8 bit 8)";

/// The input functions that own an object, with the manual's name (Tab. 6-1).
const OWNERS: [(DinFunction, &str, u16, u8); 4] = [
    (DinFunction::Enable, "Enable", 0x6040, 0x00),
    (
        DinFunction::OperationModeSel,
        "Operation Mode Sel",
        0x6060,
        0x00,
    ),
    (DinFunction::GainSwitch0, "Gain Switch0", 0x60F9, 0x28),
    (DinFunction::GainSwitch1, "Gain Switch1", 0x60F9, 0x28),
];

/// Which inputs have each function of Tab. 6-1, from DIN1…DIN7's function codes. A logic
/// cycle asks about a dozen functions, several times each; a function's inputs as a mask
/// answer each question at once, and the map is rebuilt only when a code changes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct DinFunctions {
    /// DINx_Function 2010h:03 + n − 1 as the map was built from ([`function_codes`]).
    codes: u128,
    /// Row r of [`DIN_FUNCTIONS`](super::DIN_FUNCTIONS) (the function with discriminant r):
    /// its inputs, bit n − 1 = DINn.
    inputs: [u8; super::DIN_FUNCTIONS.len()],
}

impl DinFunctions {
    fn of(codes: u128) -> Self {
        let mut inputs = [0u8; super::DIN_FUNCTIONS.len()];
        for (mask, &(_, function)) in inputs.iter_mut().zip(super::DIN_FUNCTIONS.iter()) {
            *mask = (0..DINS).fold(0u8, |acc, n| {
                acc | (u8::from(din_has(code_of(codes, n), function)) << n)
            });
        }
        DinFunctions { codes, inputs }
    }

    /// The inputs that have `function`, bit n − 1 = DINn.
    fn inputs(&self, function: DinFunction) -> u8 {
        self.inputs.get(function as usize).copied().unwrap_or(0)
    }

    /// The level of `function` from the internal levels `internal`: `None` if no input has
    /// it, else whether any input that has it is active.
    fn level(&self, internal: u8, function: DinFunction) -> Option<bool> {
        let inputs = self.inputs(function);
        (inputs != 0).then_some(internal & inputs != 0)
    }

    /// The first input (0 = DIN1) that has `function`.
    fn first(&self, function: DinFunction) -> Option<u8> {
        let inputs = self.inputs(function);
        (inputs != 0).then_some(inputs.trailing_zeros() as u8)
    }
}

/// What the inputs were at the last cycle (for their edges).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct DinMemory {
    /// Internal levels, bit n − 1 = DINn; `None` before the first cycle.
    pub(crate) internal: Option<u8>,
    /// A homing the Start Homing input started, and the mode to return to.
    pub(crate) homing_return: Option<i8>,
    /// The Kvi Off input is active (the controller runs without the velocity integral).
    pub(crate) kvi_off: bool,
    /// The input functions as of the last logic cycle (see [`Drive::kinco_din_functions`]).
    pub(crate) functions: DinFunctions,
    /// The output functions as of the last logic cycle (see [`Drive::kinco_dout_functions`]).
    pub(crate) outputs: DoutFunctions,
    /// The step whose logic built `functions` and `outputs` (the drive's `step_epoch`).
    pub(crate) mapped_at: Option<u64>,
    /// The levels this logic cycle found at the plant's position: (cycle, position, Din_Real,
    /// internal levels). The cycle reads the inputs three times at the same position (the
    /// input functions, the limit switches, Din_Real) with the same wiring and objects.
    pub(crate) levels: Option<(u64, i64, u8, u8)>,
}

/// Which functions of Tab. 6-2 each output has, from OUT1…OUT5's function codes: the
/// outputs' status is the OR of their functions, each function evaluated once a cycle.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct DoutFunctions {
    /// DOUTx_Function 2010h:0F + n − 1 as the map was built from ([`function_codes`]).
    codes: u128,
    /// OUTn's functions, bit r = row r of [`DOUT_FUNCTIONS`].
    rows: [u16; DOUTS as usize],
}

impl DoutFunctions {
    fn of(codes: u128) -> Self {
        DoutFunctions {
            codes,
            rows: core::array::from_fn(|n| dout_rows(code_of(codes, n as u8))),
        }
    }
}

/// DIN1_Function 2010h:03 and DOUT1_Function 2010h:0F.
const DIN1_FUNCTION: u8 = 0x03;
const DOUT1_FUNCTION: u8 = 0x0F;

// `function_codes` reads DINn_Function from slot `param_slot(2010h:03) + n − 1` of the
// drive's parameter cache, DOUTn_Function from `param_slot(2010h:0F) + n − 1`: the keys 2010h:03 …
// :09 and :0F … :13 must stay in consecutive slots there.
const _: () = {
    let mut group = 0;
    while group < 2 {
        let (first_sub, count) = if group == 0 {
            (DIN1_FUNCTION, DINS)
        } else {
            (DOUT1_FUNCTION, DOUTS)
        };
        let first = match crate::drive::param_slot::<Kinco>(0x2010, first_sub) {
            Some(s) => s,
            None => panic!("a function code is not cached"),
        };
        let mut n = 0;
        while n < count {
            match crate::drive::param_slot::<Kinco>(0x2010, first_sub + n) {
                Some(s) if s == first + n as usize => {}
                _ => panic!("function codes not in consecutive slots"),
            }
            n += 1;
        }
        group += 1;
    }
};

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, Kinco> {
    /// Din_Real: the wires at `position` (see the module doc), forced inputs over them.
    pub(crate) fn kinco_din_real(&self, position: i64) -> u8 {
        self.din_real_with(&self.kinco_din_functions(), position)
    }

    /// [`Drive::kinco_din_real`] with the input functions at hand.
    fn din_real_with(&self, functions: &DinFunctions, position: i64) -> u8 {
        if let Some((real, _)) = self.levels_found(position) {
            return real;
        }
        let switches = self.settings.travel.inputs(position);
        let wired_if = |on: bool, f| if on { functions.inputs(f) } else { 0 };
        let wired = wired_if(!switches.positive_limit, DinFunction::PositiveLimit)
            | wired_if(!switches.negative_limit, DinFunction::NegativeLimit)
            | wired_if(switches.home, DinFunction::HomeSignal);
        let mask = self.forced_mask as u8;
        ((wired & !mask) | (self.forced_levels as u8 & mask)) & 0x7F
    }

    /// The internal levels: `(Real OR Simulate) XOR (NOT Polarity)`.
    pub(crate) fn kinco_din_internal(&self, position: i64) -> u8 {
        self.din_internal_with(&self.kinco_din_functions(), position)
    }

    /// [`Drive::kinco_din_internal`] with the input functions at hand.
    fn din_internal_with(&self, functions: &DinFunctions, position: i64) -> u8 {
        if let Some((_, internal)) = self.levels_found(position) {
            return internal;
        }
        let simulate = self.cycle_value(0x2010, 0x02) as u8;
        let polarity = self.cycle_value(0x2010, 0x01) as u8;
        ((self.din_real_with(functions, position) | simulate) ^ !polarity) & 0x7F
    }

    /// Din_Real and the internal levels at `position` as this logic cycle found them
    /// (`None` between cycles, at another position or before the cycle read them).
    fn levels_found(&self, position: i64) -> Option<(u8, u8)> {
        match self.vendor.din.levels {
            Some((cycle, at, real, internal)) if cycle == self.cycles && at == position => {
                Some((real, internal))
            }
            _ => None,
        }
    }

    /// The first input (0 = DIN1) that has `function`.
    pub(crate) fn kinco_din_with(&self, function: DinFunction) -> Option<u8> {
        self.kinco_din_functions().first(function)
    }

    /// Whether an input has `function`.
    pub(crate) fn kinco_din_configured(&self, function: DinFunction) -> bool {
        self.kinco_din_functions().inputs(function) != 0
    }

    fn din_level(&self, internal: u8, function: DinFunction) -> Option<bool> {
        self.kinco_din_functions().level(internal, function)
    }

    /// DIN1…DIN7's function codes ([`function_codes`]).
    fn din_codes(&self) -> u128 {
        function_codes(self, DIN1_FUNCTION, DINS)
    }

    /// The input functions of DIN1…DIN7's codes as they stand. Within a step, those its
    /// first logic cycle read (`kinco_io_map`): the dictionary is written only between steps
    /// (a master, the panel, a restore), never by a cycle. Between steps, through whichever
    /// path it was written, the codes are read and compared.
    pub(crate) fn kinco_din_functions(&self) -> DinFunctions {
        let last = &self.vendor.din.functions;
        if self.vendor.din.mapped_at == Some(self.step_epoch) {
            return *last;
        }
        let codes = self.din_codes();
        if last.codes == codes {
            *last
        } else {
            DinFunctions::of(codes)
        }
    }

    /// The output functions of OUT1…OUT5's codes as they stand (as
    /// [`Drive::kinco_din_functions`]).
    fn kinco_dout_functions(&self) -> DoutFunctions {
        let last = &self.vendor.din.outputs;
        if self.vendor.din.mapped_at == Some(self.step_epoch) {
            return *last;
        }
        let codes = function_codes(self, DOUT1_FUNCTION, DOUTS);
        if last.codes == codes {
            *last
        } else {
            DoutFunctions::of(codes)
        }
    }

    /// At the start of a logic cycle: the input and output functions of the codes as they
    /// stand, for the rest of the step.
    fn kinco_io_map(&mut self) -> DinFunctions {
        if self.vendor.din.mapped_at == Some(self.step_epoch) {
            return self.vendor.din.functions;
        }
        let functions = self.kinco_din_functions();
        let outputs = self.kinco_dout_functions();
        let din = &mut self.vendor.din;
        din.functions = functions;
        din.outputs = outputs;
        din.mapped_at = Some(self.step_epoch);
        functions
    }

    /// The internal levels of this logic cycle (read once by [`Drive::kinco_din_cycle`]).
    fn din_now(&self) -> u8 {
        self.vendor
            .din
            .internal
            .unwrap_or_else(|| self.kinco_din_internal(self.plant_position()))
    }

    /// Whether `function` is active now (an input that has it is active).
    pub(crate) fn kinco_din_active(&self, function: DinFunction) -> bool {
        self.din_level(self.din_now(), function).unwrap_or(false)
    }

    /// The directions blocked now (negative, positive): a limit switch or a position limit
    /// after homing (kinco_limits.rs).
    pub(crate) fn kinco_limits_active(&self) -> (bool, bool) {
        let functions = self.kinco_din_functions();
        let internal = self.din_now();
        let (below, above) = self.kinco_position_limits_blocking();
        (
            functions.level(internal, DinFunction::NegativeLimit) == Some(false) || below,
            functions.level(internal, DinFunction::PositiveLimit) == Some(false) || above,
        )
    }

    /// The switches as homing reads them: a configured P limit input that is 0 blocks its
    /// direction.
    pub(crate) fn kinco_switches(&self, position: i64) -> Inputs {
        let functions = self.kinco_din_functions();
        let internal = self.din_internal_with(&functions, position);
        Inputs {
            negative_limit: functions.level(internal, DinFunction::NegativeLimit) == Some(false),
            positive_limit: functions.level(internal, DinFunction::PositiveLimit) == Some(false),
            home: functions.level(internal, DinFunction::HomeSignal) == Some(true),
        }
    }

    /// `Din_Speed[x]` in rpm where a Din Vel Index function is on an input (§6.2.2,
    /// KINCO-SC-03): x = Index0 + 2·Index1 + 4·Index2, an index no input has counts 0.
    pub(crate) fn kinco_din_speed_rpm(&self) -> Option<i32> {
        let internal = self.din_now();
        let functions = self.kinco_din_functions();
        let bits = [
            DinFunction::DinVelIndex0,
            DinFunction::DinVelIndex1,
            DinFunction::DinVelIndex2,
        ]
        .map(|f| functions.level(internal, f));
        if bits.iter().all(Option::is_none) {
            return None;
        }
        let x = selected_index(&bits);
        let sub = if x < 4 { 0x09 + x } else { 0x18 + x - 4 };
        Some(
            self.value(0x2020, sub)
                .clamp(i32::MIN as i64, i32::MAX as i64) as i32,
        )
    }

    /// The input that owns object `index:sub` (L1287), as a refusal.
    fn kinco_owner(&self, index: u16, sub: u8) -> Option<Refusal> {
        OWNERS
            .iter()
            .filter(|(_, _, i, s)| (*i, *s) == (index, sub))
            .find_map(|&(f, name, _, _)| {
                let n = self.kinco_din_with(f)?;
                Some(Refusal::InputOwns {
                    input: n + 1,
                    function: name,
                    function_object: (0x2010, 0x03 + n),
                    index,
                    sub,
                    rule: DIN_PRIORITY,
                })
            })
    }

    /// What the Kinco's input functions refuse: the objects they own (6040h, 6060h,
    /// PI_Pointer 60F9h:28, which PI_Switch 6069h:09 = 1 owns as well), an enable without
    /// Pre Enable. The write hooks of `kinco_drive.rs` refuse by the same rules.
    pub(crate) fn kinco_refusal(&self, request: Request) -> Option<Refusal> {
        match request {
            Request::Enable => self.kinco_owner(0x6040, 0).or_else(|| {
                let n = self.kinco_din_with(DinFunction::PreEnable)?;
                (!self.kinco_pre_enable()).then_some(Refusal::InputInactive {
                    input: n + 1,
                    function: "Pre Enable",
                    rule: PRE_ENABLE,
                })
            }),
            Request::Mode(_) => self.kinco_owner(0x6060, 0),
            Request::Write { index, sub } => {
                self.kinco_owner(index, sub).or_else(|| match (index, sub) {
                    (0x60F9, 0x28) if self.value(0x6069, 0x09) == 1 => Some(Refusal::State {
                        reason: "PI_Switch 6069h:09 = 1 switches the gain set itself",
                        rule: "Kinco FD/CD §5.5.4: PI_Pointer is set by the Gain Switch \
                            inputs, else by PI_Switch (6069h:09 = 1), else by hand",
                    }),
                    (0x3040, 0x01) if self.value(0x3041, 0x05) != 1 => Some(Refusal::State {
                        reason: "a tuning run needs WriteFUN_CTL 3041h:05 = 1",
                        rule: "Kinco FD/CD §7.1: over communication, WriteFUN_CTL 3041h:05 \
                            must be 1 before a tuning run starts",
                    }),
                    _ => None,
                })
            }
        }
    }

    /// Transition 2 / 3 may happen: no Pre Enable input, or it is active.
    pub(crate) fn kinco_pre_enable(&self) -> bool {
        let internal = self.din_now();
        self.din_level(internal, DinFunction::PreEnable) != Some(false)
    }

    /// One logic cycle of the input functions, before the controlword is read.
    pub(crate) fn kinco_din_cycle(&mut self) {
        let position = self.plant_position();
        // The functions are the inputs' until the next write, never changed by this cycle.
        let functions = self.kinco_io_map();
        self.vendor.din.levels = None;
        let real = self.din_real_with(&functions, position);
        let now = self.din_internal_with(&functions, position);
        self.vendor.din.levels = Some((self.cycles, position, real, now));
        let before = self.vendor.din.internal;
        self.vendor.din.internal = Some(now);
        let level = |_: &Self, f| functions.level(now, f);
        // Levels as in the last cycle: no function has an edge (most cycles; each question
        // below is then answered without looking the function up twice).
        let edges = before != Some(now);
        let changed = |_: &Self, f| {
            if !edges {
                return None;
            }
            let was = before.and_then(|b| functions.level(b, f));
            let is = functions.level(now, f);
            (is.is_some() && is != was).then_some(is == Some(true))
        };
        let rising = |d: &Self, f| changed(d, f) == Some(true) && before.is_some();
        if let Some(active) = changed(self, DinFunction::OperationModeSel) {
            let sub = if active { 0x0E } else { 0x0D };
            let m = self.value(0x2020, sub) as i8;
            let _ = self.write_mode(0x6060, 0, &[m as u8]);
        }
        if let Some(active) = changed(self, DinFunction::Enable) {
            let cw = if active {
                self.value(0x2020, 0x0F) as u16
            } else {
                0x0006
            };
            self.kinco_set_controlword(cw);
        }
        if let Some(active) = changed(self, DinFunction::ActivateCommand) {
            let cw = Controlword(self.read(self.hot.controlword) as u16);
            let cw = if active {
                cw | Controlword::NEW_SET_POINT
            } else {
                cw.difference(Controlword::NEW_SET_POINT)
            };
            self.kinco_set_controlword(cw.bits());
        }
        if rising(self, DinFunction::QuickStop) {
            // CiA 402 quick stop: bit 1 set, bit 2 clear.
            let cw = self.read(self.hot.controlword) as u16;
            self.kinco_set_controlword((cw & !0x0004) | 0x0002);
        }
        if rising(self, DinFunction::StartHoming) && self.dc.state() == State::OperationEnabled {
            self.vendor.din.homing_return = Some(self.mode);
            let _ = self.write_mode(0x6060, 0, &[mode::HOMING as u8]);
            let cw = Controlword(self.read(self.hot.controlword) as u16);
            self.kinco_set_controlword((cw | Controlword::HOMING_START).bits());
        }
        self.kinco_homing_return();
        // The position table (§6.4.1): its edges for the next mode-1 cycle; an error, another
        // mode or the enable gone end the flow at once.
        self.vendor.table.start_edge |= rising(self, DinFunction::StartPosTable);
        self.vendor.table.abort_edge |= rising(self, DinFunction::AbortPosTable)
            || functions.inputs(DinFunction::StartPosTable) == 0;
        self.vendor.table.cond1_rising |= rising(self, DinFunction::PosTableCond1);
        if self.mode != mode::PROFILE_POSITION
            || self.dc.state() != State::OperationEnabled
            || !self.faults.is_empty()
        {
            self.kinco_table_abort();
            self.vendor.table.start_edge = false;
            self.vendor.table.abort_edge = false;
        }
        if rising(self, DinFunction::ResetErrors) {
            self.cw_rising |= Controlword::FAULT_RESET;
        }
        self.kinco_gain_switching(&functions, now);
        let motor_error = level(self, DinFunction::MotorError) == Some(true);
        self.cause(
            MOTOR_TEMPERATURE,
            motor_error,
            super::error_register(MOTOR_TEMPERATURE),
        );
        let cw = Controlword(self.read(self.hot.controlword) as u16);
        let enabling = cw.contains(Controlword::ENABLE_OPERATION_CMD);
        let refused = level(self, DinFunction::PreEnable) == Some(false)
            && enabling
            && self.dc.state() != State::Fault;
        if refused && !self.faults.contains(&EXTERNAL_ENABLE) {
            self.raise(
                EXTERNAL_ENABLE,
                super::error_register(EXTERNAL_ENABLE),
                true,
            );
        }
        if edges {
            self.kinco_capture(&functions, before, now);
        }
        self.kinco_position_limits_cycle();
    }

    /// Gain switching (§5.5.4), in the manual's order: the Gain Switch inputs (PI_Pointer =
    /// BCD(GS1:GS0), an input not configured counts 0); else with PI_Switch 6069h:09 = 1 set 0
    /// while the motor turns and set 1 once Pos Reached or Zero Speed holds; else the
    /// PI_Pointer written. Kvi Off turns the velocity integral off.
    fn kinco_gain_switching(&mut self, functions: &DinFunctions, internal: u8) {
        let bits = [DinFunction::GainSwitch0, DinFunction::GainSwitch1]
            .map(|f| functions.level(internal, f));
        let pointer = if bits.iter().any(Option::is_some) {
            Some(i64::from(selected_index(&bits)))
        } else if self.cycle_value(0x6069, 0x09) == 1 {
            let settled = self.dout_function(DoutFunction::PosReached)
                || self.dout_function(DoutFunction::ZeroSpeed);
            Some(i64::from(settled))
        } else {
            None
        };
        if let Some(p) = pointer.filter(|p| *p != self.cycle_value(0x60F9, 0x28)) {
            self.kinco_store(0x60F9, 0x28, p);
            self.params_dirty = true;
        }
        let kvi_off = functions.level(internal, DinFunction::KviOff) == Some(true);
        if kvi_off != self.vendor.din.kvi_off {
            self.vendor.din.kvi_off = kvi_off;
            self.params_dirty = true;
        }
    }

    /// "After homing started by the input the drive returns to the previous mode" (Tab.
    /// 5-2): once the homing has ended (attained or failed), the mode and bit 4 go back.
    fn kinco_homing_return(&mut self) {
        let Some(previous) = self.vendor.din.homing_return else {
            return;
        };
        let ended = matches!(self.homing, HomingRun::Idle)
            && (self.homing_attained || self.homing_error)
            && self.mode_pending.is_none();
        if ended || self.dc.state() != State::OperationEnabled {
            self.vendor.din.homing_return = None;
            let _ = self.write_mode(0x6060, 0, &[previous as u8]);
            let cw = Controlword(self.read(self.hot.controlword) as u16);
            self.kinco_set_controlword(cw.difference(Controlword::HOMING_START).bits());
        }
    }

    /// Fast capture (§5.5.5): the first edge of Fast_Capture1 / 2 sets its
    /// flag 2010h:20 … :23 and latches Pos_Actual 6063h into 2010h:24 … :27; later edges are
    /// ignored until the flag is written back to 0.
    fn kinco_capture(&mut self, functions: &DinFunctions, before: Option<u8>, now: u8) {
        let Some(before) = before else { return };
        for (function, flag) in [
            (DinFunction::FastCapture1, 0x20u8),
            (DinFunction::FastCapture2, 0x22u8),
        ] {
            let (Some(was), Some(is)) = (
                functions.level(before, function),
                functions.level(now, function),
            ) else {
                continue;
            };
            if was == is {
                continue;
            }
            let flag = if is { flag } else { flag + 1 };
            if self.value(0x2010, flag) == 0 {
                let pos = self.value(0x6063, 0);
                let d = self.od.description();
                let (f, p) = (d.entry(0x2010, flag), d.entry(0x2010, flag + 4));
                self.store(f, 1);
                self.store(p, pos);
            }
        }
    }

    /// A controlword an input function sets, with the edges a bus write would latch.
    pub(crate) fn kinco_set_controlword(&mut self, cw: u16) {
        let _ = self.od.write_internal(0x6040, 0, &cw.to_le_bytes());
        self.take_controlword(Controlword(cw));
    }

    /// The status of one DOUT function (Tab. 5-3).
    fn dout_function(&self, f: DoutFunction) -> bool {
        let state = self.dc.state();
        let power = !matches!(self.demand, Demand::Off);
        match f {
            DoutFunction::Ready => {
                self.faults.is_empty()
                    && matches!(
                        state,
                        State::ReadyToSwitchOn | State::SwitchedOn | State::OperationEnabled
                    )
            }
            DoutFunction::Error => matches!(state, State::Fault | State::FaultReactionActive),
            DoutFunction::PosReached => {
                self.mode == mode::PROFILE_POSITION
                    && self.target_reached
                    && state == State::OperationEnabled
            }
            DoutFunction::ZeroSpeed => {
                // Speed_1ms (whole inc/ms) against Zero_Speed_Window 2010h:18 (inc/ms).
                let inc_per_ms = f64::from(self.plant_velocity_rpm())
                    * super::hooks::INCREMENTS_PER_REV as f64
                    / 60_000.0;
                (inc_per_ms as i64).abs() <= self.cycle_value(0x2010, 0x18).max(0)
            }
            DoutFunction::MotorBrake => power && !self.brake_engaged,
            DoutFunction::SpeedReached => {
                matches!(self.mode, mode::PROFILE_VELOCITY | -3)
                    && self.target_reached
                    && state == State::OperationEnabled
            }
            DoutFunction::SpeedLimit => {
                self.mode == mode::PROFILE_TORQUE
                    && !self.target_reached
                    && state == State::OperationEnabled
            }
            DoutFunction::DriverEnable => state == State::OperationEnabled,
            DoutFunction::PositionLimit => {
                let (negative, positive) = self.kinco_limits_active();
                negative || positive
            }
            DoutFunction::HomeFound => self.referenced,
            DoutFunction::PosTableActive => self.kinco_table_active(),
            DoutFunction::EncWarning => self.vendor.warnings != 0,
            DoutFunction::EncIndex => false,
        }
    }

    /// The function status of OUT1…OUT5 (each the OR of its functions), bit n − 1 = OUTn:
    /// each function the outputs have evaluated once.
    fn dout_status(&self) -> u8 {
        let rows = self.kinco_dout_functions().rows;
        let wanted = rows.iter().fold(0u16, |acc, r| acc | r);
        let active = DOUT_FUNCTIONS
            .iter()
            .enumerate()
            .filter(|(row, _)| wanted & (1 << row) != 0)
            .fold(0u16, |acc, (row, &(_, f))| {
                acc | (u16::from(self.dout_function(f)) << row)
            });
        rows.iter()
            .enumerate()
            .fold(0u8, |acc, (n, r)| acc | (u8::from(r & active != 0) << n))
    }

    /// Dout_Real 2010h:14, bit n − 1 = OUTn: `(status OR Simulate) XOR (NOT Polarity)`.
    pub fn kinco_dout_real(&self) -> u8 {
        let status = self.dout_status();
        let simulate = self.cycle_value(0x2010, 0x0E) as u8;
        let polarity = self.cycle_value(0x2010, 0x0D) as u8;
        ((status | simulate) ^ !polarity) & 0x1F
    }

    /// Din_Real 2010h:0A and Dout_Real 2010h:14.
    pub(crate) fn kinco_publish_io(&mut self) {
        let din = self.kinco_din_real(self.plant_position());
        let dout = self.kinco_dout_real();
        // Resolved once at power-on (the engine's parameter slots): this runs every cycle.
        let entry = |sub| {
            crate::drive::param_slot::<Kinco>(0x2010, sub)
                .and_then(|slot| self.params.get(slot).copied().flatten())
        };
        let (a, b) = (entry(0x0A), entry(0x14));
        self.publish_store(super::slot::DIN_REAL, a, i64::from(din));
        self.publish_store(super::slot::DOUT_REAL, b, i64::from(dout));
    }
}

// A DOUT function's row is a bit of a u16.
const _: () = assert!(DOUT_FUNCTIONS.len() <= 16);

/// The rows of [`DOUT_FUNCTIONS`] a DOUTx_Function value `code` has (bit r = row r): a
/// single-bit code combines with the others, a group code (8xxxh, 9xxxh) is that one function.
fn dout_rows(code: u16) -> u16 {
    DOUT_FUNCTIONS
        .iter()
        .enumerate()
        .fold(0u16, |acc, (row, &(c, _))| {
            let has = if c & 0x8000 == 0 {
                code & 0x8000 == 0 && code & c == c
            } else {
                code == c
            };
            acc | (u16::from(has) << row)
        })
}

/// The `count` function codes from 2010h:`first_sub` on, code n (from 0) in bits 16·n …
/// 16·n + 15: one integer, compared with the last cycle's in registers (every logic cycle
/// reads the inputs' and outputs' codes). Read through their resolved entries: the slots
/// are consecutive, checked above.
#[inline(always)]
fn function_codes<S: AsRef<[u8]> + AsMut<[u8]>>(
    d: &Drive<S, Kinco>,
    first_sub: u8,
    count: u8,
) -> u128 {
    let first = crate::drive::param_slot::<Kinco>(0x2010, first_sub).unwrap_or(usize::MAX);
    let entries = d
        .params
        .get(first..first.saturating_add(usize::from(count)))
        .unwrap_or(&[]);
    entries.iter().enumerate().fold(0u128, |acc, (n, e)| {
        let code = d.read(*e).clamp(0, 0xFFFF) as u128;
        acc | code << (16 * n)
    })
}

// The inputs' and the outputs' codes each fit the integer.
const _: () = assert!(16 * DINS as u32 <= 128 && 16 * DOUTS as u32 <= 128);

/// Code n (from 0) of [`function_codes`]'s integer.
fn code_of(codes: u128, n: u8) -> u16 {
    (codes >> (16 * u32::from(n))) as u16
}
