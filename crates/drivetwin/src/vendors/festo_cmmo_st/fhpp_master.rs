//! An FHPP master for the Festo CMMO-ST over Modbus TCP, as a PLC drives it (manual
//! GDCP-CMMO-ST-LK-C-HP §4.3 and ch. 5–6): one connection, the 8-byte output telegram written and
//! the input telegram read with one FC 0x17 (start address 0, 4 registers, or 8 with the parameter
//! channel) every cycle, and the handshakes of the state machine and of the start / acknowledge
//! protocol on top.
//!
//! The CMMO-ST serves one Modbus client and may watch the connection (the "Node Guard /
//! Timeout" watchdog), so a command keeps exchanging telegrams every cycle while it waits and
//! uses the one connection for everything.
//!
//! A command that connects to a drive some other master left running takes the state over
//! as it is: it first reads the input telegram (FC 0x03, which writes nothing) and builds its
//! first output telegram from it (ENABLE / STOP / OPM as the status shows them), so connecting
//! does not stop a drive.

pub mod diagnostics;
pub mod parameter;

use std::time::Duration;

use drive::vendors::festo_cmmo_st::fhpp::{
    Ccon, Cdir, ControlMode, Cpos, InputData, OperatingMode, OutputData, Scon, Spos,
};

use drive::vendors::festo_cmmo_st::fhpp::parameter_channel::ErrorCode;

use crate::master::modbus_tcp::{ModbusTcpClient, ModbusTcpError};

/// Registers of the FHPP Standard telegram (8 bytes).
const STD_REGISTERS: usize = 4;
/// Registers of the FHPP + FPC telegram (16 bytes).
const FPC_REGISTERS: usize = 8;

/// Why an FHPP command did not complete.
#[derive(Debug, thiserror::Error)]
pub enum FhppError {
    #[error(transparent)]
    Modbus(#[from] ModbusTcpError),
    /// The drive cannot take the command in its present state (the master sees why in the
    /// status bytes, before it sends anything that would fail).
    #[error("{command} refused: {reason} (SCON {scon}, SPOS {spos})")]
    Refused {
        command: &'static str,
        reason: &'static str,
        scon: Scon,
        spos: Spos,
    },
    /// SCON.FAULT: the drive reports a fault; `number` is the FC 0x07 exception status.
    #[error("{command}: fault {number:02X}h {name} (SCON {scon}, SPOS {spos})")]
    Fault {
        command: &'static str,
        number: u8,
        name: &'static str,
        scon: Scon,
        spos: Spos,
    },
    /// The parameter channel answered ResID 7 with a Tab. C.7 error code.
    #[error("PNU {pnu}:{subindex}: parameter channel error {code}")]
    Parameter {
        pnu: u16,
        subindex: u8,
        code: ErrorCode,
    },
    #[error("the parameter channel needs the 16-byte telegram (MasterConfig::parameter_channel)")]
    NoParameterChannel,
    #[error("{0}")]
    Protocol(&'static str),
    #[error("{command}: {want} not reached within {timeout:?} (SCON {scon}, SPOS {spos})")]
    Timeout {
        command: &'static str,
        want: &'static str,
        timeout: Duration,
        scon: Scon,
        spos: Spos,
    },
}

/// The state of the FHPP state machine as the status bytes show it (Fig. 5.1, Tab. 5.21).
pub fn state_name(scon: Scon) -> &'static str {
    if scon.contains(Scon::FAULT) {
        "S6 fault"
    } else if scon.contains(Scon::ENABLED | Scon::OPEN) {
        "S4 operation enabled"
    } else if scon.contains(Scon::ENABLED) {
        "S3 drive enabled"
    } else {
        "S2 drive disabled"
    }
}

/// The operating-mode feedback as a word.
pub fn mode_name(mode: OperatingMode) -> &'static str {
    match mode {
        OperatingMode::RecordSelection => "record selection",
        OperatingMode::Direct => "direct",
        OperatingMode::Reserved(_) => "reserved",
    }
}

