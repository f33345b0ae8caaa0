//! `drivetwin ecat scan|state|sdo`: the minimal EtherCAT master of
//! [`drivetwin::master::ecat`] on a raw socket.

use super::*;

use drivetwin::master::ecat::{abort_description, EcatError, EcatMaster, SlaveInfo};
use ethercat::master::{state_name, AlStatusBlock};
use ethercat::{AlState, DlStatus};

use crate::cli::{EcatCommand, EcatLinkArgs, EcatSdoCommand, EcatSdoTarget, EcatStateArg};

/// Exit code of a master failure (the codes of `drivetwin --help`).
pub(crate) fn exit_code(e: &EcatError) -> u8 {
    match e {
        EcatError::Io(_) | EcatError::NoReply(_) => EXIT_LINK,
        EcatError::NoSuchSlave { .. } => EXIT_USAGE,
        EcatError::StateTimeout { .. }
        | EcatError::MailboxTimeout { .. }
        | EcatError::EepromBusy { .. } => EXIT_TIMEOUT,
        EcatError::Abort { .. } => EXIT_ABORT,
        EcatError::WorkingCounter { .. }
        | EcatError::Eeprom { .. }
        | EcatError::Sii { .. }
        | EcatError::MailboxError { .. }
        | EcatError::Protocol { .. } => EXIT_PROTOCOL,
        EcatError::Refused { .. } | EcatError::NoMailbox { .. } | EcatError::Frame(_) => {
            EXIT_FAILURE
        }
    }
}

impl From<EcatStateArg> for AlState {
    fn from(s: EcatStateArg) -> AlState {
        match s {
            EcatStateArg::Init => AlState::Init,
            EcatStateArg::Preop => AlState::PreOp,
            EcatStateArg::Safeop => AlState::SafeOp,
            EcatStateArg::Op => AlState::Op,
        }
    }
}

pub(crate) async fn ecat(cmd: EcatCommand) -> Result<(), CommandError> {
    match cmd {
        EcatCommand::Scan { link } => {
            let (mut m, count) = attach(&link).await?;
            scan(&mut m, count, link.json).await
        }
        EcatCommand::State {
            state,
            slave,
            timeout_ms,
            sdo_timeout_ms,
            link,
        } => {
            let (mut m, count) = attach(&link).await?;
            let slaves = select(slave, count)?;
            match state {
                None => show_states(&mut m, &slaves, link.json).await,
                Some(s) => {
                    let timeouts = (
                        Duration::from_millis(timeout_ms),
                        Duration::from_millis(sdo_timeout_ms),
                    );
                    request_states(&mut m, &slaves, s.into(), timeouts, link.json).await
                }
            }
        }
        EcatCommand::Sdo(cmd) => sdo(cmd).await,
    }
}

type Link = drivetwin::master::ecat::link::SocketLink;

/// Opens the interface, counts the slaves and gives them their station addresses; elsewhere
/// than on Linux the raw socket refuses with its reason (`sys::packet_socket`).
async fn attach(args: &EcatLinkArgs) -> Result<(EcatMaster<Link>, u16), CommandError> {
    let link =
        Link::open(&args.interface).map_err(io(format!("EtherCAT on {}", args.interface)))?;
    let mut m = EcatMaster::new(link);
    m.frame_timeout = Duration::from_millis(args.frame_timeout_ms.max(1));
    let count = m.attach().await?;
    Ok((m, count))
}

/// The slaves a command works on: `--slave N` (checked against the count) or all.
fn select(slave: Option<u16>, count: u16) -> Result<Vec<u16>, CommandError> {
    match slave {
        Some(n) if (1..=count).contains(&n) => Ok(vec![n]),
        Some(n) => Err(EcatError::NoSuchSlave { slave: n, count }.into()),
        None if count == 0 => Err(EcatError::NoSuchSlave { slave: 1, count }.into()),
        None => Ok((1..=count).collect()),
    }
}

fn state_text(al: &AlStatusBlock) -> &'static str {
    al.state().map_or("INVALID", state_name)
}

/// The AL status fields every JSON answer carries.
fn al_json(al: &AlStatusBlock) -> serde_json::Value {
    serde_json::json!({
        "state": state_text(al),
        "al_status": al.raw,
        "error": al.error(),
        "al_status_code": al.code.0,
        "al_status_text": al.code.description(),
    })
}

