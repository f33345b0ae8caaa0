//! What one vendor's drives have that no standard describes: their serial protocols, their
//! switches and their codes, each in the folder of the device it belongs to.

pub mod festo_cmmp_as;
pub mod kinco;
pub mod nanotec;
