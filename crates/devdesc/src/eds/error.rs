//! What is wrong with an EDS or DCF, and where: file, line, section and key, so a user can
//! open the file at the line and fix it.

use std::fmt;

/// A place in an EDS / DCF file. `line` is 1-based; `key` is empty where the whole section
/// is meant (a missing section names the key that asked for it instead).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Location {
    pub file: String,
    pub line: usize,
    pub section: String,
    pub key: String,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: [{}]", self.file, self.line, self.section)?;
        if !self.key.is_empty() {
            write!(f, " {}", self.key)?;
        }
        Ok(())
    }
}

/// Why an EDS / DCF is refused.
#[derive(Debug, thiserror::Error)]
pub enum EdsError {
    #[error("{file}: {source}")]
    Io {
        file: String,
        source: std::io::Error,
    },
    /// A line that is neither a section header, a `key=value` line, a comment nor empty.
    #[error("{file}:{line}: {what}")]
    Syntax {
        file: String,
        line: usize,
        what: String,
    },
    /// A section or key given twice (CiA 306 §4: each once).
    #[error("{at}: given twice (first at line {first_line})")]
    Duplicate { at: Location, first_line: usize },
    /// A key or section CiA 306 requires is not there.
    #[error("{at}: missing: {what}")]
    Missing { at: Location, what: String },
    /// A value CiA 306 does not allow, or one that contradicts the rest of the file.
    #[error("{at}: {what}")]
    Invalid { at: Location, what: String },
    /// Valid CiA 306 that the twin does not implement.
    #[error("{at}: not supported: {what}")]
    Unsupported { at: Location, what: String },
}

impl EdsError {
    /// Where the error is, if it is in the file's text.
    pub fn location(&self) -> Option<&Location> {
        match self {
            EdsError::Duplicate { at, .. }
            | EdsError::Missing { at, .. }
            | EdsError::Invalid { at, .. }
            | EdsError::Unsupported { at, .. } => Some(at),
            EdsError::Io { .. } | EdsError::Syntax { .. } => None,
        }
    }
}
