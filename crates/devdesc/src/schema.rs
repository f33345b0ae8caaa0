//! The file format, as serde reads it. Checked and normalised in `model`.

use serde::Deserialize;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct File {
    pub device: DeviceSection,
    #[serde(default)]
    pub object: Vec<ObjectSection>,
    #[serde(default)]
    pub diagnostic: Vec<DiagnosticSection>,
}

/// One row of the manual's diagnostic table (`[[diagnostic]]`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DiagnosticSection {
    /// As the manual prints it: "08-2", "2Fh", …
    pub number: String,
    /// The CiA 301 EMCY code; none where the manual assigns none.
    pub code: Option<u16>,
    /// Error register 1001h bits (default 0: the stack adds bit 0).
    #[serde(default)]
    pub register: u8,
    /// ps_off | quick_stop | configurable | warning | ignore | unstated
    pub reaction: String,
    pub text: String,
    #[serde(default)]
    pub display: String,
    #[serde(default)]
    pub classes: String,
    #[serde(default)]
    pub reactions: String,
    #[serde(default)]
    pub memory: String,
    #[serde(default)]
    pub ack: String,
    #[serde(default)]
    pub source: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeviceSection {
    pub name: String,
    pub product_name: String,
    pub vendor_name: String,
    pub vendor_id: u32,
    #[serde(default)]
    pub product_code: u32,
    #[serde(default)]
    pub revision: u32,
    #[serde(default)]
    pub order_code: String,
    #[serde(default)]
    pub description: String,
    /// `cia402`, `fhpp` or `plain`: how the twin builds and serves the personality.
    pub profile: ProfileName,
    #[serde(default = "default_node")]
    pub default_node_id: u8,
    #[serde(default)]
    pub baud_rates: Vec<u16>,
    #[serde(default)]
    pub pdo_params_locked_while_valid: bool,
    #[serde(default)]
    pub pdo_config_outside_operational: bool,
    pub tpdo_transmit_mask_index: Option<u16>,
    #[serde(default)]
    pub tpdo_254_cyclic_inhibit: bool,
    /// 1000h does not carry the profile number (Nanotec: 00000008h); `profile` alone decides.
    #[serde(default = "yes")]
    pub device_type_carries_profile: bool,
    #[serde(default)]
    pub pdo_refuses_type_254: bool,
    #[serde(default)]
    pub pdo_map_length_filled: bool,
    #[serde(default)]
    pub nmt_command_answered_with_state: bool,
    pub life_guard_emcy_code: Option<u16>,
    #[serde(default)]
    pub restore_writes_stored_set: bool,
    pub life_time_max_ms: Option<u32>,
    #[serde(default)]
    pub pdo_valid_without_mapping: bool,
    #[serde(default)]
    pub lss_unsupported: bool,
    /// Hexadecimal rotary switches that give node-ID and bit rate (Nanotec §1.1.1): 0, 1 or 2.
    #[serde(default)]
    pub rotary_switches: u8,
    /// `can_bit_rate = { object = 0x2F81, name = "CAN_Baudrate", codes = [[100, 1000], …] }`:
    /// the object whose code sets the CAN bit rate (`od::CanBitRateCodes`).
    pub can_bit_rate: Option<CanBitRateSection>,
    /// `serial_bit_rate = { objects = [0x2FE0, …], codes = [[270, 38400], …] }`: the objects
    /// whose code sets a serial line speed (`od::SerialBitRateCodes`).
    pub serial_bit_rate: Option<SerialBitRateSection>,
    /// `[device.serial_ports.rs232]`, `[device.serial_ports.rs485]`: the objects that set up
    /// each serial port (`od::SerialPort`); one for each serial interface of `interfaces`.
    pub serial_ports: Option<SerialPortsSection>,
    /// The interfaces the real device has (default: its profile's fieldbus, CANopen or
    /// Modbus TCP), those of them that run one at a time, and the manual's rule.
    pub interfaces: Option<Vec<String>>,
    #[serde(default)]
    pub interfaces_one_of: Vec<String>,
    pub interfaces_rule: Option<String>,
    /// DIP switches (or inputs) select node-ID offset, bit rate and fieldbus at power-on.
    #[serde(default)]
    pub fieldbus_switches: bool,
    /// `[device.ethercat]`: what an EtherCAT master reads of the slave beyond the dictionary.
    pub ethercat: Option<EthercatSection>,
    /// `[device.fhpp]`: what the FHPP profile needs beyond the parameters.
    pub fhpp: Option<FhppSection>,
    /// `[device.bus_faults]`: what the device does when its CAN controller changes error
    /// state; CiA 301's usage without it.
    pub bus_faults: Option<BusFaultsSection>,
    /// `[device.brake]`: the objects whose values make the holding brake's delays; none
    /// without it.
    pub brake: Option<BrakeSection>,
    /// `[device.plant]`: the messages and objects of the drive's supervision of its plant;
    /// none without it.
    pub plant: Option<PlantSection>,
}

