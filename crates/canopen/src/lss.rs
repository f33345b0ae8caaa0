//! LSS slave (CiA 305): node-ID and bit-timing configuration over 7E5h (master → slaves) and
//! 7E4h (slave → master), selection by the 128-bit LSS address (1018h:01…04) or by fastscan.
//! Sans-IO: request bytes in, response bytes out, and an [`LssAction`] for what only the
//! owner can do (reset communication, persist, change the bit rate).
//!
//! "spec §n" below is a section of `canopen-protocols.md`, the notes on CiA 301 / 305 kept
//! beside the project with the manuals' extracts.

use od::ObjectAccess;

/// CAN-ID of LSS requests, master → slaves (CiA 305; spec `canopen-protocols.md` §6.1).
pub const LSS_REQUEST_ID: u16 = 0x7E5;
/// CAN-ID of LSS responses, slave → master.
pub const LSS_RESPONSE_ID: u16 = 0x7E4;
/// The node-ID of a node that has none ("not configured", CiA 305; spec §6.1).
pub const UNCONFIGURED: u8 = 0xFF;

/// Command specifiers (CiA 305; spec §6.3).
pub mod cs {
    pub const SWITCH_STATE_GLOBAL: u8 = 0x04;
    pub const CONFIGURE_NODE_ID: u8 = 0x11;
    pub const CONFIGURE_BIT_TIMING: u8 = 0x13;
    pub const ACTIVATE_BIT_TIMING: u8 = 0x15;
    pub const STORE_CONFIGURATION: u8 = 0x17;
    pub const SWITCH_SELECTIVE_VENDOR: u8 = 0x40;
    pub const SWITCH_SELECTIVE_PRODUCT: u8 = 0x41;
    pub const SWITCH_SELECTIVE_REVISION: u8 = 0x42;
    pub const SWITCH_SELECTIVE_SERIAL: u8 = 0x43;
    pub const SWITCH_SELECTIVE_RESPONSE: u8 = 0x44;
    pub const IDENTIFY_VENDOR: u8 = 0x46;
    pub const IDENTIFY_PRODUCT: u8 = 0x47;
    pub const IDENTIFY_REVISION_LOW: u8 = 0x48;
    pub const IDENTIFY_REVISION_HIGH: u8 = 0x49;
    pub const IDENTIFY_SERIAL_LOW: u8 = 0x4A;
    pub const IDENTIFY_SERIAL_HIGH: u8 = 0x4B;
    pub const IDENTIFY_NON_CONFIGURED: u8 = 0x4C;
    pub const IDENTIFY_SLAVE: u8 = 0x4F;
    pub const IDENTIFY_NON_CONFIGURED_SLAVE: u8 = 0x50;
    pub const FASTSCAN: u8 = 0x51;
    pub const INQUIRE_VENDOR: u8 = 0x5A;
    pub const INQUIRE_PRODUCT: u8 = 0x5B;
    pub const INQUIRE_REVISION: u8 = 0x5C;
    pub const INQUIRE_SERIAL: u8 = 0x5D;
    pub const INQUIRE_NODE_ID: u8 = 0x5E;
}

/// Fastscan BitChecked value that restarts the scan and asks every candidate to confirm.
const FASTSCAN_CONFIRM: u8 = 0x80;

/// The LSS address of a device: the identity object 1018h:01…04.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct LssAddress {
    pub vendor_id: u32,
    pub product_code: u32,
    pub revision: u32,
    pub serial: u32,
}

impl LssAddress {
    /// Reads 1018h:01…04; `None` if one of them is missing or not 32 bits wide.
    pub fn from_od(od: &dyn ObjectAccess) -> Option<Self> {
        Some(LssAddress {
            vendor_id: od.read_u32(0x1018, 1)?,
            product_code: od.read_u32(0x1018, 2)?,
            revision: od.read_u32(0x1018, 3)?,
            serial: od.read_u32(0x1018, 4)?,
        })
    }

    /// One part by its fastscan LSSSub number: 0 vendor-ID, 1 product code, 2 revision,
    /// 3 serial number.
    pub const fn part(&self, sub: u8) -> Option<u32> {
        match sub {
            0 => Some(self.vendor_id),
            1 => Some(self.product_code),
            2 => Some(self.revision),
            3 => Some(self.serial),
            _ => None,
        }
    }
}

