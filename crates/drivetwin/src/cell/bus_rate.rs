//! The bit rate a cell's CAN bus runs at. Every node is set to one by its switches or its
//! objects (CMMP-AS DIP6/DIP7 or DIN12/DIN13, manual Tab. 2.4 / 2.8; Nanotec rotary switches
//! and 2005h, §1.1.1; Kinco CAN_Baudrate 2F81h, §9.5 d5.17; a DCF's `[DeviceComissioning]
//! Baudrate`, CiA 306 §4.7), and a bus works only where they
//! agree: the bus takes theirs. A `bitrate` on the `[[bus]]` (or `drivetwin run --bitrate`) is
//! the rate the rest of the bus (the master) runs at: a node set to another one sees only
//! error frames and stays silent (ISO 11898-1; CMMP-AS §2.3). `"instant"` gives the bus no bit
//! time at all, for fast tests and latency benchmarks.
//!
//! Pure rules, no I/O: [`resolve`] takes the bus's setting and each node's rate.

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use drive::vendors::kinco::bit_rates as kinco_bit_rates;
use drive::vendors::nanotec::rotary_switches::{self, PowerOn};
use serde::Deserialize;

use crate::cell::fieldbus_switches::FieldbusSettings;

/// `bitrate` of a `[[bus]]` and `drivetwin run --bitrate`: bit/s, or `"instant"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(try_from = "RawBitrate")]
pub enum BitrateSetting {
    /// The bus runs at this many bit/s (above 0).
    Bits(u32),
    /// Frames cross at once: no arbitration, no bit time.
    Instant,
}

/// What a cell file may write for a bit rate.
#[derive(Deserialize)]
#[serde(untagged)]
enum RawBitrate {
    Number(i64),
    Word(String),
}

/// A bit rate that is neither a positive number of bit/s nor `instant`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("bitrate {0:?}: a number of bit/s above 0, or \"instant\"")]
pub struct BadBitrate(pub String);

impl TryFrom<RawBitrate> for BitrateSetting {
    type Error = BadBitrate;

    fn try_from(raw: RawBitrate) -> Result<Self, BadBitrate> {
        match raw {
            RawBitrate::Number(n) => u32::try_from(n)
                .ok()
                .filter(|b| *b > 0)
                .map(BitrateSetting::Bits)
                .ok_or_else(|| BadBitrate(n.to_string())),
            RawBitrate::Word(w) => w.parse(),
        }
    }
}

impl FromStr for BitrateSetting {
    type Err = BadBitrate;

    fn from_str(s: &str) -> Result<Self, BadBitrate> {
        if s == "instant" {
            return Ok(BitrateSetting::Instant);
        }
        s.parse::<u32>()
            .ok()
            .filter(|b| *b > 0)
            .map(BitrateSetting::Bits)
            .ok_or_else(|| BadBitrate(s.to_owned()))
    }
}

/// The bit rate a node is set to, and what sets it (a cell file key, or the default it
/// stands for), so a refusal can say where to change it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeRate {
    pub kbit: u16,
    pub set_by: String,
}

impl NodeRate {
    fn new(kbit: u16, set_by: impl Into<String>) -> Self {
        NodeRate {
            kbit,
            set_by: set_by.into(),
        }
    }

    /// A CMMP-AS: its `[drive.switches]` (`key` names the switches or inputs that set the
    /// rate), or without them an M3 whose block S1 has only DIP8 (CANopen on) ON.
    ///
    /// Decision: the manual prints no delivery state of S1 (Tab. 2.3–2.5). A drive without
    /// `[drive.switches]` is taken as DIP6/DIP7 OFF, 125 kbit/s: the untouched position,
    /// and the slowest rate the drive offers, so the twin is never faster than a real one.
    pub fn cmmp_as(switches: Option<(FieldbusSettings, &str)>) -> Self {
        match switches {
            Some((f, key)) => NodeRate::new(f.bit_rate_kbit, key),
            None => NodeRate::new(
                125,
                "[drive.switches] (none: DIP6/DIP7 OFF, CMMP-AS Tab. 2.4)",
            ),
        }
    }

