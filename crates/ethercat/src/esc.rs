//! One emulated EtherCAT slave controller: a frame in, the same frame processed out, as the
//! chip does on the fly (spec/ethercat-esc.md §1–§8).
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
//!   0x0013 (CMMP-AS, spec/cmmp-as-1-communication.md §4.2) unless configured.
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
//! (stored, not enforced); DC drift, time-control slewing and the 32-bit start-time wrap;
//! SYNC0/SYNC1 pulse status 0x098E/0x098F and latch units; FMMUs and SMs 8–15 (stored
//! only); VLAN-tagged frames (not recognised as EtherCAT); EEPROM reload (a no-op).

use od::Instant;

use crate::al_control::{check_transition, is_upward, AlControl, AlState, AlStatus};
use crate::al_status_code::AlStatusCode;
use crate::datagram::{self, Command, Datagram};
use crate::eeprom::{self, Eeprom, SiiCommand};
use crate::fmmu::{Fmmu, FMMU_LEN};
use crate::frame::{EthernetFrame, WireError, ETHERTYPE_ETHERCAT};
use crate::register::{self, RegisterAddress as R, FMMU_COUNT, MEMORY_SIZE, SM_COUNT};
use crate::sync_manager::{
    self as sm, SmDirection, SmMode, SyncManager, SM_LEN, STATUS_BUFFER_MASK, STATUS_IRQ_READ,
    STATUS_IRQ_WRITE, STATUS_MAILBOX_FULL,
};

/// Largest mailbox message the device can post (and the size of the repeat backup).
pub const MAILBOX_MAX: usize = 1024;
/// Largest output (SM2) image the PDI copy holds.
pub const PROCESS_DATA_MAX: usize = 1024;

/// SM index of the receive mailbox (master → slave), fixed on the CMMP-AS (§2.11).
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
    /// 0x0110; default [`register::DL_STATUS_LINE_END`]. In a simulated chain every slave
    /// reports "line end"; the masters then compute no propagation delays.
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
    /// Bootstrap state implemented (the CMMP-AS has none: 0x0013).
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
}

impl FrameOutcome {
    /// The frame goes on to the next slave / back to the master.
    pub fn forward(&self) -> bool {
        !matches!(self, FrameOutcome::NotEtherCat)
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

/// One emulated slave controller. `'a` is the lifetime of its SII EEPROM image.
#[derive(Debug)]
pub struct Esc<'a> {
    mem: [u8; MEMORY_SIZE],
    config: EscConfig,
    eeprom: Eeprom<'a>,
    fmmus: [Fmmu; FMMU_COUNT],
    active_fmmus: u8,
    sms: [SyncManager; SM_COUNT],
    active_sms: u8,
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
            sms: [SyncManager::default(); SM_COUNT],
            active_sms: 0,
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
    }

    // ---------------------------------------------------------------- memory helpers

    fn rd8(&self, a: u16) -> u8 {
        self.mem.get(usize::from(a)).copied().unwrap_or(0)
    }

    fn rd16(&self, a: u16) -> u16 {
        u16::from_le_bytes([self.rd8(a), self.rd8(a.wrapping_add(1))])
    }

    fn rd32(&self, a: u16) -> u32 {
        u32::from(self.rd16(a)) | (u32::from(self.rd16(a.wrapping_add(2))) << 16)
    }

