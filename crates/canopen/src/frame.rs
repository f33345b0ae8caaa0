//! The classic CAN frame CANopen is carried in: the bus model's (`canbus`), so a frame the node
//! answers is the frame the bus times.

pub use canbus::frame::{CanFrame, FrameError};
