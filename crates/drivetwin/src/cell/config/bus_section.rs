//! The `[bus]` / `[[bus]]` tables of the cell file: the CAN buses, their transports, bit
//! rate, trace and planned disturbances.

use std::path::PathBuf;

use serde::Deserialize;

use crate::cell::bus_rate::BitrateSetting;

pub const DEFAULT_SOCKETCAND: &str = "127.0.0.1:29536";
pub const DEFAULT_CHANNEL: &str = "vcan0";

/// The cell's CAN buses.
#[derive(Debug, Clone)]
pub enum Buses {
    One(BusSection),
    Many(Vec<BusSection>),
}

/// `[bus]` or `[[bus]]`, by the value's shape, so a bad key reports its own error (an
/// untagged enum would only say that neither form matched).
impl<'de> Deserialize<'de> for Buses {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        match toml::Value::deserialize(d)? {
            v @ toml::Value::Array(_) => Vec::<BusSection>::deserialize(v).map(Buses::Many),
            v => BusSection::deserialize(v).map(Buses::One),
        }
        .map_err(D::Error::custom)
    }
}

impl Default for Buses {
    fn default() -> Self {
        Buses::One(BusSection::default())
    }
}

impl Buses {
    pub fn all(&self) -> &[BusSection] {
        match self {
            Buses::One(b) => std::slice::from_ref(b),
            Buses::Many(v) => v,
        }
    }

    pub fn all_mut(&mut self) -> &mut [BusSection] {
        match self {
            Buses::One(b) => std::slice::from_mut(b),
            Buses::Many(v) => v,
        }
    }

    /// The first bus (the one `--socketcand`, `--channel` and `--socketcan` set), made if
    /// the file has none.
    pub fn first_mut(&mut self) -> &mut BusSection {
        if let Buses::Many(v) = self {
            if v.is_empty() {
                v.push(BusSection::default());
            }
        }
        match self {
            Buses::One(b) => b,
            #[allow(clippy::indexing_slicing, reason = "made non-empty above")]
            Buses::Many(v) => &mut v[0],
        }
    }

    /// The index of the bus a drive names (by `name`, else by `channel`); the first without
    /// a name.
    pub fn index(&self, name: Option<&str>) -> Option<usize> {
        match name {
            None => Some(0),
            Some(n) => self.all().iter().position(|b| b.label() == n),
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BusSection {
    /// What drives call the bus (`bus = "..."`); default its channel.
    pub name: Option<String>,
    /// socketcand server address; "" turns the server off.
    #[serde(default = "default_socketcand")]
    pub socketcand: String,
    #[serde(default = "default_channel")]
    pub channel: String,
    /// A SocketCAN interface to bridge (real hardware or vcan).
    pub socketcan: Option<String>,
    /// Bit rate, bit/s: frames take the bus for their bit time and wait for the arbitration
    /// (`cell::bus_timing`). Without it the bus runs at the rate its nodes are set to (their
    /// switches and objects), and nodes set to different rates are refused
    /// ([`crate::cell::bus_rate`]); with it a node set to another rate stays silent, as on a
    /// real bus. `"instant"`: frames cross at once (fast tests, latency benchmarks).
    pub bitrate: Option<BitrateSetting>,
    /// A frame that waits longer than this for the bus counts as late (default 1000 µs).
    pub late_after_us: Option<u32>,
    /// Join the socketcand server at this address as a client: the bus is that server's
    /// bus (one plant over several processes or machines).
    pub join: Option<String>,
    /// socketcand clients served at once (default 128); more are refused.
    pub max_clients: Option<usize>,
    /// Where every frame of this bus is written (candump `.log`, else pcap); `--trace` is the
    /// first bus's.
    pub trace: Option<PathBuf>,
    /// Planned disturbances: `[[bus.disturb]]` with `at_ms`, `node` and `frames` (that many
    /// of the node's next transmissions fail with an error frame: 16 make it error passive,
    /// 32 take it off the bus).
    #[serde(default)]
    pub disturb: Vec<DisturbSection>,
}

/// One planned disturbance of a node's transmissions.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct DisturbSection {
    pub at_ms: u64,
    pub node: u8,
    pub frames: u32,
}

impl BusSection {
    /// What drives call the bus: its name, else its channel.
    pub fn label(&self) -> &str {
        self.name.as_deref().unwrap_or(&self.channel)
    }

    /// A frame that waits longer than this for the bus counts as late.
    pub fn late_after(&self) -> std::time::Duration {
        std::time::Duration::from_micros(u64::from(self.late_after_us.unwrap_or(1000)))
    }
}

impl Default for BusSection {
    fn default() -> Self {
        BusSection {
            name: None,
            socketcand: default_socketcand(),
            channel: default_channel(),
            socketcan: None,
            bitrate: None,
            late_after_us: None,
            join: None,
            max_clients: None,
            trace: None,
            disturb: Vec::new(),
        }
    }
}

fn default_socketcand() -> String {
    DEFAULT_SOCKETCAND.into()
}
fn default_channel() -> String {
    DEFAULT_CHANNEL.into()
}
