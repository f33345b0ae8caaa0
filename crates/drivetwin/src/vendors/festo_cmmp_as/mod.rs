//! The Festo CMMP-AS (`drive::vendors::festo_cmmp_as`): its CI terminal on a TCP port, the
//! rules of its fieldbus switches and inputs (node-ID, bit rate, CAN on, profile) and its
//! section of the cell file (switches, CI terminal).

pub mod cell_section;
pub mod ci_terminal;
pub mod fieldbus_switches;
