//! AL status codes, register 0x0134 (ETG.1000.6; spec §4.3).

use core::fmt;

/// The reason in AL status code 0x0134. A newtype so that vendor codes (0x8000–0xFFFF) and
/// codes this table does not name still round-trip.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct AlStatusCode(pub u16);

impl AlStatusCode {
    pub const NO_ERROR: Self = Self(0x0000);
    pub const UNSPECIFIED_ERROR: Self = Self(0x0001);
    pub const NO_MEMORY: Self = Self(0x0002);
    pub const INVALID_DEVICE_SETUP: Self = Self(0x0003);
    pub const INVALID_REQUESTED_STATE_CHANGE: Self = Self(0x0011);
    pub const UNKNOWN_REQUESTED_STATE: Self = Self(0x0012);
    pub const BOOTSTRAP_NOT_SUPPORTED: Self = Self(0x0013);
    pub const NO_VALID_FIRMWARE: Self = Self(0x0014);
    pub const INVALID_MAILBOX_CONFIGURATION_BOOT: Self = Self(0x0015);
    pub const INVALID_MAILBOX_CONFIGURATION: Self = Self(0x0016);
    pub const INVALID_SYNC_MANAGER_CONFIGURATION: Self = Self(0x0017);
    pub const NO_VALID_INPUTS: Self = Self(0x0018);
    pub const NO_VALID_OUTPUTS: Self = Self(0x0019);
    pub const SYNCHRONIZATION_ERROR: Self = Self(0x001A);
    pub const SYNC_MANAGER_WATCHDOG: Self = Self(0x001B);
    pub const INVALID_SYNC_MANAGER_TYPES: Self = Self(0x001C);
    pub const INVALID_OUTPUT_CONFIGURATION: Self = Self(0x001D);
    pub const INVALID_INPUT_CONFIGURATION: Self = Self(0x001E);
    pub const INVALID_WATCHDOG_CONFIGURATION: Self = Self(0x001F);
    pub const NEEDS_COLD_START: Self = Self(0x0020);
    pub const NEEDS_INIT: Self = Self(0x0021);
    pub const NEEDS_PREOP: Self = Self(0x0022);
    pub const NEEDS_SAFEOP: Self = Self(0x0023);
    pub const INVALID_INPUT_MAPPING: Self = Self(0x0024);
    pub const INVALID_OUTPUT_MAPPING: Self = Self(0x0025);
    pub const INCONSISTENT_SETTINGS: Self = Self(0x0026);
    pub const FREE_RUN_NOT_SUPPORTED: Self = Self(0x0027);
    pub const SYNC_MODE_NOT_SUPPORTED: Self = Self(0x0028);
    pub const FREE_RUN_NEEDS_THREE_BUFFER_MODE: Self = Self(0x0029);
    pub const BACKGROUND_WATCHDOG: Self = Self(0x002A);
    pub const NO_VALID_INPUTS_AND_OUTPUTS: Self = Self(0x002B);
    pub const FATAL_SYNC_ERROR: Self = Self(0x002C);
    pub const NO_SYNC_ERROR: Self = Self(0x002D);
    pub const INVALID_INPUT_FMMU_CONFIGURATION: Self = Self(0x002E);
    pub const INVALID_DC_SYNC_CONFIGURATION: Self = Self(0x0030);
    pub const INVALID_DC_LATCH_CONFIGURATION: Self = Self(0x0031);
    pub const PLL_ERROR: Self = Self(0x0032);
    pub const DC_SYNC_IO_ERROR: Self = Self(0x0033);
    pub const DC_SYNC_TIMEOUT: Self = Self(0x0034);
    pub const DC_INVALID_SYNC_CYCLE_TIME: Self = Self(0x0035);
    pub const DC_SYNC0_CYCLE_TIME: Self = Self(0x0036);
    pub const DC_SYNC1_CYCLE_TIME: Self = Self(0x0037);
    pub const MAILBOX_AOE: Self = Self(0x0041);
    pub const MAILBOX_EOE: Self = Self(0x0042);
    pub const MAILBOX_COE: Self = Self(0x0043);
    pub const MAILBOX_FOE: Self = Self(0x0044);
    pub const MAILBOX_SOE: Self = Self(0x0045);
    pub const MAILBOX_VOE: Self = Self(0x004F);
    pub const EEPROM_NO_ACCESS: Self = Self(0x0050);
    pub const EEPROM_ERROR: Self = Self(0x0051);
    pub const RESTARTED_LOCALLY: Self = Self(0x0060);
    pub const DEVICE_IDENTIFICATION_UPDATED: Self = Self(0x0061);
    pub const APPLICATION_CONTROLLER_AVAILABLE: Self = Self(0x00F0);

