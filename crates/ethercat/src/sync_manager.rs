//! Sync manager register blocks (spec §2.6, §5.2, §7.3).
//!
//! Mailbox mode (one buffer): the writer fills the whole window; the write that covers the
//! last byte makes it "full" (status bit 3); the reader's access that covers the last byte
//! makes it empty again. A write while full and a read while empty are refused.
//! Buffered mode (three buffers): never blocks; the reader always sees the newest complete
//! buffer. How the ESC emulates both is in [`crate::esc`].

/// Bytes per SM register block.
pub const SM_LEN: usize = 8;

/// Status bit 0: buffer completely written (interrupt write).
pub const STATUS_IRQ_WRITE: u8 = 0x01;
/// Status bit 1: buffer completely read (interrupt read).
pub const STATUS_IRQ_READ: u8 = 0x02;
/// Status bit 3: mailbox full.
pub const STATUS_MAILBOX_FULL: u8 = 0x08;
/// Status bits 4–5: buffered mode, last written buffer (3 = none yet).
pub const STATUS_BUFFER_MASK: u8 = 0x30;
/// Activate bit 0: SM enabled.
pub const ACTIVATE_ENABLE: u8 = 0x01;
/// Activate bit 1: repeat request (mailbox read SM, toggled by the master, §5.4).
pub const ACTIVATE_REPEAT: u8 = 0x02;
/// PDI control bit 0: SM deactivated by the PDI.
pub const PDI_DEACTIVATE: u8 = 0x01;
/// PDI control bit 1: repeat acknowledge.
pub const PDI_REPEAT_ACK: u8 = 0x02;
/// Control bit 6: ECAT writes retrigger the process-data watchdog.
pub const CONTROL_WATCHDOG: u8 = 0x40;

/// Operation mode (control bits 0–1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SmMode {
    /// 00: three-buffer mode.
    Buffered,
    /// 10: one-buffer mailbox mode.
    Mailbox,
    /// 01 or 11: reserved.
    Reserved(u8),
}

/// Direction (control bits 2–3), seen from the master.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SmDirection {
    /// 00: the master reads, the PDI writes (SM1 mailbox in, SM3 inputs).
    Read,
    /// 01: the master writes, the PDI reads (SM0 mailbox out, SM2 outputs).
    Write,
    /// 10 or 11: reserved.
    Reserved(u8),
}

/// One SM register block as stored at 0x0800 + 8·n.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SyncManager {
    pub start: u16,
    pub length: u16,
    pub control: u8,
    pub status: u8,
    pub activate: u8,
    pub pdi_control: u8,
}

impl SyncManager {
    pub fn from_bytes(b: &[u8; SM_LEN]) -> Self {
        SyncManager {
            start: u16::from_le_bytes([b[0], b[1]]),
            length: u16::from_le_bytes([b[2], b[3]]),
            control: b[4],
            status: b[5],
            activate: b[6],
            pdi_control: b[7],
        }
    }

    pub fn to_bytes(&self) -> [u8; SM_LEN] {
        let s = self.start.to_le_bytes();
        let l = self.length.to_le_bytes();
        [
            s[0],
            s[1],
            l[0],
            l[1],
            self.control,
            self.status,
            self.activate,
            self.pdi_control,
        ]
    }

    /// A configuration as a master writes it (status and PDI control 0).
    pub fn new(start: u16, length: u16, control: u8, enable: bool) -> Self {
        SyncManager {
            start,
            length,
            control,
            status: 0,
            activate: u8::from(enable),
            pdi_control: 0,
        }
    }

    pub fn mode(&self) -> SmMode {
        match self.control & 0x03 {
            0 => SmMode::Buffered,
            2 => SmMode::Mailbox,
            other => SmMode::Reserved(other),
        }
    }

    pub fn direction(&self) -> SmDirection {
        match (self.control >> 2) & 0x03 {
            0 => SmDirection::Read,
            1 => SmDirection::Write,
            other => SmDirection::Reserved(other),
        }
    }

    /// Enabled by the master (activate bit 0) and not deactivated by the PDI.
    pub fn is_enabled(&self) -> bool {
        self.activate & ACTIVATE_ENABLE != 0 && self.pdi_control & PDI_DEACTIVATE == 0
    }

    /// Enabled with a non-empty window.
    pub fn is_active(&self) -> bool {
        self.is_enabled() && self.length > 0
    }

    pub fn is_mailbox_full(&self) -> bool {
        self.status & STATUS_MAILBOX_FULL != 0
    }

    /// One past the last byte of the window.
    pub fn end(&self) -> u32 {
        u32::from(self.start) + u32::from(self.length)
    }

    /// Address of the last byte of the window (the byte whose access completes a buffer).
    pub fn last_byte(&self) -> u32 {
        self.end().saturating_sub(1)
    }

    /// The window intersects `[addr, addr + len)`.
    pub fn overlaps(&self, addr: u32, len: usize) -> bool {
        let a1 = u64::from(addr) + len as u64;
        len > 0 && u64::from(addr) < u64::from(self.end()) && a1 > u64::from(self.start)
    }

    /// `[addr, addr + len)` contains the last byte of the window.
    pub fn covers_last_byte(&self, addr: u32, len: usize) -> bool {
        let last = u64::from(self.last_byte());
        self.length > 0 && u64::from(addr) <= last && last < u64::from(addr) + len as u64
    }

    /// The configuration that matters for the mailbox / process-data checks (start,
    /// length, control, enable), i.e. everything but status, repeat bits and PDI control.
    pub fn layout_eq(&self, other: &SyncManager) -> bool {
        self.start == other.start
            && self.length == other.length
            && self.control == other.control
            && (self.activate & ACTIVATE_ENABLE) == (other.activate & ACTIVATE_ENABLE)
    }

    /// Space a real ESC reserves for the SM: three buffers in buffered mode, one in mailbox
    /// mode (spec §4.2: "Buffer windows must not overlap (3 × length)").
    pub fn reserved_end(&self) -> u32 {
        match self.mode() {
            SmMode::Buffered => u32::from(self.start) + 3 * u32::from(self.length),
            _ => self.end(),
        }
    }
}
