//! One emulated EtherCAT slave controller: a frame in, the same frame processed out, as the
//! chip does on the fly (spec §1–§8).
//!
//! * [`Esc::process`] walks the datagrams of an Ethernet frame in place (or
//!   [`Esc::process_ecat`] for a buffer that starts at the EtherCAT header), executes every
//!   command addressed to this slave, adds to the working counters, increments the
//!   auto-increment address and ORs the locally-administered bit into the source MAC.
//! * [`process_chain`] passes one frame through several slaves in ring order.
//! * The device behind the ESC (the "PDI side") uses [`Esc::mailbox_read`],
//!   [`Esc::mailbox_write`], [`Esc::process_outputs`], [`Esc::set_inputs`], and learns of and
//!   vets AL state transitions through an [`AlHook`].
//!
//! Design decisions (each with its spec reference):
//!
//! * Memory: 4 KiB registers + 8 KiB RAM ([`crate::register::MEMORY_SIZE`]); addresses above
//!   read 0 and ignore writes, still counted (§1.4 rule 1).
//! * Processing order: datagrams in order, each seeing the effects of the earlier ones; the
//!   side effects of a datagram (AL control, EEPROM command, SM/FMMU reconfiguration, DC
//!   latch) are applied right after it (§1.1 "Process once", §2.4 "after the whole
//!   datagram"). Datagrams are executed as they are reached; a datagram that runs past the
//!   end of the frame (or of the EtherCAT length) stops processing there and leaves it and
//!   everything after it untouched, counted in [`ErrorCounters`] and the invalid-frame
//!   counter 0x0300. (A real ESC would also discard the writes of a frame whose FCS turns out
//!   bad; a socket delivers no FCS, so a short frame is the only evidence there is.)
//! * Sync-manager rules are checked per contiguous access: an access that touches an SM
//!   window which forbids it is refused whole (no memory change, no WKC), §1.4 rule 2.
//! * Mailbox SMs: one buffer in RAM; the write covering the last byte sets "full", the read
//!   covering the last byte clears it (§5.2). Repeat request (§5.4) re-posts the last reply.
//! * Buffered SMs, emulated with two copies as §7.3 allows: outputs (SM2) are written by the
//!   master into the RAM window and copied to a PDI buffer when the write covers the last
//!   byte; inputs (SM3) are written by the device straight into the RAM window, which the
//!   master therefore always reads complete. The master's writes never block.
//! * AL: §4.2 processing of AL control; the ESC's own checks are the mailbox SM layout for
//!   Init → Pre-Op (0x0016) and the SM2/SM3 structure for Pre-Op → Safe-Op (0x001D, 0x001E,
//!   0x0017); sizes and PDO mapping are the device's, through [`AlHook::check_transition`]
//!   (use [`Esc::check_process_data`] or [`FixedProcessData`]). Bootstrap is refused with
//!   0x0013 unless configured ([`EscConfig::bootstrap_supported`]).
//! * DC (§2.7, §8.2 "minimal DC"): local time = `now` (+ a configurable offset); a write
//!   touching 0x0900 latches receive times; 0x0910 reads local + offset; a write to 0x0910
//!   (BWR, or ARMW/FRMW at a non-reference slave) makes the system time converge to the
//!   written value + delay at once (a real ESC slews; the difference seen is stored in
//!   0x092C); a write to the speed counter start 0x0930 resets the time-control filters
//!   (0x092C and 0x0932 read 0 again); 0x0990 reads the next SYNC0 time while SYNC0 is active.
//! * Process-data watchdog (§7.6): in Op, with SM2 watchdog-triggered (control bit 6) and an
//!   active write FMMU, no complete SM2 write for 0x0420 × (0x0400 + 2) × 40 ns drops the
//!   slave to Safe-Op + error 0x001B.
//!
//! Not modelled (yet): the first-byte rule of SM buffers (a real ESC locks a buffer on the
//! first byte and reports "buffer in use", status bits 6–7; here only the last-byte rule
//! signals completion); SM event bits and the PDI-side AL event request 0x0220 (only the AL
//! status event, 0x0210 bit 3, reaches the datagram IRQ field); device identification
//! (AL control bit 5); PDI watchdog; write protection 0x0020/0x0030 and ESC reset 0x0040
//! (stored, not enforced); DC time-control slewing (a drift set with [`Esc::set_clock_error`]
//! is corrected at once by each system-time write) and the 32-bit start-time wrap;
//! SYNC0/SYNC1 pulse status 0x098E/0x098F and latch units; FMMUs and SMs 8–15 (stored
//! only); VLAN-tagged frames (not recognised as EtherCAT); EEPROM reload (a no-op).

