//! The FMI 3.0 C functions of the cell FMU: the only `unsafe` code of this crate (the C API
//! hands over raw pointers, and the functions are exported under the names the importer looks
//! up, `#[unsafe(export_name)]`). Every function of `fmi3Functions.h` is exported (an importer
//! such as fmpy binds them all); each is checked at compile time against the header's
//! `fmi3…TYPE` (`fmi::fmi3::binding`), and passes its arguments on to `fmi-export`'s
//! implementation (`Fmi3Common`, `Fmi3CoSimulation`, …), which holds the instance's state
//! machine and calls [`crate::CellModel`]. Those a co-simulation FMU without model exchange
//! and scheduled execution does not support return `fmi3Error`, as `fmi-export` writes them.
//!
//! **Why not `fmi_export::export_fmu!`.** It writes the same functions, but its
//! `fmi3GetBinary` copies the value into buffers the importer would pass, where FMI 3.0
//! (§2.2.6.2, `fmi3GetBinary`) has the FMU hand out pointers to its own memory and the
//! importer pass none (fmpy passes null pointers and reads the pointers back): through it an
//! importer never sees `Tx_Data`. [`fmi3_get_binary`] is written here instead, with the same
//! state handling: each value is read through `fmi-export` into a [`BINARY_PLACE`]-byte
//! buffer, into which [`crate::CellModel`]'s `get_binary` writes the address and the length of
//! the value it holds (the cell's own bytes, unchanged until the next call that steps or
//! updates the instance).
//!
//! **One call, one read of the cell.** `fmi-export` calls the model once per value reference
//! (`ModelGetSet::get_float64(vr, …)`), and the model cannot see the call's other value
//! references, so a get of N outputs would lock the cell and pass the panic guard N times.
//! The outputs' getters (`fmi3GetFloat64`, `fmi3GetUInt8`, `fmi3GetUInt16`, `fmi3GetInt32`)
//! are therefore written here ([`batched_get!`]): each passes `fmi-export`'s handling of a
//! get once, for the call's first value reference, with the call's value references in a
//! thread-local list ([`with_call`]) from which [`crate::CellModel`] reads all of them under
//! one lock of the cell.

use std::cell::{Cell, RefCell};

use fmi::fmi3::binding;
use fmi_export::fmi3::{Fmi3CoSimulation, Fmi3Common, Fmi3ModelExchange, Fmi3ScheduledExecution};

use crate::CellModel;

/// The size of the buffer `fmi3GetBinary` reads a value's place into: its address and its
/// length, each a little-endian `usize`.
pub const BINARY_PLACE: usize = 2 * std::mem::size_of::<usize>();

/// Exports `fmi3<Name>` as `<Trait>::<method>` of [`CellModel`], typed as the header's
/// `fmi3<Name>TYPE`.
macro_rules! forward {
    ($($c:ident => $tr:ident :: $f:ident ( $($a:ident : $t:ty),* ) -> $r:ty;)*) => {$(
        #[unsafe(export_name = stringify!($c))]
        pub unsafe extern "C" fn $f($($a: $t),*) -> $r {
            // SAFETY: the arguments are the importer's, passed on as the C API defines them.
            unsafe { <CellModel as $tr>::$f($($a),*) }
        }
        fmi_export::paste::paste! {
            const _: binding::[<$c TYPE>] = Some($f);
        }
    )*};
}

/// The typed get / set pairs: `fmi3Get<Type>` / `fmi3Set<Type>`.
macro_rules! get_set {
    ($($n:ident)*) => { fmi_export::paste::paste! {
        forward! {$(
            [<fmi3Get $n>] => Fmi3Common::[<fmi3_get_ $n:snake>](instance: binding::fmi3Instance,
                value_references: *const binding::fmi3ValueReference, n_value_references: usize,
                values: *mut binding::[<fmi3 $n>], n_values: usize) -> binding::fmi3Status;
            [<fmi3Set $n>] => Fmi3Common::[<fmi3_set_ $n:snake>](instance: binding::fmi3Instance,
                value_references: *const binding::fmi3ValueReference, n_value_references: usize,
                values: *const binding::[<fmi3 $n>], n_values: usize) -> binding::fmi3Status;
        )*}
    }};
}