    /// A Nanotec: its rotary switches at power-on (§1.1.1), or without
    /// `[drive.rotary_switches]` switches set to the node-ID, which fix 1 Mbit/s. Switches
    /// 80h and above take the rate from `code_2005h`; `None`: it holds no bit-rate code
    /// (§1.1.3 step 7: the controller still answers on CAN, so it follows the bus).
    pub fn nanotec(power_on: Option<PowerOn>, code_2005h: &RateCode) -> Option<Self> {
        match power_on {
            None => Some(NodeRate::new(
                1000,
                "[drive.rotary_switches] (none: switches at the node-ID fix 1 Mbit/s, \
                 Nanotec §1.1.1)",
            )),
            Some(p) if p.bit_rate_from_eeprom => Some(NodeRate::new(
                rotary_switches::bit_rate_kbit(code_2005h.code())?,
                code_2005h.set_by("2005:00", "rotary switches 80h and above"),
            )),
            Some(_) => Some(NodeRate::new(
                1000,
                "[drive.rotary_switches] (1…127 fix 1 Mbit/s)",
            )),
        }
    }

    /// A Kinco FD3: CAN_Baudrate 2F81h. Its DIP switches give only the station number (§3.8,
    /// Tab. 3-8). A code outside the table keeps 500 kbit/s, the default (see
    /// [`kinco_bit_rates`]).
    pub fn kinco(code: &RateCode) -> Self {
        NodeRate::new(
            kinco_bit_rates::can_kbit(code.code()).unwrap_or(kinco_bit_rates::DEFAULT_CAN_KBIT),
            code.set_by("2F81:00", "CAN_Baudrate"),
        )
    }

    /// A drive from its DCF: the file's `[DeviceComissioning] Baudrate` (CiA 306 §4.7), named
    /// with its file and line so that two files that disagree are both named.
    pub fn dcf(rate: &devdesc::eds::BitRate) -> Self {
        NodeRate::new(rate.kbit, rate.at.to_string())
    }

    pub fn bits(&self) -> u32 {
        u32::from(self.kbit) * 1000
    }
}

/// The value of the object that sets a node's rate (Kinco 2F81h, Nanotec 2005h) at power-on,
/// and where it comes from. The twin powers a drive on as the device does
/// ([`crate::cell::station::Station::with_settings`]): the default, then the cell file's
/// `[drive.objects]` (what a commissioning tool wrote), then the stored set (`--state-dir`,
/// what the drive saved), which wins.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RateCode {
    default: u8,
    cell_file: Option<u8>,
    /// The stored value and the file that holds it.
    stored: Option<(u8, String)>,
}

impl RateCode {
    /// The device's `default`, overwritten by the cell file's value, if it names one.
    pub fn new(default: u8, cell_file: Option<u8>) -> Self {
        RateCode {
            default,
            cell_file,
            stored: None,
        }
    }

    /// With the value the node's stored set in `file` holds.
    pub fn stored(self, code: u8, file: &Path) -> Self {
        RateCode {
            stored: Some((code, file.display().to_string())),
            ..self
        }
    }

    /// The value the drive powers on with.
    pub fn code(&self) -> u8 {
        match (&self.stored, self.cell_file) {
            (Some((code, _)), _) => *code,
            (None, Some(code)) => code,
            (None, None) => self.default,
        }
    }

    /// Where object `key` (named `name`) got its value, for a refusal to point at.
    fn set_by(&self, key: &str, name: &str) -> String {
        match (&self.stored, self.cell_file) {
            (Some((code, file)), _) => format!("\"{key}\" = {code} ({name}) stored in {file}"),
            (None, Some(code)) => format!("[drive.objects] \"{key}\" = {code} ({name})"),
            (None, None) => format!(
                "[drive.objects] \"{key}\" ({name}, default {})",
                self.default
            ),
        }
    }
}

/// A node whose rate one of its objects sets, so that its stored set can change the rate.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RateObject {
    /// A Kinco FD3's CAN_Baudrate 2F81h.
    Kinco(RateCode),
    /// A Nanotec's 2005h, read where its rotary switches say so.
    Nanotec(Option<PowerOn>, RateCode),
}

impl RateObject {
    /// The object's index (sub-index 0).
    pub fn index(&self) -> u16 {
        match self {
            RateObject::Kinco(_) => 0x2F81,
            RateObject::Nanotec(..) => 0x2005,
        }
    }