/// LSS slave state (CiA 305; spec §6.2). Initialisation is not a state of its own here: the slave
/// starts in Waiting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum LssState {
    Waiting = 0,
    Configuration = 1,
}

impl LssState {
    /// The mode byte of "switch state global" that selects this state.
    pub const fn code(self) -> u8 {
        self as u8
    }
    pub const fn from_code(code: u8) -> Option<Self> {
        match code {
            0 => Some(LssState::Waiting),
            1 => Some(LssState::Configuration),
            _ => None,
        }
    }
}

/// Bit rate in kbit/s of an index of the CiA 301 bit-timing table (table selector 0, CiA 305;
/// spec §6.3); `None` for reserved entries (5) and automatic detection (9), which are not
/// supported.
pub const fn bit_rate_kbit(index: u8) -> Option<u16> {
    Some(match index {
        0 => 1000,
        1 => 800,
        2 => 500,
        3 => 250,
        4 => 125,
        6 => 50,
        7 => 20,
        8 => 10,
        _ => return None,
    })
}

/// What the slave asks its owner to do; the response frame, if any, is already out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LssAction {
    /// Configure node-ID accepted (1…127, or FFh = unconfigured): it is now the pending
    /// node-ID, which becomes active at the next reset communication (CiA 305; spec §6.2).
    NodeIdConfigured(u8),
    /// Configure bit timing accepted: the pending bit timing. Activated by
    /// [`LssAction::ActivateBitTiming`], persisted by [`LssAction::StoreConfiguration`].
    BitTimingConfigured { table: u8, index: u8 },
    /// Activate bit timing: wait `delay_ms`, switch to the pending bit rate, wait `delay_ms`
    /// again before transmitting anything (CiA 305; spec §6.3).
    ActivateBitTiming { delay_ms: u16 },
    /// Store configuration (answered with success): persist the pending node-ID and bit timing
    /// so that they are used after the next power-on.
    StoreConfiguration,
    /// The LSS state changed.
    StateChanged(LssState),
    /// The slave went back to Waiting while its active node-ID was FFh and a valid pending
    /// node-ID had been configured: the node must perform NMT reset communication now and
    /// boot with `node_id` (CANopenNode behaviour, spec §6.2). The slave already reports
    /// `node_id` as active.
    ResetCommunication { node_id: u8 },
}

/// Whether `id` may be configured: 1…127 or FFh (CiA 305; spec §6.3).
const fn configurable(id: u8) -> bool {
    matches!(id, 1..=127 | UNCONFIGURED)
}

/// Maps anything outside 1…127 to FFh.
const fn normalise(id: u8) -> u8 {
    if matches!(id, 1..=127) {
        id
    } else {
        UNCONFIGURED
    }
}

/// The LSS slave of one node.
#[derive(Debug, Clone)]
pub struct LssSlave {
    address: LssAddress,
    state: LssState,
    active_node_id: u8,
    pending_node_id: u8,
    pending_bit_timing: Option<(u8, u8)>,
    /// Switch state selective: how many of 40h…42h matched in order.
    selective: u8,
    /// Identify remote slave: how many of 46h…4Ah matched in order.
    identify: u8,
    /// Fastscan: the LSSSub this slave compares next.
    fastscan_pos: u8,
    /// Lely behaviour: take part in fastscan whatever the node-ID.
    fastscan_when_configured: bool,
}

impl LssSlave {
    /// A slave in Waiting state. `active_node_id` outside 1…127 means unconfigured (FFh);
    /// the pending node-ID starts equal to it.
    pub fn new(address: LssAddress, active_node_id: u8) -> Self {
        let id = normalise(active_node_id);
        LssSlave {
            address,
            state: LssState::Waiting,
            active_node_id: id,
            pending_node_id: id,
            pending_bit_timing: None,
            selective: 0,
            identify: 0,
            fastscan_pos: 0,
            fastscan_when_configured: false,
        }
    }

    /// Take part in fastscan in Waiting state even with a node-ID (lely-core behaviour).
    /// The default, as CANopenNode, answers fastscan only while both the active and the
    /// pending node-ID are FFh (spec §6.5).
    pub fn with_fastscan_when_configured(mut self, on: bool) -> Self {
        self.fastscan_when_configured = on;
        self
    }

