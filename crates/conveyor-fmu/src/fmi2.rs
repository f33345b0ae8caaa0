//! The same conveyor as an FMI 2.0 co-simulation FMU (FMI 2.0 §4 "FMI for Co-Simulation"):
//! the C functions of FMI 2.0 written by hand, since `fmi-export` writes those of FMI 3.0
//! only; its `modelDescription.xml` is written from the model's own declarations, the ones the
//! FMI 3.0 description is written from ([`conveyor::description::fmi2`]).
//!
//! One library serves both: the FMI 3.0 archive packs it as
//! `binaries/x86_64-linux/conveyor.so`, the FMI 2.0 archive as `binaries/linux64/conveyor.so`
//! (FMI 2.0 §2.5), and each importer calls its own functions (`fmi3…`, `fmi2…`). A
//! communication step is [`Conveyor::advance`] in both, so the two FMUs give the same values.
//!
//! Value references are those of the FMI 3.0 description (0 is `time`); in FMI 2.0 they are
//! unique per base type, which they are here across all types. The FMU uses its own memory
//! (`canNotUseMemoryManagementFunctions="true"`, FMI 2.0 §4.3.1): an instance is a `Box`.
//! States (`fmi2GetFMUstate`), directional derivatives and asynchronous steps are not offered
//! (`canGetAndSetFMUstate` and the others are false) and answer `fmi2Error`.

use std::ffi::{c_char, c_int, c_void, CStr, CString};

use fmi::schema::fmi3::{AbstractVariableTrait, InitializableVariableTrait, Variable};
use fmi_export::fmi3::Model;

use conveyor::Conveyor;

/// `fmi2Status` (FMI 2.0 §2.1.3).
type Status = c_int;
const OK: Status = 0;
const DISCARD: Status = 2;
const ERROR: Status = 3;

/// `fmi2Type`: `fmi2CoSimulation`.
const CO_SIMULATION: c_int = 1;

/// `fmi2CallbackLogger`: (componentEnvironment, instanceName, status, category, message, …).
type Logger =
    unsafe extern "C" fn(*mut c_void, *const c_char, Status, *const c_char, *const c_char, ...);

/// `fmi2CallbackFunctions` (FMI 2.0 §2.1.5).
#[repr(C)]
pub struct CallbackFunctions {
    logger: Option<Logger>,
    allocate_memory: Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>,
    free_memory: Option<unsafe extern "C" fn(*mut c_void)>,
    step_finished: Option<unsafe extern "C" fn(*mut c_void, Status)>,
    component_environment: *mut c_void,
}

/// A Float64 variable of the model, by name: the field it reads and writes.
type RealField = fn(&mut Conveyor) -> &mut f64;
/// A Boolean variable of the model, by name.
type BooleanField = fn(&mut Conveyor) -> &mut bool;

const REALS: &[(&str, RealField)] = &[
    ("shaft_angle", |m| &mut m.shaft_angle),
    ("shaft_speed", |m| &mut m.shaft_speed),
    ("motor_torque", |m| &mut m.motor_torque),
    ("load_torque", |m| &mut m.load_torque),
    ("belt_position", |m| &mut m.belt_position),
    ("belt_speed", |m| &mut m.belt_speed),
    ("motor_torque_seen", |m| &mut m.motor_torque_seen),
    ("mass", |m| &mut m.mass),
    ("pulley_radius", |m| &mut m.pulley_radius),
    ("stiffness", |m| &mut m.stiffness),
    ("damping", |m| &mut m.damping),
    ("viscous_friction", |m| &mut m.viscous_friction),
    ("coulomb_friction", |m| &mut m.coulomb_friction),
    ("barrier_from", |m| &mut m.barrier_from),
    ("barrier_to", |m| &mut m.barrier_to),
];

const BOOLEANS: &[(&str, BooleanField)] = &[("light_barrier", |m| &mut m.light_barrier)];

/// The value reference of `time` (FMI 3.0's independent variable, kept in FMI 2.0).
const TIME_VR: u32 = 0;