/// An object of the dictionary as a device file names it for a purpose: `[index, sub]`.
pub type ObjectKey = (u16, u8);

/// `[device.brake]` (`od::BrakeTiming`): each delay the sum of its objects' values in ms,
/// e.g. `motion = [[0x2007, 1], [0x2007, 2]]`; each object an integer entry of the file. A
/// key left out: no delay.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BrakeSection {
    /// Output stage on → brake open.
    #[serde(default)]
    pub release: Vec<ObjectKey>,
    /// Output stage on → the set-point released.
    #[serde(default)]
    pub motion: Vec<ObjectKey>,
    /// Brake closed → output stage off.
    #[serde(default)]
    pub engage: Vec<ObjectKey>,
    /// Without a holding brake fitted nothing waits.
    #[serde(default)]
    pub only_with_brake: bool,
}

/// `[device.plant]` (`od::PlantSupervision`): the diagnostic messages (numbers of the file's
/// `[[diagnostic]]` rows) the drive raises for what its supervision finds, and the objects
/// (`[index, sub]`, integer entries of the file, °C) holding its limits and showing its
/// temperatures. A key left out: no such message or object.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantSection {
    /// The motor within the warning margin of its limit.
    pub motor_warning: Option<String>,
    /// The motor above its limit.
    pub motor_over: Option<String>,
    /// The power stage within the warning margin of its limit (FHPP).
    pub stage_warning: Option<String>,
    /// The power stage above its limit.
    pub stage_over: Option<String>,
    /// The power stage below its lower limit (FHPP).
    pub stage_under: Option<String>,
    /// The encoder signal lost.
    pub encoder_lost: Option<String>,
    /// Implausible encoder counts.
    pub encoder_implausible: Option<String>,
    /// The motor's limit (without it the drive model's own).
    pub motor_limit: Option<ObjectKey>,
    /// The power stage's limit (without it the drive model's own).
    pub stage_limit: Option<ObjectKey>,
    /// The power stage's lower limit (FHPP; without it the drive model's own).
    pub stage_low_limit: Option<ObjectKey>,
    /// Where the drive shows the motor's temperature.
    pub motor_temperature: Option<ObjectKey>,
    /// Where the drive shows the power stage's temperature.
    pub stage_temperature: Option<ObjectKey>,
}

/// `[device.bus_faults]` (`od::BusFaultReactions`): the reactions to each change of the CAN
/// controller's error state, in order, e.g. `on_bus_off = ["fault 0x8120"]`. Every key is
/// required: a device whose manual gives a reaction to one change says what it does at the
/// others too (`[]` for nothing).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BusFaultsSection {
    /// Error active → error passive.
    pub on_passive: Vec<BusFaultReactionText>,
    /// Error passive → error active.
    pub on_active: Vec<BusFaultReactionText>,
    /// → bus off.
    pub on_bus_off: Vec<BusFaultReactionText>,
    /// Bus off → error active.
    pub on_recovered: Vec<BusFaultReactionText>,
}

/// One reaction as a device file writes it: a verb and an EMCY error code, `raise 0x8120`,
/// `clear 0x8120`, `fault 0x8120` or `repeat 0x8120`; anything else is refused where it
/// stands (file, line and key).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(try_from = "String")]
pub struct BusFaultReactionText(pub od::BusFaultReaction);

impl TryFrom<String> for BusFaultReactionText {
    type Error = String;