    fn rd64(&self, a: u16) -> u64 {
        u64::from(self.rd32(a)) | (u64::from(self.rd32(a.wrapping_add(4))) << 32)
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

    /// The ESC's local clock at `now` (ns).
    pub fn local_time_at(&self, now: Instant) -> u64 {
        now.as_nanos()
            .wrapping_add(self.config.local_clock_offset_ns)
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

    // ---------------------------------------------------------------- frame processing

    /// Process an Ethernet frame in place (no hook: every transition the ESC's own checks
    /// accept is taken).
    pub fn process(&mut self, now: Instant, frame: &mut [u8]) -> FrameOutcome {
        self.process_with(now, frame, &mut NoHook)
    }

    /// Process an Ethernet frame in place, asking `hook` about AL transitions.
    pub fn process_with<H: AlHook>(
        &mut self,
        now: Instant,
        frame: &mut [u8],
        hook: &mut H,
    ) -> FrameOutcome {
        let Ok(mut eth) = EthernetFrame::new_checked(frame) else {
            self.errors.not_ethercat = self.errors.not_ethercat.wrapping_add(1);
            return FrameOutcome::NotEtherCat;
        };
        if eth.ethertype() != ETHERTYPE_ETHERCAT {
            self.errors.not_ethercat = self.errors.not_ethercat.wrapping_add(1);
            return FrameOutcome::NotEtherCat;
        }
        eth.mark_returned();
        self.process_ecat_with(now, eth.payload_mut(), hook)
    }

    /// Process a buffer that starts with the EtherCAT header (no Ethernet header, e.g.
    /// EtherCAT in UDP).
    pub fn process_ecat(&mut self, now: Instant, ecat: &mut [u8]) -> FrameOutcome {
        self.process_ecat_with(now, ecat, &mut NoHook)
    }

    /// [`Esc::process_ecat`] with a hook.
    pub fn process_ecat_with<H: AlHook>(
        &mut self,
        now: Instant,
        ecat: &mut [u8],
        hook: &mut H,
    ) -> FrameOutcome {
        self.advance(now, hook);
        let header = match ecat.get(0..2) {
            Some(&[lo, hi]) => u16::from_le_bytes([lo, hi]),
            _ => {
                self.count_truncated_frame();
                return FrameOutcome::Malformed {
                    datagrams: 0,
                    error: WireError::Truncated,
                };
            }
        };
        if header >> 12 != u16::from(crate::frame::TYPE_COMMANDS) {
            self.errors.unsupported_type = self.errors.unsupported_type.wrapping_add(1);
            return FrameOutcome::Ignored;
        }
        let length = usize::from(header & 0x07FF);
        let available = ecat.len() - 2;
        let frame_truncated = length > available;
        let Some(payload) = ecat.get_mut(2..2 + length.min(available)) else {
            return FrameOutcome::Ignored;
        };
        let mut off = 0usize;
        let mut count: u16 = 0;
        let mut error = None;
        while let Some(rest) = payload.get_mut(off..) {
            let total = match datagram::total_len(rest) {
                Some(t) if t <= rest.len() => t,
                _ => {
                    error = Some(WireError::Truncated);
                    break;
                }
            };
            let Some(dg) = rest.get_mut(..total) else {
                break;
            };
            let more = Datagram::new_unchecked(&*dg).more_follows();
            self.execute(dg, hook);
            count = count.wrapping_add(1);
            off += total;
            if !more {
                break;
            }
        }
        if error.is_some() {
            self.errors.truncated_datagrams = self.errors.truncated_datagrams.wrapping_add(1);
        }
        if frame_truncated {
            self.errors.truncated_frames = self.errors.truncated_frames.wrapping_add(1);
            error = Some(WireError::Truncated);
        }
        if error.is_some() {
            self.bump_invalid_frame_counter();
        }
        match error {
            Some(error) => FrameOutcome::Malformed {
                datagrams: count,
                error,
            },
            None => FrameOutcome::Processed { datagrams: count },
        }
    }

    fn count_truncated_frame(&mut self) {
        self.errors.truncated_frames = self.errors.truncated_frames.wrapping_add(1);
        self.bump_invalid_frame_counter();
    }

    /// Invalid-frame counter of port 0 (0x0300), saturating at 0xFF as on the chip.
    fn bump_invalid_frame_counter(&mut self) {
        let a = R::RxErrorCounter.addr();
        let v = self.rd8(a);
        self.wr8(a, v.saturating_add(1));
    }

    /// Let time pass without a frame: runs the process-data watchdog. Returns the next
    /// instant at which the ESC has something to do (the watchdog expiry), if any.
    pub fn poll(&mut self, now: Instant) -> Option<Instant> {
        self.poll_with(now, &mut NoHook)
    }

    /// [`Esc::poll`] with a hook (told about a watchdog fall-back).
    pub fn poll_with<H: AlHook>(&mut self, now: Instant, hook: &mut H) -> Option<Instant> {
        self.advance(now, hook);
        let timeout = self.watchdog_timeout_ns()?;
        let last = self.wd_last?;
        self.watchdog_armed()
            .then(|| Instant::from_nanos(last.as_nanos().saturating_add(timeout)))
    }

    fn advance<H: AlHook>(&mut self, now: Instant, hook: &mut H) {
        self.now = now;
        self.check_watchdog(hook);
    }

    fn matches_station(&self, adp: u16) -> bool {
        adp == self.station_address()
            || (self.rd8(R::DlControlAliasEnable.addr()) & 0x01 != 0
                && adp == self.rd16(R::ConfiguredStationAlias.addr()))
    }

    fn execute<H: AlHook>(&mut self, buf: &mut [u8], hook: &mut H) {
        let mut dg = Datagram::new_unchecked(buf);
        let cmd = dg.command();
        let adp = dg.adp();
        let ado = u32::from(dg.ado());
        let inc: u16 = match cmd {
            Command::Nop => 0,
            Command::Unknown(_) => {
                self.errors.unknown_commands = self.errors.unknown_commands.wrapping_add(1);
                return;
            }
            Command::Aprd | Command::Apwr | Command::Aprw | Command::Armw => {
                dg.set_adp(adp.wrapping_add(1));
                self.physical(cmd, adp == 0, ado, dg.data_mut())
            }
            Command::Fprd | Command::Fpwr | Command::Fprw | Command::Frmw => {
                let hit = self.matches_station(adp);
                self.physical(cmd, hit, ado, dg.data_mut())
            }
            Command::Brd | Command::Bwr | Command::Brw => {
                dg.set_adp(adp.wrapping_add(1));
                self.physical(cmd, true, ado, dg.data_mut())
            }
            Command::Lrd | Command::Lwr | Command::Lrw => {
                let addr = dg.logical_address();
                self.logical(cmd, addr, dg.data_mut())
            }
        };
        if inc != 0 {
            let w = dg.wkc();
            dg.set_wkc(w.wrapping_add(inc));
        }
        let irq = self.rd16(R::EcatEventRequest.addr()) & self.rd16(R::EcatEventMask.addr());
        if irq != 0 {
            let v = dg.irq();
            dg.set_irq(v | irq);
        }
        self.after_datagram(hook);
    }

    /// Position, configured and broadcast commands; returns the WKC increment.
    fn physical(&mut self, cmd: Command, addressed: bool, ado: u32, data: &mut [u8]) -> u16 {
        match cmd {
            Command::Aprd | Command::Fprd if addressed => {
                u16::from(self.ecat_read(ado, data, false))
            }
            Command::Brd => u16::from(self.ecat_read(ado, data, true)),
            Command::Apwr | Command::Fpwr if addressed => u16::from(self.ecat_write(ado, data)),
            Command::Bwr => u16::from(self.ecat_write(ado, data)),
            Command::Aprw | Command::Fprw if addressed => {
                let offset = u32::from(self.rd16(R::PhysicalRwOffset.addr()));
                self.ecat_exchange(ado, ado + offset, data, false)
            }
            Command::Brw => self.ecat_exchange(ado, ado, data, true),
            // ARMW/FRMW: the addressed slave reads, every other one writes (DC time
            // distribution, spec §1.4).
            Command::Armw | Command::Frmw if addressed => {
                u16::from(self.ecat_read(ado, data, false))
            }
            Command::Armw | Command::Frmw => u16::from(self.ecat_write(ado, data)),
            _ => 0,
        }
    }

    fn ecat_read(&mut self, addr: u32, out: &mut [u8], or: bool) -> bool {
        if !self.sm_allows(addr, out.len(), Dir::Read) {
            return false;
        }
        self.phys_read(addr, out, or);
        true
    }

    fn ecat_write(&mut self, addr: u32, data: &[u8]) -> bool {
        if !self.sm_allows(addr, data.len(), Dir::Write) {
            return false;
        }
        self.phys_write(addr, data);
        true
    }

    /// APRW/FPRW/BRW: old memory into the frame (ORed for BRW), the frame's data as it
    /// arrived into memory. +1 for the read, +2 for the write.
    fn ecat_exchange(&mut self, raddr: u32, waddr: u32, data: &mut [u8], or: bool) -> u16 {
        const CHUNK: usize = 64;
        let n = data.len();
        let read_ok = self.sm_allows(raddr, n, Dir::Read);
        let write_ok = self.sm_allows(waddr, n, Dir::Write);
        let mut off = 0usize;
        for chunk in data.chunks_mut(CHUNK) {
            let mut orig = [0u8; CHUNK];
            let len = chunk.len();
            if let Some(o) = orig.get_mut(..len) {
                o.copy_from_slice(chunk);
            }
            if read_ok {
                self.phys_read(raddr + off as u32, chunk, or);
            }
            if write_ok {
                if let Some(o) = orig.get(..len) {
                    self.phys_write(waddr + off as u32, o);
                }
            }
            off += len;
        }
        u16::from(read_ok) + 2 * u16::from(write_ok)
    }

    /// Logical commands through the FMMUs; +1 if any read FMMU hit, +1 (LWR) or +2 (LRW)
    /// if any write FMMU hit, whatever the number of FMMUs (spec §1.4 rule 4, §7.5).
    fn logical(&mut self, cmd: Command, addr: u32, data: &mut [u8]) -> u16 {
        if self.active_fmmus == 0 {
            return 0;
        }
        let mut inc = 0;
        // Writes take the data as it arrived, so they go first (LRW, §7.5).
        if matches!(cmd, Command::Lwr | Command::Lrw) {
            let mut hit = false;
            for i in 0..FMMU_COUNT {
                let Some(f) = self.fmmus.get(i).copied() else {
                    continue;
                };
                if self.active_fmmus & (1 << i) != 0 && f.write_enable {
                    hit |= self.fmmu_write(&f, addr, data);
                }
            }
            if hit {
                inc += if cmd == Command::Lrw { 2 } else { 1 };
            }
        }
        if matches!(cmd, Command::Lrd | Command::Lrw) {
            let mut hit = false;
            for i in 0..FMMU_COUNT {
                let Some(f) = self.fmmus.get(i).copied() else {
                    continue;
                };
                if self.active_fmmus & (1 << i) != 0 && f.read_enable {
                    hit |= self.fmmu_read(&f, addr, data);
                }
            }
            if hit {
                inc += 1;
            }
        }
        inc
    }

    fn fmmu_write(&mut self, f: &Fmmu, addr: u32, data: &[u8]) -> bool {
        if f.is_byte_aligned() {
            let Some(w) = f.byte_window(addr, data.len()) else {
                return false;
            };
            let Some(src) = data.get(w.datagram_offset..w.datagram_offset + w.len) else {
                return false;
            };
            return self.ecat_write(w.physical, src);
        }
        let Some(bw) = f.bit_window(addr, data.len()) else {
            return false;
        };
        let (p0, _) = f.physical_bit(bw.first);
        let (p1, _) = f.physical_bit(bw.end - 1);
        let plen = (p1 - p0 + 1) as usize;
        if !self.sm_allows(p0, plen, Dir::Write) {
            return false;
        }
        for i in bw.first..bw.end {
            let (lbyte, lbit) = f.logical_bit(addr, i);
            let Some(&src) = usize::try_from(lbyte).ok().and_then(|b| data.get(b)) else {
                continue;
            };
            let bit = (src >> lbit) & 1;
            let (pa, pb) = f.physical_bit(i);
            let mut cur = [0u8];
            self.peek(pa, &mut cur);
            let new = (cur[0] & !(1 << pb)) | (bit << pb);
            self.phys_write(pa, &[new]);
        }
        true
    }

    fn fmmu_read(&mut self, f: &Fmmu, addr: u32, data: &mut [u8]) -> bool {
        if f.is_byte_aligned() {
            let Some(w) = f.byte_window(addr, data.len()) else {
                return false;
            };
            let Some(dst) = data.get_mut(w.datagram_offset..w.datagram_offset + w.len) else {
                return false;
            };
            return self.ecat_read(w.physical, dst, false);
        }
        let Some(bw) = f.bit_window(addr, data.len()) else {
            return false;
        };
        let (p0, _) = f.physical_bit(bw.first);
        let (p1, _) = f.physical_bit(bw.end - 1);
        let plen = (p1 - p0 + 1) as usize;
        if !self.sm_allows(p0, plen, Dir::Read) {
            return false;
        }
        self.refresh_dynamic(p0 as usize, p0 as usize + plen);
        for i in bw.first..bw.end {
            let (pa, pb) = f.physical_bit(i);
            let mut cur = [0u8];
            self.peek(pa, &mut cur);
            let bit = (cur[0] >> pb) & 1;
            let (lbyte, lbit) = f.logical_bit(addr, i);
            if let Some(d) = usize::try_from(lbyte).ok().and_then(|b| data.get_mut(b)) {
                *d = (*d & !(1 << lbit)) | (bit << lbit);
            }
        }
        self.after_read(p0, plen);
        true
    }

    /// Memory content without side effects (0 beyond the backed memory).
    fn peek(&self, addr: u32, out: &mut [u8]) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.mem.get(addr as usize + i).copied().unwrap_or(0);
        }
    }

