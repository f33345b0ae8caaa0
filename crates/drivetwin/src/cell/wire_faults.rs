//! Faults on the wire of one front end, as one concept: frames of a node (or of everything
//! outside the cell: socketcand clients, the SocketCAN interface, a master on Modbus TCP or
//! EtherCAT) dropped, delayed or corrupted, a cable cut for a time, a stopped SYNC.
//!
//! Sans-IO and deterministic: a share of frames is taken by a counter, never at random, so the
//! same faults on the virtual clock give the same frames bit for bit. The CAN bus applies them
//! through its link, a [`crate::cell::fault_injector::FaultInjector`] in [`crate::cell::can_segment::SegmentBus`];
//! the cell loop applies those of the Modbus and EtherCAT front ends and of single socketcand
//! clients.
//!
//! What a fault does to a CAN frame is CAN's own (ISO 11898-1): a corrupted
//! frame fails its CRC, every receiver sends an error frame and counts it in its fault
//! confinement ([`canbus::fault_confinement`]), the sender counts a transmit error and tries
//! again; nobody gets a wrong payload. A corrupted Modbus TCP or EtherCAT frame is discarded
//! by the receiver's checksum (Ethernet FCS), so it is lost as a dropped one.

use std::time::Duration;

use od::Instant;

/// The SYNC's COB-ID (CiA 301 §7.2.5: 080h by default).
pub const SYNC_COB_ID: u16 = 0x080;

/// Whose frames a fault takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Reach {
    /// One CANopen node of the bus, by node-ID: what it sends (a cable break: both ways).
    Node(u8),
    /// Everything outside the cell on this front end (clients, SocketCAN, a master): what it
    /// sends in (a cable break: both ways).
    Outside,
    /// Every frame on the bus, whoever sends it.
    Bus,
}

/// What happens to a frame the fault takes.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum FaultKind {
    /// Lost on the wire; `share` of the frames (1.0: every one), spread evenly.
    Drop { share: f64 },
    /// Arrives `by` later.
    Delay { by: Duration },
    /// Fails its CRC (CAN: an error frame; Ethernet: discarded); `share` of the frames (1.0:
    /// every one, the default), spread evenly as a drop's.
    Corrupt {
        #[serde(default = "every_frame")]
        share: f64,
    },
    /// The cable is cut: nothing passes either way.
    CableBreak,
}

/// The share of a fault that names none: every frame.
fn every_frame() -> f64 {
    1.0
}

/// One fault as asked for.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WireFault {
    pub reach: Reach,
    pub kind: FaultKind,
    /// Only frames of this CAN identifier (e.g. [`SYNC_COB_ID`]); none: every frame.
    pub cob_id: Option<u16>,
    /// Ends after taking this many frames; none: no count.
    pub frames: Option<u32>,
    /// Ends this long after it starts; none: until cleared.
    pub lasting: Option<Duration>,
}

impl WireFault {
    /// A stopped SYNC: every 080h frame on the bus is lost, whoever produces it (the cell's
    /// own SYNC producer or a master's).
    pub fn stopped_sync(lasting: Option<Duration>) -> WireFault {
        WireFault {
            reach: Reach::Bus,
            kind: FaultKind::Drop { share: 1.0 },
            cob_id: Some(SYNC_COB_ID),
            frames: None,
            lasting,
        }
    }

    /// A cable break of `reach` for `lasting` (none: until cleared).
    pub fn cable_break(reach: Reach, lasting: Option<Duration>) -> WireFault {
        WireFault {
            reach,
            kind: FaultKind::CableBreak,
            cob_id: None,
            frames: None,
            lasting,
        }
    }