use od::Instant;

use crate::al_control::{check_transition, is_upward, AlControl, AlState, AlStatus};
use crate::al_status_code::AlStatusCode;
use crate::datagram::{self, Command, Datagram};
use crate::dl_status::DlStatus;
use crate::eeprom::{self, Eeprom, SiiCommand};
use crate::fmmu::{Fmmu, FMMU_LEN};
use crate::frame::{EthernetFrame, WireError, ETHERTYPE_ETHERCAT};
use crate::register::{self, RegisterAddress as R, FMMU_COUNT, MEMORY_SIZE, SM_COUNT};
use crate::sync_manager::{
    self as sm, SmDirection, SmMode, SyncManager, SM_LEN, STATUS_BUFFER_MASK, STATUS_IRQ_READ,
    STATUS_IRQ_WRITE, STATUS_MAILBOX_FULL,
};

mod al_state;
mod chain;
mod frame;
mod local_clock;
mod memory_access;
mod pdi;
mod ports;
mod side_effects;
mod sm_access;
mod watchdog;

pub use chain::{process_chain, process_chain_with};
pub use local_clock::ClockError;
use local_clock::LocalClock;

/// Largest mailbox message the device can post (and the size of the repeat backup).
pub const MAILBOX_MAX: usize = 1024;
/// Largest output (SM2) image the PDI copy holds.
pub const PROCESS_DATA_MAX: usize = 1024;

/// SM index of the receive mailbox (master → slave): SM0, as ETG.1000.6 assigns it.
pub const SM_MAILBOX_OUT: usize = 0;
/// SM index of the send mailbox (slave → master).
pub const SM_MAILBOX_IN: usize = 1;
/// SM index of the outputs (RxPDO, master → slave).
pub const SM_OUTPUTS: usize = 2;
/// SM index of the inputs (TxPDO, slave → master).
pub const SM_INPUTS: usize = 3;

/// ECAT event request bit 3: AL status changed (cleared by reading 0x0130).
const EVENT_AL_STATUS: u16 = 0x0008;

/// The standard mailbox as the SII describes it (words 0x18–0x1B).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MailboxLayout {
    /// SM0 start (receive mailbox, master → slave).
    pub rx_offset: u16,
    pub rx_size: u16,
    /// SM1 start (send mailbox, slave → master).
    pub tx_offset: u16,
    pub tx_size: u16,
}

impl MailboxLayout {
    /// From SII words 0x18–0x1B; `None` when the receive size is 0 ("no mailbox", as SOEM
    /// reads it). A send size of 0 means "same as receive" (SOEM).
    pub fn from_sii(image: &[u8]) -> Option<Self> {
        let e = Eeprom::ReadOnly(image);
        let (rx_offset, rx_size) = (e.word(0x18), e.word(0x19));
        let (tx_offset, tx_size) = (e.word(0x1A), e.word(0x1B));
        if rx_size == 0 || rx_size == 0xFFFF {
            return None;
        }
        let tx_size = if tx_size == 0 { rx_size } else { tx_size };
        Some(MailboxLayout {
            rx_offset,
            rx_size,
            tx_offset,
            tx_size,
        })
    }
}