    // ---------------------------------------------------------------- SM access rules

    /// May an ECAT access of `len` bytes at `addr` in direction `dir` go ahead? (§1.4 rule
    /// 2, §5.2, §7.3.)
    fn sm_allows(&self, addr: u32, len: usize, dir: Dir) -> bool {
        if self.active_sms == 0 {
            return true;
        }
        for (i, s) in self.sms.iter().enumerate() {
            if self.active_sms & (1 << i) == 0 || !s.overlaps(addr, len) {
                continue;
            }
            let mailbox = s.mode() == SmMode::Mailbox;
            let refused = match (s.direction(), dir) {
                (SmDirection::Write, Dir::Read) | (SmDirection::Read, Dir::Write) => true,
                (SmDirection::Write, Dir::Write) => mailbox && s.is_mailbox_full(),
                (SmDirection::Read, Dir::Read) => mailbox && !s.is_mailbox_full(),
                (SmDirection::Reserved(_), _) => false,
            };
            if refused {
                return false;
            }
        }
        true
    }

    fn set_sm_status(&mut self, n: usize, status: u8) {
        if let Some(s) = self.sms.get_mut(n) {
            s.status = status;
        }
        self.wr8(R::sync_manager(n as u8) + 5, status);
    }

    fn set_sm_pdi_control(&mut self, n: usize, v: u8) {
        if let Some(s) = self.sms.get_mut(n) {
            s.pdi_control = v;
        }
        self.wr8(R::sync_manager(n as u8) + 7, v);
    }