/// The decoded input telegram, as `drivetwin fhpp` prints it.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Status {
    pub state: &'static str,
    pub mode: &'static str,
    pub scon: u8,
    /// SCON bit names, e.g. `VLOAD|OPEN|ENABLED (0001.0011)`.
    pub scon_bits: String,
    pub spos: u8,
    pub spos_bits: String,
    /// Record selection: the record number feedback; direct mode: SDIR.
    pub byte3: u8,
    /// Record selection: RSB; direct mode: actual value 1 (velocity % in position mode).
    pub byte4: u8,
    /// Bits of byte 3 (SDIR, direct mode) or byte 4 (RSB, record selection).
    pub byte_bits: String,
    /// Bytes 5…8: the actual position \[SINC\] (record selection, direct position mode).
    pub actual: i32,
    /// FC 0x07: the fault number, `None` without a fault.
    pub fault: Option<u8>,
    pub fault_name: Option<&'static str>,
}

impl Status {
    pub fn new(input: &InputData, fault: u8) -> Status {
        let mode = input.scon.operating_mode();
        let byte_bits = match mode {
            OperatingMode::Direct => input.sdir().to_string(),
            _ => input.rsb().to_string(),
        };
        let fault = (fault != 0).then_some(fault);
        Status {
            state: state_name(input.scon),
            mode: mode_name(mode),
            scon: input.scon.bits(),
            scon_bits: input.scon.to_string(),
            spos: input.spos.bits(),
            spos_bits: input.spos.to_string(),
            byte3: input.byte3,
            byte4: input.byte4,
            byte_bits,
            actual: input.actual2,
            fault,
            fault_name: fault.map(diagnostics::name),
        }
    }

    /// Several lines of text.
    pub fn to_text(&self) -> String {
        let mut s = format!(
            "{}, {}{}\nSCON {:02X}h {}\nSPOS {:02X}h {}\n",
            self.state,
            self.mode,
            if self.scon & Scon::FCT_MMI.bits() != 0 {
                ", FCT / web server has device control"
            } else {
                ""
            },
            self.scon,
            self.scon_bits,
            self.spos,
            self.spos_bits
        );
        if self.mode == "direct" {
            s += &format!(
                "SDIR {:02X}h {}\nactual value 1 {}\nactual value 2 {}",
                self.byte3, self.byte_bits, self.byte4, self.actual
            );
        } else {
            s += &format!(
                "record {}\nRSB {:02X}h {}\nposition {} SINC",
                self.byte3, self.byte4, self.byte_bits, self.actual
            );
        }
        if let (Some(n), Some(name)) = (self.fault, self.fault_name) {
            s += &format!("\nfault {n:02X}h {name}");
        }
        s
    }
}

/// How the master talks to the drive.
#[derive(Debug, Clone)]
pub struct MasterConfig {
    /// The cycle: one FC 0x17 exchange per period while a command waits.
    pub cycle: Duration,
    /// Longest wait for one Modbus response.
    pub response_timeout: Duration,
    /// Exchange 16 bytes (FHPP + FPC) instead of 8.
    pub parameter_channel: bool,
    /// Keep CCON.LOCK set: FCT and the web server cannot take device control.
    pub lock: bool,
}

impl Default for MasterConfig {
    fn default() -> Self {
        MasterConfig {
            cycle: Duration::from_millis(10),
            response_timeout: Duration::from_secs(1),
            parameter_channel: false,
            lock: false,
        }
    }
}

/// One FHPP master on one Modbus TCP connection.
pub struct FhppMaster {
    link: ModbusTcpClient,
    config: MasterConfig,
    out: OutputData,
    fpc_out: [u8; 8],
    input: InputData,
    fpc_in: [u8; 8],
}

