//! `drivetwin fhpp …`: the FHPP master commands to a CMMO-ST over Modbus TCP.

use std::time::Duration;

use clap::{Args, Subcommand};
use drive::vendors::festo_cmmo_st::device::pnu_index;
use od::DataType;

use super::fhpp_master::{FhppError, FhppMaster, MasterConfig};
use crate::master::modbus_tcp::ModbusTcpError;
use crate::value_text;
use crate::vendors::{CommandError, Failure};

// `drivetwin fhpp`'s arguments: what to do, and the link (no doc comment: the sub-command's
// help is the variant's in the binary's command list).
#[derive(Args, Debug)]
pub struct FhppArgs {
    #[command(subcommand)]
    pub command: FhppCommand,
    #[command(flatten)]
    pub link: FhppLinkArgs,
}

/// The Modbus TCP link of `drivetwin fhpp`.
#[derive(Args, Debug, Clone)]
pub struct FhppLinkArgs {
    /// Modbus TCP address of the CMMO-ST.
    #[arg(
        long,
        global = true,
        value_name = "ADDR",
        default_value = "127.0.0.1:1502"
    )]
    pub modbus: String,
    /// Timeout of each handshake step and of the motion, ms.
    #[arg(long, global = true, default_value_t = 10_000)]
    pub timeout_ms: u64,
    /// PLC cycle: one FC 0x17 exchange every this many ms while waiting.
    #[arg(long, global = true, default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub cycle_ms: u64,
    /// Keep CCON.LOCK set: FCT and the web server cannot take device control.
    #[arg(long, global = true)]
    pub lock: bool,
    /// Print JSON instead of text.
    #[arg(long, global = true)]
    pub json: bool,
}

// The doc comments are clap's help text: `[SINC]`, `PNU[:SUB]` are the command line's
// notation, not links.
#[allow(rustdoc::broken_intra_doc_links)]
#[derive(Subcommand, Debug)]
pub enum FhppCommand {
    /// Print the decoded status bytes (FC 0x03 and 0x07; writes nothing).
    Status,
    /// Acknowledge a fault if needed, then ENABLE and STOP to S4 "operation enabled".
    Enable,
    /// ENABLE = 0: drive disabled, output stage off.
    Disable,
    /// Homing (CPOS.HOM); waits for MC and REF.
    Home,
    /// Direct-mode position task to POSITION [SINC]; waits for MC.
    Move {
        #[arg(allow_hyphen_values = true)]
        position: i32,
        /// Velocity, % of PNU 540.
        #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u8).range(1..=100))]
        velocity: u8,
        /// POSITION is relative (CDIR.ABS = 1).
        #[arg(long)]
        relative: bool,
    },
    /// Start record N (record selection, 0 = homing, 1…64); waits for MC.
    Record { number: u8 },
    /// Read or write a PNU through the parameter channel (EFPC, I/O bytes 9…16).
    #[command(subcommand)]
    Pnu(PnuCommand),
}

// The doc comments are clap's help text: `[SINC]`, `PNU[:SUB]` are the command line's
// notation, not links.
#[allow(rustdoc::broken_intra_doc_links)]
#[derive(Subcommand, Debug)]
pub enum PnuCommand {
    /// Read PNU[:SUB] (decimal; SUB defaults to 1).
    Read { pnu: String },
    /// Write VALUE (decimal, negative or 0x hex) to PNU[:SUB].
    Write {
        pnu: String,
        #[arg(allow_hyphen_values = true)]
        value: String,
    },
}

/// As the CANopen commands: the link, time-outs, a refusal or a parameter channel error
/// (like an SDO abort), a malformed answer, a drive fault.
pub(crate) fn failure(e: &FhppError) -> Failure {
    match e {
        FhppError::Modbus(m) => match m {
            ModbusTcpError::Connect { .. } | ModbusTcpError::Io(_) | ModbusTcpError::Closed => {
                Failure::Link
            }
            ModbusTcpError::Timeout(_) => Failure::Timeout,
            ModbusTcpError::Exception { .. } => Failure::Refused,
            ModbusTcpError::Protocol(_) => Failure::Protocol,
        },
        FhppError::Refused { .. } | FhppError::Parameter { .. } => Failure::Refused,
        FhppError::Timeout { .. } => Failure::Timeout,
        FhppError::Fault { .. } => Failure::Fault,
        FhppError::Protocol(_) => Failure::Protocol,
        FhppError::NoParameterChannel => Failure::Other,
    }
}

impl FhppArgs {
    /// Carries the command out; its answer goes to `out`.
    pub async fn run(self, out: &mut (dyn FnMut(&str) + Send)) -> Result<(), CommandError> {
        fhpp(self.command, self.link, out).await
    }
}

async fn fhpp(
    command: FhppCommand,
    link: FhppLinkArgs,
    out: &mut (dyn FnMut(&str) + Send),
) -> Result<(), CommandError> {
    let config = MasterConfig {
        cycle: Duration::from_millis(link.cycle_ms),
        lock: link.lock,
        parameter_channel: matches!(command, FhppCommand::Pnu(_)),
        ..MasterConfig::default()
    };
    let timeout = Duration::from_millis(link.timeout_ms);
    if let FhppCommand::Pnu(cmd) = command {
        return pnu(cmd, &link, config, timeout, out).await;
    }
    let mut m = FhppMaster::connect(&link.modbus, config).await?;
    match command {
        FhppCommand::Status | FhppCommand::Pnu(_) => {}
        FhppCommand::Enable => m.enable(timeout).await?,
        FhppCommand::Disable => m.disable(timeout).await?,
        FhppCommand::Home => m.home(timeout).await?,
        FhppCommand::Move {
            position,
            velocity,
            relative,
        } => m.move_to(position, velocity, relative, timeout).await?,
        FhppCommand::Record { number } => m.record(number, timeout).await?,
    }
    let status = m.status().await?;
    if link.json {
        out(&serde_json::to_string(&status).unwrap_or_default());
    } else {
        out(&status.to_text());
    }
    Ok(())
}

