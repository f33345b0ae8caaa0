//! A drive's terminal: a line-based console of the drive (the CMMP-AS's CI terminal), its
//! protocol a vendor's. The runtime declares it; the vendor folder implements it and hands it
//! in through [`super::Vendors::ci_terminal`]; the cell loop serves it on a TCP port.

use od::ObjectAccess;

/// A drive's terminal: the protocol of the lines typed at it. It reaches the drive as a
/// local interface does (the cell's local access): reads as they are, writes as
/// SDO downloads of the drive's node.
pub trait Terminal: Send {
    /// Takes one byte typed; what it completed, if anything.
    fn push(&mut self, byte: u8) -> Option<Typed>;
    /// Appends the answer to `line`, on the drive's objects `od`, with its line end.
    fn answer(&mut self, line: &[u8], od: &mut dyn ObjectAccess, answer: &mut Vec<u8>);
    /// Appends the answer to a line that reaches no drive or is too long, with its line end.
    fn refuse(&mut self, answer: &mut Vec<u8>);
}

/// What a byte typed at a [`Terminal`] completed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Typed {
    /// A line, without its end.
    Line(Vec<u8>),
    /// A line longer than any the terminal takes; its bytes are gone.
    TooLong,
}

/// A new terminal, one for each connection.
pub type NewTerminal = fn() -> Box<dyn Terminal>;
