//! The ESC address space and register map (spec §2; ET1100-compatible
//! register set as in the Infineon ECAT0 SVD and ethercrab `register.rs`).
//!
//! Memory of the emulated ESC: 0x0000–0x0FFF registers (4 KiB) and 8 KiB process-data RAM at
//! 0x1000–0x2FFF (register 0x0006 = 8), 12 KiB in all. The 64 KiB address space of a real
//! ESC is not backed: reads above 0x2FFF return 0 and writes there are ignored, both still
//! counted, as for unused registers (spec §1.4 rule 1). 8 KiB is what the spec's baseline
//! (§10) and the masters' default SM layout (0x1000–0x11FF) need; an ET1100 has 8 KiB too.

/// Bytes of backed memory (registers + process RAM).
pub const MEMORY_SIZE: usize = 0x3000;
/// First address of process-data RAM.
pub const RAM_START: u16 = 0x1000;
/// Process RAM in KiB (register 0x0006).
pub const RAM_KIB: u8 = 8;
/// FMMUs implemented (register 0x0004). The 16 blocks at 0x0600 are all stored.
pub const FMMU_COUNT: usize = 8;
/// Sync managers implemented (register 0x0005). The 16 blocks at 0x0800 are all stored.
pub const SM_COUNT: usize = 8;

/// Named register addresses (ETG.1000.4 / ESC datasheet section II).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u16)]
pub enum RegisterAddress {
    Type = 0x0000,
    Revision = 0x0001,
    Build = 0x0002,
    FmmuCount = 0x0004,
    SyncManagerCount = 0x0005,
    RamSize = 0x0006,
    PortDescriptor = 0x0007,
    SupportFlags = 0x0008,
    ConfiguredStationAddress = 0x0010,
    ConfiguredStationAlias = 0x0012,
    DlControl = 0x0100,
    /// Byte 3 of DL control: bit 0 = station alias enable (DL control bit 24).
    DlControlAliasEnable = 0x0103,
    PhysicalRwOffset = 0x0108,
    DlStatus = 0x0110,
    AlControl = 0x0120,
    AlStatus = 0x0130,
    AlStatusCode = 0x0134,
    PdiControl = 0x0140,
    EscConfiguration = 0x0141,
    EcatEventMask = 0x0200,
    AlEventMask = 0x0204,
    EcatEventRequest = 0x0210,
    AlEventRequest = 0x0220,
    /// Invalid-frame counter port 0 (first of the RX error counters 0x0300–0x0307).
    RxErrorCounter = 0x0300,
    ProcessingUnitErrorCounter = 0x030C,
    WatchdogDivider = 0x0400,
    WatchdogTimePdi = 0x0410,
    WatchdogTimeProcessData = 0x0420,
    WatchdogStatusProcessData = 0x0440,
    WatchdogCounterProcessData = 0x0442,
    WatchdogCounterPdi = 0x0443,
    SiiConfig = 0x0500,
    SiiPdiAccess = 0x0501,
    SiiControl = 0x0502,
    SiiAddress = 0x0504,
    SiiData = 0x0508,
    Fmmu0 = 0x0600,
    Sm0 = 0x0800,
    DcReceiveTimePort0 = 0x0900,
    DcReceiveTimePort1 = 0x0904,
    DcReceiveTimePort2 = 0x0908,
    DcReceiveTimePort3 = 0x090C,
    DcSystemTime = 0x0910,
    DcReceiveTimeProcessingUnit = 0x0918,
    DcSystemTimeOffset = 0x0920,
    DcSystemTimeDelay = 0x0928,
    DcSystemTimeDifference = 0x092C,
    DcSpeedCounterStart = 0x0930,
    DcSpeedCounterDifference = 0x0932,
    DcFilterDepth = 0x0934,
    DcCyclicUnitControl = 0x0980,
    DcSyncActive = 0x0981,
    DcSyncPulseLength = 0x0982,
    DcActivationStatus = 0x0984,
    DcSync0Status = 0x098E,
    DcSync1Status = 0x098F,
    DcSyncStartTime = 0x0990,
    DcSync1NextTime = 0x0998,
    DcSync0CycleTime = 0x09A0,
    DcSync1CycleTime = 0x09A4,
}

impl RegisterAddress {
    pub const fn addr(self) -> u16 {
        self as u16
    }

    /// Address of FMMU `n` (16 bytes each).
    pub const fn fmmu(n: u8) -> u16 {
        0x0600 + 16 * (n as u16 & 0x0F)
    }

    /// Address of sync manager `n` (8 bytes each).
    pub const fn sync_manager(n: u8) -> u16 {
        0x0800 + 8 * (n as u16 & 0x0F)
    }
}