/// One instance: the model, its variables by value reference with their start values, and the
/// importer's logger.
struct Component {
    model: Conveyor,
    reals: Vec<(u32, RealField, Option<f64>)>,
    booleans: Vec<(u32, BooleanField, Option<bool>)>,
    time: f64,
    name: CString,
    logger: Option<Logger>,
    environment: *mut c_void,
    /// An error stops the instance: every later call but `fmi2FreeInstance` answers
    /// `fmi2Error` (FMI 2.0 §4.2.4, state "error").
    failed: bool,
}

impl Component {
    fn new(name: CString, functions: Option<&CallbackFunctions>) -> Self {
        let meta = Conveyor::build_toplevel_metadata();
        let mut reals = Vec::new();
        let mut booleans = Vec::new();
        for v in &meta.model_variables.variables {
            match v {
                Variable::Float64(f) => {
                    if let Some((_, field)) = REALS.iter().find(|(n, _)| *n == f.name()) {
                        let start = f.start().and_then(|s| s.first().copied());
                        reals.push((f.value_reference(), *field, start));
                    }
                }
                Variable::Boolean(b) => {
                    if let Some((_, field)) = BOOLEANS.iter().find(|(n, _)| *n == b.name()) {
                        let start = b.start().and_then(|s| s.first().copied());
                        booleans.push((b.value_reference(), *field, start));
                    }
                }
                _ => {}
            }
        }
        let mut c = Component {
            model: Conveyor::default(),
            reals,
            booleans,
            time: 0.0,
            name,
            logger: functions.and_then(|f| f.logger),
            environment: functions.map_or(std::ptr::null_mut(), |f| f.component_environment),
            failed: false,
        };
        c.reset();
        c
    }

    /// Start values, the mass at rest, time 0.
    fn reset(&mut self) {
        self.model = Conveyor::default();
        for (_, field, start) in &self.reals {
            *field(&mut self.model) = start.unwrap_or(0.0);
        }
        for (_, field, start) in &self.booleans {
            *field(&mut self.model) = start.unwrap_or(false);
        }
        self.model.outputs();
        self.time = 0.0;
        self.failed = false;
    }

    fn real(&mut self, vr: u32) -> Option<&mut f64> {
        let (_, field, _) = self.reals.iter().find(|(r, _, _)| *r == vr)?;
        Some(field(&mut self.model))
    }

    fn boolean(&mut self, vr: u32) -> Option<&mut bool> {
        let (_, field, _) = self.booleans.iter().find(|(r, _, _)| *r == vr)?;
        Some(field(&mut self.model))
    }

    /// Logs `message` through the importer's logger with `status`, and returns `status`.
    fn log(&self, status: Status, message: &str) -> Status {
        if let (Some(logger), Ok(text)) = (self.logger, CString::new(message)) {
            // SAFETY: the logger is the importer's, called as FMI 2.0 §2.1.5 defines it, with
            // a "%s" format and one NUL-terminated string.
            unsafe {
                logger(
                    self.environment,
                    self.name.as_ptr(),
                    status,
                    c"logAll".as_ptr(),
                    c"%s".as_ptr(),
                    text.as_ptr(),
                )
            };
        }
        status
    }

    fn fail(&mut self, message: &str) -> Status {
        self.failed = true;
        self.log(ERROR, message)
    }
}

/// The instance behind `c`, if any.
///
/// # Safety
/// `c` is null or a pointer `fmi2Instantiate` returned and `fmi2FreeInstance` has not freed.
unsafe fn component<'a>(c: *mut c_void) -> Option<&'a mut Component> {
    // SAFETY: as the function's contract says.
    unsafe { c.cast::<Component>().as_mut() }
}

/// `vr[..n]` and `value[..n]` as slices (empty when `n` is 0, whatever the pointers).
///
/// # Safety
/// Each pointer is valid for `n` elements when `n > 0`.
unsafe fn slices<'a, T, U>(
    vr: *const u32,
    n: usize,
    value: *mut U,
) -> Option<(&'a [u32], &'a mut [T])> {
    if n == 0 {
        return Some((&[], &mut []));
    }
    if vr.is_null() || value.is_null() {
        return None;
    }
    // SAFETY: as the function's contract says.
    unsafe {
        Some((
            std::slice::from_raw_parts(vr, n),
            std::slice::from_raw_parts_mut(value.cast::<T>(), n),
        ))
    }
}

#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