/// Power-on configuration of an ESC.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EscConfig {
    /// 0x0000. Masters do not interpret it; 0x04 as KickCAT's emulated ESC.
    pub esc_type: u8,
    /// 0x0001.
    pub revision: u8,
    /// 0x0002.
    pub build: u16,
    /// 0x0008; default [`register::FEATURES_DC`] (DC, 64 bit, enhanced SYNC activation).
    pub features: u16,
    /// 0x0007.
    pub port_descriptor: u8,
    /// 0x0110 at power-on; default [`register::DL_STATUS_LINE_END`] (a link on port 0
    /// only). A line of ESCs shows its links with [`Esc::set_port_link`]: port 1 of every
    /// slave but the last has one. Every port latches the same receive time (0x0900), so the
    /// masters compute no propagation delays either way.
    pub dl_status: u16,
    /// 0x0140 (SII word 0 low byte).
    pub pdi_control: u8,
    /// 0x0141 (SII word 0 high byte); bit 0 (device emulation) is ignored: the device runs
    /// the AL state machine.
    pub esc_configuration: u8,
    /// 0x0012 (SII word 4).
    pub station_alias: u16,
    /// 0x0982 (SII word 2).
    pub sync_pulse_length: u16,
    /// Expected mailbox SM layout, checked on Init → Pre-Op; `None`: no mailbox.
    pub mailbox: Option<MailboxLayout>,
    /// Bootstrap state implemented (without it: 0x0013).
    pub bootstrap_supported: bool,
    /// Safe-Op → Op only after a complete SM2 write (else 0x0019). Off by default:
    /// ethercrab's `into_op()` sends no process data first (spec §4.2 note).
    pub require_outputs_for_op: bool,
    /// Added to `now` to give the ESC's local clock (different slaves, different clocks).
    pub local_clock_offset_ns: u64,
}

impl Default for EscConfig {
    fn default() -> Self {
        EscConfig {
            esc_type: 0x04,
            revision: 0x01,
            build: 0x0001,
            features: register::FEATURES_DC,
            port_descriptor: register::PORT_DESCRIPTOR_RESET,
            dl_status: register::DL_STATUS_LINE_END,
            pdi_control: 0x05,
            esc_configuration: 0x00,
            station_alias: 0,
            sync_pulse_length: 0,
            mailbox: None,
            bootstrap_supported: false,
            require_outputs_for_op: false,
            local_clock_offset_ns: 0,
        }
    }
}

impl EscConfig {
    /// The configuration an ESC loads from its SII at power-on (words 0, 2, 4 and the
    /// mailbox words 0x18–0x1B), the rest as [`EscConfig::default`].
    pub fn from_sii(image: &[u8]) -> Self {
        let e = Eeprom::ReadOnly(image);
        let w0 = e.word(0);
        let mut c = EscConfig::default();
        if w0 != 0xFFFF {
            c.pdi_control = w0 as u8;
            c.esc_configuration = (w0 >> 8) as u8;
            c.sync_pulse_length = e.word(2);
            c.station_alias = e.word(4);
        }
        c.mailbox = MailboxLayout::from_sii(image);
        c
    }
}

/// What became of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameOutcome {
    /// All datagrams processed; send the frame on.
    Processed { datagrams: u16 },
    /// Processed up to `datagrams`, then a datagram (or the frame) was cut short; the rest is
    /// untouched. Send the frame on.
    Malformed { datagrams: u16, error: WireError },
    /// An EtherCAT frame of a type other than 1 (commands): forwarded unchanged.
    Ignored,
    /// Not an EtherCAT frame (or shorter than an Ethernet header): drop it.
    NotEtherCat,
    /// No slave closed the loop: the link into the first one is down (its cable pulled, it
    /// powered off), so nothing comes back to the master.
    Unreturned,
}

impl FrameOutcome {
    /// The frame goes on to the next slave / back to the master.
    pub fn forward(&self) -> bool {
        !matches!(self, FrameOutcome::NotEtherCat | FrameOutcome::Unreturned)
    }
}