    /// Checks the figures: a share within 0…1, a delay within a minute.
    pub fn validate(&self) -> Result<(), WireFaultError> {
        match self.kind {
            FaultKind::Drop { share } | FaultKind::Corrupt { share }
                if !(share > 0.0 && share <= 1.0) =>
            {
                Err(WireFaultError::Share(share))
            }
            FaultKind::Delay { by } if by > MAX_DELAY || by.is_zero() => {
                Err(WireFaultError::Delay(by))
            }
            _ => match self.reach {
                Reach::Node(n) if !(1..=127).contains(&n) => Err(WireFaultError::Node(n)),
                _ => Ok(()),
            },
        }
    }
}

/// The longest delay a fault may ask for.
pub const MAX_DELAY: Duration = Duration::from_secs(60);

/// Frames a tap holds before newer ones are dropped.
pub const TAP_QUEUE: usize = 16 * 1024;

/// Faults active at once on one front end at most.
pub const MAX_FAULTS: usize = 64;

#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum WireFaultError {
    #[error("share {0}: a part of the frames above 0 and at most 1")]
    Share(f64),
    #[error("delay {0:?}: above 0 and at most 60 s")]
    Delay(Duration),
    #[error("node {0}: a node-ID 1…127")]
    Node(u8),
    #[error("at most {MAX_FAULTS} faults at once")]
    TooMany,
    #[error("this front end cannot delay frames (only drop, corrupt, cable break)")]
    NoDelay,
    #[error("no fault {0}")]
    NoFault(u32),
}

/// What becomes of one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    Pass,
    /// Lost (dropped, or a cable break).
    Lost,
    /// Fails its CRC.
    Corrupt,
    /// Arrives at this time.
    Delay(Instant),
}

/// Who sent a frame, as the faults see it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sender {
    Node(u8),
    Outside,
}

/// A fault while it is active.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActiveFault {
    pub id: u32,
    pub fault: WireFault,
    /// When it ends, on the cell's clock.
    pub until: Option<Instant>,
    /// Frames it takes still (with a count).
    pub left: Option<u32>,
    /// The share's counter, in millionths.
    credit: u32,
}

impl ActiveFault {
    /// Whether the fault takes the frame it sees now, at `share` of the frames.
    fn take(&mut self, share: f64) -> bool {
        // Decision: a share is spread evenly by a counter (0.25: every 4th frame), not drawn
        // at random, so that a run is the same bit for bit.
        let step = (share.clamp(0.0, 1.0) * 1e6).round() as u32;
        self.credit = self.credit.saturating_add(step);
        if self.credit < 1_000_000 {
            return false;
        }
        self.credit -= 1_000_000;
        true
    }
}

/// The faults of one front end.
#[derive(Debug, Clone, Default)]
pub struct WireFaults {
    active: Vec<ActiveFault>,
    next_id: u32,
}

impl WireFaults {
    /// Starts `fault` at `now`; its id.
    pub fn add(&mut self, now: Instant, fault: WireFault) -> Result<u32, WireFaultError> {
        fault.validate()?;
        self.expire(now);
        if self.active.len() >= MAX_FAULTS {
            return Err(WireFaultError::TooMany);
        }
        self.next_id = self.next_id.wrapping_add(1);
        let until = fault
            .lasting
            .map(|d| Instant::from_nanos(now.as_nanos().saturating_add(nanos(d))));
        self.active.push(ActiveFault {
            id: self.next_id,
            fault,
            until,
            left: fault.frames,
            credit: 0,
        });
        Ok(self.next_id)
    }

    /// Ends fault `id`.
    pub fn remove(&mut self, id: u32) -> Result<(), WireFaultError> {
        let before = self.active.len();
        self.active.retain(|a| a.id != id);
        if self.active.len() == before {
            return Err(WireFaultError::NoFault(id));
        }
        Ok(())
    }

    /// Ends every fault.
    pub fn clear(&mut self) {
        self.active.clear();
    }

    /// The faults active at `now`.
    pub fn active(&mut self, now: Instant) -> &[ActiveFault] {
        self.expire(now);
        &self.active
    }

