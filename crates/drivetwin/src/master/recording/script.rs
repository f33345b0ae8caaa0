//! The script of a recording: SDO, NMT and PDO steps in a small TOML file, or the requests of
//! a candump log.
//!
//! ```toml
//! node = 1                  # the node the steps address (default 1)
//! sdo_timeout_ms = 1000     # how long an SDO request waits for its answer (default 1000)
//! ignore = ["080", "100", "701-77F"]   # frames that are no answers (the default)
//!
//! [[step]]
//! read = "1018:01"          # SDO upload, expedited or segmented
//! [[step]]
//! write = "6040:00"         # SDO download: `type` and `value` as `drivetwin sdo write`,
//! type = "u16"              # or `data = "06 00"` (hex bytes)
//! value = 6
//! [[step]]
//! nmt = "start"             # awaits the node's heartbeat (boot-up after a reset),
//! wait_ms = 1500            # 1500 ms (5000 ms for a reset) unless given
//! [[step]]
//! rpdo = 1                  # RPDO1 of the node (200h + node); or `frame = "080#"`
//! data = "0F 00"
//! window_ms = 100           # answers gathered this long (default 100 ms)
//! ```
//!
//! Every step may name itself (`name`), address another node (`node`) and gather answers
//! longer (`window_ms`). In a candump log the requests are the frames a master sends (NMT,
//! SYNC, TIME, RPDOs, SDO requests, node guarding, LSS master); the node's frames in the log
//! are skipped (they are the old answers). **Decision:** a logged request's answers are the
//! frames until the next request is due at the log's spacing (the last one: a quiet time),
//! and an SDO request's until its response has come, as the master that wrote the log waited
//! for it.

use std::time::Duration;

use canopen::decode::{classify, Function};
use canopen::{CanFrame, NmtCommand};
use serde::Deserialize;

use super::sdo_transfer::SdoTransfer;
use crate::value_text::Number;

use super::{AnswerRule, Awaited, CobRange, LineError, Step, DEFAULT_IGNORE};

const DEFAULT_SDO_TIMEOUT_MS: u64 = 1000;
const DEFAULT_NMT_WAIT_MS: u64 = 1500;
const DEFAULT_RESET_WAIT_MS: u64 = 5000;
const DEFAULT_WINDOW_MS: u64 = 100;

/// One action of a script: a single frame, or an SDO transfer that sends frames as answers
/// come.
#[derive(Debug, Clone)]
pub enum Action {
    Frame(Step),
    Sdo(SdoTransfer),
}

/// A script ready to run.
#[derive(Debug, Clone)]
pub struct Script {
    pub ignore: Vec<CobRange>,
    pub actions: Vec<Action>,
}