    fn try_from(text: String) -> Result<Self, String> {
        let refuse = |why: &str| {
            format!(
                "{text:?}: {why}; a reaction is `raise`, `clear`, `fault` or `repeat` and an EMCY code, as \"raise 0x8120\""
            )
        };
        let mut words = text.split_whitespace();
        let (Some(verb), Some(code), None) = (words.next(), words.next(), words.next()) else {
            return Err(refuse("not a verb and a code"));
        };
        let code = code
            .strip_prefix("0x")
            .filter(|hex| (1..=4).contains(&hex.len()))
            .and_then(|hex| u16::from_str_radix(hex, 16).ok())
            .ok_or_else(|| refuse("the code is no 16-bit hexadecimal number (0x…)"))?;
        if code == 0 {
            return Err(refuse("0x0000 is \"no error\", not an error code"));
        }
        let reaction = match verb {
            "raise" => od::BusFaultReaction::Raise(code),
            "clear" => od::BusFaultReaction::Clear(code),
            "fault" => od::BusFaultReaction::Fault(code),
            "repeat" => od::BusFaultReaction::Repeat(code),
            _ => return Err(refuse("unknown reaction")),
        };
        Ok(BusFaultReactionText(reaction))
    }
}

/// `can_bit_rate` of `[device]`: an UNSIGNED8 object (sub-index 0) whose value is a code of
/// the CAN bit rate, with the manual's table of codes and bit rates (kbit/s).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CanBitRateSection {
    pub object: u16,
    /// As the manual prints it.
    pub name: String,
    /// `[code, kbit/s]` pairs; each bit rate one of `baud_rates`.
    pub codes: Vec<[u16; 2]>,
}

/// `serial_bit_rate` of `[device]`: UNSIGNED16 objects (sub-index 0) whose value is a code
/// of a serial line speed, with the manual's table of codes and bit rates (bit/s).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SerialBitRateSection {
    pub objects: Vec<u16>,
    /// `[code, bit/s]` pairs.
    pub codes: Vec<[u32; 2]>,
}

/// `[device.serial_ports]`: a table per serial interface.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SerialPortsSection {
    pub rs232: Option<SerialPortSection>,
    pub rs485: Option<SerialPortSection>,
}

/// One serial port's objects (`od::SerialPort`): `bit_rate = 0x2FE0`, `bit_rate_now =
/// 0x2FE1` (objects of `serial_bit_rate`), `loop_enable = [0x6510, 0x0B]`, `protocol = {
/// object = [0x6510, 0x0C], modbus_rtu = 0, telegrams = 1 }`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SerialPortSection {
    /// The object whose code is the port's bit rate from power-up.
    pub bit_rate: u16,
    /// The object whose code, written, is the port's bit rate at once.
    pub bit_rate_now: Option<u16>,
    /// The object whose value 1 makes drives on one line a ring.
    pub loop_enable: Option<ObjectKey>,
    /// The object that selects the protocol; without it the device's telegrams alone.
    pub protocol: Option<ProtocolSection>,
}

/// `protocol` of a serial port: the object and its values.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProtocolSection {
    pub object: ObjectKey,
    pub modbus_rtu: u32,
    pub telegrams: u32,
}

/// `[device.fhpp]` (`od::FhppParameters`): required with `profile = "fhpp"`, refused with
/// another profile.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FhppSection {
    /// Motion records of record selection, numbered 1…`records`.
    pub records: u8,
    /// PNUs writable only with the output stage off (access "rw2"), ascending.
    pub stage_off_pnus: Vec<u16>,
}

/// `[device.ethercat]`: the SII's layout and names and what the CoE mailbox serves
/// (`od::EthercatSlave`). Every key but `coe_hidden` is required: the manual's values, or the
/// ESC reference baseline with a comment saying so.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EthercatSection {
    pub group_type: String,
    pub group_name: String,
    pub pdi_control: u16,
    /// SM0 start address and size.
    pub mailbox_out: [u16; 2],
    /// SM1 start address and size.
    pub mailbox_in: [u16; 2],
    pub outputs_start: u16,
    pub inputs_start: u16,
    pub rx_assigned: Vec<u16>,
    pub tx_assigned: Vec<u16>,
    pub ds402_channels: u8,
    pub physical_ports: u16,
    pub complete_access: bool,
    pub sdo_info: bool,
    #[serde(default)]
    pub coe_hidden: Vec<u16>,
    pub version: u16,
    /// The diagnostic number raised when the process-data watchdog expires in Op.
    #[serde(default)]
    pub watchdog_diagnostic: Option<String>,
}

/// `panel = "d3.01"` or `panel = ["d2.00", "d3.00"]`: one object may have several panel
/// addresses (Kinco 2FF0h:01 is d2.00, d3.00 and d5.00).
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum PanelKeys {
    One(String),
    Many(Vec<String>),
}