    pub fn is_empty(&self) -> bool {
        self.active.is_empty()
    }

    /// When the next fault ends.
    pub fn deadline(&self) -> Option<Instant> {
        self.active.iter().filter_map(|a| a.until).min()
    }

    /// Whether the cable of `who` is cut at `now` (it neither sends nor receives).
    pub fn cut_off(&self, now: Instant, who: Sender) -> bool {
        self.active.iter().any(|a| {
            a.fault.kind == FaultKind::CableBreak
                && a.until.is_none_or(|u| u > now)
                && reaches(a.fault.reach, who)
        })
    }

    /// What becomes of a frame with identifier `id` sent by `from` at `now`: the first fault
    /// that takes it decides (in the order they were added).
    pub fn judge(&mut self, now: Instant, from: Sender, id: u32) -> Verdict {
        if self.active.is_empty() {
            return Verdict::Pass;
        }
        self.expire(now);
        for a in &mut self.active {
            if !reaches(a.fault.reach, from) || a.fault.cob_id.is_some_and(|c| u32::from(c) != id) {
                continue;
            }
            let verdict = match a.fault.kind {
                FaultKind::CableBreak => Verdict::Lost,
                FaultKind::Delay { by } => Verdict::Delay(Instant::from_nanos(
                    now.as_nanos().saturating_add(nanos(by)),
                )),
                FaultKind::Drop { share } => {
                    if !a.take(share) {
                        continue;
                    }
                    Verdict::Lost
                }
                FaultKind::Corrupt { share } => {
                    if !a.take(share) {
                        continue;
                    }
                    Verdict::Corrupt
                }
            };
            if let Some(left) = a.left.as_mut() {
                *left = left.saturating_sub(1);
            }
            self.active.retain(|a| a.left != Some(0));
            return verdict;
        }
        Verdict::Pass
    }

    fn expire(&mut self, now: Instant) {
        self.active
            .retain(|a| a.until.is_none_or(|u| u > now) && a.left != Some(0));
    }
}

/// A front end of the cell a fault sits on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FrontEnd {
    /// CAN bus `n` of the cell: between its drives and its clients / SocketCAN interface.
    Bus(usize),
    /// The Modbus TCP server of Modbus drive `n` (in the order of the cell file).
    Modbus(usize),
    /// EtherCAT chain `n`.
    Ethercat(usize),
    /// One socketcand client of a bus, by its TCP port (the client's local port): the
    /// frames it sends to the bus and those the bus sends it, for it alone.
    Client(u16),
}

/// What a control handle asks of the wire ([`crate::cell::control::ControlHandle::wire`]).
#[derive(Debug)]
pub enum WireRequest {
    Add {
        front: FrontEnd,
        fault: WireFault,
    },
    Remove {
        front: FrontEnd,
        id: u32,
    },
    Clear {
        front: FrontEnd,
    },
    List {
        front: FrontEnd,
    },
    /// Starts a trace of bus `bus` into `path` (pcap; `*.log`: candump).
    StartTrace {
        bus: usize,
        path: std::path::PathBuf,
    },
    StopTrace {
        bus: usize,
    },
    /// Every frame on bus `bus` with its time on the cell's clock, until the receiver is
    /// dropped; a receiver that falls behind loses frames (the loop never waits).
    Tap {
        bus: usize,
        frames: std::sync::mpsc::SyncSender<(Duration, canopen::CanFrame)>,
    },
    /// The cell's clock.
    Now,
    /// A frame on bus `bus` from outside (as a client's: to the drives, the clients, the
    /// interface).
    Send {
        bus: usize,
        frame: canopen::CanFrame,
    },
}