/// Counters of frames the ESC could not (fully) process. Never reset by the ESC.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ErrorCounters {
    /// Frames without EtherType 0x88A4 or shorter than an Ethernet header.
    pub not_ethercat: u32,
    /// EtherCAT frames of a type other than 1.
    pub unsupported_type: u32,
    /// Frames whose EtherCAT length runs past the end of the buffer, or too short for the
    /// EtherCAT header.
    pub truncated_frames: u32,
    /// Datagrams whose header, data or WKC run past the end of the frame.
    pub truncated_datagrams: u32,
    /// Datagrams with a reserved command code (≥ 0x0F), left untouched.
    pub unknown_commands: u32,
}

/// Why a PDI-side call could not be served.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PdiError {
    /// The mailbox is not running (AL state Init).
    NotRunning,
    /// The SM is disabled or not configured for this use.
    NotConfigured,
    /// The send mailbox still holds a message the master has not read.
    Busy,
    /// The data does not fit the SM window (or the emulator's buffers).
    TooLong,
}

/// The device's say in AL transitions. Both methods have defaults that accept everything.
pub trait AlHook {
    /// Called for an upward transition after the ESC's own checks passed (mailbox SM layout,
    /// SM2/SM3 structure). Return the AL status code to refuse it; the slave then stays in
    /// `from` with the error bit set.
    fn check_transition(
        &mut self,
        esc: &Esc<'_>,
        from: AlState,
        to: AlState,
    ) -> Result<(), AlStatusCode> {
        let _ = (esc, from, to);
        Ok(())
    }

    /// Called after the AL status shows the new state (also for fall-backs such as the
    /// process-data watchdog). The device may use the PDI calls here, e.g. post its inputs
    /// on Pre-Op → Safe-Op.
    fn state_changed(&mut self, esc: &mut Esc<'_>, from: AlState, to: AlState) {
        let _ = (esc, from, to);
    }
}

/// A hook that accepts every transition the ESC's own checks accept.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoHook;

impl AlHook for NoHook {}

/// A hook for a device with a fixed process image: Pre-Op → Safe-Op needs SM2 of `outputs`
/// bytes and SM3 of `inputs` bytes ([`Esc::check_process_data`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FixedProcessData {
    pub outputs: u16,
    pub inputs: u16,
}

impl AlHook for FixedProcessData {
    fn check_transition(
        &mut self,
        esc: &Esc<'_>,
        from: AlState,
        to: AlState,
    ) -> Result<(), AlStatusCode> {
        if from == AlState::PreOp && to == AlState::SafeOp {
            esc.check_process_data(self.outputs, self.inputs)
        } else {
            Ok(())
        }
    }
}

/// Registers written by the current datagram whose effects follow it.
#[derive(Debug, Clone, Copy, Default)]
struct Dirty {
    al_control: bool,
    sii_control: bool,
    fmmu: bool,
    sm: u16,
    dc_latch: bool,
    system_time: bool,
    speed_counter_start: bool,
    sync_start: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Dir {
    Read,
    Write,
}

fn overlaps(a0: usize, a1: usize, b0: usize, b1: usize) -> bool {
    a0 < b1 && b0 < a1
}

/// A half-open range of addresses, the union's hull of a few windows: what lies outside
/// needs no look at the windows one by one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Span {
    start: u64,
    end: u64,
}

impl Span {
    const EMPTY: Span = Span { start: 0, end: 0 };

    /// The hull of `self` and `[start, end)`.
    fn with(self, start: u64, end: u64) -> Span {
        if self.start >= self.end {
            Span { start, end }
        } else {
            Span {
                start: self.start.min(start),
                end: self.end.max(end),
            }
        }
    }

    /// `[addr, addr + len)` meets the span.
    fn meets(&self, addr: u32, len: usize) -> bool {
        let a = u64::from(addr);
        len > 0 && a < self.end && a + len as u64 > self.start
    }
}