impl PanelKeys {
    pub fn keys(&self) -> Vec<String> {
        match self {
            PanelKeys::One(k) => vec![k.clone()],
            PanelKeys::Many(v) => v.clone(),
        }
    }
}

fn yes() -> bool {
    true
}

/// `profile` of `[device]`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ProfileName {
    Cia402,
    Fhpp,
    Plain,
}

fn default_node() -> u8 {
    1
}

/// Fields shared by a VAR object and a sub-entry.
#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct EntryFields {
    #[serde(rename = "type")]
    pub data_type: Option<String>,
    pub access: Option<String>,
    pub pdo: Option<bool>,
    pub default: Option<toml::Value>,
    pub min: Option<toml::Value>,
    pub max: Option<toml::Value>,
    pub unit: Option<String>,
    pub size: Option<u32>,
    pub behaviour: Option<String>,
    pub storable: Option<bool>,
    pub kept_on_restore: Option<bool>,
    pub allowed_bits: Option<u64>,
    pub source: Option<String>,
    pub panel: Option<PanelKeys>,
    pub modbus: Option<u16>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSection {
    pub index: u16,
    pub name: String,
    pub kind: Option<String>,
    #[serde(rename = "type")]
    pub data_type: Option<String>,
    pub access: Option<String>,
    pub pdo: Option<bool>,
    pub default: Option<toml::Value>,
    pub min: Option<toml::Value>,
    pub max: Option<toml::Value>,
    pub unit: Option<String>,
    pub size: Option<u32>,
    pub behaviour: Option<String>,
    pub storable: Option<bool>,
    pub kept_on_restore: Option<bool>,
    pub allowed_bits: Option<u64>,
    pub source: Option<String>,
    /// The LED panel address(es) of a VAR (Kinco `d3.01`, `EA02`, `tn01`, `F001`).
    pub panel: Option<PanelKeys>,
    /// The Modbus register of a VAR (Kinco `0x3100`).
    pub modbus: Option<u16>,
    /// Two sub-indices whose values must stay ordered (min ≤ max); a write that would break
    /// the order is refused with 0609 0036h.
    pub min_max_subs: Option<[u8; 2]>,
    #[serde(default)]
    pub sub: Vec<SubSection>,
}

/// A sub-entry of an ARRAY or RECORD: the fields of [`EntryFields`] plus its sub-index.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SubSection {
    pub sub: u8,
    pub name: String,
    #[serde(rename = "type")]
    pub data_type: Option<String>,
    pub access: Option<String>,
    pub pdo: Option<bool>,
    pub default: Option<toml::Value>,
    pub min: Option<toml::Value>,
    pub max: Option<toml::Value>,
    pub unit: Option<String>,
    pub size: Option<u32>,
    pub behaviour: Option<String>,
    pub storable: Option<bool>,
    pub kept_on_restore: Option<bool>,
    pub allowed_bits: Option<u64>,
    pub source: Option<String>,
    pub panel: Option<PanelKeys>,
    pub modbus: Option<u16>,
}

impl SubSection {
    pub fn fields(&self) -> EntryFields {
        EntryFields {
            data_type: self.data_type.clone(),
            access: self.access.clone(),
            pdo: self.pdo,
            default: self.default.clone(),
            min: self.min.clone(),
            max: self.max.clone(),
            unit: self.unit.clone(),
            size: self.size,
            behaviour: self.behaviour.clone(),
            storable: self.storable,
            kept_on_restore: self.kept_on_restore,
            allowed_bits: self.allowed_bits,
            source: self.source.clone(),
            panel: self.panel.clone(),
            modbus: self.modbus,
        }
    }
}

impl ObjectSection {
    /// The VAR fields of this object, as an entry.
    pub fn var_fields(&self) -> EntryFields {
        EntryFields {
            data_type: self.data_type.clone(),
            access: self.access.clone(),
            pdo: self.pdo,
            default: self.default.clone(),
            min: self.min.clone(),
            max: self.max.clone(),
            unit: self.unit.clone(),
            size: self.size,
            behaviour: self.behaviour.clone(),
            storable: self.storable,
            kept_on_restore: self.kept_on_restore,
            allowed_bits: self.allowed_bits,
            source: self.source.clone(),
            panel: self.panel.clone(),
            modbus: self.modbus,
        }
    }
}