use binding::{
    fmi3Boolean as Boolean, fmi3Float64 as Float64, fmi3Instance as Instance, fmi3Status as Status,
    fmi3ValueReference as Vr,
};

get_set! { Float32 Int8 Int16 UInt32 Int64 UInt64 Boolean }

/// The setters of the types whose getters are [`batched_get!`]'s.
macro_rules! set_only {
    ($($n:ident)*) => { fmi_export::paste::paste! {
        forward! {$(
            [<fmi3Set $n>] => Fmi3Common::[<fmi3_set_ $n:snake>](instance: binding::fmi3Instance,
                value_references: *const binding::fmi3ValueReference, n_value_references: usize,
                values: *const binding::[<fmi3 $n>], n_values: usize) -> binding::fmi3Status;
        )*}
    }};
}

set_only! { Float64 UInt8 UInt16 Int32 }

/// The most value references the model reads in one pass: a longer call is read in passes
/// of this many.
pub const BATCH: usize = 64;

thread_local! {
    /// The value references of the [`batched_get!`] call this thread is in (up to [`BATCH`],
    /// and how many), empty outside one.
    static CALL: RefCell<([Vr; BATCH], usize)> = const { RefCell::new(([0; BATCH], 0)) };
}

/// `f` of the value references of the get call this thread is in when `first` is the first
/// of them, else of `first` alone (a get that reached the model otherwise). Nothing here can
/// panic across the C boundary: a list already borrowed counts as none.
pub fn with_call<R>(first: Vr, f: impl FnOnce(&[Vr]) -> R) -> R {
    CALL.with(|call| {
        let call = call.try_borrow().ok();
        match call.as_ref().and_then(|c| c.0.get(..c.1)) {
            Some(vrs) if vrs.first() == Some(&first) => f(vrs),
            _ => f(std::slice::from_ref(&first)),
        }
    })
}

/// The call's value references into [`CALL`] (`vrs` at most [`BATCH`]), or none.
fn set_call(vrs: &[Vr]) {
    CALL.with(|call| {
        if let Ok(mut call) = call.try_borrow_mut() {
            let (list, n) = &mut *call;
            *n = match list.get_mut(..vrs.len()) {
                Some(slots) => {
                    slots.copy_from_slice(vrs);
                    vrs.len()
                }
                None => 0,
            };
        }
    });
}

/// `fmi3Get<Type>` passed to `fmi-export` once per [`BATCH`] value references (the first
/// of them, with room for all their values), the value references in [`CALL`] for the model
/// to read. A call that names `time` (value reference 0, which `fmi-export` answers itself)
/// goes through `fmi-export` value by value.
macro_rules! batched_get {
    ($($n:ident)*) => { fmi_export::paste::paste! {$(
        #[unsafe(export_name = stringify!([<fmi3Get $n>]))]
        pub unsafe extern "C" fn [<fmi3_get_ $n:snake>](
            instance: Instance,
            value_references: *const Vr,
            n_value_references: usize,
            values: *mut binding::[<fmi3 $n>],
            n_values: usize,
        ) -> Status {
            if n_values < n_value_references
                || (n_value_references > 0 && (value_references.is_null() || values.is_null()))
            {
                return binding::fmi3Status_fmi3Error;
            }
            let vrs = if n_value_references == 0 {
                &[]
            } else {
                // SAFETY: the importer's array of `n_value_references` (checked non-null).
                unsafe { std::slice::from_raw_parts(value_references, n_value_references) }
            };
            if vrs.is_empty() || vrs.contains(&0) {
                // SAFETY: the importer's arguments, passed on.
                return unsafe {
                    <CellModel as Fmi3Common>::[<fmi3_get_ $n:snake>](
                        instance, value_references, n_value_references, values, n_values)
                };
            }
            for (k, part) in vrs.chunks(BATCH).enumerate() {
                set_call(part);
                // SAFETY: `part`'s values start at `k * BATCH`, below `n_value_references`
                // (at most `n_values`), and `part.len()` of them fit in the importer's array.
                let status = unsafe {
                    <CellModel as Fmi3Common>::[<fmi3_get_ $n:snake>](
                        instance, part.as_ptr(), 1, values.add(k * BATCH), part.len())
                };
                set_call(&[]);
                if status != binding::fmi3Status_fmi3OK {
                    return status;
                }
            }
            binding::fmi3Status_fmi3OK
        }
        const _: binding::[<fmi3Get $n TYPE>] = Some([<fmi3_get_ $n:snake>]);
    )*}};
}