    fn sm(&self, n: usize) -> SyncManager {
        self.sms.get(n).copied().unwrap_or_default()
    }

    /// SM events of a completed ECAT read.
    fn after_read(&mut self, addr: u32, len: usize) {
        let (a0, a1) = (addr as usize, addr as usize + len);
        if overlaps(a0, a1, 0x0130, 0x0132) {
            let ev = self.rd16(R::EcatEventRequest.addr()) & !EVENT_AL_STATUS;
            self.wr16(R::EcatEventRequest.addr(), ev);
        }
        if self.active_sms == 0 {
            return;
        }
        for n in 0..SM_COUNT {
            let s = self.sm(n);
            if self.active_sms & (1 << n) == 0
                || s.direction() != SmDirection::Read
                || !s.covers_last_byte(addr, len)
            {
                continue;
            }
            let status = match s.mode() {
                SmMode::Mailbox => (s.status & !STATUS_MAILBOX_FULL) | STATUS_IRQ_READ,
                _ => s.status | STATUS_IRQ_READ,
            };
            self.set_sm_status(n, status);
        }
    }

    /// SM events of a completed ECAT write.
    fn after_write(&mut self, addr: u32, len: usize) {
        if self.active_sms == 0 {
            return;
        }
        for n in 0..SM_COUNT {
            let s = self.sm(n);
            if self.active_sms & (1 << n) == 0
                || s.direction() != SmDirection::Write
                || !s.covers_last_byte(addr, len)
            {
                continue;
            }
            match s.mode() {
                SmMode::Mailbox => {
                    self.set_sm_status(n, s.status | STATUS_MAILBOX_FULL | STATUS_IRQ_WRITE);
                }
                SmMode::Buffered => {
                    let last = (s.status & STATUS_BUFFER_MASK) >> 4;
                    let next = if last >= 2 { 0 } else { last + 1 };
                    let status = (s.status & !STATUS_BUFFER_MASK) | (next << 4) | STATUS_IRQ_WRITE;
                    self.set_sm_status(n, status);
                    if n == SM_OUTPUTS {
                        self.outputs_completed(s);
                    }
                    if s.control & sm::CONTROL_WATCHDOG != 0 {
                        self.wd_last = Some(self.now);
                        let st = self.rd16(R::WatchdogStatusProcessData.addr()) | 1;
                        self.wr16(R::WatchdogStatusProcessData.addr(), st);
                    }
                }
                SmMode::Reserved(_) => {}
            }
        }
    }

    fn outputs_completed(&mut self, s: SyncManager) {
        let len = usize::from(s.length);
        let start = usize::from(s.start);
        let Some(src) = self.mem.get(start..start + len) else {
            return;
        };
        if let Some(dst) = self.pd_out.get_mut(..len) {
            dst.copy_from_slice(src);
            self.pd_out_len = len;
            self.pd_out_new = true;
            self.outputs_seen = true;
        }
    }

    // ---------------------------------------------------------------- memory access

    /// Registers whose content is computed when read.
    fn refresh_dynamic(&mut self, a0: usize, a1: usize) {
        if overlaps(a0, a1, 0x0910, 0x0918) {
            let t = self.system_time_at(self.now);
            self.wr64(R::DcSystemTime.addr(), t);
        }
        if overlaps(a0, a1, 0x0990, 0x0998) {
            if let Some(t) = self.next_sync0_at(self.now) {
                self.wr64(R::DcSyncStartTime.addr(), t);
            }
        }
    }

    fn phys_read(&mut self, addr: u32, out: &mut [u8], or: bool) {
        let start = addr as usize;
        let end = start + out.len();
        if start < 0x1000 {
            self.refresh_dynamic(start, end);
        }
        let backed_end = end.min(MEMORY_SIZE);
        let n = backed_end.saturating_sub(start);
        if let (Some(src), Some(dst)) = (self.mem.get(start..backed_end), out.get_mut(..n)) {
            if or {
                for (d, s) in dst.iter_mut().zip(src) {
                    *d |= *s;
                }
            } else {
                dst.copy_from_slice(src);
            }
        }
        if !or {
            if let Some(rest) = out.get_mut(n..) {
                rest.fill(0);
            }
        }
        self.after_read(addr, out.len());
    }

    fn phys_write(&mut self, addr: u32, data: &[u8]) {
        let start = addr as usize;
        let end = start + data.len();
        if start < 0x1000 {
            let rend = end.min(0x1000);
            self.note_register_write(start, rend);
            for (i, &d) in data.iter().enumerate().take(rend - start) {
                self.write_register_byte(start + i, d);
            }
        }
        let lo = start.max(0x1000);
        let hi = end.min(MEMORY_SIZE);
        if lo < hi {
            if let (Some(dst), Some(src)) =
                (self.mem.get_mut(lo..hi), data.get(lo - start..hi - start))
            {
                dst.copy_from_slice(src);
            }
        }
        self.after_write(addr, data.len());
    }

    fn write_register_byte(&mut self, a: usize, d: u8) {
        match a {
            // Error counters: any write clears (spec §2.1).
            0x0300..=0x0313 | 0x0442..=0x0443 => {
                if let Some(m) = self.mem.get_mut(a) {
                    *m = 0;
                }
            }
            // System time: an input to the time-control loop, handled after the datagram.
            0x0910..=0x0917 => {
                if let Some(b) = self.systime_write.get_mut(a - 0x0910) {
                    *b = d;
                }
            }
            _ => {
                let mask = register::ECAT_WRITE_MASK.get(a).copied().unwrap_or(0);
                if mask != 0 {
                    if let Some(m) = self.mem.get_mut(a) {
                        *m = (*m & !mask) | (d & mask);
                    }
                }
            }
        }
    }

