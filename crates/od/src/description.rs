//! The static description of a device personality: what `devices/*.toml` says, turned into
//! tables at build time by the `devdesc` code generator.

use crate::{Access, DataType};

/// A numeric limit or default, in the widest form of its kind.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Limit {
    Signed(i64),
    Unsigned(u64),
    Real(f64),
}

/// CiA 301 semantics an entry has beyond storing a value. Data, not code: the description
/// names the behaviour, the dictionary implements it once for every device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Behaviour {
    /// Stores what is written, reads what is stored.
    Plain,
    /// 1010h: reads 1 ("saves on command"); a write of "save" asks for the parameters to be stored.
    StoreSignature,
    /// 1011h: reads 1; a write of "load" restores the default parameters.
    RestoreSignature,
    /// 1003h:00: only 0 may be written, which clears the error history.
    ErrorHistoryCount,
    /// Accepts writes of a valid value but always reads 0 (CMMP-AS 1016h, kept for compatibility).
    ReadsZero,
    /// PDO communication sub 1: COB-ID with the CiA 301 §7.5.2.35 write rules.
    PdoCobId,
    /// PDO communication sub 2: transmission type 0…240, 254, 255.
    PdoTransmissionType,
    /// PDO communication sub 3: inhibit time, not changed while the PDO is valid.
    PdoInhibitTime,
    /// PDO communication sub 5: event timer.
    PdoEventTimer,
    /// PDO communication sub 6: SYNC start value 0…240, not changed while valid.
    PdoSyncStart,
    /// PDO mapping sub 0: number of mapped objects, checked against the entries.
    PdoMapCount,
    /// PDO mapping sub 1…: `index << 16 | sub << 8 | bits`, changed only by the CiA 301 procedure.
    PdoMapEntry,
}

/// How a personality reads the CiA 301 rules the standard leaves open.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Cia301Options {
    /// Every PDO parameter but the COB-ID may be written only while the PDO is not valid
    /// (CMMP-AS §3.3: "only while the PDO is disabled"); CiA 301 locks only some.
    pub pdo_params_locked_while_valid: bool,
    /// PDO parameters may not be written in NMT Operational (CMMP-AS §3.3.3).
    pub pdo_config_outside_operational: bool,
    /// First index of per-TPDO transmit masks (CMMP-AS 2014h…2017h), if the device has them.
    pub tpdo_transmit_mask_index: Option<u16>,
    /// Transmission type 254 sends cyclically with the inhibit time as period (CMMP-AS Tab. 3.7)
    /// instead of CiA 301's event-driven meaning.
    pub tpdo_254_cyclic_inhibit: bool,
    /// PDO transmission type 254 is not offered (Nanotec §9.10–9.21 list 0…240 and 255 only).
    pub pdo_refuses_type_254: bool,
    /// A mapping entry written with length 0 gets the object's length filled in (Nanotec §12.2:
    /// "the firmware fills in bits 7–0", 60400000h maps the controlword).
    pub pdo_map_length_filled: bool,
    /// Every NMT node-control command (start, stop, pre-operational) is answered with the state
    /// byte on 700h + node-ID (Nanotec §12.2 prints `000: 80 01` → `701: 7F`).
    pub nmt_command_answered_with_state: bool,
    /// The EMCY code of a life-guarding error, where the device does not send CiA 301's 8130h
    /// (Nanotec §13.3: 0004h).
    pub life_guard_emcy_code: Option<u16>,
    /// A restore (1011h "load") also overwrites the stored parameter set at once (Nanotec §11.25)
    /// instead of taking effect at the next reset.
    pub restore_writes_stored_set: bool,
    /// Guard time × life time factor (100Ch × 100Dh) may not exceed this many ms; a write
    /// that would is refused with 0604 0043h (Nanotec §11.23: one minute).
    pub life_time_max_ms: Option<u32>,
    /// A PDO may be made valid with no object mapped (it then carries nothing): the Nanotec's
    /// PDOs 2–4 default to valid COB-IDs with empty mappings (§9.11–9.21), so a master that
    /// writes back what it read must be able to. Without it, CiA 301's 0609 0030h.
    pub pdo_valid_without_mapping: bool,
    /// The device has no LSS slave (CiA 305): LSS requests on 7E5h go unanswered (the
    /// Nanotec's node-ID comes from its switches or 2009h only, §1.1).
    pub lss_unsupported: bool,
    /// The dummy objects 0001h–0007h (CiA 301's static data types) that may be
    /// mapped into a PDO, bit n for 000nh: an EDS's `[DummyUsage]` (CiA 306). `None`: the
    /// device file lists the dummies it offers as objects with their mapping flag.
    pub dummy_usage: Option<u8>,
}