    /// The standard's text for the code, if it names it.
    pub fn description(self) -> Option<&'static str> {
        Some(match self.0 {
            0x0000 => "No error",
            0x0001 => "Unspecified error",
            0x0002 => "No memory",
            0x0003 => "Invalid device setup",
            0x0011 => "Invalid requested state change",
            0x0012 => "Unknown requested state",
            0x0013 => "Bootstrap not supported",
            0x0014 => "No valid firmware",
            0x0015 => "Invalid mailbox configuration (bootstrap)",
            0x0016 => "Invalid mailbox configuration",
            0x0017 => "Invalid sync manager configuration",
            0x0018 => "No valid inputs available",
            0x0019 => "No valid outputs",
            0x001A => "Synchronization error",
            0x001B => "Sync manager watchdog",
            0x001C => "Invalid sync manager types",
            0x001D => "Invalid output configuration",
            0x001E => "Invalid input configuration",
            0x001F => "Invalid watchdog configuration",
            0x0020 => "Slave needs cold start",
            0x0021 => "Slave needs INIT",
            0x0022 => "Slave needs PREOP",
            0x0023 => "Slave needs SAFEOP",
            0x0024 => "Invalid input mapping",
            0x0025 => "Invalid output mapping",
            0x0026 => "Inconsistent settings",
            0x0027 => "Free run not supported",
            0x0028 => "Sync mode not supported",
            0x0029 => "Free run needs 3-buffer mode",
            0x002A => "Background watchdog",
            0x002B => "No valid inputs and outputs",
            0x002C => "Fatal sync error",
            0x002D => "No sync error",
            0x002E => "Invalid input FMMU configuration",
            0x0030 => "Invalid DC SYNC configuration",
            0x0031 => "Invalid DC latch configuration",
            0x0032 => "PLL error",
            0x0033 => "DC sync IO error",
            0x0034 => "DC sync timeout",
            0x0035 => "DC invalid sync cycle time",
            0x0036 => "DC SYNC0 cycle time",
            0x0037 => "DC SYNC1 cycle time",
            0x0041 => "Mailbox AoE",
            0x0042 => "Mailbox EoE",
            0x0043 => "Mailbox CoE",
            0x0044 => "Mailbox FoE",
            0x0045 => "Mailbox SoE",
            0x004F => "Mailbox VoE",
            0x0050 => "EEPROM no access",
            0x0051 => "EEPROM error",
            0x0060 => "Slave restarted locally",
            0x0061 => "Device identification value updated",
            0x00F0 => "Application controller available",
            _ => return None,
        })
    }
}

impl From<u16> for AlStatusCode {
    fn from(v: u16) -> Self {
        AlStatusCode(v)
    }
}

impl From<AlStatusCode> for u16 {
    fn from(c: AlStatusCode) -> u16 {
        c.0
    }
}

impl fmt::Debug for AlStatusCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.description() {
            Some(d) => write!(f, "AlStatusCode({:#06x} {})", self.0, d),
            None => write!(f, "AlStatusCode({:#06x})", self.0),
        }
    }
}

impl fmt::Display for AlStatusCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.description() {
            Some(d) => write!(f, "{:#06x}: {}", self.0, d),
            None if self.0 >= 0x8000 => write!(f, "{:#06x}: vendor specific", self.0),
            None => write!(f, "{:#06x}", self.0),
        }
    }
}
