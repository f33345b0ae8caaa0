//! The scenario file: a cell and a timeline of steps, each an action or an expectation at a
//! time (TOML).
//!
//! ```toml
//! cell = "../cell.toml"          # a cell file (relative to this file), or [cell] inline
//! until = "2s"                   # optional: how long the run lasts at least
//!
//! [[step]]
//! at = "0s"
//! nmt = "start"                  # node = 0 (all) unless `node` names one
//!
//! [[step]]
//! at = "1.5s"
//! din = 7                        # force DIN7 (level = true unless given)
//!
//! [[step]]
//! at = "1.5s"
//! name = "the drive faults"
//! expect = "6041:00"
//! mask = 0x004F
//! equals = 0x0008
//! within = "50ms"
//! ```
//!
//! One key names what a step does: an action (`write`, `sdo_write`, `din`, `load`,
//! `ambient`, `encoder`, `switch` (the plant's physics), `raise`,
//! `clear` (a diagnostic message by its number), `fault`,
//! `clear_faults`, `nmt`, `frame`, `ethercat_line` (a live cell's chain)) or an expectation (`expect`, `expect_state`, `expect_emcy`,
//! `expect_frame`); an action with `repeat` and `every` is done that many times. [`Step::kind`] turns the keys into an [`Action`] or an [`Expectation`]; a
//! new action is a field here, a variant of [`Action`] and its arm in each rig.

use std::path::{Path, PathBuf};
use std::time::Duration;

use canopen::{CanFrame, NmtCommand};
use serde::Deserialize;

use crate::cell::config::{parse_key, CellFile};
use crate::cell::wire_faults::{FaultName, FaultSpec, ReachName, TimeSpan, WireFault};

/// How long an expectation waits unless its step says `within`.
pub const DEFAULT_WITHIN: Duration = Duration::from_millis(100);

#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("scenario: {0}")]
    Toml(#[from] toml::de::Error),
    #[error("step {step} (at {at}): {what}")]
    Step {
        step: usize,
        at: String,
        what: String,
    },
    #[error("cell: {0}")]
    Cell(String),
}

/// The file as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioFile {
    /// What the report calls the scenario (default: the file's name).
    pub name: Option<String>,
    /// The cell: a path to a cell file, or a cell file's tables inline.
    pub cell: Option<CellRef>,
    /// The run lasts at least this long (default: until the last step has ended).
    pub until: Option<TimeSpan>,
    #[serde(default)]
    pub step: Vec<Step>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum CellRef {
    Path(PathBuf),
    Inline(Box<CellFile>),
}

pub use crate::value_text::Number;

