use super::*;
use ::drive::device_control::State;
use ::drive::statusword::Statusword;
use drivetwin::master::cia402::VelocityMode;

pub(crate) async fn drive_command(
    node: u8,
    command: DriveCommand,
    wait: bool,
    timeout_ms: u64,
    bus: BusArgs,
) -> Result<(), CommandError> {
    check_node(node)?;
    let timeout = Duration::from_millis(timeout_ms);
    let mut link = connect(&bus).await?;
    let mut c = SdoClient::new(&mut link, node, Duration::from_millis(1000));
    match command {
        DriveCommand::State => {}
        DriveCommand::Enable => cia402::enable(&mut c, timeout).await?,
        DriveCommand::Disable => cia402::disable(&mut c, timeout).await?,
        DriveCommand::Move {
            target,
            relative,
            velocity,
            accel,
            decel,
        } => {
            cia402::move_to(&mut c, target, relative, (velocity, accel, decel), timeout).await?;
        }
        DriveCommand::Velocity { velocity } => {
            if cia402::run_at(&mut c, velocity, timeout).await? == VelocityMode::Vl {
                eprintln!(
                    "node {node} has no profile velocity mode (6502h bit 2): velocity mode VL \
                     (6060h = 2), {velocity} in 6042h (units of 604Ch)"
                );
            }
        }
        DriveCommand::Torque { torque, slope } => {
            cia402::run_torque(&mut c, torque, slope, timeout).await?;
        }
    }
    let moving = !matches!(
        command,
        DriveCommand::State | DriveCommand::Enable | DriveCommand::Disable
    );
    if wait && moving {
        if !matches!(command, DriveCommand::Move { .. }) {
            // A velocity or torque target has no handshake: bit 10 may still be the old
            // target's until the drive's next cycles have seen the new one.
            tokio::time::sleep(cia402::SET_POINT_SETTLE).await;
        }
        // Target reached in OPERATION ENABLED (bit 10 with the state bits).
        cia402::wait_for(&mut c, "target reached", timeout, |sw| {
            sw.contains(Statusword::TARGET_REACHED) && sw.state() == Some(State::OperationEnabled)
        })
        .await?;
    }
    let s = cia402::snapshot(&mut c).await.map_err(Cia402Error::from)?;
    if bus.json {
        out!("{}", serde_json::to_string(&s).unwrap_or_default());
    } else {
        out!("{}", describe(&s));
    }
    Ok(())
}

/// One line: state, mode and the actual values; "n/a (no 6078h)" for an object the drive
/// does not have.
fn describe(s: &cia402::Snapshot) -> String {
    let velocity = match (s.velocity, s.velocity_object) {
        (Some(v), Some("606Ch") | None) => v.to_string(),
        (Some(v), Some(object)) => format!("{v} ({object})"),
        (None, _) => "n/a (no 606Ch)".to_string(),
    };
    let permille = |v: Option<i16>, object: &str| {
        v.map_or_else(|| format!("n/a (no {object})"), |v| format!("{v}‰"))
    };
    format!(
        "{} (statusword {:04X}h) mode {} position {} velocity {} current {} torque {}{}{}",
        s.state,
        s.statusword,
        s.mode,
        s.position,
        velocity,
        permille(s.current_permille, "6078h"),
        permille(s.torque_permille, "6077h"),
        if s.target_reached {
            ", target reached"
        } else {
            ""
        },
        if s.following_error {
            ", FOLLOWING ERROR"
        } else {
            ""
        }
    )
}