    fn note_register_write(&mut self, a0: usize, a1: usize) {
        if overlaps(a0, a1, 0x0120, 0x0122) {
            self.dirty.al_control = true;
        }
        if overlaps(a0, a1, 0x0502, 0x0504) {
            self.dirty.sii_control = true;
        }
        if overlaps(a0, a1, 0x0600, 0x0600 + FMMU_LEN * FMMU_COUNT) {
            self.dirty.fmmu = true;
        }
        if overlaps(a0, a1, 0x0800, 0x0800 + SM_LEN * SM_COUNT) {
            for n in 0..SM_COUNT {
                let s = 0x0800 + SM_LEN * n;
                if overlaps(a0, a1, s, s + SM_LEN) {
                    self.dirty.sm |= 1 << n;
                }
            }
        }
        if overlaps(a0, a1, 0x0900, 0x0910) {
            self.dirty.dc_latch = true;
        }
        if overlaps(a0, a1, 0x0910, 0x0918) && !self.dirty.system_time {
            self.dirty.system_time = true;
            // Bytes the datagram does not cover keep the current system time.
            self.systime_write = self.system_time_at(self.now).to_le_bytes();
        }
        if overlaps(a0, a1, 0x0930, 0x0932) {
            self.dirty.speed_counter_start = true;
        }
        if overlaps(a0, a1, 0x0990, 0x0998) {
            self.dirty.sync_start = true;
        }
    }

    // ---------------------------------------------------------------- side effects

    fn after_datagram<H: AlHook>(&mut self, hook: &mut H) {
        let d = core::mem::take(&mut self.dirty);
        if d.sm != 0 {
            self.sm_config_written(d.sm, hook);
        }
        if d.fmmu {
            self.refresh_fmmus();
        }
        if d.sii_control {
            self.sii_command();
        }
        if d.dc_latch {
            self.dc_latch();
        }
        if d.system_time {
            self.dc_system_time_written();
        }
        if d.speed_counter_start {
            self.dc_filters_reset();
        }
        if d.sync_start {
            self.sync0_start = self.rd64(R::DcSyncStartTime.addr());
        }
        if d.al_control {
            self.al_control_written(hook);
        }
    }

    fn read_sm_block(&self, n: usize) -> SyncManager {
        let mut b = [0u8; SM_LEN];
        let a = usize::from(R::sync_manager(n as u8));
        if let Some(src) = self.mem.get(a..a + SM_LEN) {
            b.copy_from_slice(src);
        }
        SyncManager::from_bytes(&b)
    }

    fn refresh_all_sms(&mut self) {
        for n in 0..SM_COUNT {
            let s = self.read_sm_block(n);
            if let Some(c) = self.sms.get_mut(n) {
                *c = s;
            }
        }
        self.recompute_active_sms();
    }

    fn recompute_active_sms(&mut self) {
        self.active_sms = 0;
        for (n, s) in self.sms.iter().enumerate() {
            if s.is_active() {
                self.active_sms |= 1 << n;
            }
        }
    }

    fn refresh_fmmus(&mut self) {
        self.active_fmmus = 0;
        for n in 0..FMMU_COUNT {
            let a = usize::from(R::fmmu(n as u8));
            let mut b = [0u8; FMMU_LEN];
            if let Some(src) = self.mem.get(a..a + FMMU_LEN) {
                b.copy_from_slice(src);
            }
            let f = Fmmu::from_bytes(&b);
            if f.is_active() && f.bit_count() > 0 {
                self.active_fmmus |= 1 << n;
            }
            if let Some(c) = self.fmmus.get_mut(n) {
                *c = f;
            }
        }
    }

    fn sm_config_written<H: AlHook>(&mut self, mask: u16, hook: &mut H) {
        let mut changed = 0u16;
        for n in 0..SM_COUNT {
            if mask & (1 << n) == 0 {
                continue;
            }
            let new = self.read_sm_block(n);
            let old = self.sm(n);
            if let Some(c) = self.sms.get_mut(n) {
                *c = new;
            }
            if !old.layout_eq(&new) {
                changed |= 1 << n;
                // A reconfigured SM starts empty (mailbox) / with no buffer written.
                let status = if new.mode() == SmMode::Buffered {
                    STATUS_BUFFER_MASK
                } else {
                    0
                };
                self.set_sm_status(n, status);
                if n == SM_OUTPUTS {
                    self.pd_out_new = false;
                }
            }
            if n == SM_MAILBOX_IN && self.mailbox_running {
                let s = self.sm(n);
                let request = s.activate & sm::ACTIVATE_REPEAT != 0;
                let ack = s.pdi_control & sm::PDI_REPEAT_ACK != 0;
                if request != ack {
                    self.mailbox_repeat();
                }
            }
        }
        self.recompute_active_sms();
        // Autonomous fall-backs (spec §4.2): SMs reconfigured invalidly while in use.
        let state = self.al_state();
        if changed & 0b0011 != 0 && self.mailbox_running && self.check_mailbox_sms().is_err() {
            self.fall_back_with(
                AlState::Init,
                AlStatusCode::INVALID_MAILBOX_CONFIGURATION,
                hook,
            );
        } else if changed & 0b1100 != 0 && matches!(state, AlState::SafeOp | AlState::Op) {
            if let Err(code) = self.check_process_data_structure() {
                self.fall_back_with(AlState::PreOp, code, hook);
            }
        }
    }

    /// Repeat request (§5.4): post the last reply again and acknowledge.
    fn mailbox_repeat(&mut self) {
        let s = self.sm(SM_MAILBOX_IN);
        let len = self.mbx_backup_len;
        if len > 0 && s.is_active() && len <= usize::from(s.length) {
            let mut backup = [0u8; MAILBOX_MAX];
            if let (Some(b), Some(src)) = (backup.get_mut(..len), self.mbx_backup.get(..len)) {
                b.copy_from_slice(src);
            }
            if let Some(w) = self.window_mut(s.start, s.length) {
                w.fill(0);
                if let (Some(d), Some(src)) = (w.get_mut(..len), backup.get(..len)) {
                    d.copy_from_slice(src);
                }
            }
            self.set_sm_status(
                SM_MAILBOX_IN,
                (s.status | STATUS_MAILBOX_FULL) & !STATUS_IRQ_READ,
            );
        }
        let pdi = (s.pdi_control & !sm::PDI_REPEAT_ACK) | (s.activate & sm::ACTIVATE_REPEAT);
        self.set_sm_pdi_control(SM_MAILBOX_IN, pdi);
    }