batched_get! { Float64 UInt8 UInt16 Int32 }

forward! {
    fmi3GetVersion => Fmi3Common::fmi3_get_version() -> *const std::os::raw::c_char;
    fmi3SetDebugLogging => Fmi3Common::fmi3_set_debug_logging(instance: Instance,
        logging_on: Boolean, n_categories: usize, categories: *const binding::fmi3String) -> Status;
    fmi3InstantiateModelExchange => Fmi3Common::fmi3_instantiate_model_exchange(
        instance_name: binding::fmi3String, instantiation_token: binding::fmi3String,
        resource_path: binding::fmi3String, visible: Boolean, logging_on: Boolean,
        instance_environment: binding::fmi3InstanceEnvironment,
        log_message: binding::fmi3LogMessageCallback) -> Instance;
    fmi3InstantiateCoSimulation => Fmi3Common::fmi3_instantiate_co_simulation(
        instance_name: binding::fmi3String, instantiation_token: binding::fmi3String,
        resource_path: binding::fmi3String, visible: Boolean, logging_on: Boolean,
        event_mode_used: Boolean, early_return_allowed: Boolean,
        required_intermediate_variables: *const Vr, n_required_intermediate_variables: usize,
        instance_environment: binding::fmi3InstanceEnvironment,
        log_message: binding::fmi3LogMessageCallback,
        intermediate_update: binding::fmi3IntermediateUpdateCallback) -> Instance;
    fmi3InstantiateScheduledExecution => Fmi3Common::fmi3_instantiate_scheduled_execution(
        instance_name: binding::fmi3String, instantiation_token: binding::fmi3String,
        resource_path: binding::fmi3String, visible: Boolean, logging_on: Boolean,
        instance_environment: binding::fmi3InstanceEnvironment,
        log_message: binding::fmi3LogMessageCallback,
        clock_update: binding::fmi3ClockUpdateCallback,
        lock_preemption: binding::fmi3LockPreemptionCallback,
        unlock_preemption: binding::fmi3UnlockPreemptionCallback) -> Instance;
    fmi3EnterInitializationMode => Fmi3Common::fmi3_enter_initialization_mode(instance: Instance,
        tolerance_defined: Boolean, tolerance: Float64, start_time: Float64,
        stop_time_defined: Boolean, stop_time: Float64) -> Status;
    fmi3ExitInitializationMode => Fmi3Common::fmi3_exit_initialization_mode(instance: Instance) -> Status;
    fmi3EnterEventMode => Fmi3Common::fmi3_enter_event_mode(instance: Instance) -> Status;
    fmi3Terminate => Fmi3Common::fmi3_terminate(instance: Instance) -> Status;
    fmi3Reset => Fmi3Common::fmi3_reset(instance: Instance) -> Status;
    fmi3SetString => Fmi3Common::fmi3_set_string(instance: Instance, value_references: *const Vr,
        n_value_references: usize, values: *const binding::fmi3String, n_values: usize) -> Status;
    fmi3SetBinary => Fmi3Common::fmi3_set_binary(instance: Instance, value_references: *const Vr,
        n_value_references: usize, value_sizes: *const usize, values: *const binding::fmi3Binary,
        n_values: usize) -> Status;
    fmi3GetClock => Fmi3Common::fmi3_get_clock(instance: Instance, value_references: *const Vr,
        n_value_references: usize, values: *mut binding::fmi3Clock) -> Status;
    fmi3SetClock => Fmi3Common::fmi3_set_clock(instance: Instance, value_references: *const Vr,
        n_value_references: usize, values: *const binding::fmi3Clock) -> Status;
    fmi3GetNumberOfVariableDependencies => Fmi3Common::fmi3_get_number_of_variable_dependencies(
        instance: Instance, value_reference: Vr, n_dependencies: *mut usize) -> Status;
    fmi3GetVariableDependencies => Fmi3Common::fmi3_get_variable_dependencies(instance: Instance,
        dependent: Vr, element_indices_of_dependent: *mut usize, independents: *mut Vr,
        element_indices_of_independents: *mut usize,
        dependency_kinds: *mut binding::fmi3DependencyKind, n_dependencies: usize) -> Status;
    fmi3GetFMUState => Fmi3Common::fmi3_get_fmu_state(instance: Instance,
        fmu_state: *mut binding::fmi3FMUState) -> Status;
    fmi3SetFMUState => Fmi3Common::fmi3_set_fmu_state(instance: Instance,
        fmu_state: binding::fmi3FMUState) -> Status;
    fmi3FreeFMUState => Fmi3Common::fmi3_free_fmu_state(instance: Instance,
        fmu_state: *mut binding::fmi3FMUState) -> Status;
    fmi3SerializedFMUStateSize => Fmi3Common::fmi3_serialized_fmu_state_size(instance: Instance,
        fmu_state: binding::fmi3FMUState, size: *mut usize) -> Status;
    fmi3SerializeFMUState => Fmi3Common::fmi3_serialize_fmu_state(instance: Instance,
        fmu_state: binding::fmi3FMUState, serialized_state: *mut binding::fmi3Byte,
        size: usize) -> Status;
    fmi3DeserializeFMUState => Fmi3Common::fmi3_deserialize_fmu_state(instance: Instance,
        serialized_state: *const binding::fmi3Byte, size: usize,
        fmu_state: *mut binding::fmi3FMUState) -> Status;
    fmi3GetDirectionalDerivative => Fmi3Common::fmi3_get_directional_derivative(instance: Instance,
        unknowns: *const Vr, n_unknowns: usize, knowns: *const Vr, n_knowns: usize,
        seed: *const Float64, n_seed: usize, sensitivity: *mut Float64,
        n_sensitivity: usize) -> Status;
    fmi3GetAdjointDerivative => Fmi3Common::fmi3_get_adjoint_derivative(instance: Instance,
        unknowns: *const Vr, n_unknowns: usize, knowns: *const Vr, n_knowns: usize,
        seed: *const Float64, n_seed: usize, sensitivity: *mut Float64,
        n_sensitivity: usize) -> Status;
    fmi3EnterConfigurationMode => Fmi3Common::fmi3_enter_configuration_mode(instance: Instance) -> Status;
    fmi3ExitConfigurationMode => Fmi3Common::fmi3_exit_configuration_mode(instance: Instance) -> Status;
    fmi3EvaluateDiscreteStates => Fmi3Common::fmi3_evaluate_discrete_states(instance: Instance) -> Status;
    fmi3UpdateDiscreteStates => Fmi3Common::fmi3_update_discrete_states(instance: Instance,
        discrete_states_need_update: *mut Boolean, terminate_simulation: *mut Boolean,
        nominals_of_continuous_states_changed: *mut Boolean,
        values_of_continuous_states_changed: *mut Boolean, next_event_time_defined: *mut Boolean,
        next_event_time: *mut Float64) -> Status;
    fmi3EnterContinuousTimeMode => Fmi3ModelExchange::fmi3_enter_continuous_time_mode(instance: Instance) -> Status;
    fmi3CompletedIntegratorStep => Fmi3ModelExchange::fmi3_completed_integrator_step(
        instance: Instance, no_set_fmu_state_prior: Boolean, enter_event_mode: *mut Boolean,
        terminate_simulation: *mut Boolean) -> Status;
    fmi3SetTime => Fmi3ModelExchange::fmi3_set_time(instance: Instance, time: Float64) -> Status;
    fmi3SetContinuousStates => Fmi3ModelExchange::fmi3_set_continuous_states(instance: Instance,
        continuous_states: *const Float64, n_continuous_states: usize) -> Status;
    fmi3GetContinuousStateDerivatives => Fmi3ModelExchange::fmi3_get_continuous_state_derivatives(
        instance: Instance, derivatives: *mut Float64, n_continuous_states: usize) -> Status;
    fmi3GetEventIndicators => Fmi3ModelExchange::fmi3_get_event_indicators(instance: Instance,
        event_indicators: *mut Float64, n_event_indicators: usize) -> Status;
    fmi3GetContinuousStates => Fmi3ModelExchange::fmi3_get_continuous_states(instance: Instance,
        continuous_states: *mut Float64, n_continuous_states: usize) -> Status;
    fmi3GetNominalsOfContinuousStates => Fmi3ModelExchange::fmi3_get_nominals_of_continuous_states(
        instance: Instance, nominals: *mut Float64, n_continuous_states: usize) -> Status;
    fmi3GetNumberOfEventIndicators => Fmi3ModelExchange::fmi3_get_number_of_event_indicators(
        instance: Instance, n_event_indicators: *mut usize) -> Status;
    fmi3GetNumberOfContinuousStates => Fmi3ModelExchange::fmi3_get_number_of_continuous_states(
        instance: Instance, n_continuous_states: *mut usize) -> Status;
    fmi3EnterStepMode => Fmi3CoSimulation::fmi3_enter_step_mode(instance: Instance) -> Status;
    fmi3GetOutputDerivatives => Fmi3CoSimulation::fmi3_get_output_derivatives(instance: Instance,
        value_references: *const Vr, n_value_references: usize, orders: *const binding::fmi3Int32,
        values: *mut Float64, n_values: usize) -> Status;
    fmi3DoStep => Fmi3CoSimulation::fmi3_do_step(instance: Instance,
        current_communication_point: Float64, communication_step_size: Float64,
        no_set_fmu_state_prior_to_current_point: Boolean, event_handling_needed: *mut Boolean,
        terminate_simulation: *mut Boolean, early_return: *mut Boolean,
        last_successful_time: *mut Float64) -> Status;
    fmi3ActivateModelPartition => Fmi3ScheduledExecution::fmi3_activate_model_partition(
        instance: Instance, clock_reference: Vr, activation_time: Float64) -> Status;
}