#[derive(Debug, Clone, PartialEq)]
pub enum WireAnswer {
    Added(u32),
    Done,
    Faults(Vec<ActiveFault>),
    Now(Duration),
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WireError {
    #[error("the cell has stopped")]
    Stopped,
    #[error("no front end {0:?} in the cell")]
    NoFrontEnd(FrontEnd),
    #[error(transparent)]
    Fault(#[from] WireFaultError),
    #[error("bus {0} is traced already")]
    Tracing(usize),
    #[error("bus {0} has no trace")]
    NoTrace(usize),
    #[error("trace: {0}")]
    Trace(String),
}

/// A time span as people write it: `"1.5s"`, `"50ms"`, `"200us"`, or a number of
/// milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct TimeSpan(pub Duration);

impl TimeSpan {
    pub fn parse(text: &str) -> Result<TimeSpan, String> {
        let t = text.trim();
        let split = t
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap_or(t.len());
        let (number, unit) = t.split_at(split);
        let value: f64 = number
            .parse()
            .map_err(|_| format!("{text:?}: a time like \"1.5s\", \"50ms\" or \"200us\""))?;
        let scale = match unit.trim() {
            "s" => 1e9,
            "ms" | "" => 1e6,
            "us" | "µs" => 1e3,
            "ns" => 1.0,
            "min" => 60e9,
            other => {
                return Err(format!(
                    "{text:?}: unknown unit {other:?} (s, ms, us, ns, min)"
                ))
            }
        };
        TimeSpan::from_nanos_f64(value * scale).ok_or_else(|| format!("{text:?}: out of range"))
    }

    fn from_nanos_f64(n: f64) -> Option<TimeSpan> {
        // Ten years at most: beyond that a time is a typing error.
        (n.is_finite() && (0.0..=3.2e17).contains(&n))
            .then(|| TimeSpan(Duration::from_nanos(n.round() as u64)))
    }
}

impl std::fmt::Display for TimeSpan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let n = self.0.as_nanos();
        if n.is_multiple_of(1_000_000) {
            write!(f, "{}ms", n / 1_000_000)
        } else if n.is_multiple_of(1_000) {
            write!(f, "{}us", n / 1_000)
        } else {
            write!(f, "{n}ns")
        }
    }
}

impl<'de> serde::Deserialize<'de> for TimeSpan {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(serde::Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Text(String),
            Millis(f64),
        }
        match Raw::deserialize(d)? {
            Raw::Text(t) => TimeSpan::parse(&t).map_err(serde::de::Error::custom),
            Raw::Millis(ms) => TimeSpan::from_nanos_f64(ms * 1e6)
                .ok_or_else(|| serde::de::Error::custom(format!("{ms} ms: out of range"))),
        }
    }
}

/// A fault's name as the API and the scenario files give it.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, utoipa::ToSchema,
)]
#[serde(rename_all = "kebab-case")]
pub enum FaultName {
    Drop,
    Delay,
    Corrupt,
    CableBreak,
    StopSync,
}

/// Whose frames, when no node is named.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, utoipa::ToSchema,
)]
#[serde(rename_all = "kebab-case")]
pub enum ReachName {
    /// What the front end's clients, interface or master send in (the default).
    Outside,
    /// Every frame.
    Bus,
}

/// A fault as written in a request or a scenario: `{"fault": "cable-break", "node": 1,
/// "for": "500ms"}`.
#[derive(Debug, Clone, Default, PartialEq, serde::Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct FaultSpec {
    pub fault: Option<FaultName>,
    /// A node's frames (CAN only); none: `reach`.
    pub node: Option<u8>,
    pub reach: Option<ReachName>,
    /// Only frames of this CAN identifier.
    pub cob_id: Option<u16>,
    /// drop, corrupt: the share of frames taken, above 0 and at most 1 (default 1), spread
    /// evenly (0.25: every 4th frame).
    pub share: Option<f64>,
    /// delay: by how long (`"5ms"`, or milliseconds).
    #[schema(value_type = Option<String>)]
    pub delay: Option<TimeSpan>,
    /// Ends after this many frames.
    pub frames: Option<u32>,
    /// Ends after this long (`"1.5s"`, or milliseconds); none: until cleared.
    #[serde(rename = "for")]
    #[schema(value_type = Option<String>)]
    pub lasting: Option<TimeSpan>,
}