/// `dst.copy_from_slice(src)` for slices of one length (the shorter one's, should they
/// differ). The copies of a frame's pass are a few bytes each (a slave's process data, a
/// system time), which two overlapping loads and stores move without a call into `memcpy`.
#[inline]
fn copy_bytes(dst: &mut [u8], src: &[u8]) {
    let n = dst.len().min(src.len());
    match n {
        0 => {}
        1 => {
            if let (Some(d), Some(s)) = (dst.first_mut(), src.first()) {
                *d = *s;
            }
        }
        2..=3 => copy_ends::<2>(dst, src, n),
        4..=7 => copy_ends::<4>(dst, src, n),
        8..=16 => copy_ends::<8>(dst, src, n),
        _ => {
            if let (Some(d), Some(s)) = (dst.get_mut(..n), src.get(..n)) {
                d.copy_from_slice(s);
            }
        }
    }
}

/// The first and the last `K` of `n` bytes (`K <= n <= 2K`; they overlap below `2K`).
#[inline]
fn copy_ends<const K: usize>(dst: &mut [u8], src: &[u8], n: usize) {
    let Some(tail_at) = n.checked_sub(K) else {
        return;
    };
    let head: Option<[u8; K]> = src.get(..K).and_then(|s| s.try_into().ok());
    let tail: Option<[u8; K]> = src.get(tail_at..n).and_then(|s| s.try_into().ok());
    if let (Some(h), Some(t)) = (head, tail) {
        if let Some(d) = dst.get_mut(..K) {
            d.copy_from_slice(&h);
        }
        if let Some(d) = dst.get_mut(tail_at..n) {
            d.copy_from_slice(&t);
        }
    }
}

/// The set bits of a mask, lowest first: the active FMMUs or SMs.
fn set_bits(mut mask: u8) -> impl Iterator<Item = usize> {
    core::iter::from_fn(move || {
        if mask == 0 {
            return None;
        }
        let i = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        Some(i)
    })
}

/// One emulated slave controller. `'a` is the lifetime of its SII EEPROM image.
#[derive(Debug)]
pub struct Esc<'a> {
    mem: [u8; MEMORY_SIZE],
    config: EscConfig,
    eeprom: Eeprom<'a>,
    fmmus: [Fmmu; FMMU_COUNT],
    active_fmmus: u8,
    /// The logical bytes `[start, end)` the active FMMUs map between them: a logical
    /// datagram outside it is no business of this slave (kept with `active_fmmus`).
    fmmu_span: Span,
    sms: [SyncManager; SM_COUNT],
    active_sms: u8,
    /// The physical bytes `[start, end)` the active SM windows cover between them: an
    /// access outside it meets no SM rule and completes no buffer (kept with `active_sms`).
    sm_span: Span,
    /// For each FMMU, the sync manager whose rules alone govern an access through it
    /// ([`Esc::refresh_fmmu_routes`]), kept with the FMMUs and the active SMs.
    fmmu_sm: [Option<u8>; FMMU_COUNT],
    mailbox_running: bool,
    mbx_backup: [u8; MAILBOX_MAX],
    mbx_backup_len: usize,
    pd_out: [u8; PROCESS_DATA_MAX],
    pd_out_len: usize,
    pd_out_new: bool,
    outputs_seen: bool,
    sync0_start: u64,
    wd_last: Option<Instant>,
    now: Instant,
    errors: ErrorCounters,
    dirty: Dirty,
    systime_write: [u8; 8],
    clock: LocalClock,
    /// The event request 0x0210 masked by 0x0200, ORed into every datagram's IRQ field
    /// (kept with the two registers, [`Esc::refresh_irq`]).
    irq: u16,
    /// The process-data watchdog's timeout, kept with 0x0400 and 0x0420
    /// ([`Esc::refresh_watchdog_timeout`]).
    pd_watchdog_timeout: Option<u64>,
    /// The watchdog expired and cleared 0x0440 bit 0, which the next complete SM2 write
    /// sets again.
    pd_watchdog_expired: bool,
}