/// # Safety
/// The arguments are as FMI 2.0 §2.1.5 defines them.
#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instance_name: *const c_char,
    fmu_type: c_int,
    guid: *const c_char,
    _resource_location: *const c_char,
    functions: *const CallbackFunctions,
    _visible: c_int,
    _logging_on: c_int,
) -> *mut c_void {
    // SAFETY: null or the importer's callback table, alive while the instance is.
    let functions = unsafe { functions.as_ref() };
    let name = if instance_name.is_null() {
        CString::default()
    } else {
        // SAFETY: a NUL-terminated string (FMI 2.0 §2.1.5).
        unsafe { CStr::from_ptr(instance_name) }.to_owned()
    };
    let c = Component::new(name, functions);
    if fmu_type != CO_SIMULATION {
        c.log(ERROR, "only co-simulation is offered");
        return std::ptr::null_mut();
    }
    if !guid.is_null() {
        // SAFETY: a NUL-terminated string (FMI 2.0 §2.1.5).
        let guid = unsafe { CStr::from_ptr(guid) };
        if guid.to_bytes() != Conveyor::INSTANTIATION_TOKEN.as_bytes() {
            c.log(ERROR, "the GUID is not this FMU's");
            return std::ptr::null_mut();
        }
    }
    Box::into_raw(Box::new(c)).cast()
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`, not yet freed.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: *mut c_void) {
    if !c.is_null() {
        // SAFETY: made by `Box::into_raw` in `fmi2Instantiate`, freed once.
        drop(unsafe { Box::from_raw(c.cast::<Component>()) });
    }
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`, not yet freed.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: *mut c_void,
    _logging_on: c_int,
    _n: usize,
    _categories: *const *const c_char,
) -> Status {
    // SAFETY: as the function's contract says.
    match unsafe { component(c) } {
        Some(_) => OK,
        None => ERROR,
    }
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`, not yet freed.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: *mut c_void,
    _tolerance_defined: c_int,
    _tolerance: f64,
    start_time: f64,
    _stop_time_defined: c_int,
    _stop_time: f64,
) -> Status {
    // SAFETY: as the function's contract says.
    let Some(c) = (unsafe { component(c) }) else {
        return ERROR;
    };
    c.time = start_time;
    OK
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`, not yet freed.
#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: *mut c_void) -> Status {
    // SAFETY: as the function's contract says.
    match unsafe { component(c) } {
        Some(c) if !c.failed => OK,
        _ => ERROR,
    }
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`, not yet freed.
#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: *mut c_void) -> Status {
    // SAFETY: as the function's contract says.
    let Some(c) = (unsafe { component(c) }) else {
        return ERROR;
    };
    if c.failed {
        return ERROR;
    }
    c.model.outputs();
    OK
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`, not yet freed.
#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(c: *mut c_void) -> Status {
    // SAFETY: as the function's contract says.
    match unsafe { component(c) } {
        Some(_) => OK,
        None => ERROR,
    }
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`, not yet freed.
#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(c: *mut c_void) -> Status {
    // SAFETY: as the function's contract says.
    let Some(c) = (unsafe { component(c) }) else {
        return ERROR;
    };
    c.reset();
    OK
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`; `vr` and `value` hold `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    value: *mut f64,
) -> Status {
    // SAFETY: as the function's contract says.
    let (Some(c), Some((vrs, values))) = (unsafe { component(c) }, unsafe {
        slices::<f64, f64>(vr, n, value)
    }) else {
        return ERROR;
    };
    for (&r, v) in vrs.iter().zip(values.iter_mut()) {
        if r == TIME_VR {
            *v = c.time;
            continue;
        }
        match c.real(r) {
            Some(x) => *v = *x,
            None => return c.fail(&format!("no Real variable with value reference {r}")),
        }
    }
    OK
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`; `vr` and `value` hold `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    value: *const f64,
) -> Status {
    // SAFETY: as the function's contract says (the values are only read).
    let (Some(c), Some((vrs, values))) = (unsafe { component(c) }, unsafe {
        slices::<f64, f64>(vr, n, value.cast_mut())
    }) else {
        return ERROR;
    };
    for (&r, v) in vrs.iter().zip(values.iter()) {
        match c.real(r) {
            Some(x) => *x = *v,
            None => return c.fail(&format!("no settable Real with value reference {r}")),
        }
    }
    c.model.outputs();
    OK
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`; `vr` and `value` hold `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    value: *mut c_int,
) -> Status {
    // SAFETY: as the function's contract says.
    let (Some(c), Some((vrs, values))) = (unsafe { component(c) }, unsafe {
        slices::<c_int, c_int>(vr, n, value)
    }) else {
        return ERROR;
    };
    for (&r, v) in vrs.iter().zip(values.iter_mut()) {
        match c.boolean(r) {
            Some(x) => *v = c_int::from(*x),
            None => return c.fail(&format!("no Boolean variable with value reference {r}")),
        }
    }
    OK
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`; `vr` and `value` hold `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    value: *const c_int,
) -> Status {
    // SAFETY: as the function's contract says (the values are only read).
    let (Some(c), Some((vrs, values))) = (unsafe { component(c) }, unsafe {
        slices::<c_int, c_int>(vr, n, value.cast_mut())
    }) else {
        return ERROR;
    };
    for (&r, v) in vrs.iter().zip(values.iter()) {
        match c.boolean(r) {
            Some(x) => *x = *v != 0,
            None => return c.fail(&format!("no settable Boolean with value reference {r}")),
        }
    }
    OK
}

/// The model has no Integer variables: any value reference is refused.
///
/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(
    c: *mut c_void,
    _vr: *const u32,
    n: usize,
    _value: *mut c_int,
) -> Status {
    no_variables(c, n, "Integer")
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(
    c: *mut c_void,
    _vr: *const u32,
    n: usize,
    _value: *const c_int,
) -> Status {
    no_variables(c, n, "Integer")
}

/// The model has no String variables.
///
/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(
    c: *mut c_void,
    _vr: *const u32,
    n: usize,
    _value: *mut *const c_char,
) -> Status {
    no_variables(c, n, "String")
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(
    c: *mut c_void,
    _vr: *const u32,
    n: usize,
    _value: *const *const c_char,
) -> Status {
    no_variables(c, n, "String")
}

fn no_variables(c: *mut c_void, n: usize, kind: &str) -> Status {
    // SAFETY: the callers' contract: an instance of `fmi2Instantiate`.
    let Some(c) = (unsafe { component(c) }) else {
        return ERROR;
    };
    if n == 0 {
        return OK;
    }
    c.fail(&format!("the conveyor has no {kind} variables"))
}

/// What the capability flags say is not offered: logged, `fmi2Error`.
fn not_offered(c: *mut c_void, call: &str) -> Status {
    // SAFETY: the callers' contract: an instance of `fmi2Instantiate`.
    match unsafe { component(c) } {
        Some(c) => c.log(ERROR, &format!("{call} is not offered")),
        None => ERROR,
    }
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(c: *mut c_void, _state: *mut *mut c_void) -> Status {
    not_offered(c, "fmi2GetFMUstate")
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetFMUstate(c: *mut c_void, _state: *mut c_void) -> Status {
    not_offered(c, "fmi2SetFMUstate")
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: *mut c_void, _state: *mut *mut c_void) -> Status {
    not_offered(c, "fmi2FreeFMUstate")
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: *mut c_void,
    _state: *mut c_void,
    _size: *mut usize,
) -> Status {
    not_offered(c, "fmi2SerializedFMUstateSize")
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: *mut c_void,
    _state: *mut c_void,
    _bytes: *mut c_char,
    _size: usize,
) -> Status {
    not_offered(c, "fmi2SerializeFMUstate")
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: *mut c_void,
    _bytes: *const c_char,
    _size: usize,
    _state: *mut *mut c_void,
) -> Status {
    not_offered(c, "fmi2DeSerializeFMUstate")
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: *mut c_void,
    _unknown: *const u32,
    _n_unknown: usize,
    _known: *const u32,
    _n_known: usize,
    _dv_known: *const f64,
    _dv_unknown: *mut f64,
) -> Status {
    not_offered(c, "fmi2GetDirectionalDerivative")
}

// ---- FMI 2.0 §4.2: the co-simulation functions ----

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
    c: *mut c_void,
    _vr: *const u32,
    _n: usize,
    _order: *const c_int,
    _value: *const f64,
) -> Status {
    not_offered(c, "fmi2SetRealInputDerivatives")
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
    c: *mut c_void,
    _vr: *const u32,
    _n: usize,
    _order: *const c_int,
    _value: *mut f64,
) -> Status {
    not_offered(c, "fmi2GetRealOutputDerivatives")
}

/// One communication step: [`Conveyor::advance`], as the FMI 3.0 `fmi3DoStep` does it.
///
/// # Safety
/// `c` is an instance of `fmi2Instantiate`, not yet freed.
#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(
    c: *mut c_void,
    current_communication_point: f64,
    communication_step_size: f64,
    _no_set_fmu_state_prior_to_current_point: c_int,
) -> Status {
    // SAFETY: as the function's contract says.
    let Some(c) = (unsafe { component(c) }) else {
        return ERROR;
    };
    if c.failed {
        return ERROR;
    }
    match c.model.advance(communication_step_size) {
        Ok(()) => {
            c.time = current_communication_point + communication_step_size;
            OK
        }
        Err(message) => c.fail(&message),
    }
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2CancelStep(c: *mut c_void) -> Status {
    not_offered(c, "fmi2CancelStep")
}

/// Steps are never asynchronous: there is no status to ask for (`fmi2Discard`, FMI 2.0
/// §4.2.3).
///
/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStatus(c: *mut c_void, _kind: c_int, _value: *mut c_int) -> Status {
    no_status(c)
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(
    c: *mut c_void,
    _kind: c_int,
    _value: *mut f64,
) -> Status {
    no_status(c)
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetIntegerStatus(
    c: *mut c_void,
    _kind: c_int,
    _value: *mut c_int,
) -> Status {
    no_status(c)
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBooleanStatus(
    c: *mut c_void,
    _kind: c_int,
    _value: *mut c_int,
) -> Status {
    no_status(c)
}

/// # Safety
/// `c` is an instance of `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStringStatus(
    c: *mut c_void,
    _kind: c_int,
    _value: *mut *const c_char,
) -> Status {
    no_status(c)
}

fn no_status(c: *mut c_void) -> Status {
    // SAFETY: the callers' contract: an instance of `fmi2Instantiate`.
    match unsafe { component(c) } {
        Some(_) => DISCARD,
        None => ERROR,
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    fn vr_of(name: &str) -> u32 {
        let meta = Conveyor::build_toplevel_metadata();
        let v = meta
            .model_variables
            .iter_abstract()
            .find(|v| v.name() == name);
        v.unwrap().value_reference()
    }

    #[test]
    fn a_step_through_the_c_functions_moves_the_belt_as_advance_does() {
        let guid = CString::new(Conveyor::INSTANTIATION_TOKEN).unwrap();
        // SAFETY: the calls an importer makes, in FMI 2.0's order, on one instance.
        unsafe {
            let c = fmi2Instantiate(
                c"t".as_ptr(),
                CO_SIMULATION,
                guid.as_ptr(),
                std::ptr::null(),
                std::ptr::null(),
                0,
                0,
            );
            assert!(!c.is_null());
            assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), OK);
            assert_eq!(fmi2EnterInitializationMode(c), OK);
            assert_eq!(fmi2ExitInitializationMode(c), OK);
            let speed_vr = vr_of("shaft_speed");
            let pos_vr = vr_of("belt_position");
            assert_eq!(fmi2SetReal(c, &speed_vr, 1, &10.0), OK);
            for k in 0..1000 {
                assert_eq!(fmi2DoStep(c, f64::from(k) * 1e-3, 1e-3, 1), OK);
            }
            let mut pos = 0.0;
            assert_eq!(fmi2GetReal(c, &pos_vr, 1, &mut pos), OK);
            // The declared start values, set one by one (the belt's state is the model's own).
            let mut reference = Conveyor::default();
            reference.shaft_speed = 10.0;
            reference.mass = 0.5;
            reference.pulley_radius = 0.01;
            reference.stiffness = 1.0e5;
            reference.damping = 100.0;
            reference.viscous_friction = 5.0;
            reference.coulomb_friction = 2.0;
            reference.barrier_from = 0.10;
            reference.barrier_to = 0.12;
            for _ in 0..1000 {
                reference.advance(1e-3).unwrap();
            }
            assert_eq!(pos, reference.belt_position);
            assert!(pos > 0.05, "{pos}");
            fmi2FreeInstance(c);
        }
    }
}
