//! The Kinco drives' keys of a `[[drive]]` (their sections of the cell file,
//! [`crate::cell::config::DeviceSection`]): the FD3's DIP switches SW1…SW8 (§3.8), which set
//! its station number, and the serial ports, RS232 on X3 (FD3, CD3) and RS485 on X10 (FD3),
//! §1.1 Tab. 3-7. The CAN bit rate is CAN_Baudrate 2F81h, whose codes are the device file's
//! (`can_bit_rate`).

use drive::vendors::kinco::dip_switches::{self as kinco_dip_switches, Station};
use serde::Deserialize;

use crate::cell::config::{
    eight_switches, DeviceSection, DriveContext, Key, OwnSettings, Ports, SectionError,
};

/// The Kinco FD3's section.
pub const FD3: DeviceSection = DeviceSection {
    devices: &["kinco-fd3"],
    keys: &FD3_KEYS,
    read: read_fd3,
};

/// The Kinco CD3's section.
pub const CD3: DeviceSection = DeviceSection {
    devices: &["kinco-cd3"],
    keys: &CD3_KEYS,
    read: read_cd3,
};

/// The keys of a Kinco FD3.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KincoFd3Keys {
    /// DIP switches SW1…SW8 (§3.8): the station number at power-on; when they give one it
    /// wins over `node`.
    pub dip_switches: Option<DipSwitchesSection>,
    /// The RS232 port X3 (the 10-byte telegrams): a path made a link to a pty of the twin,
    /// or a real serial device. Drives that name one path form a ring.
    pub rs232: Option<String>,
    /// The RS485 port X10 (Modbus RTU): as `rs232`; drives that name one path share the
    /// line, each answering its station number (= node-ID).
    pub rs485: Option<String>,
}

/// The keys of a Kinco CD3 (RS232 only: no CAN, no RS485, no DIP switches).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KincoCd3Keys {
    /// The RS232 port X3, as the FD3's `rs232`.
    pub rs232: Option<String>,
}

/// The DIP switches of an FD3.
const DIP_SWITCHES: Key = Key {
    name: "dip_switches",
    what: "DIP switches SW1…SW8 (Kinco §3.8: the FD3's)",
};
/// The RS232 port of an FD3 and a CD3.
const RS232: Key = Key {
    name: "rs232",
    what: "RS232 port for the Kinco telegrams (Kinco §1.1, Tab. 3-7: X3)",
};
/// The RS485 port of an FD3.
const RS485: Key = Key {
    name: "rs485",
    what: "RS485 port for Modbus RTU (Kinco §1.1, Tab. 3-7: the FD3's X10)",
};

/// What each key of an FD3 is, for the refusal of the key on another device.
pub const FD3_KEYS: [Key; 3] = [DIP_SWITCHES, RS232, RS485];
/// What each key of a CD3 is.
pub const CD3_KEYS: [Key; 1] = [RS232];

/// `[drive.dip_switches]`: the DIP switches SW1…SW8 of a Kinco FD3 that are ON (`on = [1,
/// 2]` is station 3; none ON: the stored station number 2F80h:01 of `[drive.objects]`, else
/// its default). The table of §3.8 (Tab. 3-8) gives the station number only; the CAN bit rate
/// is CAN_Baudrate 2F81h.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DipSwitchesSection {
    #[serde(default)]
    pub on: Vec<u8>,
}

impl DipSwitchesSection {
    /// The station number the switches select, or `None` for the stored one (all OFF).
    pub fn station(&self) -> Result<Option<u8>, String> {
        let sw = eight_switches(&self.on, |n| format!("SW{n}: the FD3 has SW1…SW8"))?;
        match kinco_dip_switches::station(sw) {
            Station::Stored => Ok(None),
            Station::Switches(s) => kinco_dip_switches::can_node_id(s).map(Some).ok_or(format!(
                "station {s}: a CANopen node-ID is 1…127 (§11.1); the twin runs the FD3 as a \
                 CANopen node, so 128…255 (RS232 / RS485 only) is not simulated"
            )),
        }
    }
}

/// Reads an FD3's keys: the DIP switches' station number, the serial ports.
fn read_fd3(table: toml::Table, drive: &DriveContext<'_>) -> Result<OwnSettings, SectionError> {
    let keys = KincoFd3Keys::deserialize(toml::Value::Table(table))?;
    let node = match &keys.dip_switches {
        Some(dip) => {
            let err = SectionError::key("dip_switches");
            // All OFF: the stored station number 2F80h:01 (§3.8).
            match dip.station().map_err(err)? {
                Some(s) => Some(s),
                None => match drive.stored_u8(0x2F80, 1).map_err(err)? {
                    s @ 1..=127 => Some(s),
                    s => return Err(err(format!("station {s} from 2F80h:01"))),
                },
            }
        }
        None => None,
    };
    Ok(OwnSettings {
        node,
        ports: Ports {
            rs232: keys.rs232,
            rs485: keys.rs485,
            ..Ports::default()
        },
        ..OwnSettings::default()
    })
}

/// Reads a CD3's keys: its RS232 port.
fn read_cd3(table: toml::Table, _: &DriveContext<'_>) -> Result<OwnSettings, SectionError> {
    let keys = KincoCd3Keys::deserialize(toml::Value::Table(table))?;
    Ok(OwnSettings {
        ports: Ports {
            rs232: keys.rs232,
            ..Ports::default()
        },
        ..OwnSettings::default()
    })
}