/// One sub-index of an object (sub-index 0 for a VAR).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Entry {
    pub index: u16,
    pub sub: u8,
    pub name: &'static str,
    pub data_type: DataType,
    pub access: Access,
    pub pdo_mappable: bool,
    /// Default value, little-endian, as it is stored (strings without a terminator).
    pub default: &'static [u8],
    /// The default is `$NODEID + default` (CiA 306), e.g. the COB-IDs of the communication objects.
    pub default_plus_node_id: bool,
    pub min: Option<Limit>,
    pub max: Option<Limit>,
    pub unit: &'static str,
    pub behaviour: Behaviour,
    /// Saved by 1010h and reloaded at reset (writable entries are, unless a file says otherwise).
    pub storable: bool,
    /// A restore of the defaults (1011h) leaves the value as it is (Nanotec 2005h, 2009h).
    pub kept_on_restore: bool,
    /// Bits an unsigned value may have set; a write with another bit is refused with
    /// 0609 0030h (Nanotec 60FEh:02: "the whole mask is discarded").
    pub allowed_bits: Option<u64>,
    /// Byte offset of the value in the dictionary's storage buffer.
    pub offset: u32,
    /// Bytes reserved for the value: the type's size, or the maximum length of a string/domain.
    pub capacity: u32,
}

impl Entry {
    /// Variable-length entries keep a 2-byte length in front of their bytes in the buffer.
    pub const fn is_variable(&self) -> bool {
        self.data_type.fixed_size().is_none()
    }
    /// Bytes this entry takes in the storage buffer.
    pub const fn storage_len(&self) -> usize {
        if self.is_variable() {
            self.capacity as usize + 2
        } else {
            self.capacity as usize
        }
    }
    pub const fn bit_len(&self) -> u32 {
        self.capacity * 8
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObjectKind {
    /// CiA 306 object code 7.
    Var,
    /// Object code 8: sub-entries of one type.
    Array,
    /// Object code 9: sub-entries of any type.
    Record,
}

impl ObjectKind {
    pub const fn object_code(self) -> u8 {
        match self {
            ObjectKind::Var => 7,
            ObjectKind::Array => 8,
            ObjectKind::Record => 9,
        }
    }
}

/// One index of the dictionary.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Object {
    pub index: u16,
    pub name: &'static str,
    pub kind: ObjectKind,
    /// Two sub-indices whose values stay ordered, min ≤ max (Nanotec 6046h): a write that
    /// would break the order is refused with 0609 0036h.
    pub min_max: Option<(u8, u8)>,
    /// Sorted by sub-index; a VAR has exactly one entry, sub 0.
    pub entries: &'static [Entry],
}

impl Object {
    pub fn entry(&self, sub: u8) -> Option<&'static Entry> {
        let entries: &'static [Entry] = self.entries;
        entries
            .binary_search_by_key(&sub, |e| e.sub)
            .ok()
            .and_then(|i| entries.get(i))
    }
}

/// The device profile a personality speaks on its fieldbus: how the rest of the twin builds
/// and serves it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Profile {
    /// CiA 402 drive (device type 1000h = 0192h): the CiA 402 drive model behind CANopen or
    /// EtherCAT CoE.
    Cia402,
    /// Festo FHPP (the CMMO-ST): cyclic FHPP telegrams over Modbus TCP, PNUs as objects.
    Fhpp,
    /// A plain CiA 301 device (the test bench): the dictionary alone.
    Plain,
}

/// The interfaces a device has and which of them run only one at a time, with the manual's
/// rule (device file keys `interfaces`, `interfaces_one_of`, `interfaces_rule`). Names as a
/// cell file writes them: `canopen`, `ethercat`, `modbus-tcp`, `ci-terminal`, …
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InterfaceOffer {
    pub has: &'static [&'static str],
    pub one_of: &'static [&'static str],
    pub rule: &'static str,
}