impl FaultSpec {
    pub fn to_fault(&self) -> Result<WireFault, String> {
        let name = self
            .fault
            .ok_or("which fault: drop, delay, corrupt, cable-break, stop-sync")?;
        let reach = match (self.node, self.reach) {
            (Some(_), Some(_)) => return Err("a node or a reach, not both".into()),
            (Some(n), None) => Reach::Node(n),
            (None, Some(ReachName::Bus)) => Reach::Bus,
            (None, _) => Reach::Outside,
        };
        let lasting = self.lasting.map(|t| t.0);
        if self.delay.is_some() && name != FaultName::Delay {
            return Err("delay is a delay fault's".into());
        }
        if self.share.is_some() && !matches!(name, FaultName::Drop | FaultName::Corrupt) {
            return Err("share is a drop or corrupt fault's".into());
        }
        let kind = match name {
            FaultName::Drop => FaultKind::Drop {
                share: self.share.unwrap_or(1.0),
            },
            FaultName::Delay => FaultKind::Delay {
                by: self.delay.ok_or("delay: by how long (\"5ms\")")?.0,
            },
            FaultName::Corrupt => FaultKind::Corrupt {
                share: self.share.unwrap_or(1.0),
            },
            FaultName::CableBreak => FaultKind::CableBreak,
            FaultName::StopSync => {
                if self.cob_id.is_some() || self.node.is_some() {
                    return Err("stop-sync takes every 080h frame; no node, no cob_id".into());
                }
                let mut f = WireFault::stopped_sync(lasting);
                f.frames = self.frames;
                return Ok(f);
            }
        };
        if self.cob_id.is_some_and(|c| c > 0x7FF) {
            return Err("cob_id: an 11-bit CAN identifier (at most 0x7FF)".into());
        }
        let fault = WireFault {
            reach,
            kind,
            cob_id: self.cob_id,
            frames: self.frames,
            lasting,
        };
        fault.validate().map_err(|e| e.to_string())?;
        Ok(fault)
    }
}

fn reaches(reach: Reach, who: Sender) -> bool {
    match (reach, who) {
        (Reach::Bus, _) => true,
        (Reach::Node(n), Sender::Node(m)) => n == m,
        (Reach::Outside, Sender::Outside) => true,
        _ => false,
    }
}