impl<'a> Esc<'a> {
    /// An ESC at power-on: registers at their reset values, AL status Init.
    pub fn new(config: EscConfig, eeprom: Eeprom<'a>) -> Self {
        let mut esc = Esc {
            mem: [0; MEMORY_SIZE],
            config,
            eeprom,
            fmmus: [Fmmu::default(); FMMU_COUNT],
            active_fmmus: 0,
            fmmu_span: Span::EMPTY,
            sms: [SyncManager::default(); SM_COUNT],
            active_sms: 0,
            sm_span: Span::EMPTY,
            fmmu_sm: [None; FMMU_COUNT],
            mailbox_running: false,
            mbx_backup: [0; MAILBOX_MAX],
            mbx_backup_len: 0,
            pd_out: [0; PROCESS_DATA_MAX],
            pd_out_len: 0,
            pd_out_new: false,
            outputs_seen: false,
            sync0_start: 0,
            wd_last: None,
            now: Instant::ZERO,
            errors: ErrorCounters::default(),
            dirty: Dirty::default(),
            systime_write: [0; 8],
            clock: LocalClock::default(),
            irq: 0,
            pd_watchdog_timeout: None,
            pd_watchdog_expired: false,
        };
        esc.power_on();
        esc
    }

    /// An ESC that loads its configuration from, and serves SII reads out of, `image`.
    pub fn with_sii(image: &'a [u8]) -> Self {
        Esc::new(EscConfig::from_sii(image), Eeprom::ReadOnly(image))
    }

    fn power_on(&mut self) {
        self.mem.fill(0);
        let c = self.config.clone();
        self.wr8(R::Type.addr(), c.esc_type);
        self.wr8(R::Revision.addr(), c.revision);
        self.wr16(R::Build.addr(), c.build);
        self.wr8(R::FmmuCount.addr(), FMMU_COUNT as u8);
        self.wr8(R::SyncManagerCount.addr(), SM_COUNT as u8);
        self.wr8(R::RamSize.addr(), register::RAM_KIB);
        self.wr8(R::PortDescriptor.addr(), c.port_descriptor);
        self.wr16(R::SupportFlags.addr(), c.features);
        self.wr16(R::ConfiguredStationAlias.addr(), c.station_alias);
        self.wr32(R::DlControl.addr(), register::DL_CONTROL_RESET);
        self.wr16(R::DlStatus.addr(), c.dl_status);
        self.wr16(R::AlControl.addr(), AlState::Init as u16);
        self.wr16(R::AlStatus.addr(), AlState::Init as u16);
        self.wr8(R::PdiControl.addr(), c.pdi_control);
        self.wr8(R::EscConfiguration.addr(), c.esc_configuration);
        self.wr16(R::WatchdogDivider.addr(), register::WATCHDOG_DIVIDER_RESET);
        self.wr16(R::WatchdogTimePdi.addr(), register::WATCHDOG_TIME_RESET);
        self.wr16(
            R::WatchdogTimeProcessData.addr(),
            register::WATCHDOG_TIME_RESET,
        );
        self.wr16(R::WatchdogStatusProcessData.addr(), 0x0001);
        self.wr16(R::SiiControl.addr(), eeprom::READ_SIZE_8);
        self.wr16(R::DcSyncPulseLength.addr(), c.sync_pulse_length);
        for n in 0..SM_COUNT {
            // Buffered-mode status reset value: no buffer written yet.
            self.wr8(R::sync_manager(n as u8) + 5, STATUS_BUFFER_MASK);
        }
        self.refresh_fmmus();
        self.refresh_all_sms();
        self.refresh_irq();
        self.refresh_watchdog_timeout();
        self.pd_watchdog_expired = false;
    }

