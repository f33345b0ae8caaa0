//! CiA 301 §7.1 static data types, with their object-dictionary indices.

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u16)]
pub enum DataType {
    Boolean = 0x0001,
    Integer8 = 0x0002,
    Integer16 = 0x0003,
    Integer32 = 0x0004,
    Unsigned8 = 0x0005,
    Unsigned16 = 0x0006,
    Unsigned32 = 0x0007,
    Real32 = 0x0008,
    VisibleString = 0x0009,
    OctetString = 0x000A,
    Domain = 0x000F,
    Real64 = 0x0011,
    Integer64 = 0x0015,
    Unsigned64 = 0x001B,
}

impl DataType {
    /// Size in bytes of a fixed-size type; `None` for strings and domains.
    pub const fn fixed_size(self) -> Option<usize> {
        match self {
            DataType::Boolean | DataType::Integer8 | DataType::Unsigned8 => Some(1),
            DataType::Integer16 | DataType::Unsigned16 => Some(2),
            DataType::Integer32 | DataType::Unsigned32 | DataType::Real32 => Some(4),
            DataType::Integer64 | DataType::Unsigned64 | DataType::Real64 => Some(8),
            DataType::VisibleString | DataType::OctetString | DataType::Domain => None,
        }
    }
    pub const fn is_signed(self) -> bool {
        matches!(
            self,
            DataType::Integer8 | DataType::Integer16 | DataType::Integer32 | DataType::Integer64
        )
    }
    pub const fn is_real(self) -> bool {
        matches!(self, DataType::Real32 | DataType::Real64)
    }
    pub const fn is_numeric(self) -> bool {
        self.fixed_size().is_some()
    }
    /// The CiA 301 name, also used in device description files.
    pub const fn name(self) -> &'static str {
        match self {
            DataType::Boolean => "BOOLEAN",
            DataType::Integer8 => "INTEGER8",
            DataType::Integer16 => "INTEGER16",
            DataType::Integer32 => "INTEGER32",
            DataType::Unsigned8 => "UNSIGNED8",
            DataType::Unsigned16 => "UNSIGNED16",
            DataType::Unsigned32 => "UNSIGNED32",
            DataType::Real32 => "REAL32",
            DataType::VisibleString => "VISIBLE_STRING",
            DataType::OctetString => "OCTET_STRING",
            DataType::Domain => "DOMAIN",
            DataType::Real64 => "REAL64",
            DataType::Integer64 => "INTEGER64",
            DataType::Unsigned64 => "UNSIGNED64",
        }
    }
    pub const ALL: [DataType; 14] = [
        DataType::Boolean,
        DataType::Integer8,
        DataType::Integer16,
        DataType::Integer32,
        DataType::Unsigned8,
        DataType::Unsigned16,
        DataType::Unsigned32,
        DataType::Real32,
        DataType::VisibleString,
        DataType::OctetString,
        DataType::Domain,
        DataType::Real64,
        DataType::Integer64,
        DataType::Unsigned64,
    ];
    pub fn from_name(s: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|t| t.name() == s)
    }
    pub const fn code(self) -> u16 {
        self as u16
    }
}