fn nanos(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(t: u64) -> Instant {
        Instant::from_millis(t)
    }

    fn drop_share(share: f64) -> WireFault {
        WireFault {
            reach: Reach::Node(1),
            kind: FaultKind::Drop { share },
            cob_id: None,
            frames: None,
            lasting: None,
        }
    }

    #[test]
    fn a_quarter_share_drops_every_fourth_frame() {
        let mut f = WireFaults::default();
        f.add(ms(0), drop_share(0.25)).expect("fault");
        let lost: Vec<bool> = (0..8)
            .map(|_| f.judge(ms(1), Sender::Node(1), 0x181) == Verdict::Lost)
            .collect();
        assert_eq!(lost, [false, false, false, true, false, false, false, true]);
        // Another node's frames pass.
        assert_eq!(f.judge(ms(1), Sender::Node(2), 0x182), Verdict::Pass);
    }

    #[test]
    fn a_quarter_share_corrupts_every_fourth_frame() {
        let mut f = WireFaults::default();
        f.add(
            ms(0),
            WireFault {
                kind: FaultKind::Corrupt { share: 0.25 },
                ..drop_share(1.0)
            },
        )
        .expect("fault");
        let verdicts: Vec<Verdict> = (0..8)
            .map(|_| f.judge(ms(1), Sender::Node(1), 0x181))
            .collect();
        let (p, c) = (Verdict::Pass, Verdict::Corrupt);
        assert_eq!(verdicts, [p, p, p, c, p, p, p, c]);
        assert_eq!(f.judge(ms(1), Sender::Node(2), 0x182), Verdict::Pass);
    }

    #[test]
    fn a_share_with_a_count_ends_after_the_frames_it_took() {
        let mut f = WireFaults::default();
        f.add(
            ms(0),
            WireFault {
                kind: FaultKind::Corrupt { share: 0.5 },
                frames: Some(2),
                ..drop_share(1.0)
            },
        )
        .expect("fault");
        let verdicts: Vec<Verdict> = (0..6)
            .map(|_| f.judge(ms(1), Sender::Node(1), 0x181))
            .collect();
        let (p, c) = (Verdict::Pass, Verdict::Corrupt);
        assert_eq!(verdicts, [p, c, p, c, p, p]);
        assert!(f.is_empty());
    }

    #[test]
    fn a_corrupt_share_is_taken_from_a_spec_and_a_bad_one_refused() {
        let spec: FaultSpec =
            serde_json::from_str(r#"{"fault": "corrupt", "share": 0.5}"#).expect("spec");
        assert_eq!(
            spec.to_fault().map(|f| f.kind),
            Ok(FaultKind::Corrupt { share: 0.5 })
        );
        let spec: FaultSpec = serde_json::from_str(r#"{"fault": "corrupt"}"#).expect("spec");
        assert_eq!(
            spec.to_fault().map(|f| f.kind),
            Ok(FaultKind::Corrupt { share: 1.0 })
        );
        let spec: FaultSpec =
            serde_json::from_str(r#"{"fault": "corrupt", "share": 1.5}"#).expect("spec");
        assert_eq!(
            spec.to_fault(),
            Err("share 1.5: a part of the frames above 0 and at most 1".into())
        );
        let spec: FaultSpec =
            serde_json::from_str(r#"{"fault": "delay", "delay": "5ms", "share": 0.5}"#)
                .expect("spec");
        assert_eq!(
            spec.to_fault(),
            Err("share is a drop or corrupt fault's".into())
        );
        // A fault written before corruption had a share still reads: every frame.
        let kind: FaultKind = serde_json::from_str(r#"{"kind": "corrupt"}"#).expect("kind");
        assert_eq!(kind, FaultKind::Corrupt { share: 1.0 });
        let mut f = WireFaults::default();
        let bad = WireFault {
            kind: FaultKind::Corrupt { share: 0.0 },
            ..drop_share(1.0)
        };
        assert_eq!(f.add(ms(0), bad), Err(WireFaultError::Share(0.0)));
        let nan = WireFault {
            kind: FaultKind::Corrupt { share: f64::NAN },
            ..drop_share(1.0)
        };
        assert!(matches!(f.add(ms(0), nan), Err(WireFaultError::Share(_))));
    }

    #[test]
    fn a_counted_fault_ends_after_its_frames() {
        let mut f = WireFaults::default();
        f.add(
            ms(0),
            WireFault {
                frames: Some(2),
                kind: FaultKind::Corrupt { share: 1.0 },
                ..drop_share(1.0)
            },
        )
        .expect("fault");
        assert_eq!(f.judge(ms(1), Sender::Node(1), 0x701), Verdict::Corrupt);
        assert_eq!(f.judge(ms(1), Sender::Node(1), 0x701), Verdict::Corrupt);
        assert_eq!(f.judge(ms(1), Sender::Node(1), 0x701), Verdict::Pass);
        assert!(f.is_empty());
    }

    #[test]
    fn a_cable_break_ends_after_its_time() {
        let mut f = WireFaults::default();
        f.add(
            ms(100),
            WireFault::cable_break(Reach::Node(3), Some(Duration::from_millis(50))),
        )
        .expect("fault");
        assert!(f.cut_off(ms(120), Sender::Node(3)));
        assert!(!f.cut_off(ms(120), Sender::Outside));
        assert_eq!(f.judge(ms(120), Sender::Node(3), 0x703), Verdict::Lost);
        assert_eq!(f.deadline(), Some(ms(150)));
        assert!(!f.cut_off(ms(150), Sender::Node(3)));
        assert_eq!(f.judge(ms(150), Sender::Node(3), 0x703), Verdict::Pass);
    }

    #[test]
    fn a_stopped_sync_takes_only_080h() {
        let mut f = WireFaults::default();
        f.add(ms(0), WireFault::stopped_sync(None)).expect("fault");
        assert_eq!(f.judge(ms(1), Sender::Outside, 0x080), Verdict::Lost);
        assert_eq!(f.judge(ms(1), Sender::Node(1), 0x080), Verdict::Lost);
        assert_eq!(f.judge(ms(1), Sender::Outside, 0x601), Verdict::Pass);
    }

    #[test]
    fn a_delay_gives_the_arrival_time() {
        let mut f = WireFaults::default();
        let id = f
            .add(
                ms(0),
                WireFault {
                    reach: Reach::Outside,
                    kind: FaultKind::Delay {
                        by: Duration::from_millis(5),
                    },
                    cob_id: None,
                    frames: None,
                    lasting: None,
                },
            )
            .expect("fault");
        assert_eq!(
            f.judge(ms(10), Sender::Outside, 0x601),
            Verdict::Delay(ms(15))
        );
        f.remove(id).expect("removed");
        assert_eq!(f.remove(id), Err(WireFaultError::NoFault(id)));
    }

    #[test]
    fn time_spans_as_people_write_them() {
        assert_eq!(
            TimeSpan::parse("1.5s"),
            Ok(TimeSpan(Duration::from_millis(1500)))
        );
        assert_eq!(
            TimeSpan::parse("50ms"),
            Ok(TimeSpan(Duration::from_millis(50)))
        );
        assert_eq!(
            TimeSpan::parse("200us"),
            Ok(TimeSpan(Duration::from_micros(200)))
        );
        assert_eq!(
            TimeSpan::parse("20"),
            Ok(TimeSpan(Duration::from_millis(20)))
        );
        assert!(TimeSpan::parse("1.5 parsecs").is_err());
        assert!(TimeSpan::parse("-1s").is_err());
        assert_eq!(TimeSpan(Duration::from_millis(1500)).to_string(), "1500ms");
    }

    #[test]
    fn a_spec_becomes_a_fault() {
        let spec: FaultSpec =
            serde_json::from_str(r#"{"fault": "cable-break", "node": 3, "for": "500ms"}"#)
                .expect("spec");
        assert_eq!(
            spec.to_fault(),
            Ok(WireFault::cable_break(
                Reach::Node(3),
                Some(Duration::from_millis(500))
            ))
        );
        let spec: FaultSpec = serde_json::from_str(r#"{"fault": "stop-sync"}"#).expect("spec");
        assert_eq!(spec.to_fault(), Ok(WireFault::stopped_sync(None)));
        let spec: FaultSpec =
            serde_json::from_str(r#"{"fault": "drop", "share": 2}"#).expect("spec");
        assert!(spec.to_fault().is_err());
        let spec: FaultSpec = serde_json::from_str(r#"{"fault": "delay"}"#).expect("spec");
        assert!(spec.to_fault().is_err());
    }

    #[test]
    fn bad_figures_are_refused() {
        let mut f = WireFaults::default();
        assert_eq!(
            f.add(ms(0), drop_share(0.0)),
            Err(WireFaultError::Share(0.0))
        );
        assert_eq!(
            f.add(ms(0), drop_share(1.5)),
            Err(WireFaultError::Share(1.5))
        );
        assert_eq!(
            f.add(ms(0), WireFault::cable_break(Reach::Node(0), None)),
            Err(WireFaultError::Node(0))
        );
    }
}