    fn sii_command(&mut self) {
        let a = R::SiiControl.addr();
        let control = self.rd16(a);
        let mut status = eeprom::READ_SIZE_8;
        let addr = self.rd32(R::SiiAddress.addr());
        match SiiCommand::from_control(control) {
            SiiCommand::Nop => {}
            SiiCommand::Read => {
                for i in 0..4u32 {
                    let w = self.eeprom.word(addr.wrapping_add(i));
                    self.wr16(R::SiiData.addr() + 2 * i as u16, w);
                }
            }
            SiiCommand::Write => {
                if control & eeprom::WRITE_ENABLE == 0 {
                    status |= eeprom::WRITE_ENABLE_ERROR;
                } else {
                    let v = self.rd16(R::SiiData.addr());
                    if !self.eeprom.write_word(addr, v) {
                        status |= eeprom::ACK_ERROR;
                    }
                }
            }
            SiiCommand::Reload => {}
            SiiCommand::Invalid(_) => status |= eeprom::ACK_ERROR,
        }
        self.wr16(a, status);
    }

    fn dc_latch(&mut self) {
        let t = self.local_time_at(self.now);
        for p in 0..4u16 {
            self.wr32(R::DcReceiveTimePort0.addr() + 4 * p, t as u32);
        }
        self.wr64(R::DcReceiveTimeProcessingUnit.addr(), t);
    }

    fn dc_system_time_written(&mut self) {
        let written = u64::from_le_bytes(self.systime_write);
        let delay = u64::from(self.rd32(R::DcSystemTimeDelay.addr()));
        let received = written.wrapping_add(delay);
        let local_copy = self.system_time_at(self.now);
        let diff = received.wrapping_sub(local_copy) as i64;
        let magnitude = diff.unsigned_abs().min(0x7FFF_FFFF) as u32;
        let sign = if diff <= 0 { 0x8000_0000 } else { 0 };
        self.wr32(R::DcSystemTimeDifference.addr(), sign | magnitude);
        let offset = self.rd64(R::DcSystemTimeOffset.addr());
        self.wr64(
            R::DcSystemTimeOffset.addr(),
            offset.wrapping_add(diff as u64),
        );
    }

    /// A write to the speed counter start 0x0930 resets the time-control loop's filters: the
    /// system time difference 0x092C and the speed counter difference 0x0932 start again from
    /// 0 (ESC datasheet section II, 0x0930; masters write it right after zeroing 0x0910 in
    /// their DC reset, spec §8.1). Without it the reference clock, which never receives a
    /// system time again (FRMW reads it), would show the difference of that reset write for
    /// ever, and ethercrab's alignment check on 0x092C (examples/dc.rs) would never settle.
    fn dc_filters_reset(&mut self) {
        self.wr32(R::DcSystemTimeDifference.addr(), 0);
        self.wr16(R::DcSpeedCounterDifference.addr(), 0);
    }

    // ---------------------------------------------------------------- AL state machine

    fn set_al_status(&mut self, state: AlState, error: bool, code: AlStatusCode) {
        let v = AlStatus { state, error }.to_u16();
        if v != self.rd16(R::AlStatus.addr()) {
            let ev = self.rd16(R::EcatEventRequest.addr()) | EVENT_AL_STATUS;
            self.wr16(R::EcatEventRequest.addr(), ev);
        }
        self.wr16(R::AlStatus.addr(), v);
        self.wr16(R::AlStatusCode.addr(), code.0);
    }

    fn al_control_written<H: AlHook>(&mut self, hook: &mut H) {
        let control = AlControl::from_u16(self.rd16(R::AlControl.addr()));
        let status = self.al_status();
        // §4.2 step 2: with the error bit set, only an acknowledging request is served.
        if status.error && !control.error_ack {
            return;
        }
        let from = status.state;
        if control.error_ack {
            self.set_al_status(from, false, AlStatusCode::NO_ERROR);
        }
        let to = match check_transition(from, control.requested, self.config.bootstrap_supported) {
            Ok(to) => to,
            Err(code) => {
                self.set_al_status(from, true, code);
                return;
            }
        };
        if to == from {
            return;
        }
        if is_upward(from, to) {
            let checked = self
                .builtin_check(from, to)
                .and_then(|()| hook.check_transition(self, from, to));
            if let Err(code) = checked {
                self.set_al_status(from, true, code);
                return;
            }
        }
        self.enter_state(from, to, false, AlStatusCode::NO_ERROR);
        hook.state_changed(self, from, to);
    }

    fn builtin_check(&self, from: AlState, to: AlState) -> Result<(), AlStatusCode> {
        match (from, to) {
            (AlState::Init, AlState::PreOp) => self.check_mailbox_sms(),
            (AlState::PreOp, AlState::SafeOp) => self.check_process_data_structure(),
            (AlState::SafeOp, AlState::Op)
                if self.config.require_outputs_for_op && !self.outputs_seen =>
            {
                Err(AlStatusCode::NO_VALID_OUTPUTS)
            }
            _ => Ok(()),
        }
    }

    fn enter_state(&mut self, from: AlState, to: AlState, error: bool, code: AlStatusCode) {
        self.set_al_status(to, error, code);
        match to {
            AlState::Init | AlState::Bootstrap => {
                self.mailbox_running = false;
                self.clear_mailboxes();
                self.pd_out_new = false;
                self.wd_last = None;
            }
            AlState::PreOp => {
                if matches!(from, AlState::Init | AlState::Bootstrap) {
                    // Start the mailbox handler: both mailboxes empty, repeat-ack = request.
                    self.clear_mailboxes();
                    let s = self.sm(SM_MAILBOX_IN);
                    let pdi =
                        (s.pdi_control & !sm::PDI_REPEAT_ACK) | (s.activate & sm::ACTIVATE_REPEAT);
                    self.set_sm_pdi_control(SM_MAILBOX_IN, pdi);
                    self.mbx_backup_len = 0;
                    self.mailbox_running = true;
                }
                self.pd_out_new = false;
                self.wd_last = None;
            }
            AlState::SafeOp => {
                if from == AlState::PreOp {
                    self.outputs_seen = false;
                }
                self.wd_last = None;
            }
            AlState::Op => {
                self.wd_last = Some(self.now);
            }
        }
    }