impl FhppMaster {
    /// Connects and reads the input telegram (FC 0x03); nothing is written yet.
    pub async fn connect(addr: &str, config: MasterConfig) -> Result<FhppMaster, FhppError> {
        let link = ModbusTcpClient::connect(addr, config.response_timeout).await?;
        let mut m = FhppMaster {
            link,
            config,
            out: OutputData::default(),
            fpc_out: [0; 8],
            input: InputData::default(),
            fpc_in: [0; 8],
        };
        m.read().await?;
        m.out = m.takeover_outputs();
        Ok(m)
    }

    /// The last input telegram.
    pub fn input(&self) -> &InputData {
        &self.input
    }

    /// The last EFPC input bytes (FPCS first; zero without the parameter channel).
    pub fn fpc_input(&self) -> [u8; 8] {
        self.fpc_in
    }

    /// Sets the EFPC output bytes (FPCC first) sent from the next cycle on.
    pub fn set_fpc_output(&mut self, bytes: [u8; 8]) {
        self.fpc_out = bytes;
    }

    /// The output telegram that keeps the drive as the status shows it.
    fn takeover_outputs(&self) -> OutputData {
        let scon = self.input.scon;
        let ccon = Ccon::EMPTY
            .with(Ccon::ENABLE, scon.contains(Scon::ENABLED))
            .with(Ccon::STOP, scon.contains(Scon::OPEN))
            .with(Ccon::LOCK, self.config.lock)
            .with_operating_mode(scon.operating_mode());
        let byte3 = match scon.operating_mode() {
            // SDIR's ABS / COM bits sit where CDIR has them.
            OperatingMode::Direct => self.input.byte3 & (Cdir::ABS | Cdir::COM1 | Cdir::COM2).0,
            _ => self.input.byte3,
        };
        OutputData {
            ccon,
            cpos: Cpos::HALT,
            byte3,
            byte4: 0,
            setpoint2: 0,
        }
    }

    fn registers(&self) -> usize {
        if self.config.parameter_channel {
            FPC_REGISTERS
        } else {
            STD_REGISTERS
        }
    }

    fn take_input(&mut self, regs: &[u16; FPC_REGISTERS]) {
        let mut bytes = [0u8; 16];
        for (chunk, r) in bytes.chunks_exact_mut(2).zip(regs) {
            chunk.copy_from_slice(&r.to_be_bytes());
        }
        let (fhpp, fpc) = bytes.split_at(8);
        let mut b = [0u8; 8];
        b.copy_from_slice(fhpp);
        self.input = InputData::from_bytes(b);
        if self.config.parameter_channel {
            self.fpc_in.copy_from_slice(fpc);
        }
    }

