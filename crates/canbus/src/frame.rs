//! A classic CAN frame as the stack sees it: identifier, flags, up to 8 data bytes.

/// A classic CAN 2.0 frame. `Copy` and fixed-size, so the hot path never allocates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    /// 11-bit (standard) or 29-bit (extended) identifier.
    pub id: u32,
    pub extended: bool,
    /// Remote transmission request: no data, `len` is the requested DLC.
    pub rtr: bool,
    pub len: u8,
    pub data: [u8; 8],
}

/// Why bytes could not become a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameError {
    /// More than 8 data bytes.
    TooLong,
    /// Identifier beyond 11 bits (standard) or 29 bits (extended).
    BadId,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            FrameError::TooLong => "more than 8 data bytes",
            FrameError::BadId => "identifier out of range",
        })
    }
}

impl CanFrame {
    pub const MAX_STANDARD_ID: u32 = 0x7FF;
    pub const MAX_EXTENDED_ID: u32 = 0x1FFF_FFFF;

    /// A standard (11-bit) data frame.
    pub fn new(id: u16, data: &[u8]) -> Result<Self, FrameError> {
        Self::with_id(u32::from(id), false, data)
    }

    pub fn with_id(id: u32, extended: bool, data: &[u8]) -> Result<Self, FrameError> {
        let max = if extended {
            Self::MAX_EXTENDED_ID
        } else {
            Self::MAX_STANDARD_ID
        };
        if id > max {
            return Err(FrameError::BadId);
        }
        let mut buf = [0u8; 8];
        buf.get_mut(..data.len())
            .ok_or(FrameError::TooLong)?
            .copy_from_slice(data);
        Ok(CanFrame {
            id,
            extended,
            rtr: false,
            len: data.len() as u8,
            data: buf,
        })
    }

    /// A standard frame of 8 bytes; the stack always answers with DLC 8.
    pub const fn full(id: u16, data: [u8; 8]) -> Self {
        CanFrame {
            id: id as u32,
            extended: false,
            rtr: false,
            len: 8,
            data,
        }
    }

    /// A remote frame requesting `len` bytes.
    pub fn remote(id: u16, len: u8) -> Self {
        CanFrame {
            id: u32::from(id) & Self::MAX_STANDARD_ID,
            extended: false,
            rtr: true,
            len: len.min(8),
            data: [0; 8],
        }
    }

    /// The data bytes actually carried (none for a remote frame).
    pub fn payload(&self) -> &[u8] {
        if self.rtr {
            &[]
        } else {
            self.data.get(..usize::from(self.len).min(8)).unwrap_or(&[])
        }
    }

    /// The 11-bit COB-ID, or `None` for an extended frame.
    pub fn cob_id(&self) -> Option<u16> {
        (!self.extended).then_some(self.id as u16)
    }
}