/// What an EtherCAT master reads of a slave beyond the dictionary: the SII's layout and names
/// and what its CoE mailbox serves (device file `[device.ethercat]`, ETG.1000.6 §5.4,
/// ETG.2010). Sync manager addresses and sizes are the device's; the identity (vendor id,
/// product code, revision, names) is the description's own.
/// The object whose value sets a device's CAN bit rate, and the codes it takes (device file
/// `can_bit_rate`): code → kbit/s, as the manual's table lists them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CanBitRateCodes {
    /// The object (sub-index 0).
    pub index: u16,
    /// Its name as the manual prints it, for a message that points at it.
    pub name: &'static str,
    /// Each code with its bit rate, kbit/s.
    pub codes: &'static [(u8, u16)],
}

impl CanBitRateCodes {
    /// The bit rate of `code` in kbit/s; `None` for a code the table does not list.
    pub fn kbit(&self, code: u8) -> Option<u16> {
        self.codes.iter().find(|(c, _)| *c == code).map(|&(_, k)| k)
    }
}

/// The objects whose value sets a device's serial line speeds, and the codes they take
/// (device file `serial_bit_rate`): code → bit/s, as the manual's table lists them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SerialBitRateCodes {
    /// The objects (sub-index 0), each an UNSIGNED16 holding a code of the table.
    pub objects: &'static [u16],
    /// Each code with its bit rate, bit/s.
    pub codes: &'static [(u16, u32)],
}

impl SerialBitRateCodes {
    /// The bit rate of `code` in bit/s; `None` for a code the table does not list.
    pub fn bit_rate(&self, code: u16) -> Option<u32> {
        self.codes.iter().find(|(c, _)| *c == code).map(|&(_, b)| b)
    }

    /// The code of `bit_rate` (bit/s); `None` for a bit rate the table does not list.
    pub fn code(&self, bit_rate: u32) -> Option<u16> {
        self.codes
            .iter()
            .find(|(_, b)| *b == bit_rate)
            .map(|&(c, _)| c)
    }
}

/// What an FHPP device (Festo Handling and Positioning Profile, parameters PNU n at object
/// 2000h + n) says beyond its parameters (device file `[device.fhpp]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FhppParameters {
    /// Motion records of record selection, numbered 1…`records` (the record list's
    /// subindices; record number 0 is homing).
    pub records: u8,
    /// PNUs writable only with the output stage off (access "rw2"), sorted: a write while
    /// the stage is on is refused.
    pub stage_off_pnus: &'static [u16],
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EthercatSlave {
    /// ESI `GroupType` (the SII GENERAL GroupIdx string).
    pub group_type: &'static str,
    /// ESI `<Group><Name>`.
    pub group_name: &'static str,
    /// SII word 0: PDI control (low byte) and ESC configuration (high byte).
    pub pdi_control: u16,
    /// SM0, the receive mailbox (master → slave): start address and size in bytes.
    pub mailbox_out: (u16, u16),
    /// SM1, the send mailbox (slave → master): start address and size in bytes.
    pub mailbox_in: (u16, u16),
    /// SM2 (process-data outputs) start address.
    pub outputs_start: u16,
    /// SM3 (process-data inputs) start address.
    pub inputs_start: u16,
    /// RxPDOs assigned to SM2 by default (1C12h).
    pub rx_assigned: &'static [u16],
    /// TxPDOs assigned to SM3 by default (1C13h).
    pub tx_assigned: &'static [u16],
    /// CiA 402 axes (SII GENERAL byte 9).
    pub ds402_channels: u8,
    /// Physical ports, 4 bits each, 1 = MII (ETG.2010 GENERAL bytes 16–17).
    pub physical_ports: u16,
    /// SDO complete access is served (and advertised in the SII).
    pub complete_access: bool,
    /// The SDO information service is served (and advertised in the SII).
    pub sdo_info: bool,
    /// Indices not served over CoE (abort 0602 0000h), though the dictionary has them.
    pub coe_hidden: &'static [u16],
    /// SII word 0x3F.
    pub version: u16,
    /// The diagnostic message (its number in the device's table) the device raises when the
    /// ESC's process-data watchdog expires in Op (the master's frames stopped); `None`: the
    /// ESC's fall-back to Safe-Op (0x001B) alone.
    pub watchdog_diagnostic: Option<&'static str>,
}