/// One `[[step]]` as written.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Step {
    pub at: Option<TimeSpan>,
    /// The expectation's name in the report (default: made from the step).
    pub name: Option<String>,
    /// The drive, by node-ID (default: the cell's first drive); for `nmt`, the target.
    pub node: Option<u8>,
    /// The bus (default 0): for `fault`, `clear_faults`, `frame`, `nmt`, `sdo_write`, frames.
    pub bus: Option<usize>,

    // Actions.
    /// Object `"IIII:SS"` written through the cell (no SDO).
    pub write: Option<String>,
    /// Object `"IIII:SS"` written by a master client: an expedited SDO download on the bus.
    pub sdo_write: Option<String>,
    pub value: Option<Number>,
    /// Force digital input DINn to `level` (default HIGH).
    pub din: Option<u8>,
    pub level: Option<bool>,
    /// Load torque on the shaft, N·m.
    pub load: Option<f64>,
    /// The ambient temperature of the drive and its motor, °C (the plant heats or cools
    /// towards it; the drive's supervision raises its temperature messages).
    pub ambient: Option<f64>,
    /// The encoder: `disconnected`, `noisy` (with `noise`, increments; default 100) or
    /// `connected`.
    pub encoder: Option<String>,
    pub noise: Option<u32>,
    /// A limit or home switch by name (`limit_positive`, `limit_negative`, `home`), on the
    /// input its function is on: actuated (`level = true`, the default), released (`false`)
    /// or back to the travel (`release = true`).
    pub switch: Option<String>,
    pub release: Option<bool>,
    /// A diagnostic message raised by its number as the manual writes it (`"08-2"`,
    /// `"2Fh"`, `"0x8611"` …), as if the drive's supervision had found it.
    pub raise: Option<String>,
    /// A raised diagnostic message cleared by its number.
    pub clear: Option<String>,
    /// A wire fault ([`crate::cell::wire_faults`]) with `node`, `reach`, `cob_id`, `share`,
    /// `delay`, `frames`, `for`.
    pub fault: Option<FaultName>,
    pub reach: Option<ReachName>,
    pub cob_id: Option<u16>,
    pub share: Option<f64>,
    pub delay: Option<TimeSpan>,
    pub frames: Option<u32>,
    #[serde(rename = "for")]
    pub lasting: Option<TimeSpan>,
    /// Ends every wire fault of the bus.
    pub clear_faults: Option<bool>,
    /// NMT node control: start, stop, pre-operational, reset-node, reset-communication.
    pub nmt: Option<String>,
    /// A raw CAN frame, cansend style: `"601#4000100000000000"`.
    pub frame: Option<String>,
    /// A Modbus TCP request (the ADU in hex, MBAP header first) to the CMMO-ST `node`, as
    /// its one client sends it (the virtual clock's rig).
    pub modbus_request: Option<String>,
    /// A change to an EtherCAT chain's line, as the API takes it:
    /// `ethercat_line = { action = "pull-cable", after = 1 }` on chain `chain` (default 0)
    /// ([`crate::cell::ethercat_line`]; a live cell's).
    pub ethercat_line: Option<crate::cell::ethercat_line::LineAction>,
    pub chain: Option<usize>,

    // Expectations.
    /// Object `"IIII:SS"` whose value & `mask` == `equals` within `within`.
    pub expect: Option<String>,
    pub mask: Option<Number>,
    pub equals: Option<Number>,
    /// A CiA 402 state by name (`"fault"`, `"operation enabled"`, …) in 6041h.
    pub expect_state: Option<String>,
    /// An EMCY with this error code on the bus (from `node` if given).
    pub expect_emcy: Option<Number>,
    /// A frame on the bus: `"ID"` (any payload) or `"ID#HEX"` (payload starting with HEX).
    pub expect_frame: Option<String>,
    /// The frame / EMCY must not be seen within `within` (a silence).
    pub absent: Option<bool>,
    pub within: Option<TimeSpan>,

    /// An action done `repeat` times, `every` apart (a master's SYNC every 10 ms).
    pub repeat: Option<u32>,
    pub every: Option<TimeSpan>,
}

/// Repetitions of one step at most.
pub const MAX_REPEAT: u32 = 100_000;

/// What an action does.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    Write {
        node: Option<u8>,
        index: u16,
        sub: u8,
        value: String,
    },
    SdoWrite {
        bus: usize,
        node: Option<u8>,
        index: u16,
        sub: u8,
        value: String,
    },
    Input {
        node: Option<u8>,
        din: u8,
        level: bool,
    },
    Load {
        node: Option<u8>,
        torque_nm: f64,
    },
    Fault {
        bus: usize,
        fault: WireFault,
    },
    ClearFaults {
        bus: usize,
    },
    /// The plant's physics: ambient temperature, encoder, a switch by name.
    Physics {
        node: Option<u8>,
        change: crate::cell::control::PhysicsChange,
    },
    /// A diagnostic message of the drive's table raised (`raise = true`) or cleared.
    Diagnostic {
        node: Option<u8>,
        number: String,
        raise: bool,
    },
    /// A Modbus TCP request to a CMMO-ST.
    Modbus {
        node: Option<u8>,
        request: Vec<u8>,
    },
    /// A change to EtherCAT chain `chain`'s line.
    EthercatLine {
        chain: usize,
        action: crate::cell::ethercat_line::LineAction,
    },
    /// A frame from outside on bus `bus` (NMT commands are such frames).
    Frame {
        bus: usize,
        frame: CanFrame,
    },
}

/// What an expectation looks for.
#[derive(Debug, Clone, PartialEq)]
pub enum Expectation {
    Object {
        node: Option<u8>,
        index: u16,
        sub: u8,
        mask: u64,
        equals: u64,
    },
    Emcy {
        bus: usize,
        node: Option<u8>,
        code: u16,
        absent: bool,
    },
    Frame {
        bus: usize,
        id: u32,
        prefix: Vec<u8>,
        absent: bool,
    },
}

/// A step made sense of.
#[derive(Debug, Clone, PartialEq)]
pub enum StepKind {
    Act(Action),
    Expect {
        name: String,
        what: Expectation,
        within: Duration,
    },
}