    /// The datagrams' IRQ (`irq`) from 0x0200 and 0x0210, after either changed: every datagram
    /// carries it, and a register line of every slave of a long line read per datagram is a
    /// cache miss.
    fn refresh_irq(&mut self) {
        self.irq = self.rd16(R::EcatEventRequest.addr()) & self.rd16(R::EcatEventMask.addr());
    }

    // ---------------------------------------------------------------- memory helpers

    fn rd8(&self, a: u16) -> u8 {
        self.mem.get(usize::from(a)).copied().unwrap_or(0)
    }

    /// `N` bytes from `a` on, when they all lie in the backed memory.
    fn rd_array<const N: usize>(&self, a: u16) -> Option<[u8; N]> {
        let s = usize::from(a);
        self.mem.get(s..s + N)?.try_into().ok()
    }

    fn rd16(&self, a: u16) -> u16 {
        match self.rd_array(a) {
            Some(b) => u16::from_le_bytes(b),
            None => u16::from_le_bytes([self.rd8(a), self.rd8(a.wrapping_add(1))]),
        }
    }

    fn rd32(&self, a: u16) -> u32 {
        match self.rd_array(a) {
            Some(b) => u32::from_le_bytes(b),
            None => u32::from(self.rd16(a)) | (u32::from(self.rd16(a.wrapping_add(2))) << 16),
        }
    }

    fn rd64(&self, a: u16) -> u64 {
        match self.rd_array(a) {
            Some(b) => u64::from_le_bytes(b),
            None => u64::from(self.rd32(a)) | (u64::from(self.rd32(a.wrapping_add(4))) << 32),
        }
    }

    fn wr_bytes(&mut self, a: u16, b: &[u8]) {
        let s = usize::from(a);
        if let Some(d) = self.mem.get_mut(s..s + b.len()) {
            d.copy_from_slice(b);
        }
    }

    fn wr8(&mut self, a: u16, v: u8) {
        self.wr_bytes(a, &[v]);
    }

    fn wr16(&mut self, a: u16, v: u16) {
        self.wr_bytes(a, &v.to_le_bytes());
    }

    fn wr32(&mut self, a: u16, v: u32) {
        self.wr_bytes(a, &v.to_le_bytes());
    }

    fn wr64(&mut self, a: u16, v: u64) {
        self.wr_bytes(a, &v.to_le_bytes());
    }

    fn window(&self, start: u16, len: u16) -> Option<&[u8]> {
        let s = usize::from(start);
        self.mem.get(s..s + usize::from(len))
    }

    fn window_mut(&mut self, start: u16, len: u16) -> Option<&mut [u8]> {
        let s = usize::from(start);
        self.mem.get_mut(s..s + usize::from(len))
    }

    // ---------------------------------------------------------------- public read side

    /// The whole backed memory (registers and RAM) as the last datagram left it. Dynamic
    /// registers (system time 0x0910, next SYNC0 0x0990) are refreshed on ECAT reads only;
    /// use [`Esc::system_time_at`] and [`Esc::next_sync0_at`] instead.
    pub fn memory(&self) -> &[u8] {
        &self.mem
    }

    /// A little-endian 16-bit register.
    pub fn read_u16(&self, addr: u16) -> u16 {
        self.rd16(addr)
    }

    /// A little-endian 32-bit register.
    pub fn read_u32(&self, addr: u16) -> u32 {
        self.rd32(addr)
    }

    /// A little-endian 64-bit register.
    pub fn read_u64(&self, addr: u16) -> u64 {
        self.rd64(addr)
    }

    pub fn config(&self) -> &EscConfig {
        &self.config
    }

    pub fn errors(&self) -> ErrorCounters {
        self.errors
    }

    /// Configured station address (0x0010).
    pub fn station_address(&self) -> u16 {
        self.rd16(R::ConfiguredStationAddress.addr())
    }