    /// The node's rate ([`NodeRate::kinco`], [`NodeRate::nanotec`]).
    pub fn rate(&self) -> Option<NodeRate> {
        match self {
            RateObject::Kinco(code) => Some(NodeRate::kinco(code)),
            RateObject::Nanotec(p, code) => NodeRate::nanotec(*p, code),
        }
    }

    /// With the value the node's stored set in `file` holds, which wins at power-on.
    pub fn stored(self, code: u8, file: &Path) -> Self {
        match self {
            RateObject::Kinco(c) => RateObject::Kinco(c.stored(code, file)),
            RateObject::Nanotec(p, c) => RateObject::Nanotec(p, c.stored(code, file)),
        }
    }
}

/// A node of a bus with its rate: personality, node-ID, rate.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BusNode {
    pub device: &'static str,
    pub node: u8,
    pub rate: NodeRate,
}

/// What a bus runs at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BusRate {
    /// Frames cross at once (`bitrate = "instant"`).
    Instant,
    /// Frames take their bit time at `bitrate` bit/s; `from_nodes`: the nodes' rate, no
    /// `bitrate` named.
    Timed { bitrate: u32, from_nodes: bool },
}

impl BusRate {
    /// The bit rate, none for the instant bus.
    pub fn bitrate(self) -> Option<u32> {
        match self {
            BusRate::Instant => None,
            BusRate::Timed { bitrate, .. } => Some(bitrate),
        }
    }

    /// Whether a node set to `rate` takes part: on a timed bus only at the bus's rate (else it
    /// sees error frames and stays silent); the instant bus has no bit time to differ from.
    pub fn carries(self, rate: &NodeRate) -> bool {
        match self {
            BusRate::Instant => true,
            BusRate::Timed { bitrate, .. } => rate.bits() == bitrate,
        }
    }
}

impl fmt::Display for BusRate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BusRate::Instant => f.write_str("instant (frames cross at once)"),
            BusRate::Timed {
                bitrate,
                from_nodes: true,
            } => write!(f, "{} kbit/s, its nodes' bit rate", bitrate / 1000),
            BusRate::Timed { bitrate, .. } => write!(f, "{} kbit/s", bitrate / 1000),
        }
    }
}

/// Decision: a bus none of whose nodes sets a rate (the test bench, which has no manual; a
/// Nanotec whose 2005h holds no code; no node at all) runs at 1 Mbit/s, CiA 301's highest
/// rate, as the bus-off recovery of an untimed bus counts it (`cell::UNTIMED_BITRATE`).
pub const WITHOUT_NODE_RATES: u32 = 1_000_000;

/// The nodes of a bus are set to different rates and the cell names no `bitrate`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "bus {bus:?}: its nodes are set to different bit rates and the cell names no `bitrate`:\n{}\n\
     Set the nodes to one rate, or name the bus's `bitrate` (a node at another rate stays \
     silent, as on a real bus).",
    list(nodes)
)]
pub struct Disagreement {
    pub bus: String,
    pub nodes: Vec<BusNode>,
}

