//! The CMMP-AS's controller parameter sets: the sub-indices of CiA 402's 60F6h current,
//! 60F9h velocity and 60FBh position control parameter set, whose meaning CiA 402 leaves to
//! the manufacturer, as CMMP-AS §5.5–5.7 gives them (gains 256 = 1, times in µs; the
//! engine's normalisation of a gain of 1 is [`crate::control`]'s).

use od::ObjectDictionary;

use crate::control::ControlParams;

/// `params` with the gains, times and limits of 60F6h, 60F9h and 60FBh (each sub-index that
/// the dictionary lacks keeps its value in `params`).
pub fn parameter_sets<S: AsRef<[u8]> + AsMut<[u8]>>(
    od: &ObjectDictionary<S>,
    params: ControlParams,
) -> ControlParams {
    let p = params;
    let u = |index: u16, sub: u8, default: u64| od.get_unsigned(index, sub).unwrap_or(default);
    ControlParams {
        // §5.5: 60F6h:01 torque_control_gain (256 = 1), :02 torque_control_time (µs).
        torque_control_gain: u(0x60F6, 1, p.torque_control_gain.into()) as u16,
        torque_control_time_us: u(0x60F6, 2, p.torque_control_time_us.into()) as u16,
        // §5.6: 60F9h:01 velocity_control_gain, :02 velocity_control_time (µs), :04
        // velocity_control_filter_time (µs, the actual speed's filter).
        velocity_control_gain: u(0x60F9, 1, p.velocity_control_gain.into()) as u16,
        velocity_control_time_us: u(0x60F9, 2, p.velocity_control_time_us.into()) as u16,
        velocity_control_filter_time_us: u(0x60F9, 4, p.velocity_control_filter_time_us.into())
            as u16,
        // §5.7: 60FBh:01 position_control_gain, :02 position_control_time (µs, 0 = no
        // integrator), :04 position_control_v_max (min⁻¹), :05
        // position_error_tolerance_window (increments).
        position_control_gain: u(0x60FB, 1, p.position_control_gain.into()) as u16,
        position_control_time_us: u(0x60FB, 2, p.position_control_time_us.into()) as u16,
        position_control_v_max_rpm: u(0x60FB, 4, p.position_control_v_max_rpm.into()) as u32,
        position_error_tolerance_window: u(0x60FB, 5, p.position_error_tolerance_window.into())
            as u32,
        ..p
    }
}
