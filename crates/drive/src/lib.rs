//! CiA 402 drive logic, sans-IO and `no_std`: the device control state machine, the operating
//! modes, the factor group, cascaded control loops and a simulated motor and load. The drive
//! is stepped on an explicit clock and never knows which protocol wrote its objects.
#![no_std]
#![forbid(unsafe_code)]

pub mod axis;
mod bit_word;
pub mod bldc;
pub mod control;
pub mod controlword;
pub mod current_filters;
pub mod device_control;
pub mod digital_inputs;
pub mod drive;
pub mod encoder_fault;
pub mod factor_group;
pub mod homing;
pub mod interpolated_position;
pub mod measured_velocity;
pub mod motor;
mod object_keys;
pub mod personality;
pub mod profile_position;
pub(crate) mod published;
pub mod rounding;
pub mod smoothing;
pub mod statusword;
pub mod stepper;
pub mod thermal;
pub mod trajectory;
pub mod travel;
pub mod vendors;