impl From<RegisterAddress> for u16 {
    fn from(r: RegisterAddress) -> u16 {
        r as u16
    }
}

/// Bits of register byte `addr` an ECAT write may change (0 = read-only for the master; the
/// write is ignored but the datagram still counts, spec §1.4 rule 1). Registers whose writes
/// have side effects instead of storage (DC receive-time latch 0x0900–0x090F, system time
/// 0x0910–0x0917, counters that clear on write) read as 0 here and are handled by the ESC.
pub const fn ecat_write_mask(addr: u16) -> u8 {
    match addr {
        // Station address; the alias 0x0012 is ECAT read-only on an ET1100 (PDI writes it,
        // or the SII word 4 at power-on). The spec table's "R/W" is not what the chip does;
        // no master writes it.
        0x0010..=0x0011 => 0xFF,
        // Write enable / protection, ESC reset: stored, not enforced.
        0x0020 | 0x0030 | 0x0040 => 0xFF,
        // DL control (bit 0 forwarding, loop control, FIFO, alias enable bit 24).
        0x0100..=0x0103 => 0xFF,
        0x0108..=0x0109 => 0xFF,
        // AL control.
        0x0120..=0x0121 => 0xFF,
        // LED overrides.
        0x0138..=0x0139 => 0xFF,
        // ECAT event mask.
        0x0200..=0x0201 => 0xFF,
        // Watchdog divider, PDI and process-data watchdog times.
        0x0400..=0x0401 | 0x0410..=0x0411 | 0x0420..=0x0421 => 0xFF,
        // EEPROM configuration: bit 0 "EEPROM offered to PDI" is stored; bit 1 (force ECAT
        // access) only acts (the PDI never holds the EEPROM here).
        0x0500 => 0x01,
        // EEPROM control/status: write enable (bit 0) and command (bits 8–10).
        0x0502 => 0x01,
        0x0503 => 0x07,
        // EEPROM address and data.
        0x0504..=0x050F => 0xFF,
        // FMMU 0–15.
        0x0600..=0x06FF => 0xFF,
        // SM 0–15: start, length, control, (status RO), activate, (PDI control RO).
        0x0800..=0x087F => match (addr - 0x0800) % 8 {
            5 | 7 => 0x00,
            6 => 0xC3,
            _ => 0xFF,
        },
        // DC: offset, delay, speed counter start, filter depths.
        0x0920..=0x092B => 0xFF,
        0x0930..=0x0931 | 0x0934..=0x0935 => 0xFF,
        // Cyclic unit control, activation.
        0x0980..=0x0981 => 0xFF,
        // Start time, SYNC0/SYNC1 cycle times, latch control.
        0x0990..=0x0997 | 0x09A0..=0x09A9 => 0xFF,
        // Digital output data, user RAM.
        0x0F00..=0x0F07 | 0x0F80..=0x0FFF => 0xFF,
        _ => 0x00,
    }
}

// Evaluated when compiling (`ECAT_WRITE_MASK`); `a` stays below the array's length.
#[allow(clippy::indexing_slicing)]
const fn build_write_masks() -> [u8; 0x1000] {
    let mut t = [0u8; 0x1000];
    let mut a = 0usize;
    while a < 0x1000 {
        t[a] = ecat_write_mask(a as u16);
        a += 1;
    }
    t
}

/// [`ecat_write_mask`] for every register byte, as a table.
pub static ECAT_WRITE_MASK: [u8; 0x1000] = build_write_masks();

/// DL status of a slave with a link on port 0 only (spec §2.3): PDI operational, PDI
/// watchdog reloaded, link port 0, port 0 open with communication, ports 1–3 closed.
pub const DL_STATUS_LINE_END: u16 = 0x5613;
/// DL status of a slave inside a line (spec §2.3): as [`DL_STATUS_LINE_END`] with a link on
/// port 1 as well, its loop open and communicating.
pub const DL_STATUS_LINE_THROUGH: u16 = 0x5A33;
/// DL control power-on value (Infineon ECAT0 reset value).
pub const DL_CONTROL_RESET: u32 = 0x0007_C001;
/// Watchdog divider reset value: 2498 → 100 µs ticks.
pub const WATCHDOG_DIVIDER_RESET: u16 = 0x09C2;
/// PDI and process-data watchdog reset value: 1000 ticks = 100 ms.
pub const WATCHDOG_TIME_RESET: u16 = 0x03E8;
/// ESC features with minimal DC: DC available, 64-bit, enhanced SYNC activation (spec §8.3).
pub const FEATURES_DC: u16 = 0x010C;
/// Port descriptor: ports 0 and 1 MII, 2 and 3 not implemented (spec §2.1).
pub const PORT_DESCRIPTOR_RESET: u8 = 0x0F;