/// CiA 402 §6.1.2, Table 30: the states as 6041h shows them (mask, value).
pub const CIA402_STATES: &[(&str, u16, u16)] = &[
    ("not ready to switch on", 0x004F, 0x0000),
    ("switch on disabled", 0x004F, 0x0040),
    ("ready to switch on", 0x006F, 0x0021),
    ("switched on", 0x006F, 0x0023),
    ("operation enabled", 0x006F, 0x0027),
    ("quick stop active", 0x006F, 0x0007),
    ("fault reaction active", 0x004F, 0x000F),
    ("fault", 0x004F, 0x0008),
];

/// NMT node control commands by name (CiA 301 §7.2.8.3.1).
const NMT: &[(&str, NmtCommand)] = &[
    ("start", NmtCommand::Start),
    ("stop", NmtCommand::Stop),
    ("pre-operational", NmtCommand::EnterPreOperational),
    ("reset-node", NmtCommand::ResetNode),
    ("reset-communication", NmtCommand::ResetCommunication),
];

fn object(key: &str) -> Result<(u16, u8), String> {
    parse_key(key).ok_or_else(|| format!("{key:?}: an object as \"6041:00\""))
}

/// `"ID#HEX"` (cansend style) or `"ID"`: identifier and payload bytes.
pub fn parse_frame(text: &str) -> Result<(u32, Vec<u8>), String> {
    let (id, data) = text.split_once('#').unwrap_or((text, ""));
    let id = u32::from_str_radix(id.trim(), 16)
        .ok()
        .filter(|id| *id <= 0x7FF)
        .ok_or_else(|| format!("{text:?}: an 11-bit identifier in hex, as \"701#05\""))?;
    let data = if data.trim().is_empty() {
        Vec::new()
    } else {
        crate::value_text::parse_hex(data)
            .filter(|d| d.len() <= 8)
            .ok_or_else(|| format!("{text:?}: at most 8 bytes of hex after '#'"))?
    };
    Ok((id, data))
}