#[unsafe(export_name = "fmi3FreeInstance")]
pub unsafe extern "C" fn fmi3_free_instance(instance: Instance) {
    // SAFETY: the importer's instance, passed on.
    unsafe { <CellModel as Fmi3Common>::fmi3_free_instance(instance) }
}
const _: binding::fmi3FreeInstanceTYPE = Some(fmi3_free_instance);

/// The clock interval and shift functions: for clocks whose intervals the FMU or the importer
/// sets (periodic, countdown). The cell FMU's clocks are triggered, which have none (FMI 3.0
/// §2.2.8.3), so every call is an error (`fmi-export` leaves them unimplemented).
macro_rules! no_interval {
    ($($c:ident $f:ident ( $($a:ident : $t:ty),* );)*) => {$(
        #[unsafe(export_name = stringify!($c))]
        pub extern "C" fn $f($(_: $t),*) -> Status {
            binding::fmi3Status_fmi3Error
        }
        fmi_export::paste::paste! {
            const _: binding::[<$c TYPE>] = Some($f);
        }
    )*};
}

no_interval! {
    fmi3GetIntervalDecimal fmi3_get_interval_decimal(i: Instance, v: *const Vr, n: usize,
        intervals: *mut Float64, qualifiers: *mut binding::fmi3IntervalQualifier);
    fmi3GetIntervalFraction fmi3_get_interval_fraction(i: Instance, v: *const Vr, n: usize,
        counters: *mut binding::fmi3UInt64, resolutions: *mut binding::fmi3UInt64,
        qualifiers: *mut binding::fmi3IntervalQualifier);
    fmi3GetShiftDecimal fmi3_get_shift_decimal(i: Instance, v: *const Vr, n: usize,
        shifts: *mut Float64);
    fmi3GetShiftFraction fmi3_get_shift_fraction(i: Instance, v: *const Vr, n: usize,
        counters: *mut binding::fmi3UInt64, resolutions: *mut binding::fmi3UInt64);
    fmi3SetIntervalDecimal fmi3_set_interval_decimal(i: Instance, v: *const Vr, n: usize,
        intervals: *const Float64);
    fmi3SetIntervalFraction fmi3_set_interval_fraction(i: Instance, v: *const Vr, n: usize,
        counters: *const binding::fmi3UInt64, resolutions: *const binding::fmi3UInt64);
    fmi3SetShiftDecimal fmi3_set_shift_decimal(i: Instance, v: *const Vr, n: usize,
        shifts: *const Float64);
    fmi3SetShiftFraction fmi3_set_shift_fraction(i: Instance, v: *const Vr, n: usize,
        counters: *const binding::fmi3UInt64, resolutions: *const binding::fmi3UInt64);
}