    pub fn address(&self) -> LssAddress {
        self.address
    }
    pub fn state(&self) -> LssState {
        self.state
    }
    pub fn active_node_id(&self) -> u8 {
        self.active_node_id
    }
    /// The node-ID to use at the next reset communication.
    pub fn pending_node_id(&self) -> u8 {
        self.pending_node_id
    }
    /// The pending bit timing `(table, index)`, if one was configured.
    pub fn pending_bit_timing(&self) -> Option<(u8, u8)> {
        self.pending_bit_timing
    }
    /// The node-ID in use after a reset communication (normally [`Self::pending_node_id`]);
    /// outside 1…127 means unconfigured.
    pub fn set_active_node_id(&mut self, id: u8) {
        self.active_node_id = normalise(id);
    }
    /// Non-configured in the sense of CiA 305: no active and no pending node-ID.
    pub fn is_non_configured(&self) -> bool {
        self.active_node_id == UNCONFIGURED && self.pending_node_id == UNCONFIGURED
    }

    /// One frame received on 7E5h. Frames whose length is not 8, unknown command specifiers
    /// and commands not valid in the current state are ignored without an answer. Responses
    /// (to be sent on 7E4h) go to `out`.
    pub fn on_request(&mut self, data: &[u8], out: &mut dyn FnMut([u8; 8])) -> Option<LssAction> {
        let Ok([code, b1, b2, b3, b4, b5, b6, b7]) = <[u8; 8]>::try_from(data) else {
            return None; // LSS frames always have 8 data bytes (spec §6.1)
        };
        let value = u32::from_le_bytes([b1, b2, b3, b4]);
        let configuration = self.state == LssState::Configuration;
        match code {
            cs::SWITCH_STATE_GLOBAL => self.switch_global(b1),
            cs::SWITCH_SELECTIVE_VENDOR..=cs::SWITCH_SELECTIVE_SERIAL if !configuration => {
                self.switch_selective(code, value, out)
            }
            cs::IDENTIFY_VENDOR..=cs::IDENTIFY_SERIAL_HIGH => {
                self.identify_remote(code, value, out);
                None
            }
            cs::IDENTIFY_NON_CONFIGURED => {
                if self.is_non_configured() {
                    out(response(cs::IDENTIFY_NON_CONFIGURED_SLAVE, [0; 7]));
                }
                None
            }
            cs::FASTSCAN if !configuration => self.fastscan(value, b5, b6, b7, out),
            cs::CONFIGURE_NODE_ID if configuration => {
                if configurable(b1) {
                    self.pending_node_id = b1;
                    out(response(code, [0; 7]));
                    Some(LssAction::NodeIdConfigured(b1))
                } else {
                    out(response(code, [1, 0, 0, 0, 0, 0, 0])); // node-ID out of range
                    None
                }
            }
            cs::CONFIGURE_BIT_TIMING if configuration => {
                if b1 == 0 && bit_rate_kbit(b2).is_some() {
                    self.pending_bit_timing = Some((b1, b2));
                    out(response(code, [0; 7]));
                    Some(LssAction::BitTimingConfigured {
                        table: b1,
                        index: b2,
                    })
                } else {
                    out(response(code, [1, 0, 0, 0, 0, 0, 0])); // bit timing not supported
                    None
                }
            }
            cs::ACTIVATE_BIT_TIMING if configuration => Some(LssAction::ActivateBitTiming {
                delay_ms: u16::from_le_bytes([b1, b2]),
            }),
            cs::STORE_CONFIGURATION if configuration => {
                out(response(code, [0; 7]));
                Some(LssAction::StoreConfiguration)
            }
            cs::INQUIRE_VENDOR..=cs::INQUIRE_SERIAL if configuration => {
                let part = self
                    .address
                    .part(code.wrapping_sub(cs::INQUIRE_VENDOR))
                    .unwrap_or(0);
                let [v0, v1, v2, v3] = part.to_le_bytes();
                out(response(code, [v0, v1, v2, v3, 0, 0, 0]));
                None
            }
            cs::INQUIRE_NODE_ID if configuration => {
                // The active node-ID, FFh while unconfigured (CANopenNode, spec §6.3).
                out(response(code, [self.active_node_id, 0, 0, 0, 0, 0, 0]));
                None
            }
            _ => None,
        }
    }