    /// FC 0x03: reads the input telegram without writing.
    pub async fn read(&mut self) -> Result<&InputData, FhppError> {
        let mut regs = [0u16; FPC_REGISTERS];
        let n = self.registers();
        #[allow(
            clippy::indexing_slicing,
            reason = "registers() is STD_REGISTERS or FPC_REGISTERS, the array's length"
        )]
        let read = &mut regs[..n];
        self.link.read_holding(0, read).await?;
        self.take_input(&regs);
        Ok(&self.input)
    }

    /// One cycle: FC 0x17 writes the output telegram and reads the input telegram.
    pub async fn exchange(&mut self) -> Result<&InputData, FhppError> {
        let mut image = [0u8; 16];
        let telegram = self.out.to_bytes().into_iter().chain(self.fpc_out);
        for (dst, src) in image.iter_mut().zip(telegram) {
            *dst = src;
        }
        let mut values = [0u16; FPC_REGISTERS];
        for (v, chunk) in values.iter_mut().zip(image.chunks_exact(2)) {
            if let [hi, lo] = *chunk {
                *v = u16::from_be_bytes([hi, lo]);
            }
        }
        let n = self.registers();
        let mut regs = [0u16; FPC_REGISTERS];
        #[allow(
            clippy::indexing_slicing,
            reason = "registers() is STD_REGISTERS or FPC_REGISTERS, the arrays' length"
        )]
        let (read, write) = (&mut regs[..n], &values[..n]);
        self.link.read_write(0, read, 0, write).await?;
        self.take_input(&regs);
        Ok(&self.input)
    }

    /// FC 0x07: the fault number (0 = no fault).
    pub async fn fault_number(&mut self) -> Result<u8, FhppError> {
        Ok(self.link.exception_status().await?)
    }

    /// The status with the fault number.
    pub async fn status(&mut self) -> Result<Status, FhppError> {
        let fault = self.fault_number().await?;
        Ok(Status::new(&self.input, fault))
    }

    async fn fault_error(&mut self, command: &'static str) -> FhppError {
        let number = match self.fault_number().await {
            Ok(n) => n,
            Err(e) => return e,
        };
        FhppError::Fault {
            command,
            number,
            name: diagnostics::name(number),
            scon: self.input.scon,
            spos: self.input.spos,
        }
    }

    fn refused(&self, command: &'static str, reason: &'static str) -> FhppError {
        FhppError::Refused {
            command,
            reason,
            scon: self.input.scon,
            spos: self.input.spos,
        }
    }

    /// Exchanges every cycle until `done` holds for the input telegram. A fault ends the wait
    /// with [`FhppError::Fault`] unless `faults_ok`.
    async fn wait(
        &mut self,
        command: &'static str,
        want: &'static str,
        timeout: Duration,
        faults_ok: bool,
        done: impl Fn(&InputData) -> bool,
    ) -> Result<(), FhppError> {
        self.wait_for(command, want, timeout, faults_ok, |input, _| done(input))
            .await
    }

    /// Exchanges every cycle until `done` holds for the EFPC input bytes (faults do not end
    /// the wait: the parameter channel works in every state).
    async fn wait_fpc(
        &mut self,
        command: &'static str,
        want: &'static str,
        timeout: Duration,
        done: impl Fn(&[u8; 8]) -> bool,
    ) -> Result<(), FhppError> {
        self.wait_for(command, want, timeout, true, |_, fpc| done(fpc))
            .await
    }

    /// One FC 0x17 exchange every PLC cycle until `done` holds for the input telegram and the
    /// EFPC input bytes; a fault ends it unless `faults_ok`, and so does `timeout`.
    async fn wait_for(
        &mut self,
        command: &'static str,
        want: &'static str,
        timeout: Duration,
        faults_ok: bool,
        done: impl Fn(&InputData, &[u8; 8]) -> bool,
    ) -> Result<(), FhppError> {
        let deadline = tokio::time::Instant::now() + timeout;
        let mut tick = tokio::time::interval(self.config.cycle);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tick.tick().await;
            let input = *self.exchange().await?;
            if !faults_ok && input.scon.contains(Scon::FAULT) {
                return Err(self.fault_error(command).await);
            }
            if done(&input, &self.fpc_in) {
                return Ok(());
            }
            if tokio::time::Instant::now() >= deadline {
                return Err(FhppError::Timeout {
                    command,
                    want,
                    timeout,
                    scon: input.scon,
                    spos: input.spos,
                });
            }
        }
    }

    fn check_authority(&self, command: &'static str) -> Result<(), FhppError> {
        if self.input.scon.contains(Scon::FCT_MMI) {
            // PNU 125 / B.2: FCT or the web server holds device control.
            return Err(self.refused(
                command,
                "FCT or the web server has device control (SCON.FCT/MMI; writing PNU 125 = 1 \
                 takes it back from the web server)",
            ));
        }
        Ok(())
    }

    /// Checks the drive is in S4 "operation enabled" without a fault, ready for a task.
    async fn check_operational(&mut self, command: &'static str) -> Result<(), FhppError> {
        self.check_authority(command)?;
        if self.input.scon.contains(Scon::FAULT) {
            return Err(self.fault_error(command).await);
        }
        if !self.input.scon.contains(Scon::ENABLED | Scon::OPEN) {
            return Err(self.refused(
                command,
                "the drive is not in S4 operation enabled (drivetwin fhpp enable)",
            ));
        }
        Ok(())
    }

    /// Takes control and runs the state machine to S4 "operation enabled": acknowledges a
    /// fault first (RESET rising edge with ENABLE = 0, T9), then ENABLE (T2, S2 → S3), then
    /// STOP (T3, S3 → S4). Ends with SCON.ENABLED and OPEN, e.g. SCON 13h SPOS 05h in record
    /// selection (§4.3 Example 2).
    pub async fn enable(&mut self, timeout: Duration) -> Result<(), FhppError> {
        const CMD: &str = "enable";
        self.check_authority(CMD)?;
        let mode = self.input.scon.operating_mode();
        self.out.cpos = Cpos::HALT;
        if self.input.scon.contains(Scon::FAULT) {
            // CMMO-ST Tab. 5.2 T9: RESET 0 → 1 with ENABLE = 0 acknowledges any fault.
            self.out.ccon = self.base_ccon(mode);
            self.exchange().await?;
            self.out.ccon = self.base_ccon(mode) | Ccon::RESET;
            let acknowledged = self
                .wait(
                    CMD,
                    "fault acknowledged (SCON.FAULT = 0)",
                    timeout,
                    true,
                    |i| !i.scon.contains(Scon::FAULT),
                )
                .await;
            if let Err(FhppError::Timeout { .. }) = acknowledged {
                // The cause is still there (T11): report the fault itself.
                return Err(self.fault_error(CMD).await);
            }
            acknowledged?;
            self.out.ccon = self.base_ccon(mode);
            self.exchange().await?;
        }
        if self.input.scon.contains(Scon::ENABLED | Scon::OPEN) {
            self.out.ccon = self.base_ccon(mode) | Ccon::ENABLE | Ccon::STOP;
            self.exchange().await?;
            return Ok(());
        }
        if !self.input.scon.contains(Scon::VLOAD) {
            // T2 needs the load voltage.
            return Err(self.refused(CMD, "no load voltage (SCON.VLOAD = 0)"));
        }
        self.out.ccon = self.base_ccon(mode) | Ccon::ENABLE;
        self.wait(
            CMD,
            "S3 drive enabled (SCON.ENABLED)",
            timeout,
            false,
            |i| i.scon.contains(Scon::ENABLED),
        )
        .await?;
        self.out.ccon = self.base_ccon(mode) | Ccon::ENABLE | Ccon::STOP;
        self.wait(
            CMD,
            "S4 operation enabled (SCON.ENABLED + OPEN)",
            timeout,
            false,
            |i| i.scon.contains(Scon::ENABLED | Scon::OPEN),
        )
        .await
    }

    /// ENABLE = 0 (T5 / T6): the drive is disabled, the output stage off. In S6 "fault" a
    /// RESET rising edge with ENABLE = 0 (T9) leaves the fault for S2 as well.
    pub async fn disable(&mut self, timeout: Duration) -> Result<(), FhppError> {
        self.check_authority("disable")?;
        let mode = self.input.scon.operating_mode();
        self.out.ccon = self.base_ccon(mode);
        self.out.cpos = Cpos::HALT;
        if self.input.scon.contains(Scon::FAULT) {
            self.exchange().await?;
            self.out.ccon = self.base_ccon(mode) | Ccon::RESET;
        }
        self.wait(
            "disable",
            "S2 drive disabled (SCON.ENABLED = 0)",
            timeout,
            true,
            |i| !i.scon.contains(Scon::ENABLED),
        )
        .await?;
        self.out.ccon = self.base_ccon(mode);
        self.exchange().await?;
        Ok(())
    }

    /// CCON with LOCK as configured and the operating mode, ENABLE and STOP clear.
    fn base_ccon(&self, mode: OperatingMode) -> Ccon {
        Ccon::EMPTY
            .with(Ccon::LOCK, self.config.lock)
            .with_operating_mode(mode)
    }

    /// Homing with CPOS.HOM (TA7): HOM rising edge, wait for ACK, take HOM away, wait for
    /// ACK = 0 with MC and REF (§4.3 "homing done").
    pub async fn home(&mut self, timeout: Duration) -> Result<(), FhppError> {
        const CMD: &str = "home";
        self.check_operational(CMD).await?;
        self.out.cpos = Cpos::HALT;
        self.exchange().await?;
        self.handshake(CMD, Cpos::HOM, timeout, |i| i.spos.contains(Spos::REF))
            .await
    }

    /// Starts record `number` in record selection (§5.1, Fig. 6.3) and waits for MC.
    pub async fn record(&mut self, number: u8, timeout: Duration) -> Result<(), FhppError> {
        const CMD: &str = "record";
        self.check_operational(CMD).await?;
        self.out = OutputData::record(
            self.base_ccon(OperatingMode::RecordSelection) | Ccon::ENABLE | Ccon::STOP,
            Cpos::HALT,
            number,
        );
        self.select_mode(CMD, OperatingMode::RecordSelection, timeout)
            .await?;
        self.handshake(CMD, Cpos::START, timeout, |_| true).await
    }

    /// A direct-mode position task (§5.2, CDIR.COM = 00): `position` \[SINC\], absolute or
    /// relative (CDIR.ABS), at `velocity` % of PNU 540; waits for MC.
    pub async fn move_to(
        &mut self,
        position: i32,
        velocity: u8,
        relative: bool,
        timeout: Duration,
    ) -> Result<(), FhppError> {
        const CMD: &str = "move";
        self.check_operational(CMD).await?;
        let cdir = Cdir::EMPTY
            .with_control_mode(ControlMode::Position)
            .with(Cdir::ABS, relative);
        self.out = OutputData::direct(
            self.base_ccon(OperatingMode::Direct) | Ccon::ENABLE | Ccon::STOP,
            Cpos::HALT,
            cdir,
            velocity,
            position,
        );
        self.select_mode(CMD, OperatingMode::Direct, timeout)
            .await?;
        self.handshake(CMD, Cpos::START, timeout, |_| true).await
    }

    /// Waits for the operating-mode feedback (the change is taken in SA1 "ready" only).
    async fn select_mode(
        &mut self,
        command: &'static str,
        mode: OperatingMode,
        timeout: Duration,
    ) -> Result<(), FhppError> {
        let want = match mode {
            OperatingMode::Direct => "direct mode (SCON.OPM = 01)",
            _ => "record selection (SCON.OPM = 00)",
        };
        self.wait(command, want, timeout, false, |i| {
            i.scon.operating_mode() == mode
        })
        .await
    }

    /// The start handshake (Fig. 6.3): `bit` rising (START or HOM), wait for SPOS.ACK, take
    /// `bit` away, wait for ACK = 0 and MC (and `done`).
    async fn handshake(
        &mut self,
        command: &'static str,
        bit: Cpos,
        timeout: Duration,
        done: impl Fn(&InputData) -> bool,
    ) -> Result<(), FhppError> {
        let deadline = tokio::time::Instant::now() + timeout;
        self.out.cpos = Cpos::HALT | bit;
        self.wait(
            command,
            "start acknowledged (SPOS.ACK)",
            timeout,
            false,
            |i| i.spos.contains(Spos::ACK),
        )
        .await?;
        self.out.cpos = Cpos::HALT;
        let rest = deadline.saturating_duration_since(tokio::time::Instant::now());
        self.wait(
            command,
            "motion complete (SPOS.MC, ACK = 0)",
            rest,
            false,
            |i| i.spos.contains(Spos::MC) && !i.spos.contains(Spos::ACK) && done(i),
        )
        .await
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The twin's Modbus server in this process, on a free loopback port.
    async fn twin() -> (String, tokio::task::JoinHandle<()>) {
        use super::super::modbus_server::FhppModbus;
        use crate::modbus_tcp::device_thread::{run, ServeOptions};
        use drive::vendors::festo_cmmo_st::device::{FhppDevice, FhppSettings};
        let desc = &devices::CMMO_ST;
        let od = od::ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]).unwrap();
        let dev = Box::new(FhppModbus::new(
            FhppDevice::new(od, FhppSettings::default()),
            None,
        ));
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let task = tokio::spawn(run(
            listener,
            dev,
            ServeOptions::default(),
            std::future::pending(),
        ));
        (addr, task)
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn enable_home_move_and_pnu_against_the_twin() {
        let (addr, task) = twin().await;
        let t = Duration::from_secs(5);
        let config = MasterConfig {
            cycle: Duration::from_millis(2),
            parameter_channel: true,
            ..MasterConfig::default()
        };
        let mut m = FhppMaster::connect(&addr, config).await.unwrap();
        // FHPP-CB-01 power-on 10h / 04h; FHPP-ST-01, ST-02, CB-03 enabled 13h / 05h.
        assert_eq!((m.input().scon.0, m.input().spos.0), (0x10, 0x04));
        m.enable(t).await.unwrap();
        assert_eq!((m.input().scon.0, m.input().spos.0), (0x13, 0x05));
        // FHPP-ST-08: not referenced, the drive refuses the start with 28h; `enable`
        // acknowledges it (FHPP-ST-05, T9).
        match m.move_to(1000, 100, false, t).await {
            Err(FhppError::Fault { number: 0x28, .. }) => {}
            other => panic!("{other:?}"),
        }
        m.enable(t).await.unwrap();
        m.home(t).await.unwrap();
        assert!(m.input().spos.contains(Spos::REF | Spos::MC)); // FHPP-CB-10
                                                                // FHPP-CB-14, ST-19: direct mode 53h, position task.
        m.move_to(9000, 100, false, t).await.unwrap();
        assert_eq!(m.input().scon.0, 0x53);
        assert!((m.input().actual2 - 9000).abs() <= 180, "{:?}", m.input());
        // FHPP-FPC-01 and FHPP-FPC-02: PNU 1041 is the same actual position; PNU 9999 does
        // not exist (Tab. C.7 code 0).
        let pos = m.read_parameter(1041, 1, t).await.unwrap() as i32;
        assert!((pos - m.input().actual2).abs() <= 18, "{pos}");
        match m.read_parameter(9999, 1, t).await {
            Err(FhppError::Parameter {
                code: ErrorCode::IllegalPnu,
                ..
            }) => {}
            other => panic!("{other:?}"),
        }
        m.disable(t).await.unwrap();
        assert_eq!(m.input().scon.0 & 0x03, 0);
        task.abort();
    }

    #[test]
    fn state_names_follow_the_reference_values() {
        // §4.3: power-on 10h, enabled 13h, direct 53h, fault xxxx.1xxx.
        assert_eq!(state_name(Scon(0x10)), "S2 drive disabled");
        assert_eq!(state_name(Scon(0x13)), "S4 operation enabled");
        assert_eq!(state_name(Scon(0x53)), "S4 operation enabled");
        assert_eq!(state_name(Scon(0x11)), "S3 drive enabled");
        assert_eq!(state_name(Scon(0x19)), "S6 fault");
    }

    #[test]
    fn status_decodes_record_and_direct_telegrams() {
        let s = Status::new(
            &InputData::from_bytes([0x13, 0x85, 1, 0, 0, 0, 0x69, 0x78]),
            0,
        );
        assert_eq!(s.mode, "record selection");
        assert_eq!(s.actual, 27000);
        assert_eq!(s.spos_bits, "REF|MC|HALT (1000.0101)");
        assert!(s.to_text().contains("record 1\n"));
        assert_eq!(s.fault, None);
        let s = Status::new(
            &InputData::from_bytes([0x5B, 0x04, 0x01, 0, 0, 0, 0, 0]),
            0x28,
        );
        assert_eq!(s.mode, "direct");
        assert_eq!(s.state, "S6 fault");
        assert_eq!(s.byte_bits, "ABS (0000.0001)");
        assert!(s.to_text().ends_with("fault 28h homing required"));
    }
}
