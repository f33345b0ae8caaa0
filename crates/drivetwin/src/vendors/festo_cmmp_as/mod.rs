//! The Festo CMMP-AS (`drive::vendors::festo_cmmp_as`): its CI terminal on a TCP port.

pub mod ci_terminal;