thread_local! {
    /// Whether this thread is inside [`fmi3_get_string`], where [`crate::CellModel`]'s
    /// `get_uint64` answers a display's address.
    static STRING_GET: Cell<bool> = const { Cell::new(false) };
}

/// Whether this thread is inside [`fmi3_get_string`].
pub fn in_string_get() -> bool {
    STRING_GET.with(Cell::get)
}

/// `fmi3GetString` (FMI 3.0 §2.2.6.2): the FMU owns the strings it hands out. `fmi-export`'s
/// copies each into a `CString` it drops before it returns; this one hands out the instance's
/// own bytes (`CellInstance::display`), which stay where they are until a step changes the
/// display: no allocation per get. Each value reference passes `fmi-export`'s state checks
/// of a get through `fmi3GetUInt64`, which gives the text's address while [`STRING_GET`] is
/// set.
#[unsafe(export_name = "fmi3GetString")]
pub unsafe extern "C" fn fmi3_get_string(
    instance: Instance,
    value_references: *const Vr,
    n_value_references: usize,
    values: *mut binding::fmi3String,
    n_values: usize,
) -> Status {
    if n_value_references != n_values
        || (n_values > 0 && (value_references.is_null() || values.is_null()))
    {
        return binding::fmi3Status_fmi3Error;
    }
    for i in 0..n_values {
        // SAFETY: `i < n_values`, the length of the importer's arrays (checked non-null).
        let vr = unsafe { *value_references.add(i) };
        let mut address: binding::fmi3UInt64 = 0;
        STRING_GET.with(|s| s.set(true));
        // SAFETY: one value reference, one local value.
        let status = unsafe {
            <CellModel as Fmi3Common>::fmi3_get_u_int64(instance, &vr, 1, &mut address, 1)
        };
        STRING_GET.with(|s| s.set(false));
        if status != binding::fmi3Status_fmi3OK {
            return status;
        }
        let Ok(address) = usize::try_from(address) else {
            return binding::fmi3Status_fmi3Error;
        };
        // SAFETY: as above; the address is of a NUL-terminated text the instance holds until
        // its next step.
        unsafe {
            *values.add(i) = std::ptr::with_exposed_provenance::<std::ffi::c_char>(address);
        }
    }
    binding::fmi3Status_fmi3OK
}
const _: binding::fmi3GetStringTYPE = Some(fmi3_get_string);