impl Step {
    /// What the step does; an error says which keys do not fit.
    pub fn kind(&self) -> Result<StepKind, String> {
        let keys = [
            ("write", self.write.is_some()),
            ("sdo_write", self.sdo_write.is_some()),
            ("din", self.din.is_some()),
            ("load", self.load.is_some()),
            ("ambient", self.ambient.is_some()),
            ("encoder", self.encoder.is_some()),
            ("switch", self.switch.is_some()),
            ("raise", self.raise.is_some()),
            ("clear", self.clear.is_some()),
            ("fault", self.fault.is_some()),
            ("clear_faults", self.clear_faults.is_some()),
            ("nmt", self.nmt.is_some()),
            ("frame", self.frame.is_some()),
            ("modbus_request", self.modbus_request.is_some()),
            ("ethercat_line", self.ethercat_line.is_some()),
            ("expect", self.expect.is_some()),
            ("expect_state", self.expect_state.is_some()),
            ("expect_emcy", self.expect_emcy.is_some()),
            ("expect_frame", self.expect_frame.is_some()),
        ];
        let given: Vec<&str> = keys.iter().filter(|(_, g)| *g).map(|(k, _)| *k).collect();
        let [key] = given.as_slice() else {
            return Err(format!(
                "one of write, sdo_write, din, load, ambient, encoder, switch, raise, clear, \
                 fault, clear_faults, nmt, frame, modbus_request, ethercat_line, expect, \
                 expect_state, expect_emcy, expect_frame (found {})",
                if given.is_empty() {
                    "none".to_string()
                } else {
                    given.join(", ")
                }
            ));
        };
        let bus = self.bus.unwrap_or(0);
        let value = || {
            self.value
                .as_ref()
                .map(Number::text)
                .ok_or_else(|| "a value".to_string())
        };
        let act = |a| Ok(StepKind::Act(a));
        let within = self.within.map_or(DEFAULT_WITHIN, |t| t.0);
        let expect = |name: String, what| {
            Ok(StepKind::Expect {
                name: self.name.clone().unwrap_or(name),
                what,
                within,
            })
        };
        let on_node = match self.node {
            Some(n) => format!(" of node {n}"),
            None => String::new(),
        };
        match *key {
            "write" | "sdo_write" => {
                let key = self
                    .write
                    .as_deref()
                    .or(self.sdo_write.as_deref())
                    .unwrap_or("");
                let (index, sub) = object(key)?;
                let value = value()?;
                if self.write.is_some() {
                    act(Action::Write {
                        node: self.node,
                        index,
                        sub,
                        value,
                    })
                } else {
                    act(Action::SdoWrite {
                        bus,
                        node: self.node,
                        index,
                        sub,
                        value,
                    })
                }
            }
            "din" => {
                let din = self.din.unwrap_or(0);
                if din > 15 {
                    return Err(format!("din {din}: DIN0…DIN15"));
                }
                act(Action::Input {
                    node: self.node,
                    din,
                    level: self.level.unwrap_or(true),
                })
            }
            "load" => {
                let torque_nm = self.load.unwrap_or(0.0);
                if !(torque_nm.is_finite() && torque_nm.abs() <= 1000.0) {
                    return Err(format!("load {torque_nm}: N·m within ±1000"));
                }
                act(Action::Load {
                    node: self.node,
                    torque_nm,
                })
            }
            "ambient" => {
                let c = self.ambient.unwrap_or(0.0);
                if !(c.is_finite() && (-50.0..=200.0).contains(&c)) {
                    return Err(format!("ambient {c}: °C within −50 … 200"));
                }
                act(Action::Physics {
                    node: self.node,
                    change: crate::cell::control::PhysicsChange::Ambient(c),
                })
            }
            "encoder" => {
                let name = self.encoder.as_deref().unwrap_or("");
                let fault =
                    drive::drive::plant_supervision::encoder_fault(name, self.noise.unwrap_or(100))
                        .ok_or_else(|| {
                            format!("encoder {name:?}: connected, disconnected or noisy")
                        })?;
                act(Action::Physics {
                    node: self.node,
                    change: crate::cell::control::PhysicsChange::Encoder(fault),
                })
            }
            "switch" => {
                let name = self.switch.as_deref().unwrap_or("");
                let switch =
                    drive::drive::named_switches::NamedSwitch::parse(name).ok_or_else(|| {
                        format!("switch {name:?}: limit_positive, limit_negative or home")
                    })?;
                let state = if self.release == Some(true) {
                    None
                } else {
                    Some(self.level.unwrap_or(true))
                };
                act(Action::Physics {
                    node: self.node,
                    change: crate::cell::control::PhysicsChange::Switch(switch, state),
                })
            }
            "raise" | "clear" => act(Action::Diagnostic {
                node: self.node,
                number: self
                    .raise
                    .as_deref()
                    .or(self.clear.as_deref())
                    .unwrap_or("")
                    .to_string(),
                raise: self.raise.is_some(),
            }),
            "fault" => {
                let spec = FaultSpec {
                    fault: self.fault,
                    node: self.node,
                    reach: self.reach,
                    cob_id: self.cob_id,
                    share: self.share,
                    delay: self.delay,
                    frames: self.frames,
                    lasting: self.lasting,
                };
                act(Action::Fault {
                    bus,
                    fault: spec.to_fault()?,
                })
            }
            "clear_faults" => act(Action::ClearFaults { bus }),
            "ethercat_line" => match self.ethercat_line {
                Some(action) => act(Action::EthercatLine {
                    chain: self.chain.unwrap_or(0),
                    action,
                }),
                None => Err("ethercat_line: no action".into()),
            },
            "nmt" => {
                let name = self.nmt.as_deref().unwrap_or("");
                let cmd = NMT
                    .iter()
                    .find(|(n, _)| *n == name)
                    .map(|(_, c)| *c)
                    .ok_or_else(|| {
                        format!("nmt {name:?}: start, stop, pre-operational, reset-node, reset-communication")
                    })?;
                let frame = CanFrame::new(0x000, &[cmd as u8, self.node.unwrap_or(0)])
                    .map_err(|e| format!("{e:?}"))?;
                act(Action::Frame { bus, frame })
            }
            "modbus_request" => {
                let text = self.modbus_request.as_deref().unwrap_or("");
                let request = crate::value_text::parse_hex(text)
                    .filter(|r| (8..=260).contains(&r.len()))
                    .ok_or_else(|| {
                        format!("modbus_request {text:?}: an ADU in hex (8 … 260 bytes)")
                    })?;
                act(Action::Modbus {
                    node: self.node,
                    request,
                })
            }
            "frame" => {
                let (id, data) = parse_frame(self.frame.as_deref().unwrap_or(""))?;
                let frame = CanFrame::new(id as u16, &data).map_err(|e| format!("{e:?}"))?;
                act(Action::Frame { bus, frame })
            }
            "expect" => {
                let key = self.expect.as_deref().unwrap_or("");
                let (index, sub) = object(key)?;
                let equals = self
                    .equals
                    .as_ref()
                    .and_then(Number::integer)
                    .ok_or("expect: `equals`, an integer")?;
                let mask = match &self.mask {
                    Some(m) => m.integer().ok_or("mask: an integer")?,
                    None => -1,
                };
                expect(
                    format!("{index:04X}:{sub:02X}{on_node} & {mask:#X} == {equals:#X}"),
                    Expectation::Object {
                        node: self.node,
                        index,
                        sub,
                        mask: mask as u64,
                        equals: equals as u64,
                    },
                )
            }
            "expect_state" => {
                let name = self
                    .expect_state
                    .as_deref()
                    .unwrap_or("")
                    .to_ascii_lowercase();
                let (_, mask, value) = CIA402_STATES
                    .iter()
                    .find(|(n, _, _)| *n == name)
                    .ok_or_else(|| {
                        let names: Vec<&str> = CIA402_STATES.iter().map(|s| s.0).collect();
                        format!("expect_state {name:?}: one of {}", names.join(", "))
                    })?;
                expect(
                    format!("state{on_node} {}", name.to_ascii_uppercase()),
                    Expectation::Object {
                        node: self.node,
                        index: 0x6041,
                        sub: 0,
                        mask: u64::from(*mask),
                        equals: u64::from(*value),
                    },
                )
            }
            "expect_emcy" => {
                let code = self
                    .expect_emcy
                    .as_ref()
                    .and_then(Number::integer)
                    .and_then(|c| u16::try_from(c).ok())
                    .ok_or("expect_emcy: an error code 0…0xFFFF")?;
                let absent = self.absent.unwrap_or(false);
                expect(
                    format!(
                        "{}EMCY {code:04X}h{on_node}",
                        if absent { "no " } else { "" }
                    ),
                    Expectation::Emcy {
                        bus,
                        node: self.node,
                        code,
                        absent,
                    },
                )
            }
            _ => {
                let text = self.expect_frame.as_deref().unwrap_or("");
                let (id, prefix) = parse_frame(text)?;
                let absent = self.absent.unwrap_or(false);
                expect(
                    format!("{}frame {text}", if absent { "no " } else { "" }),
                    Expectation::Frame {
                        bus,
                        id,
                        prefix,
                        absent,
                    },
                )
            }
        }
    }
}