    fn clear_mailboxes(&mut self) {
        for n in [SM_MAILBOX_OUT, SM_MAILBOX_IN] {
            let s = self.sm(n);
            if s.mode() == SmMode::Mailbox {
                self.set_sm_status(
                    n,
                    s.status & !(STATUS_MAILBOX_FULL | STATUS_IRQ_WRITE | STATUS_IRQ_READ),
                );
            }
        }
    }

    fn fall_back_with<H: AlHook>(&mut self, to: AlState, code: AlStatusCode, hook: &mut H) {
        let from = self.al_state();
        let target = if is_upward(from, to) { from } else { to };
        self.enter_state(from, target, true, code);
        if target != from {
            hook.state_changed(self, from, target);
        }
    }

    /// The device drops the slave to `to` (not above the current state) with the error bit
    /// and `code`, e.g. a synchronisation error (0x001A) in Op. The hook is not called: the
    /// device knows.
    pub fn fall_back(&mut self, to: AlState, code: AlStatusCode) {
        self.fall_back_with(to, code, &mut NoHook);
    }

    /// Init → Pre-Op check of SM0/SM1 against the configured mailbox (§4.2 table).
    pub fn check_mailbox_sms(&self) -> Result<(), AlStatusCode> {
        let Some(m) = self.config.mailbox else {
            return Ok(());
        };
        let rx = self.sm(SM_MAILBOX_OUT);
        let tx = self.sm(SM_MAILBOX_IN);
        let ok = rx.is_enabled()
            && rx.start == m.rx_offset
            && rx.length == m.rx_size
            && rx.mode() == SmMode::Mailbox
            && rx.direction() == SmDirection::Write
            && tx.is_enabled()
            && tx.start == m.tx_offset
            && tx.length == m.tx_size
            && tx.mode() == SmMode::Mailbox
            && tx.direction() == SmDirection::Read
            && !tx.overlaps(u32::from(rx.start), usize::from(rx.length))
            && usize::from(rx.length) <= MAILBOX_MAX
            && usize::from(tx.length) <= MAILBOX_MAX;
        if ok {
            Ok(())
        } else {
            Err(AlStatusCode::INVALID_MAILBOX_CONFIGURATION)
        }
    }

    /// The ESC's structural Pre-Op → Safe-Op check: an enabled SM2 is buffered with the
    /// master writing (else 0x001D), an enabled SM3 buffered with the master reading (else
    /// 0x001E), and no two of SM0–SM3 overlap (3 × length for buffered SMs; else 0x0017).
    pub fn check_process_data_structure(&self) -> Result<(), AlStatusCode> {
        let out = self.sm(SM_OUTPUTS);
        if out.is_active()
            && (out.mode() != SmMode::Buffered || out.direction() != SmDirection::Write)
        {
            return Err(AlStatusCode::INVALID_OUTPUT_CONFIGURATION);
        }
        let inp = self.sm(SM_INPUTS);
        if inp.is_active()
            && (inp.mode() != SmMode::Buffered || inp.direction() != SmDirection::Read)
        {
            return Err(AlStatusCode::INVALID_INPUT_CONFIGURATION);
        }
        if usize::from(out.length) > PROCESS_DATA_MAX && out.is_active() {
            return Err(AlStatusCode::INVALID_OUTPUT_CONFIGURATION);
        }
        for a in 0..4 {
            for b in (a + 1)..4 {
                let (sa, sb) = (self.sm(a), self.sm(b));
                if !sa.is_active() || !sb.is_active() {
                    continue;
                }
                if u32::from(sa.start) < sb.reserved_end()
                    && u32::from(sb.start) < sa.reserved_end()
                {
                    return Err(AlStatusCode::INVALID_SYNC_MANAGER_CONFIGURATION);
                }
            }
        }
        Ok(())
    }

    /// Pre-Op → Safe-Op check for a device that needs `outputs` bytes in SM2 and `inputs`
    /// bytes in SM3 (§4.2 table): with data, the SM must be enabled with exactly that length
    /// (buffered, right direction); without, it must be disabled or have length 0 (both are
    /// what masters write). Failures: 0x001D outputs, 0x001E inputs; then the structural
    /// check.
    pub fn check_process_data(&self, outputs: u16, inputs: u16) -> Result<(), AlStatusCode> {
        let fits = |s: SyncManager, len: u16, dir: SmDirection| {
            if len == 0 {
                !s.is_active()
            } else {
                s.is_enabled()
                    && s.length == len
                    && s.mode() == SmMode::Buffered
                    && s.direction() == dir
            }
        };
        if !fits(self.sm(SM_OUTPUTS), outputs, SmDirection::Write) {
            return Err(AlStatusCode::INVALID_OUTPUT_CONFIGURATION);
        }
        if !fits(self.sm(SM_INPUTS), inputs, SmDirection::Read) {
            return Err(AlStatusCode::INVALID_INPUT_CONFIGURATION);
        }
        self.check_process_data_structure()
    }

    // ---------------------------------------------------------------- watchdog

    fn watchdog_timeout_ns(&self) -> Option<u64> {
        let t = u64::from(self.rd16(R::WatchdogTimeProcessData.addr()));
        let div = u64::from(self.rd16(R::WatchdogDivider.addr()));
        (t != 0).then(|| t * (div + 2) * 40)
    }

    fn watchdog_armed(&self) -> bool {
        let out = self.sm(SM_OUTPUTS);
        self.al_state() == AlState::Op
            && out.is_active()
            && out.control & sm::CONTROL_WATCHDOG != 0
            && self
                .fmmus
                .iter()
                .enumerate()
                .any(|(i, f)| self.active_fmmus & (1 << i) != 0 && f.write_enable)
    }

    fn check_watchdog<H: AlHook>(&mut self, hook: &mut H) {
        let (Some(timeout), Some(last)) = (self.watchdog_timeout_ns(), self.wd_last) else {
            return;
        };
        if !self.watchdog_armed()
            || self.now.saturating_since(last).as_nanos() <= u128::from(timeout)
        {
            return;
        }
        let st = self.rd16(R::WatchdogStatusProcessData.addr()) & !1;
        self.wr16(R::WatchdogStatusProcessData.addr(), st);
        let a = R::WatchdogCounterProcessData.addr();
        let c = self.rd8(a);
        self.wr8(a, c.saturating_add(1));
        self.wd_last = None;
        self.fall_back_with(AlState::SafeOp, AlStatusCode::SYNC_MANAGER_WATCHDOG, hook);
    }