/// " (error: AL status code 0x0011: Invalid requested state change)" when the error bit is set.
fn error_suffix(al: &AlStatusBlock) -> String {
    if al.error() {
        format!(" (error: AL status code {})", al.code)
    } else {
        String::new()
    }
}

/// Ports 0 and 1, the two of a line: "0:up 1:down" (a link or none).
fn ports_text(dl: DlStatus) -> String {
    (0..2u8)
        .filter_map(|n| {
            dl.port(n)
                .map(|p| format!("{n}:{}", if p.link { "up" } else { "down" }))
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// The DL status as JSON: the raw register and ports 0 and 1.
fn dl_json(dl: DlStatus) -> serde_json::Value {
    let ports: Vec<_> = (0..2u8)
        .filter_map(|n| {
            dl.port(n).map(|p| {
                serde_json::json!({
                    "port": n, "link": p.link, "loop_closed": p.loop_closed,
                    "communication": p.communication,
                })
            })
        })
        .collect();
    serde_json::json!({"dl_status": dl.0, "ports": ports})
}

fn merge(mut a: serde_json::Value, b: serde_json::Value) -> serde_json::Value {
    if let (Some(a), serde_json::Value::Object(b)) = (a.as_object_mut(), b) {
        a.extend(b);
    }
    a
}

async fn scan(m: &mut EcatMaster<Link>, count: u16, json: bool) -> Result<(), CommandError> {
    let mut infos: Vec<SlaveInfo> = Vec::new();
    let bar = super::progress::bar(usize::from(count), "ecat scan");
    for n in 1..=count {
        infos.push(m.slave_info(n).await?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    if json {
        let slaves: Vec<_> = infos
            .iter()
            .map(|i| {
                merge(
                    merge(
                        serde_json::json!({
                            "slave": i.number, "station": i.station,
                            "vendor_id": i.identity.vendor_id,
                            "product_code": i.identity.product_code,
                            "revision": i.identity.revision, "serial": i.identity.serial,
                            "name": i.name,
                        }),
                        al_json(&i.al),
                    ),
                    dl_json(i.dl),
                )
            })
            .collect();
        out!("{}", serde_json::json!({"count": count, "slaves": slaves}));
        return Ok(());
    }
    if count == 0 {
        out!("no slave answered");
        return Ok(());
    }
    out!(
        "{:<5} {:<7} {:<10} {:<10} {:<10} {:<10} {:<7} {:<11} name",
        "slave",
        "station",
        "vendor",
        "product",
        "revision",
        "serial",
        "state",
        "ports"
    );
    for i in &infos {
        out!(
            "{:<5} {:#06x}  {:#010x} {:#010x} {:#010x} {:#010x} {:<7} {:<11} {}{}",
            i.number,
            i.station,
            i.identity.vendor_id,
            i.identity.product_code,
            i.identity.revision,
            i.identity.serial,
            state_text(&i.al),
            ports_text(i.dl),
            i.name.as_deref().unwrap_or("-"),
            error_suffix(&i.al)
        );
    }
    out!("{count} slave(s)");
    Ok(())
}

async fn show_states(
    m: &mut EcatMaster<Link>,
    slaves: &[u16],
    json: bool,
) -> Result<(), CommandError> {
    let mut all = Vec::new();
    for &n in slaves {
        let al = m.al_status(n).await?;
        if json {
            all.push(merge(
                serde_json::json!({"slave": n, "station": ethercat::master::station_address(n)}),
                al_json(&al),
            ));
        } else {
            out!(
                "slave {n} ({:#06x}): {}{}",
                ethercat::master::station_address(n),
                state_text(&al),
                error_suffix(&al)
            );
        }
    }
    if json {
        out!("{}", serde_json::json!(all));
    }
    Ok(())
}

async fn request_states(
    m: &mut EcatMaster<Link>,
    slaves: &[u16],
    target: AlState,
    (timeout, sdo_timeout): (Duration, Duration),
    json: bool,
) -> Result<(), CommandError> {
    let mut all = Vec::new();
    let mut failure = None;
    for &n in slaves {
        let station = ethercat::master::station_address(n);
        match m.request_state(n, target, timeout, sdo_timeout).await {
            Ok(c) => {
                if json {
                    all.push(merge(
                        serde_json::json!({
                            "slave": n, "station": station, "requested": state_name(target),
                            "from": state_text(&c.from),
                        }),
                        al_json(&c.to),
                    ));
                } else {
                    out!(
                        "slave {n} ({station:#06x}): {} -> {}",
                        state_text(&c.from),
                        state_text(&c.to)
                    );
                }
            }
            Err(e) => {
                if json {
                    let mut j = serde_json::json!({
                        "slave": n, "station": station, "requested": state_name(target),
                        "failed": e.to_string(),
                    });
                    // Where the slave stands now, with the code of a refusal.
                    if let Ok(al) = m.al_status(n).await {
                        j = merge(j, al_json(&al));
                    }
                    all.push(j);
                }
                failure = Some(e);
                break;
            }
        }
    }
    if json {
        out!("{}", serde_json::json!(all));
    }
    match failure {
        Some(e) => Err(e.into()),
        None => Ok(()),
    }
}

/// `INDEX:SUB` (hex; the sub-index may be left out).
fn parse_object(s: &str) -> Result<(u16, u8), CommandError> {
    let (i, sub) = s.split_once(':').unwrap_or((s, "0"));
    Ok((parse_hex_u16(i, "index")?, parse_hex_u8(sub, "sub-index")?))
}

/// The mailbox runs from Pre-Op on; a slave still in Init is taken there first, as
/// SOEM's `config_init` does.
async fn mailbox_ready(
    m: &mut EcatMaster<Link>,
    slave: u16,
    timeout: Duration,
) -> Result<(), CommandError> {
    let al = m.al_status(slave).await?;
    if al.state() == Some(AlState::Init) {
        tracing::info!(slave, "slave in INIT: requesting PREOP for the mailbox");
        m.request_state(slave, AlState::PreOp, Duration::from_secs(5), timeout)
            .await?;
    }
    Ok(())
}

/// The master on the link, its slave `target.slave` with a working mailbox (taken to Pre-Op
/// if needed), and the SDO timeout.
async fn sdo_session(target: &EcatSdoTarget) -> Result<(EcatMaster<Link>, Duration), CommandError> {
    let timeout = Duration::from_millis(target.timeout_ms);
    let (mut m, count) = attach(&target.link).await?;
    select(Some(target.slave), count)?;
    mailbox_ready(&mut m, target.slave, timeout).await?;
    Ok((m, timeout))
}

async fn sdo(cmd: EcatSdoCommand) -> Result<(), CommandError> {
    match cmd {
        EcatSdoCommand::Read { object, target } => {
            let (index, sub) = parse_object(&object)?;
            let ty = sdo::resolve_type(&target.typing, index, sub)?;
            let (mut m, timeout) = sdo_session(&target).await?;
            let (slave, link) = (target.slave, &target.link);
            let head = || serde_json::json!({"slave": slave, "index": format!("0x{index:04X}"), "sub": sub});
            match m.sdo_upload(slave, index, sub, timeout).await {
                Ok(data) => {
                    sdo::print_upload(ty, &data, link.json.then(head));
                    Ok(())
                }
                Err(e) => Err(report(link.json, head(), e)),
            }
        }
        EcatSdoCommand::Write {
            object,
            value,
            target,
        } => {
            let (index, sub) = parse_object(&object)?;
            let ty = sdo::resolve_type(&target.typing, index, sub)?.ok_or_else(|| {
                CommandError::Usage(
                    "ecat sdo write needs --type or --device to encode the value".into(),
                )
            })?;
            let data = value_text::encode(ty, &value).map_err(CommandError::Usage)?;
            let (mut m, timeout) = sdo_session(&target).await?;
            let (slave, link) = (target.slave, &target.link);
            let head =
                serde_json::json!({"slave": slave, "index": format!("0x{index:04X}"), "sub": sub});
            match m.sdo_download(slave, index, sub, &data, timeout).await {
                Ok(()) => {
                    if link.json {
                        out!(
                            "{}",
                            merge(head, serde_json::json!({"written": value_text::hex(&data)}))
                        );
                    }
                    Ok(())
                }
                Err(e) => Err(report(link.json, head, e)),
            }
        }
    }
}

/// In JSON mode an SDO failure is also a JSON object on standard output (as `drivetwin sdo`).
fn report(json: bool, head: serde_json::Value, e: EcatError) -> CommandError {
    if json {
        let mut j = merge(head, serde_json::json!({"error": e.to_string()}));
        if let (EcatError::Abort { code, .. }, Some(o)) = (&e, j.as_object_mut()) {
            o.insert(
                "abort_code".into(),
                serde_json::json!(format!("0x{:08X}", code.0)),
            );
            o.insert(
                "abort_text".into(),
                serde_json::json!(abort_description(*code)),
            );
        }
        out!("{j}");
    }
    e.into()
}
