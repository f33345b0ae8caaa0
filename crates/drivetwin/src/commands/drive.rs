use super::*;

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
            cia402::set_mode(&mut c, 3, timeout).await?;
            c.download(0x60FF, 0, &velocity.to_le_bytes())
                .await
                .map_err(Cia402Error::from)?;
        }
        DriveCommand::Torque { torque, slope } => {
            cia402::set_mode(&mut c, 4, timeout).await?;
            if let Some(s) = slope {
                c.download(0x6087, 0, &s.to_le_bytes())
                    .await
                    .map_err(Cia402Error::from)?;
            }
            c.download(0x6071, 0, &torque.to_le_bytes())
                .await
                .map_err(Cia402Error::from)?;
        }
    }
    let moving = !matches!(
        command,
        DriveCommand::State | DriveCommand::Enable | DriveCommand::Disable
    );
    if wait && moving {
        // Target reached in OPERATION ENABLED (bit 10 with the state bits).
        cia402::wait_for(&mut c, "target reached", timeout, |sw| {
            sw & 0x0400 != 0 && sw & 0x6F == 0x27
        })
        .await?;
    }
    let s = cia402::snapshot(&mut c).await.map_err(Cia402Error::from)?;
    if bus.json {
        out!("{}", serde_json::to_string(&s).unwrap_or_default());
    } else {
        out!(
            "{} (statusword {:04X}h) mode {} position {} velocity {} current {}‰ torque {}‰{}{}",
            s.state,
            s.statusword,
            s.mode,
            s.position,
            s.velocity,
            s.current_permille,
            s.torque_permille,
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
        );
    }
    Ok(())
}