/// A scenario ready to run: its name, its cell and its timeline in time order.
#[derive(Debug, Clone)]
pub struct Scenario {
    pub name: String,
    pub cell: Option<CellFile>,
    pub until: Duration,
    pub steps: Vec<(Duration, StepKind)>,
}

impl Scenario {
    /// Reads a scenario file; a cell file it names is found relative to it.
    pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let name = path.display().to_string();
        Scenario::parse(&text, &name, path.parent())
    }

    /// Parses scenario text; `base` is where a cell file it names is found (none: no cell
    /// file by path, as from the API).
    pub fn parse(text: &str, name: &str, base: Option<&Path>) -> Result<Scenario, ScenarioError> {
        let file: ScenarioFile = toml::from_str(text)?;
        let cell = match file.cell {
            None => None,
            Some(CellRef::Inline(c)) => Some(*c),
            Some(CellRef::Path(p)) => match base {
                Some(b) => Some(
                    CellFile::load(&b.join(&p)).map_err(|e| ScenarioError::Cell(e.to_string()))?,
                ),
                None => None,
            },
        };
        let mut steps = Vec::new();
        for (i, s) in file.step.iter().enumerate() {
            let at = s.at.unwrap_or_default().0;
            let err = |what: String| ScenarioError::Step {
                step: i + 1,
                at: TimeSpan(at).to_string(),
                what,
            };
            let kind = s.kind().map_err(err)?;
            match (s.repeat, s.every) {
                (None, None) => steps.push((at, kind)),
                (Some(n), Some(every)) if (1..=MAX_REPEAT).contains(&n) && !every.0.is_zero() => {
                    if matches!(kind, StepKind::Expect { .. }) {
                        return Err(err("repeat is an action's".into()));
                    }
                    for k in 0..n {
                        steps.push((at + every.0 * k, kind.clone()));
                    }
                }
                _ => {
                    return Err(err(format!(
                        "repeat (1…{MAX_REPEAT}) and every (above 0) go together"
                    )))
                }
            }
        }
        // Stable: steps at one time keep the file's order.
        steps.sort_by_key(|(at, _)| *at);
        let last = steps
            .iter()
            .map(|(at, k)| match k {
                StepKind::Expect { within, .. } => *at + *within,
                StepKind::Act(_) => *at,
            })
            .max()
            .unwrap_or_default();
        Ok(Scenario {
            name: file.name.unwrap_or_else(|| name.to_string()),
            cell,
            until: file.until.map_or(last, |u| u.0.max(last)),
            steps,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = r#"
        [cell]
        [[cell.drive]]
        device = "cmmp-as"
        node = 1

        [[step]]
        at = "0s"
        nmt = "start"

        [[step]]
        at = "1.5s"
        din = 7

        [[step]]
        at = "1.5s"
        expect = "6041:00"
        mask = 0x4F
        equals = 0x08
        within = "50ms"

        [[step]]
        at = "1s"
        name = "heartbeat lost"
        expect_emcy = 0x8130
        node = 2
    "#;

    #[test]
    fn an_ethercat_line_step_is_the_apis_action() {
        let text = r#"
            [[step]]
            at = "1s"
            ethercat_line = { action = "pull-cable", after = 32 }
            chain = 1
        "#;
        let s = Scenario::parse(text, "t", None).expect("parses");
        let kinds: Vec<_> = s.steps.iter().map(|(_, k)| k.clone()).collect();
        assert!(
            matches!(
                kinds.as_slice(),
                [StepKind::Act(Action::EthercatLine {
                    chain: 1,
                    action: crate::cell::ethercat_line::LineAction::PullCable { after: 32 }
                })]
            ),
            "{kinds:?}"
        );
    }

    #[test]
    fn a_scenario_parses_into_a_sorted_timeline() {
        let s = Scenario::parse(TEXT, "t", None).expect("parses");
        assert!(s.cell.is_some());
        assert_eq!(s.steps.len(), 4);
        assert_eq!(s.steps[1].0, Duration::from_secs(1));
        assert_eq!(
            s.steps[0].1,
            StepKind::Act(Action::Frame {
                bus: 0,
                frame: CanFrame::new(0, &[1, 0]).expect("frame")
            })
        );
        let StepKind::Expect { name, within, .. } = &s.steps[1].1 else {
            panic!("an expectation");
        };
        assert_eq!(name, "heartbeat lost");
        assert_eq!(*within, DEFAULT_WITHIN);
        let StepKind::Expect { name, what, .. } = &s.steps[3].1 else {
            panic!("an expectation");
        };
        assert_eq!(name, "6041:00 & 0x4F == 0x8");
        assert_eq!(
            *what,
            Expectation::Object {
                node: None,
                index: 0x6041,
                sub: 0,
                mask: 0x4F,
                equals: 8
            }
        );
        assert_eq!(s.until, Duration::from_millis(1550));
    }

    #[test]
    fn a_repeated_action_is_one_step_per_time() {
        let s = Scenario::parse(
            "[[step]]\nat = \"10ms\"\nframe = \"080\"\nrepeat = 3\nevery = \"5ms\"\n",
            "t",
            None,
        )
        .expect("parses");
        let times: Vec<u128> = s.steps.iter().map(|(t, _)| t.as_millis()).collect();
        assert_eq!(times, [10, 15, 20]);
        assert!(Scenario::parse("[[step]]\nframe = \"080\"\nrepeat = 3\n", "t", None).is_err());
        assert!(Scenario::parse(
            "[[step]]\nexpect_frame = \"080\"\nrepeat = 3\nevery = 1\n",
            "t",
            None
        )
        .is_err());
    }

    #[test]
    fn a_step_with_two_things_or_none_is_refused_with_its_number() {
        let e = Scenario::parse("[[step]]\nat = \"1s\"\ndin = 3\nload = 1.0\n", "t", None)
            .expect_err("refused");
        assert!(e.to_string().contains("step 1 (at 1000ms)"), "{e}");
        assert!(e.to_string().contains("din, load"), "{e}");
        let e = Scenario::parse("[[step]]\nat = \"1s\"\n", "t", None).expect_err("refused");
        assert!(e.to_string().contains("found none"), "{e}");
        let e = Scenario::parse("[[step]]\nexpect_state = \"dancing\"\n", "t", None)
            .expect_err("refused");
        assert!(e.to_string().contains("operation enabled"), "{e}");
        assert!(Scenario::parse("[[step]]\nbogus = 1\n", "t", None).is_err());
    }
}
