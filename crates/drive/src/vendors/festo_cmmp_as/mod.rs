//! The Festo CMMP-AS servo drive.

pub mod ci_terminal;
