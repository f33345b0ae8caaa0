//! The Festo CMMO-ST, a stepper controller driven over FHPP (CMMO-ST manual
//! GDCP-CMMO-ST-LK-C-HP): a device of its own beside the CiA 402 engine, with the profile it
//! speaks in [`fhpp`] and the device around it here.
//!
//! Decision: the FHPP profile (Festo's Handling and Positioning Profile, which several Festo
//! controllers speak) lives in this folder as [`fhpp`], not in a shared `vendors/festo_fhpp/`.
//! It follows the CMMO-ST's manual and carries its numbers (the 64 records of the record table,
//! the rw2 PNUs of the parameter channel, the parameter file of its dictionary), and the
//! CMMO-ST is the only FHPP device of the twin; a folder shared by one device would be a name
//! only. [`fhpp`] imports nothing from the device, so when a second FHPP controller comes it
//! moves to `vendors/festo_fhpp/` as it is and the CMMO-ST's numbers become its data.
//!
//! Files, one concept each, named as the manual names them:
//! - [`fhpp`]: the profile, its byte layouts, state machine, record table and parameter channel;
//! - [`device`]: the CMMO-ST itself, FHPP telegrams in, the stepper plant moving, its PNUs;
//! - [`diagnostics`]: the App. D messages and the error-management coding (PNU 234…246);
//! - [`diagnostic_memory`]: the 200-entry ring of PNU 200…204 (§7.1.3);
//! - [`seven_segment`]: what the 7-segment display shows (§7.1.2 Tab. 7.3);
//! - [`homing`]: the homing methods of PNU 1011 (Tab. 6.2) as data;
//! - [`axis_mechanics`]: the end stops, reference switch and index pulse homing finds;
//! - [`plant_supervision`]: the CMMO-ST's own supervision of its plant's physics.

pub mod axis_mechanics;
pub mod device;
pub mod diagnostic_memory;
pub mod diagnostics;
pub mod fhpp;
pub mod homing;
pub mod plant_supervision;
pub mod seven_segment;