/// A device personality: identity and the complete object list.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceDescription {
    /// The personality's short name (`cmmp-as`), as on the command line.
    pub name: &'static str,
    pub product_name: &'static str,
    pub vendor_name: &'static str,
    pub vendor_id: u32,
    pub product_code: u32,
    pub revision: u32,
    pub order_code: &'static str,
    pub description: &'static str,
    /// The device profile (`profile` in the device file).
    pub profile: Profile,
    pub default_node_id: u8,
    /// Bit rates in kbit/s the device supports (EDS `[DeviceInfo]`).
    pub baud_rates: &'static [u16],
    /// Hexadecimal rotary switches that select node-ID and bit rate at power-on (Nanotec
    /// §1.1.1: SMCI47-S two, PD4-N one), 0 for none.
    pub rotary_switches: u8,
    /// The object that sets the CAN bit rate by a code, and its codes (device file
    /// `can_bit_rate`); `None` where no object does, or where the vendor's rules decide.
    pub can_bit_rate: Option<CanBitRateCodes>,
    /// The objects that set the serial line speeds by a code, and their codes (device file
    /// `serial_bit_rate`); `None` for a device without such objects.
    pub serial_bit_rate: Option<SerialBitRateCodes>,
    /// The serial ports and the objects that set them up (device file
    /// `[device.serial_ports]`), one per serial interface of `interfaces`.
    pub serial_ports: &'static [crate::SerialPort],
    /// Which interfaces the real device has.
    pub interfaces: InterfaceOffer,
    /// DIP switches (or inputs) select node-ID offset, bit rate and fieldbus at power-on
    /// (device file `fieldbus_switches`).
    pub fieldbus_switches: bool,
    /// The EtherCAT slave's SII and CoE data, for a device with an EtherCAT interface.
    pub ethercat: Option<EthercatSlave>,
    /// What the FHPP profile needs beyond the parameters, for a device of that profile.
    pub fhpp: Option<FhppParameters>,
    /// What the device does when its CAN controller changes error state (device file
    /// `[device.bus_faults]`; CiA 301's usage for a file without one, an EDS among them).
    pub bus_faults: crate::BusFaultReactions,
    /// The holding brake's delay objects (device file `[device.brake]`; none for a file
    /// without one, an EDS among them).
    pub brake: crate::BrakeTiming,
    /// The plant supervision's messages and objects (device file `[device.plant]`; none for
    /// a file without one, an EDS among them).
    pub plant: crate::PlantSupervision,
    pub cia301: Cia301Options,
    /// Sorted by index.
    pub objects: &'static [Object],
    /// The manual's diagnostic table (`[[diagnostic]]` rows), in file order.
    pub diagnostics: &'static [crate::Diagnostic],
    /// Size of the value buffer an `ObjectDictionary` needs.
    pub storage_size: usize,
}

impl DeviceDescription {
    pub fn object(&self, index: u16) -> Option<&'static Object> {
        let objects: &'static [Object] = self.objects;
        objects
            .binary_search_by_key(&index, |o| o.index)
            .ok()
            .and_then(|i| objects.get(i))
    }
    pub fn entry(&self, index: u16, sub: u8) -> Option<&'static Entry> {
        self.object(index).and_then(|o| o.entry(sub))
    }
    /// The diagnostic message numbered `number` as the manual prints it ("08-2", "2Fh").
    pub fn diagnostic(&self, number: &str) -> Option<&'static crate::Diagnostic> {
        let rows: &'static [crate::Diagnostic] = self.diagnostics;
        rows.iter().find(|d| d.number.eq_ignore_ascii_case(number))
    }
    /// Every entry of every object, in dictionary order.
    pub fn entries(&self) -> impl Iterator<Item = &'static Entry> {
        let objects: &'static [Object] = self.objects;
        objects.iter().flat_map(|o| o.entries.iter())
    }
}