/// `fmi3GetBinary` (FMI 3.0 §2.2.6.2): for each value reference the FMU sets `values[i]` to
/// its own bytes and `value_sizes[i]` to their length.
#[unsafe(export_name = "fmi3GetBinary")]
pub unsafe extern "C" fn fmi3_get_binary(
    instance: Instance,
    value_references: *const Vr,
    n_value_references: usize,
    value_sizes: *mut usize,
    values: *mut binding::fmi3Binary,
    n_values: usize,
) -> Status {
    if n_value_references != n_values
        || (n_values > 0
            && (value_references.is_null() || value_sizes.is_null() || values.is_null()))
    {
        return binding::fmi3Status_fmi3Error;
    }
    for i in 0..n_values {
        let mut place = [0u8; BINARY_PLACE];
        let mut size = BINARY_PLACE;
        let mut at = place.as_mut_ptr();
        // SAFETY: `i < n_values`, the length of the importer's arrays (checked non-null).
        let vr = unsafe { *value_references.add(i) };
        // SAFETY: one value reference, one buffer of `size` bytes, all local.
        let status = unsafe {
            <CellModel as Fmi3Common>::fmi3_get_binary(instance, &vr, 1, &mut size, &mut at, 1)
        };
        if status != binding::fmi3Status_fmi3OK {
            return status;
        }
        let Some((address, length)) = crate::binary_place::read(&place) else {
            return binding::fmi3Status_fmi3Error;
        };
        // SAFETY: as above; the address is of bytes the instance holds until its next
        // stepping or updating call.
        unsafe {
            *values.add(i) = std::ptr::with_exposed_provenance::<binding::fmi3Byte>(address);
            *value_sizes.add(i) = length;
        }
    }
    binding::fmi3Status_fmi3OK
}
const _: binding::fmi3GetBinaryTYPE = Some(fmi3_get_binary);