/// `PNU[:SUB]`, both decimal as the manual numbers them; SUB defaults to 1 ("1 = simple
/// variable", FHPP has no subindex 0).
fn parse_pnu(text: &str) -> Result<(u16, u8), CommandError> {
    let bad = || CommandError::Usage(format!("{text:?} is not PNU[:SUB] (e.g. 1041 or 404:2)"));
    let (pnu, sub) = match text.split_once(':') {
        Some((p, s)) => (p, s.parse::<u8>().map_err(|_| bad())?),
        None => (text, 1),
    };
    Ok((pnu.parse::<u16>().map_err(|_| bad())?, sub))
}

/// The type the cmmo-st dictionary gives the PNU (PNU n = object 2000h + n), `None` for a
/// PNU it does not have (the drive then answers "illegal PNU").
fn pnu_entry(pnu: u16, sub: u8) -> Option<&'static od::Entry> {
    // pnu_index adds 2000h: a PNU above DFFFh has no object (the drive answers "illegal PNU").
    let index = (pnu <= u16::MAX - pnu_index(0)).then(|| pnu_index(pnu))?;
    devices::CMMO_ST.entry(index, sub)
}

/// The PWE as the parameter's type reads it: the low bytes, signed types sign-extended.
fn pwe_text(entry: Option<&od::Entry>, pwe: u32) -> String {
    let t = entry.map_or(DataType::Unsigned32, |e| e.data_type);
    let size = t.fixed_size().unwrap_or(4).min(4);
    let bytes = pwe.to_le_bytes();
    value_text::decode(t, bytes.get(..size).unwrap_or(&bytes)).unwrap_or_else(|| pwe.to_string())
}

/// The PWE for `text` written as the parameter's type (checked against the type's range;
/// signed values sign-extended to 32 bits, as the CMMO-ST sends them).
fn pwe_of(entry: Option<&od::Entry>, text: &str) -> Result<u32, CommandError> {
    let t = entry.map_or(DataType::Unsigned32, |e| e.data_type);
    if t.fixed_size().is_none_or(|n| n > 4) {
        return Err(CommandError::Usage(format!(
            "a {} does not fit the 32-bit PWE",
            t.name()
        )));
    }
    let bytes = value_text::encode(t, text).map_err(CommandError::Usage)?;
    let negative = t.is_signed() && bytes.last().is_some_and(|b| b & 0x80 != 0);
    let mut pwe = if negative { [0xFF; 4] } else { [0; 4] };
    for (p, b) in pwe.iter_mut().zip(&bytes) {
        *p = *b;
    }
    Ok(u32::from_le_bytes(pwe))
}

#[derive(serde::Serialize)]
struct PnuValue<'a> {
    pnu: u16,
    sub: u8,
    name: Option<&'a str>,
    #[serde(rename = "type")]
    data_type: &'a str,
    value: String,
    pwe: u32,
}

async fn pnu(
    cmd: PnuCommand,
    link: &FhppLinkArgs,
    config: MasterConfig,
    timeout: Duration,
    out: &mut (dyn FnMut(&str) + Send),
) -> Result<(), CommandError> {
    let (text, value) = match &cmd {
        PnuCommand::Read { pnu } => (pnu, None),
        PnuCommand::Write { pnu, value } => (pnu, Some(value)),
    };
    let (pnu, sub) = parse_pnu(text)?;
    let entry = pnu_entry(pnu, sub);
    let write = value.map(|v| pwe_of(entry, v)).transpose()?;
    let mut m = FhppMaster::connect(&link.modbus, config).await?;
    let pwe = match write {
        Some(v) => m.write_parameter(pnu, sub, v, timeout).await?,
        None => m.read_parameter(pnu, sub, timeout).await?,
    };
    let v = PnuValue {
        pnu,
        sub,
        name: entry
            .and_then(|e| devices::CMMO_ST.object(e.index))
            .map(|o| o.name),
        data_type: entry.map_or("UNSIGNED32", |e| e.data_type.name()),
        value: pwe_text(entry, pwe),
        pwe,
    };
    if link.json {
        out(&serde_json::to_string(&v).unwrap_or_default());
    } else {
        out(&format!(
            "PNU {}:{} {}= {}",
            v.pnu,
            v.sub,
            v.name.map(|n| format!("({n}) ")).unwrap_or_default(),
            v.value
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pnu_text_and_pwe_follow_the_type() {
        assert_eq!(parse_pnu("1041").unwrap(), (1041, 1));
        assert_eq!(parse_pnu("404:2").unwrap(), (404, 2));
        assert!(parse_pnu("404:x").is_err() && parse_pnu("70000").is_err());
        assert!(pnu_entry(65535, 1).is_none());
        // PNU 1041 actual position, int32; PNU 127 data memory control, uint8.
        let pos = pnu_entry(1041, 1);
        assert_eq!(pos.map(|e| e.data_type), Some(DataType::Integer32));
        assert_eq!(pwe_of(pos, "-2").unwrap(), 0xFFFF_FFFE);
        assert_eq!(pwe_text(pos, 0xFFFF_FFFE), "-2");
        let mem = pnu_entry(127, 2);
        assert_eq!(pwe_of(mem, "1").unwrap(), 1);
        assert!(pwe_of(mem, "256").is_err());
        assert!(pwe_of(mem, "-1").is_err());
        // Unknown PNU: the raw 32-bit PWE.
        assert_eq!(pwe_of(None, "0x12345678").unwrap(), 0x1234_5678);
    }
}
