//! The Nanotec SMCI47-S and PD4-N (`drive::vendors::nanotec`): their section of the cell file
//! (rotary switches, motor type).

pub mod cell_section;
