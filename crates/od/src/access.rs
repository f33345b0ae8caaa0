//! Access rights of an entry as CiA 301 and CiA 306 (EDS `AccessType`) name them.

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    ReadOnly,
    WriteOnly,
    ReadWrite,
    /// Read-only and never changes.
    Const,
}

impl Access {
    pub const fn readable(self) -> bool {
        !matches!(self, Access::WriteOnly)
    }
    pub const fn writable(self) -> bool {
        matches!(self, Access::WriteOnly | Access::ReadWrite)
    }
    /// The EDS spelling (CiA 306 §4.6.3).
    pub const fn eds_name(self) -> &'static str {
        match self {
            Access::ReadOnly => "ro",
            Access::WriteOnly => "wo",
            Access::ReadWrite => "rw",
            Access::Const => "const",
        }
    }
    pub fn from_name(s: &str) -> Option<Self> {
        Some(match s {
            "ro" => Access::ReadOnly,
            "wo" => Access::WriteOnly,
            "rw" | "rwr" | "rww" => Access::ReadWrite,
            "const" => Access::Const,
            _ => return None,
        })
    }
}