    // ---------------------------------------------------------------- PDI side

    /// Take the message the master wrote into the receive mailbox (SM0), if there is one:
    /// the whole SM window (header and padding; parse it with [`crate::mailbox::Mailbox`]).
    /// Taking it empties the mailbox, so the master may write the next one.
    pub fn mailbox_read(&mut self) -> Option<&[u8]> {
        if !self.mailbox_running {
            return None;
        }
        let s = self.sm(SM_MAILBOX_OUT);
        if !s.is_active()
            || s.mode() != SmMode::Mailbox
            || s.direction() != SmDirection::Write
            || !s.is_mailbox_full()
        {
            return None;
        }
        self.set_sm_status(
            SM_MAILBOX_OUT,
            s.status & !(STATUS_MAILBOX_FULL | STATUS_IRQ_WRITE),
        );
        self.window(s.start, s.length)
    }

    /// The send mailbox (SM1) can take a message.
    pub fn mailbox_write_ready(&self) -> bool {
        let s = self.sm(SM_MAILBOX_IN);
        self.mailbox_running
            && s.is_active()
            && s.mode() == SmMode::Mailbox
            && s.direction() == SmDirection::Read
            && !s.is_mailbox_full()
    }

    /// Post a message (mailbox header included) into the send mailbox (SM1); the rest of
    /// the window is zeroed and "mailbox full" set. A copy is kept for the repeat request.
    pub fn mailbox_write(&mut self, msg: &[u8]) -> Result<(), PdiError> {
        if !self.mailbox_running {
            return Err(PdiError::NotRunning);
        }
        let s = self.sm(SM_MAILBOX_IN);
        if !s.is_active() || s.mode() != SmMode::Mailbox || s.direction() != SmDirection::Read {
            return Err(PdiError::NotConfigured);
        }
        if s.is_mailbox_full() {
            return Err(PdiError::Busy);
        }
        if msg.len() > usize::from(s.length) || msg.len() > MAILBOX_MAX {
            return Err(PdiError::TooLong);
        }
        let Some(w) = self.window_mut(s.start, s.length) else {
            return Err(PdiError::NotConfigured);
        };
        w.fill(0);
        if let Some(d) = w.get_mut(..msg.len()) {
            d.copy_from_slice(msg);
        }
        if let Some(b) = self.mbx_backup.get_mut(..msg.len()) {
            b.copy_from_slice(msg);
            self.mbx_backup_len = msg.len();
        }
        self.set_sm_status(
            SM_MAILBOX_IN,
            (s.status | STATUS_MAILBOX_FULL) & !STATUS_IRQ_READ,
        );
        Ok(())
    }

    /// The newest complete output buffer (SM2) if the master completed one since the last
    /// call. The ESC hands it over in every state; the device applies set-points only in Op
    /// (spec/cmmp-as-1-communication.md §4.2: Safe-Op ignores set-points).
    pub fn process_outputs(&mut self) -> Option<&[u8]> {
        if !self.pd_out_new {
            return None;
        }
        self.pd_out_new = false;
        let s = self.sm(SM_OUTPUTS);
        self.set_sm_status(SM_OUTPUTS, s.status & !STATUS_IRQ_WRITE);
        self.pd_out.get(..self.pd_out_len)
    }

    /// The newest complete output buffer, whether or not it was taken already (empty
    /// before the first complete write).
    pub fn outputs(&self) -> &[u8] {
        self.pd_out.get(..self.pd_out_len).unwrap_or(&[])
    }

    /// Write a complete input buffer (SM3); the master's next read returns it. `data` may be
    /// shorter than the SM (the rest keeps its content).
    pub fn set_inputs(&mut self, data: &[u8]) -> Result<(), PdiError> {
        let s = self.sm(SM_INPUTS);
        if !s.is_active() || s.mode() != SmMode::Buffered || s.direction() != SmDirection::Read {
            return Err(PdiError::NotConfigured);
        }
        if data.len() > usize::from(s.length) {
            return Err(PdiError::TooLong);
        }
        let Some(w) = self.window_mut(s.start, s.length) else {
            return Err(PdiError::NotConfigured);
        };
        if let Some(d) = w.get_mut(..data.len()) {
            d.copy_from_slice(data);
        }
        let last = (s.status & STATUS_BUFFER_MASK) >> 4;
        let next = if last >= 2 { 0 } else { last + 1 };
        self.set_sm_status(
            SM_INPUTS,
            (s.status & !(STATUS_BUFFER_MASK | STATUS_IRQ_READ)) | (next << 4),
        );
        Ok(())
    }
}

/// Pass one Ethernet frame through `slaves` in ring order, as the frame travels through a
/// line of ESCs: auto-increment addresses and working counters add up. Returns the first
/// slave's outcome (a frame one slave drops goes no further).
pub fn process_chain(slaves: &mut [Esc<'_>], now: Instant, frame: &mut [u8]) -> FrameOutcome {
    let mut first = None;
    for s in slaves.iter_mut() {
        let o = s.process(now, frame);
        let outcome = *first.get_or_insert(o);
        if !o.forward() {
            return outcome;
        }
    }
    first.unwrap_or(FrameOutcome::Processed { datagrams: 0 })
}

/// [`process_chain`] with one hook per slave (`hooks[i]` for `slaves[i]`; slaves without a
/// hook accept every transition).
pub fn process_chain_with<H: AlHook>(
    slaves: &mut [Esc<'_>],
    hooks: &mut [H],
    now: Instant,
    frame: &mut [u8],
) -> FrameOutcome {
    let mut first = None;
    let mut hooks = hooks.iter_mut();
    for s in slaves.iter_mut() {
        let o = match hooks.next() {
            Some(h) => s.process_with(now, frame, h),
            None => s.process(now, frame),
        };
        let outcome = *first.get_or_insert(o);
        if !o.forward() {
            return outcome;
        }
    }
    first.unwrap_or(FrameOutcome::Processed { datagrams: 0 })
}