    pub fn al_status(&self) -> AlStatus {
        AlStatus::from_u16(self.rd16(R::AlStatus.addr()))
    }

    pub fn al_state(&self) -> AlState {
        self.al_status().state
    }

    pub fn al_status_code(&self) -> AlStatusCode {
        AlStatusCode(self.rd16(R::AlStatusCode.addr()))
    }

    /// Decoded FMMU `n` (0..FMMU_COUNT).
    pub fn fmmu(&self, n: usize) -> Option<Fmmu> {
        self.fmmus.get(n).copied()
    }

    /// Sync manager `n` (0..SM_COUNT), status and PDI control as they are now.
    pub fn sync_manager(&self, n: usize) -> Option<SyncManager> {
        self.sms.get(n).copied()
    }

    /// The mailbox is running (AL state Pre-Op or higher).
    pub fn mailbox_running(&self) -> bool {
        self.mailbox_running
    }

    /// The ESC's local clock at `now` (ns): `now`, its offset, and the deviation of an
    /// oscillator off nominal ([`Esc::set_clock_error`]).
    pub fn local_time_at(&self, now: Instant) -> u64 {
        now.as_nanos()
            .wrapping_add(self.config.local_clock_offset_ns)
            .wrapping_add(self.clock.deviation(now) as u64)
    }

    /// From `now` on the local clock runs off nominal by `error` (drift and jitter); the time
    /// it gained so far stays. The master's system-time writes correct it (0x092C shows the
    /// difference each one found).
    pub fn set_clock_error(&mut self, now: Instant, error: ClockError) {
        self.clock.set(now, error);
    }

    /// How far the local clock runs off nominal.
    pub fn clock_error(&self) -> ClockError {
        self.clock.error()
    }

    /// DC system time at `now`: local time + offset 0x0920.
    pub fn system_time_at(&self, now: Instant) -> u64 {
        self.local_time_at(now)
            .wrapping_add(self.rd64(R::DcSystemTimeOffset.addr()))
    }

    /// SYNC0 cycle time (0x09A0) if cyclic SYNC0 generation is active (0x0981 bits 0–1).
    pub fn sync0_cycle_ns(&self) -> Option<u32> {
        let act = self.rd8(R::DcSyncActive.addr());
        let cycle = self.rd32(R::DcSync0CycleTime.addr());
        (act & 0x03 == 0x03 && cycle > 0).then_some(cycle)
    }

    /// Start time of cyclic operation (the first SYNC0 event, system time) as last written to
    /// 0x0990.
    pub fn sync0_start(&self) -> u64 {
        self.sync0_start
    }

    /// System time of the next SYNC0 event at or after `now` while SYNC0 is active (a
    /// start time in the past runs on from the next cycle boundary, spec §8.2).
    pub fn next_sync0_at(&self, now: Instant) -> Option<u64> {
        if self.rd8(R::DcSyncActive.addr()) & 0x03 != 0x03 {
            return None;
        }
        let start = self.sync0_start;
        let cycle = u64::from(self.rd32(R::DcSync0CycleTime.addr()));
        let sys = self.system_time_at(now);
        if sys <= start || cycle == 0 {
            return Some(start);
        }
        let k = (sys - start).div_ceil(cycle);
        Some(start.wrapping_add(k.wrapping_mul(cycle)))
    }
}

#[cfg(test)]
mod copy_tests {
    use super::copy_bytes;

    /// Every length a pass copies, short and long, lands byte for byte as `copy_from_slice`.
    #[test]
    fn copy_bytes_is_copy_from_slice() {
        let src: [u8; 40] = core::array::from_fn(|i| i as u8 + 1);
        for n in 0..=40 {
            let mut dst = [0xEEu8; 40];
            let mut want = [0xEEu8; 40];
            copy_bytes(&mut dst[..n], &src[..n]);
            want[..n].copy_from_slice(&src[..n]);
            assert_eq!(dst, want, "{n} bytes");
        }
    }
}