    fn enter(&mut self, state: LssState) -> Option<LssAction> {
        if self.state == state {
            return None;
        }
        self.state = state;
        self.selective = 0;
        if state == LssState::Configuration {
            return Some(LssAction::StateChanged(state));
        }
        // Back to Waiting: an unconfigured node that got a node-ID starts with it now.
        if self.active_node_id == UNCONFIGURED && self.pending_node_id != UNCONFIGURED {
            self.active_node_id = self.pending_node_id;
            return Some(LssAction::ResetCommunication {
                node_id: self.pending_node_id,
            });
        }
        Some(LssAction::StateChanged(state))
    }

    /// 04h: mode 0 = Waiting, 1 = Configuration; other modes are ignored.
    fn switch_global(&mut self, mode: u8) -> Option<LssAction> {
        self.enter(LssState::from_code(mode)?)
    }

    /// 40h…43h in this order with the four address parts; 44h and Configuration on the fourth.
    fn switch_selective(
        &mut self,
        code: u8,
        value: u32,
        out: &mut dyn FnMut([u8; 8]),
    ) -> Option<LssAction> {
        let step = code.wrapping_sub(cs::SWITCH_SELECTIVE_VENDOR);
        let in_order = step == 0 || step == self.selective;
        if !in_order || self.address.part(step) != Some(value) {
            self.selective = 0;
            return None;
        }
        if step < 3 {
            self.selective = step + 1;
            return None;
        }
        out(response(cs::SWITCH_SELECTIVE_RESPONSE, [0; 7]));
        self.enter(LssState::Configuration)
    }

    /// 46h…4Bh in this order: vendor and product equal, revision and serial within the
    /// inclusive bounds; 4Fh on the last one.
    fn identify_remote(&mut self, code: u8, value: u32, out: &mut dyn FnMut([u8; 8])) {
        let step = code.wrapping_sub(cs::IDENTIFY_VENDOR);
        let a = &self.address;
        let matched = match step {
            0 => a.vendor_id == value,
            1 => a.product_code == value,
            2 => a.revision >= value,
            3 => a.revision <= value,
            4 => a.serial >= value,
            _ => a.serial <= value,
        };
        let in_order = step == 0 || step == self.identify;
        if !in_order || !matched {
            self.identify = 0;
        } else if step < 5 {
            self.identify = step + 1;
        } else {
            self.identify = 0;
            out(response(cs::IDENTIFY_SLAVE, [0; 7]));
        }
    }

    /// 51h (CiA 305 fastscan; spec §6.5). Silence is the answer "no match".
    fn fastscan(
        &mut self,
        id_number: u32,
        bit_checked: u8,
        lss_sub: u8,
        lss_next: u8,
        out: &mut dyn FnMut([u8; 8]),
    ) -> Option<LssAction> {
        if !(self.is_non_configured() || self.fastscan_when_configured) {
            return None;
        }
        if (bit_checked > 31 && bit_checked != FASTSCAN_CONFIRM) || lss_sub > 3 || lss_next > 3 {
            return None;
        }
        if bit_checked == FASTSCAN_CONFIRM {
            self.fastscan_pos = 0;
            out(response(cs::IDENTIFY_SLAVE, [0; 7]));
            return None;
        }
        if self.fastscan_pos != lss_sub {
            return None;
        }
        let mask = u32::MAX.checked_shl(u32::from(bit_checked)).unwrap_or(0);
        let part = self.address.part(lss_sub)?;
        if (part ^ id_number) & mask != 0 {
            return None;
        }
        out(response(cs::IDENTIFY_SLAVE, [0; 7]));
        self.fastscan_pos = lss_next;
        if bit_checked == 0 && lss_next < lss_sub {
            // The whole address matched and the scan wrapped after the serial number.
            return self.enter(LssState::Configuration);
        }
        None
    }
}

/// A response frame: command specifier and seven bytes.
fn response(cs: u8, rest: [u8; 7]) -> [u8; 8] {
    let [a, b, c, d, e, f, g] = rest;
    [cs, a, b, c, d, e, f, g]
}
