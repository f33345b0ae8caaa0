//! The bit rate a cell's CAN bus runs at. Every node is set to one by its switches or its
//! objects (the rules of its vendor's manual, which its vendor's cell-file section applies; an
//! object whose code the device file's `can_bit_rate` lists; a DCF's `[DeviceComissioning]
//! Baudrate`, CiA 306 §4.7), and a bus works only where they agree: the bus takes theirs. A
//! `bitrate` on the `[[bus]]` (or `drivetwin run --bitrate`) is the rate the rest of the bus
//! (the master) runs at: a node set to another one sees only error frames and stays silent
//! (ISO 11898-1). `"instant"` gives the bus no bit time at all, for fast tests and latency
//! benchmarks.
//!
//! Pure rules, no I/O: [`resolve`] takes the bus's setting and each node's rate.

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use serde::Deserialize;

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
    pub fn new(kbit: u16, set_by: impl Into<String>) -> Self {
        NodeRate {
            kbit,
            set_by: set_by.into(),
        }
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

/// The value of the object that sets a node's rate at power-on, and where it comes from. The
/// twin powers a drive on as the device does
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

    /// The device's default.
    pub fn default_code(&self) -> u8 {
        self.default
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

/// How an object's code gives a bit rate.
#[derive(Debug, Clone, Copy)]
pub enum RateCodes {
    /// The device file's table (`can_bit_rate`). Decision: a code outside it keeps the rate of
    /// the object's default code, as the device file says, rather than guess one.
    Device(&'static od::CanBitRateCodes),
    /// A vendor's rule, in kbit/s; `None`: the code sets no rate, and the node follows the
    /// bus.
    Vendor(fn(u8) -> Option<u16>),
}

/// A node whose rate one of its objects sets (sub-index 0), so that its stored set can change
/// the rate.
#[derive(Debug, Clone)]
pub struct RateObject {
    index: u16,
    /// What the object is, for a refusal to name.
    name: &'static str,
    code: RateCode,
    codes: RateCodes,
}

impl RateObject {
    /// Object `index`, named `name`, holding `code`, read by `codes`.
    pub fn new(index: u16, name: &'static str, code: RateCode, codes: RateCodes) -> Self {
        RateObject {
            index,
            name,
            code,
            codes,
        }
    }

    /// The object the device file's `can_bit_rate` names, holding `code`.
    pub fn of_device(codes: &'static od::CanBitRateCodes, code: RateCode) -> Self {
        RateObject::new(codes.index, codes.name, code, RateCodes::Device(codes))
    }

    /// The object's index (sub-index 0).
    pub fn index(&self) -> u16 {
        self.index
    }

    /// The node's rate, named with the object's key and where its value comes from.
    pub fn rate(&self) -> Option<NodeRate> {
        let code = self.code.code();
        let kbit = match self.codes {
            RateCodes::Device(table) => table
                .kbit(code)
                .or_else(|| table.kbit(self.code.default_code()))?,
            RateCodes::Vendor(rule) => rule(code)?,
        };
        let key = format!("{:04X}:00", self.index);
        Some(NodeRate::new(kbit, self.code.set_by(&key, self.name)))
    }

    /// With the value the node's stored set in `file` holds, which wins at power-on.
    pub fn stored(self, code: u8, file: &Path) -> Self {
        RateObject {
            code: self.code.stored(code, file),
            ..self
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

    fn node(device: &'static str, node: u8, rate: NodeRate) -> BusNode {
        BusNode { device, node, rate }
    }

    /// The CAN_Baudrate 2F81h codes of the Kinco FD3's device file.
    fn kinco_codes() -> &'static od::CanBitRateCodes {
        devices::by_name("kinco-fd3")
            .and_then(|d| d.can_bit_rate.as_ref())
            .expect("kinco-fd3's can_bit_rate")
    }

    /// A Kinco FD3 whose cell file sets 2F81h to `code`, if to anything (default 50).
    fn kinco(code: Option<u8>) -> NodeRate {
        RateObject::of_device(kinco_codes(), RateCode::new(50, code))
            .rate()
            .expect("a rate")
    }

    /// A node at a fixed rate, named by `key`.
    fn fixed(kbit: u16, key: &str) -> NodeRate {
        NodeRate::new(kbit, key)
    }

    /// KINCO-CAN-06 from the device file: 100, 50 (default), 25, 12, 5 → 1000, 500, 250, 125,
    /// 50 kbit/s; 125 kbit/s is 12, not 12.5; a code outside the table keeps the default's
    /// 500 kbit/s (the device file's Decision).
    #[test]
    fn kinco_can_06_codes_are_device_data() {
        assert_eq!(
            [100, 50, 25, 12, 5].map(|c| kinco_codes().kbit(c)),
            [Some(1000), Some(500), Some(250), Some(125), Some(50)]
        );
        assert_eq!(kinco_codes().kbit(13), None);
        assert_eq!(kinco_codes().index, 0x2F81);
        assert_eq!(kinco(None).kbit, 500);
        assert_eq!(kinco(Some(100)).kbit, 1000);
        assert_eq!(kinco(Some(12)).kbit, 125);
        assert_eq!(kinco(Some(13)).kbit, 500);
    }

    /// A saved rate object wins at power-on over the cell file's value, as the drive loads its
    /// stored set after the commissioning values (`Station::with_settings`), and a refusal
    /// names the stored file: a Kinco saved at 2F81h = 25 (250 kbit/s, KINCO-CAN-06); a
    /// vendor's rule that gives no rate leaves the node to the bus.
    #[test]
    fn a_stored_rate_object_wins_over_the_cell_file() {
        let file = Path::new("state/kinco-fd3-node2.params");
        let kinco = RateObject::of_device(kinco_codes(), RateCode::new(50, Some(100)));
        assert_eq!(kinco.rate().map(|r| r.kbit), Some(1000));
        let stored = kinco.stored(25, file).rate().unwrap();
        assert_eq!(stored.kbit, 250);
        assert_eq!(
            stored.set_by,
            "\"2F81:00\" = 25 (CAN_Baudrate) stored in state/kinco-fd3-node2.params"
        );
        let rule = RateCodes::Vendor(|code| (code == 133).then_some(250));
        let vendor = RateObject::new(0x2005, "a rule", RateCode::new(0, Some(135)), rule);
        assert_eq!(vendor.rate(), None);
        let vendor = vendor.stored(133, Path::new("state/n.params"));
        assert_eq!(vendor.index(), 0x2005);
        assert_eq!(vendor.rate().map(|r| r.kbit), Some(250));
        let nodes = [
            node("cmmp-as", 1, fixed(125, "[drive.switches]")),
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
            node("nanotec-smci47s", 1, fixed(1000, "[drive.rotary_switches]")),
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
            node(
                "cmmp-as",
                1,
                fixed(125, "[drive.switches] (none: DIP6/DIP7 OFF"),
            ),
            node(
                "nanotec-smci47s",
                2,
                fixed(1000, "[drive.rotary_switches] (none:"),
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
            node("cmmp-as", 1, fixed(125, "[drive.switches]")),
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