fn list(nodes: &[BusNode]) -> String {
    nodes
        .iter()
        .map(|n| {
            format!(
                "  {} node {}: {} kbit/s, set by {}",
                n.device, n.node, n.rate.kbit, n.rate.set_by
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The rate of bus `bus` with `setting` (its `bitrate`, if named) and these nodes (those that
/// set a rate of their own).
pub fn resolve(
    bus: &str,
    setting: Option<BitrateSetting>,
    nodes: &[BusNode],
) -> Result<BusRate, Disagreement> {
    match setting {
        Some(BitrateSetting::Instant) => Ok(BusRate::Instant),
        Some(BitrateSetting::Bits(bitrate)) => Ok(BusRate::Timed {
            bitrate,
            from_nodes: false,
        }),
        None => {
            let first = nodes.first().map_or(WITHOUT_NODE_RATES, |n| n.rate.bits());
            if nodes.iter().any(|n| n.rate.bits() != first) {
                return Err(Disagreement {
                    bus: bus.to_owned(),
                    nodes: nodes.to_vec(),
                });
            }
            Ok(BusRate::Timed {
                bitrate: first,
                from_nodes: true,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cell::fieldbus_switches::m3_power_on;
    use drive::vendors::nanotec::rotary_switches::{power_on, RotarySwitches};

    fn node(device: &'static str, node: u8, rate: NodeRate) -> BusNode {
        BusNode { device, node, rate }
    }

    /// A Kinco FD3 whose cell file sets 2F81h to `code`, if to anything (default 50).
    fn kinco(code: Option<u8>) -> NodeRate {
        NodeRate::kinco(&RateCode::new(50, code))
    }

    /// A Nanotec's 2005h as its cell file sets it.
    fn code_2005h(code: u8) -> RateCode {
        RateCode::new(0, Some(code))
    }

    /// The factory rates: a CMMP-AS without switches 125 kbit/s, a Nanotec without rotary
    /// switches 1 Mbit/s, a Kinco FD3 with 2F81h = 50 500 kbit/s (KINCO-CAN-06).
    #[test]
    fn each_personality_has_its_factory_rate() {
        assert_eq!(NodeRate::cmmp_as(None).kbit, 125);
        assert_eq!(
            NodeRate::nanotec(None, &code_2005h(135)).map(|r| r.kbit),
            Some(1000)
        );
        assert_eq!(kinco(None).kbit, 500);
        assert_eq!(kinco(Some(100)).kbit, 1000);
        assert_eq!(kinco(Some(12)).kbit, 125);
        // Outside the table: the default (kinco_bit_rates' Decision).
        assert_eq!(kinco(Some(13)).kbit, 500);
    }

    /// CMMP-NODE-05 through the rate: DIP6/DIP7 ON/ON is 1 Mbit/s, named by the key.
    #[test]
    fn cmmp_as_switches_give_the_rate() {
        let mut dip = [false; 8];
        dip[5] = true;
        dip[6] = true;
        let r = NodeRate::cmmp_as(Some((m3_power_on(0, dip), "[drive.switches] DIP6/DIP7")));
        assert_eq!(
            (r.kbit, r.set_by.as_str()),
            (1000, "[drive.switches] DIP6/DIP7")
        );
    }

    /// NT-NODE-03 / NT-NODE-06 / NT-NODE-07 through the rate: switches ≥ 80h take 2005h,
    /// 1…127 fix 1 Mbit/s, an invalid 2005h sets none (the node follows the bus).
    #[test]
    fn nanotec_switches_and_2005h_give_the_rate() {
        let two = |left, right| RotarySwitches::Two { left, right };
        let r = NodeRate::nanotec(Some(power_on(two(5, 8), 1, 134)), &code_2005h(134)).unwrap();
        assert_eq!(r.kbit, 500);
        assert!(r.set_by.contains("\"2005:00\" = 134"), "{}", r.set_by);
        let r = NodeRate::nanotec(Some(power_on(two(5, 0), 1, 134)), &code_2005h(134)).unwrap();
        assert_eq!(r.kbit, 1000);
        assert_eq!(
            NodeRate::nanotec(Some(power_on(two(5, 8), 1, 0)), &code_2005h(0)),
            None
        );
    }

    /// A saved rate object wins at power-on over the cell file's value, as the drive loads its
    /// stored set after the commissioning values (`Station::with_settings`), and a refusal
    /// names the stored file: a Kinco saved at 2F81h = 25 (250 kbit/s, KINCO-CAN-06), a Nanotec
    /// at switches 80h + node with 2005h = 133 (250 kbit/s, §1.1.3 step 4).
    #[test]
    fn a_stored_rate_object_wins_over_the_cell_file() {
        let file = Path::new("state/kinco-fd3-node2.params");
        let kinco = RateObject::Kinco(RateCode::new(50, Some(100)));
        assert_eq!(kinco.rate().map(|r| r.kbit), Some(1000));
        let stored = kinco.stored(25, file).rate().unwrap();
        assert_eq!(stored.kbit, 250);
        assert_eq!(
            stored.set_by,
            "\"2F81:00\" = 25 (CAN_Baudrate) stored in state/kinco-fd3-node2.params"
        );
        let switches = RotarySwitches::Two { left: 1, right: 8 };
        let nanotec = RateObject::Nanotec(Some(power_on(switches, 1, 135)), code_2005h(135))
            .stored(133, Path::new("state/n.params"));
        assert_eq!(nanotec.index(), 0x2005);
        assert_eq!(nanotec.rate().map(|r| r.kbit), Some(250));
        let nodes = [
            node("cmmp-as", 1, NodeRate::cmmp_as(None)),
            node("kinco-fd3", 2, stored),
        ];
        let text = resolve("vcan0", None, &nodes).unwrap_err().to_string();
        assert!(
            text.contains(
                "kinco-fd3 node 2: 250 kbit/s, set by \"2F81:00\" = 25 (CAN_Baudrate) \
                           stored in state/kinco-fd3-node2.params"
            ),
            "{text}"
        );
    }

    #[test]
    fn agreeing_nodes_give_the_bus_their_rate() {
        let nodes = [
            node(
                "nanotec-smci47s",
                1,
                NodeRate::nanotec(None, &code_2005h(135)).unwrap(),
            ),
            node("kinco-fd3", 2, kinco(Some(100))),
        ];
        assert_eq!(
            resolve("vcan0", None, &nodes),
            Ok(BusRate::Timed {
                bitrate: 1_000_000,
                from_nodes: true
            })
        );
        assert_eq!(
            resolve("vcan0", None, &[]),
            Ok(BusRate::Timed {
                bitrate: WITHOUT_NODE_RATES,
                from_nodes: true
            })
        );
    }

    #[test]
    fn disagreeing_nodes_are_refused_naming_each_rate_and_key() {
        let nodes = [
            node("cmmp-as", 1, NodeRate::cmmp_as(None)),
            node(
                "nanotec-smci47s",
                2,
                NodeRate::nanotec(None, &code_2005h(135)).unwrap(),
            ),
            node("kinco-fd3", 3, kinco(None)),
        ];
        let err = resolve("line-a", None, &nodes).unwrap_err();
        let text = err.to_string();
        for part in [
            "bus \"line-a\"",
            "cmmp-as node 1: 125 kbit/s, set by [drive.switches] (none: DIP6/DIP7 OFF",
            "nanotec-smci47s node 2: 1000 kbit/s, set by [drive.rotary_switches] (none:",
            "kinco-fd3 node 3: 500 kbit/s, set by [drive.objects] \"2F81:00\" (CAN_Baudrate,",
            "`bitrate`",
        ] {
            assert!(text.contains(part), "{part:?} not in {text}");
        }
    }

    /// With a named rate the bus runs at it and a node set to another one is silent; the
    /// instant bus carries every node.
    #[test]
    fn an_explicit_bitrate_wins_and_silences_other_nodes() {
        let nodes = [
            node("cmmp-as", 1, NodeRate::cmmp_as(None)),
            node("kinco-fd3", 2, kinco(None)),
        ];
        let bus = resolve("vcan0", Some(BitrateSetting::Bits(500_000)), &nodes).unwrap();
        assert_eq!(bus.bitrate(), Some(500_000));
        assert!(!bus.carries(&nodes[0].rate));
        assert!(bus.carries(&nodes[1].rate));
        let bus = resolve("vcan0", Some(BitrateSetting::Instant), &nodes).unwrap();
        assert_eq!(bus, BusRate::Instant);
        assert_eq!(bus.bitrate(), None);
        assert!(nodes.iter().all(|n| bus.carries(&n.rate)));
    }

    #[test]
    fn the_setting_is_a_positive_number_or_instant() {
        #[derive(Deserialize)]
        struct Bus {
            bitrate: BitrateSetting,
        }
        let parse = |text: &str| toml::from_str::<Bus>(text).map(|b| b.bitrate);
        assert_eq!(
            parse("bitrate = 250000").ok(),
            Some(BitrateSetting::Bits(250_000))
        );
        assert_eq!(
            parse("bitrate = \"instant\"").ok(),
            Some(BitrateSetting::Instant)
        );
        for bad in ["bitrate = 0", "bitrate = -5", "bitrate = \"fast\""] {
            assert!(parse(bad).is_err(), "{bad}");
        }
        assert_eq!("instant".parse(), Ok(BitrateSetting::Instant));
        assert_eq!("125000".parse(), Ok(BitrateSetting::Bits(125_000)));
        assert!("0".parse::<BitrateSetting>().is_err());
    }
}