/// The settings of a candump script (a TOML script carries its own).
#[derive(Debug, Clone, Copy)]
pub struct CandumpOptions {
    pub sdo_timeout: Duration,
    /// How long the answers of the log's last request are gathered.
    pub quiet: Duration,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ScriptFile {
    node: Option<u8>,
    sdo_timeout_ms: Option<u64>,
    ignore: Option<Vec<String>>,
    #[serde(default)]
    step: Vec<toml::Spanned<StepSpec>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct StepSpec {
    name: Option<String>,
    node: Option<u8>,
    window_ms: Option<u64>,
    wait_ms: Option<u64>,
    read: Option<String>,
    write: Option<String>,
    #[serde(rename = "type")]
    type_name: Option<String>,
    value: Option<Number>,
    data: Option<String>,
    nmt: Option<String>,
    rpdo: Option<u8>,
    frame: Option<String>,
}

/// The 1-based line of byte `offset` in `text`.
fn line_of(text: &str, offset: usize) -> usize {
    text.get(..offset).unwrap_or(text).matches('\n').count() + 1
}

/// `IIII:SS` (hex) as an object.
fn parse_object(text: &str) -> Option<(u16, u8)> {
    let (i, s) = text.split_once(':')?;
    Some((
        u16::from_str_radix(i.trim(), 16).ok()?,
        u8::from_str_radix(s.trim(), 16).ok()?,
    ))
}

fn parse_ignore(list: Option<Vec<String>>, line: usize) -> Result<Vec<CobRange>, LineError> {
    match list {
        None => Ok(DEFAULT_IGNORE.to_vec()),
        Some(l) => l
            .iter()
            .map(|t| {
                CobRange::parse(t).ok_or_else(|| {
                    LineError::new(
                        line,
                        format!("ignore: {t:?} is not a COB-ID or range (\"701-77F\")"),
                    )
                })
            })
            .collect(),
    }
}

/// Parses a TOML script.
pub fn parse_toml(text: &str) -> Result<Script, LineError> {
    let file: ScriptFile = toml::from_str(text).map_err(|e| {
        let line = e.span().map(|s| line_of(text, s.start)).unwrap_or(0);
        LineError::new(line, e.message().to_string())
    })?;
    let ignore_line = text
        .lines()
        .position(|l| l.trim_start().starts_with("ignore"))
        .map_or(1, |i| i + 1);
    let ignore = parse_ignore(file.ignore, ignore_line)?;
    let node = file.node.unwrap_or(1);
    let sdo_timeout = Duration::from_millis(file.sdo_timeout_ms.unwrap_or(DEFAULT_SDO_TIMEOUT_MS));
    let mut actions = Vec::with_capacity(file.step.len());
    for spanned in &file.step {
        let line = line_of(text, spanned.span().start);
        let action = step_action(spanned.get_ref(), node, sdo_timeout)
            .map_err(|what| LineError::new(line, format!("step: {what}")))?;
        actions.push(with_line(action, line));
    }
    if actions.is_empty() {
        return Err(LineError::new(0, "the script has no [[step]]"));
    }
    Ok(Script { ignore, actions })
}

fn with_line(action: Action, line: usize) -> Action {
    match action {
        Action::Frame(mut s) => {
            s.line = line;
            Action::Frame(s)
        }
        Action::Sdo(t) => Action::Sdo(t.at_line(line)),
    }
}

fn node_id(node: u8) -> Result<u8, String> {
    if (1..=127).contains(&node) {
        Ok(node)
    } else {
        Err(format!("node {node} is outside 1…127"))
    }
}

/// What one `[[step]]` does; an error says which keys do not fit.
fn step_action(s: &StepSpec, node: u8, sdo_timeout: Duration) -> Result<Action, String> {
    let kinds = [
        s.read.is_some(),
        s.write.is_some(),
        s.nmt.is_some(),
        s.rpdo.is_some(),
        s.frame.is_some(),
    ];
    if kinds.iter().filter(|k| **k).count() != 1 {
        return Err("give exactly one of read, write, nmt, rpdo, frame".into());
    }
    let window = Duration::from_millis(s.window_ms.unwrap_or(0));
    let sdo_rule = |node: u8| AnswerRule {
        window,
        until: Some(Awaited {
            cob_id: 0x580 + u16::from(node),
            timeout: s.wait_ms.map_or(sdo_timeout, Duration::from_millis),
        }),
    };
    if let Some(obj) = &s.read {
        let node = node_id(s.node.unwrap_or(node))?;
        let (index, sub) =
            parse_object(obj).ok_or_else(|| format!("read: {obj:?} is not IIII:SS"))?;
        return Ok(Action::Sdo(
            SdoTransfer::read(node, index, sub, sdo_rule(node), 0).named(s.name.clone()),
        ));
    }
    if let Some(obj) = &s.write {
        let node = node_id(s.node.unwrap_or(node))?;
        let (index, sub) =
            parse_object(obj).ok_or_else(|| format!("write: {obj:?} is not IIII:SS"))?;
        let data = match (&s.type_name, &s.value, &s.data) {
            (Some(t), Some(v), None) => {
                let ty = crate::value_text::parse_type(t)
                    .ok_or_else(|| format!("type {t:?} is unknown (u8, u16, i32, …)"))?;
                crate::value_text::encode(ty, &v.text()).map_err(|e| format!("value: {e}"))?
            }
            (None, None, Some(d)) => crate::value_text::parse_hex(d)
                .ok_or_else(|| format!("data {d:?} is not hex bytes"))?,
            _ => return Err("write needs `type` and `value`, or `data`".into()),
        };
        if data.is_empty() {
            return Err("write: no bytes to write".into());
        }
        let most = 7 * super::sdo_transfer::MAX_SEGMENTS as usize;
        if data.len() > most {
            return Err(format!(
                "write: {} bytes, a script writes at most {most}",
                data.len()
            ));
        }
        return Ok(Action::Sdo(
            SdoTransfer::write(node, index, sub, data, sdo_rule(node), 0).named(s.name.clone()),
        ));
    }
    if s.type_name.is_some() || s.value.is_some() {
        return Err("`type` and `value` belong to a write".into());
    }
    if let Some(cmd) = &s.nmt {
        let target = s.node.unwrap_or(node);
        if target > 127 {
            return Err(format!("node {target} is outside 0…127"));
        }
        let command = [
            NmtCommand::Start,
            NmtCommand::Stop,
            NmtCommand::EnterPreOperational,
            NmtCommand::ResetNode,
            NmtCommand::ResetCommunication,
        ]
        .into_iter()
        .find(|c| c.name() == cmd)
        .ok_or_else(|| {
            format!(
                "nmt {cmd:?} is not start, stop, pre-operational, reset-node or reset-communication"
            )
        })?;
        let reset = matches!(
            command,
            NmtCommand::ResetNode | NmtCommand::ResetCommunication
        );
        let wait = Duration::from_millis(s.wait_ms.unwrap_or(if reset {
            DEFAULT_RESET_WAIT_MS
        } else {
            DEFAULT_NMT_WAIT_MS
        }));
        // All nodes: no one heartbeat to await; answers within the wait.
        let rule = if target == 0 {
            AnswerRule {
                window: window.max(wait),
                until: None,
            }
        } else {
            AnswerRule {
                window,
                until: Some(Awaited {
                    cob_id: 0x700 + u16::from(target),
                    timeout: wait,
                }),
            }
        };
        let request = CanFrame::new(0x000, &[command.cs(), target]).map_err(|e| e.to_string())?;
        let label = s.name.clone().unwrap_or_else(|| {
            if target == 0 {
                format!("nmt {}, all nodes", command.name())
            } else {
                format!("nmt {} node {target}", command.name())
            }
        });
        return Ok(Action::Frame(Step {
            label,
            line: 0,
            request,
            rule,
        }));
    }
    if s.wait_ms.is_some() {
        return Err("wait_ms belongs to read, write and nmt; a frame gathers for window_ms".into());
    }
    let window = Duration::from_millis(s.window_ms.unwrap_or(DEFAULT_WINDOW_MS));
    let request = if let Some(n) = s.rpdo {
        if !(1..=4).contains(&n) {
            return Err(format!("rpdo {n} is not 1…4 (the predefined RPDO COB-IDs)"));
        }
        let node = node_id(s.node.unwrap_or(node))?;
        let data = s.data.as_deref().unwrap_or("");
        let bytes = crate::value_text::parse_hex(data)
            .ok_or_else(|| format!("data {data:?} is not hex bytes"))?;
        CanFrame::new(0x100 * u16::from(n) + 0x100 + u16::from(node), &bytes)
            .map_err(|e| format!("rpdo: {e}"))?
    } else if let Some(f) = &s.frame {
        if s.data.is_some() {
            return Err("frame carries its data (`ID#DATA`)".into());
        }
        crate::trace::parse_candump_frame(f).map_err(|e| format!("frame {f:?}: {e}"))?
    } else {
        return Err("give exactly one of read, write, nmt, rpdo, frame".into());
    };
    let label = s.name.clone().unwrap_or_else(|| describe(&request));
    Ok(Action::Frame(Step {
        label,
        line: 0,
        request,
        rule: AnswerRule {
            window,
            until: None,
        },
    }))
}

fn describe(frame: &CanFrame) -> String {
    let mut text = String::new();
    let _ = canopen::decode::describe(frame, &mut text);
    text
}

/// Whether a master sends this frame (the node's own frames in a log are its old answers).
fn from_master(frame: &CanFrame) -> bool {
    let Some(cob) = frame.cob_id() else {
        return false;
    };
    match classify(cob).0 {
        Function::Nmt
        | Function::Sync
        | Function::Time
        | Function::Rpdo(_)
        | Function::SdoRx
        | Function::LssMaster => true,
        Function::ErrorControl => frame.rtr,
        _ => false,
    }
}

/// The requests of a candump log.
pub fn parse_candump(text: &str, options: CandumpOptions) -> Result<Script, LineError> {
    let lines =
        crate::trace::parse_candump_lines(text).map_err(|e| LineError::new(e.line, e.what))?;
    let requests: Vec<_> = lines.iter().filter(|l| from_master(&l.frame)).collect();
    let mut actions = Vec::with_capacity(requests.len());
    for (i, r) in requests.iter().enumerate() {
        let window = requests
            .get(i + 1)
            .map_or(options.quiet, |next| next.time.saturating_sub(r.time));
        let cob = r.frame.cob_id().unwrap_or(0);
        let node = cob & 0x7F;
        let until = match classify(cob).0 {
            Function::SdoRx => Some(Awaited {
                cob_id: 0x580 + node,
                timeout: options.sdo_timeout,
            }),
            Function::ErrorControl => Some(Awaited {
                cob_id: cob,
                timeout: options.sdo_timeout,
            }),
            _ => None,
        };
        actions.push(Action::Frame(Step {
            label: describe(&r.frame),
            line: r.line,
            request: r.frame,
            rule: AnswerRule { window, until },
        }));
    }
    if actions.is_empty() {
        return Err(LineError::new(0, "the log has no request a master sends"));
    }
    Ok(Script {
        ignore: DEFAULT_IGNORE.to_vec(),
        actions,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options() -> CandumpOptions {
        CandumpOptions {
            sdo_timeout: Duration::from_millis(1000),
            quiet: Duration::from_millis(200),
        }
    }

    fn first_step(action: &Action) -> Step {
        match action {
            Action::Frame(s) => s.clone(),
            Action::Sdo(t) => t.clone().first(),
        }
    }

    #[test]
    fn a_toml_script_becomes_its_steps_with_their_lines() {
        let text = r#"node = 2
sdo_timeout_ms = 500

[[step]]
read = "1018:01"

[[step]]
write = "6040:00"
type = "u16"
value = 6

[[step]]
nmt = "reset-communication"

[[step]]
rpdo = 1
data = "0F 00"
window_ms = 50

[[step]]
frame = "080#"
name = "a SYNC"
"#;
        let s = parse_toml(text).expect("script");
        assert_eq!(s.ignore, DEFAULT_IGNORE.to_vec());
        let steps: Vec<Step> = s.actions.iter().map(first_step).collect();
        assert_eq!(steps.len(), 5);
        assert_eq!(steps[0].label, "sdo read 1018:01");
        assert_eq!(steps[0].request.id, 0x602);
        assert_eq!(steps[0].line, 4, "the `[[step]]` line");
        assert_eq!(
            steps[0].rule.until,
            Some(Awaited {
                cob_id: 0x582,
                timeout: Duration::from_millis(500)
            })
        );
        assert_eq!(
            steps[1].request.payload(),
            &[0x2B, 0x40, 0x60, 0, 6, 0, 0, 0]
        );
        assert_eq!(steps[1].line, 7);
        assert_eq!(steps[2].request.payload(), &[0x82, 2]);
        assert_eq!(steps[2].label, "nmt reset-communication node 2");
        assert_eq!(
            steps[2].rule.until,
            Some(Awaited {
                cob_id: 0x702,
                timeout: Duration::from_millis(5000)
            })
        );
        assert_eq!(steps[3].request.id, 0x202);
        assert_eq!(steps[3].rule.window, Duration::from_millis(50));
        assert_eq!(steps[4].label, "a SYNC");
        assert_eq!(steps[4].request.id, 0x080);
        assert_eq!(steps[4].line, 20);
    }

    #[test]
    fn a_bad_step_is_refused_with_its_line() {
        let bad = |text: &str| parse_toml(text).expect_err("refused");
        let e = bad("[[step]]\nread = \"1018:01\"\n\n[[step]]\nread = \"10x8\"\n");
        assert_eq!(e.line, 4, "{e}");
        assert!(e.what.contains("IIII:SS"), "{e}");
        let e = bad("[[step]]\nread = \"1018:01\"\nnmt = \"start\"\n");
        assert!(e.what.contains("exactly one"), "{e}");
        let e = bad("[[step]]\nwrite = \"6040:00\"\ntype = \"u16\"\nvalue = 70000\n");
        assert!(e.what.contains("value"), "{e}");
        let e = bad("[[step]]\nnmt = \"go\"\n");
        assert!(e.what.contains("start, stop"), "{e}");
        let e = bad("[[step]]\nread = \"1018:01\"\ncolour = 1\n");
        assert!(e.line >= 1 && e.what.contains("colour"), "{e}");
        let e = bad("ignore = [\"9999\"]\n[[step]]\nread = \"1018:01\"\n");
        assert_eq!(e.line, 1, "{e}");
        let e = bad("[[step]]\nrpdo = 5\n");
        assert!(e.what.contains("1…4"), "{e}");
        let e = bad("node = 1\n");
        assert!(e.what.contains("no [[step]]"), "{e}");
    }

    #[test]
    fn a_candump_log_gives_the_masters_frames_with_the_logs_spacing() {
        let log = "\
(100.000000) can0 601#4018100100000000
(100.000400) can0 581#4318100119000000
(100.000900) can0 701#05
(100.010000) can0 000#0101
(100.030000) can0 181#3702
(100.050000) can0 201#0F00
";
        let s = parse_candump(log, options()).expect("script");
        let steps: Vec<Step> = s.actions.iter().map(first_step).collect();
        assert_eq!(steps.len(), 3);
        assert_eq!(steps[0].line, 1);
        assert_eq!(steps[0].rule.window, Duration::from_millis(10));
        assert_eq!(steps[0].rule.until.map(|a| a.cob_id), Some(0x581));
        assert_eq!(steps[1].line, 4);
        assert_eq!(steps[1].rule.window, Duration::from_millis(40));
        assert_eq!(steps[1].rule.until, None);
        assert_eq!(steps[2].rule.window, Duration::from_millis(200));
        let e = parse_candump("(1.0) can0 601#4\n", options()).expect_err("bad data");
        assert_eq!(e.line, 1);
        let e = parse_candump("(1.0) can0 581#40\n", options()).expect_err("no request");
        assert!(e.what.contains("no request"), "{e}");
    }
}
