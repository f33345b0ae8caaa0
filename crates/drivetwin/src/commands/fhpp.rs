//! `drivetwin fhpp …`: the FHPP master commands to a CMMO-ST over Modbus TCP.

use super::*;
use drivetwin::master::fhpp::{FhppMaster, MasterConfig};
use drivetwin::master::modbus_tcp::ModbusTcpError;

/// Exit codes as for the CANopen commands: the link 3, timeouts 4, a refusal 5 (like an SDO
/// abort), a malformed answer 6, a drive fault 7.
pub(crate) fn exit_code(e: &FhppError) -> u8 {
    match e {
        FhppError::Modbus(m) => match m {
            ModbusTcpError::Connect { .. } | ModbusTcpError::Io(_) | ModbusTcpError::Closed => {
                EXIT_LINK
            }
            ModbusTcpError::Timeout(_) => EXIT_TIMEOUT,
            ModbusTcpError::Exception { .. } => EXIT_ABORT,
            ModbusTcpError::Protocol(_) => EXIT_PROTOCOL,
        },
        FhppError::Refused { .. } => EXIT_ABORT,
        FhppError::Timeout { .. } => EXIT_TIMEOUT,
        FhppError::Fault { .. } => EXIT_FAULT,
    }
}

pub(crate) async fn fhpp(command: FhppCommand, link: FhppArgs) -> Result<(), CommandError> {
    let config = MasterConfig {
        cycle: Duration::from_millis(link.cycle_ms),
        lock: link.lock,
        ..MasterConfig::default()
    };
    let timeout = Duration::from_millis(link.timeout_ms);
    let mut m = FhppMaster::connect(&link.modbus, config).await?;
    match command {
        FhppCommand::Status => {}
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
        out!("{}", serde_json::to_string(&status).unwrap_or_default());
    } else {
        out!("{}", status.to_text());
    }
    Ok(())
}
