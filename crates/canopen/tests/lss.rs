//! LSS slave (CiA 305; spec `canopen-protocols.md` §6): every command with its exact bytes on
//! 7E5h/7E4h, wrong-state and malformed requests, and python-canopen 2.4.1's
//! `LssMaster.fast_scan()` played bit by bit against simulated slaves.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use canopen::lss::{
    bit_rate_kbit, LssAction, LssAddress, LssSlave, LssState, LSS_REQUEST_ID, LSS_RESPONSE_ID,
    UNCONFIGURED,
};
use od::ObjectDictionary;

/// A Festo-like identity with ones and zeros spread over every part.
const ADDR: LssAddress = LssAddress {
    vendor_id: 0x0000_001D,
    product_code: 0x0018_C375,
    revision: 0x0004_0000,
    serial: 0x8001_E241,
};

fn unconfigured() -> LssSlave {
    LssSlave::new(ADDR, UNCONFIGURED)
}

/// A request padded with zeros to 8 bytes, as every LSS master sends it.
fn req(bytes: &[u8]) -> [u8; 8] {
    let mut f = [0u8; 8];
    f[..bytes.len()].copy_from_slice(bytes);
    f
}

/// Sends one request; returns the responses and the action.
fn send(s: &mut LssSlave, bytes: &[u8]) -> (Vec<[u8; 8]>, Option<LssAction>) {
    let mut out = Vec::new();
    let action = s.on_request(&req(bytes), &mut |r| out.push(r));
    (out, action)
}

/// Sends raw data (any length) and expects neither a response nor an action.
fn ignored(s: &mut LssSlave, data: &[u8]) {
    let mut out = Vec::new();
    let action = s.on_request(data, &mut |r| out.push(r));
    assert!(out.is_empty(), "{data:02X?} answered with {out:02X?}");
    assert_eq!(action, None, "{data:02X?}");
}

fn to_configuration(s: &mut LssSlave) {
    assert_eq!(
        send(s, &[0x04, 0x01]),
        (
            vec![],
            Some(LssAction::StateChanged(LssState::Configuration))
        )
    );
}

#[test]
fn cob_ids_and_tables() {
    assert_eq!((LSS_REQUEST_ID, LSS_RESPONSE_ID), (0x7E5, 0x7E4));
    let rates: Vec<_> = (0..=10).map(bit_rate_kbit).collect();
    assert_eq!(
        rates,
        [
            Some(1000),
            Some(800),
            Some(500),
            Some(250),
            Some(125),
            None,
            Some(50),
            Some(20),
            Some(10),
            None,
            None
        ]
    );
    assert_eq!(
        (0..5).map(|i| ADDR.part(i)).collect::<Vec<_>>(),
        [
            Some(0x1D),
            Some(0x0018_C375),
            Some(0x0004_0000),
            Some(0x8001_E241),
            None
        ]
    );
    // Node-IDs outside 1…127 mean "unconfigured".
    for id in [0, 128, 0xFE, 0xFF] {
        let s = LssSlave::new(ADDR, id);
        assert_eq!((s.active_node_id(), s.pending_node_id()), (0xFF, 0xFF));
        assert!(s.is_non_configured());
    }
    let s = LssSlave::new(ADDR, 127);
    assert_eq!((s.active_node_id(), s.pending_node_id()), (127, 127));
    assert_eq!(s.state(), LssState::Waiting);
}

#[test]
fn address_from_identity_object() {
    let desc = devices::by_name("cmmp-as").expect("cmmp-as personality");
    let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).expect("dictionary");
    let a = LssAddress::from_od(&od).expect("1018h:01…04");
    assert_eq!(a.vendor_id, 0x1D);
    assert_eq!(a.product_code, 0x0018_C375);
    assert_eq!(a.revision, 0x0004_0000);
    assert_eq!(a.serial, 0x0001_E240);
}

#[test]
fn switch_state_global() {
    let mut s = LssSlave::new(ADDR, 1);
    // 7E5: 04 01 → configuration, no answer.
    to_configuration(&mut s);
    assert_eq!(s.state(), LssState::Configuration);
    // Again: no change, no action.
    assert_eq!(send(&mut s, &[0x04, 0x01]), (vec![], None));
    // Invalid mode: ignored.
    ignored(&mut s, &req(&[0x04, 0x02]));
    assert_eq!(s.state(), LssState::Configuration);
    // 7E5: 04 00 → waiting; a configured node keeps its node-ID.
    assert_eq!(
        send(&mut s, &[0x04, 0x00]),
        (vec![], Some(LssAction::StateChanged(LssState::Waiting)))
    );
    assert_eq!(s.state(), LssState::Waiting);
    assert_eq!(s.active_node_id(), 1);
    assert_eq!(send(&mut s, &[0x04, 0x00]), (vec![], None));
}

#[test]
fn switch_state_selective() {
    let mut s = LssSlave::new(ADDR, 1);
    // 40 1D 00 00 00, 41 75 C3 18 00, 42 00 00 04 00: no answers.
    assert_eq!(send(&mut s, &[0x40, 0x1D, 0, 0, 0]), (vec![], None));
    assert_eq!(
        send(&mut s, &[0x41, 0x75, 0xC3, 0x18, 0x00]),
        (vec![], None)
    );
    assert_eq!(
        send(&mut s, &[0x42, 0x00, 0x00, 0x04, 0x00]),
        (vec![], None)
    );
    // 43 41 E2 01 80 → 7E4: 44 00 00 00 00 00 00 00, configuration.
    assert_eq!(
        send(&mut s, &[0x43, 0x41, 0xE2, 0x01, 0x80]),
        (
            vec![[0x44, 0, 0, 0, 0, 0, 0, 0]],
            Some(LssAction::StateChanged(LssState::Configuration))
        )
    );
    assert_eq!(s.state(), LssState::Configuration);
    // In configuration the selective switch is not a valid request.
    for f in [
        [0x40, 0x1D, 0, 0, 0],
        [0x41, 0x75, 0xC3, 0x18, 0x00],
        [0x42, 0x00, 0x00, 0x04, 0x00],
        [0x43, 0x41, 0xE2, 0x01, 0x80],
    ] {
        ignored(&mut s, &req(&f));
    }
    send(&mut s, &[0x04, 0x00]);

    // Wrong serial number: no answer, still waiting.
    let mut s = LssSlave::new(ADDR, 1);
    send(&mut s, &[0x40, 0x1D, 0, 0, 0]);
    send(&mut s, &[0x41, 0x75, 0xC3, 0x18, 0x00]);
    send(&mut s, &[0x42, 0x00, 0x00, 0x04, 0x00]);
    ignored(&mut s, &req(&[0x43, 0x40, 0xE2, 0x01, 0x80]));
    assert_eq!(s.state(), LssState::Waiting);
    // Out of order (product code skipped): no answer.
    send(&mut s, &[0x40, 0x1D, 0, 0, 0]);
    send(&mut s, &[0x42, 0x00, 0x00, 0x04, 0x00]);
    ignored(&mut s, &req(&[0x43, 0x41, 0xE2, 0x01, 0x80]));
    // A mismatch in the middle restarts the match; the next full sequence works.
    send(&mut s, &[0x40, 0x1D, 0, 0, 0]);
    send(&mut s, &[0x41, 0x76, 0xC3, 0x18, 0x00]);
    send(&mut s, &[0x42, 0x00, 0x00, 0x04, 0x00]);
    ignored(&mut s, &req(&[0x43, 0x41, 0xE2, 0x01, 0x80]));
    send(&mut s, &[0x40, 0x1D, 0, 0, 0]);
    send(&mut s, &[0x41, 0x75, 0xC3, 0x18, 0x00]);
    send(&mut s, &[0x42, 0x00, 0x00, 0x04, 0x00]);
    let (out, action) = send(&mut s, &[0x43, 0x41, 0xE2, 0x01, 0x80]);
    assert_eq!(out, vec![[0x44, 0, 0, 0, 0, 0, 0, 0]]);
    assert_eq!(
        action,
        Some(LssAction::StateChanged(LssState::Configuration))
    );
}

#[test]
fn configure_node_id() {
    let mut s = unconfigured();
    to_configuration(&mut s);
    // 11 05 → 11 00 00 00 00 00 00 00; pending only.
    assert_eq!(
        send(&mut s, &[0x11, 0x05]),
        (
            vec![[0x11, 0, 0, 0, 0, 0, 0, 0]],
            Some(LssAction::NodeIdConfigured(5))
        )
    );
    assert_eq!((s.pending_node_id(), s.active_node_id()), (5, 0xFF));
    // Out of range: 11 01 (error 1), pending unchanged.
    for id in [0x00, 0x80, 0xFE] {
        assert_eq!(
            send(&mut s, &[0x11, id]),
            (vec![[0x11, 0x01, 0, 0, 0, 0, 0, 0]], None),
            "node-ID {id:#04X}"
        );
    }
    assert_eq!(s.pending_node_id(), 5);
    // Both ends of the range and FFh are accepted.
    for id in [1, 127, 0xFF] {
        assert_eq!(
            send(&mut s, &[0x11, id]),
            (
                vec![[0x11, 0, 0, 0, 0, 0, 0, 0]],
                Some(LssAction::NodeIdConfigured(id))
            )
        );
        assert_eq!(s.pending_node_id(), id);
    }
}

#[test]
fn configure_and_activate_bit_timing() {
    let mut s = LssSlave::new(ADDR, 1);
    to_configuration(&mut s);
    for index in [0, 1, 2, 3, 4, 6, 7, 8] {
        // 13 00 <index> → 13 00 00 …
        assert_eq!(
            send(&mut s, &[0x13, 0x00, index]),
            (
                vec![[0x13, 0, 0, 0, 0, 0, 0, 0]],
                Some(LssAction::BitTimingConfigured { table: 0, index })
            )
        );
        assert_eq!(s.pending_bit_timing(), Some((0, index)));
    }
    // Reserved 5, automatic detection 9, beyond the table, other tables: 13 01 (not supported).
    for (table, index) in [(0, 5), (0, 9), (0, 10), (0, 0xFF), (1, 0), (0x80, 2)] {
        assert_eq!(
            send(&mut s, &[0x13, table, index]),
            (vec![[0x13, 0x01, 0, 0, 0, 0, 0, 0]], None),
            "table {table} index {index}"
        );
    }
    assert_eq!(s.pending_bit_timing(), Some((0, 8)));
    // 15 E8 03: activate with 1000 ms switch delay, no answer.
    assert_eq!(
        send(&mut s, &[0x15, 0xE8, 0x03]),
        (
            vec![],
            Some(LssAction::ActivateBitTiming { delay_ms: 1000 })
        )
    );
}

#[test]
fn store_configuration() {
    let mut s = LssSlave::new(ADDR, 1);
    to_configuration(&mut s);
    assert_eq!(
        send(&mut s, &[0x17]),
        (
            vec![[0x17, 0, 0, 0, 0, 0, 0, 0]],
            Some(LssAction::StoreConfiguration)
        )
    );
}

#[test]
fn inquire_identity_and_node_id() {
    let mut s = LssSlave::new(ADDR, 4);
    to_configuration(&mut s);
    let cases: [(u8, [u8; 8]); 5] = [
        (0x5A, [0x5A, 0x1D, 0x00, 0x00, 0x00, 0, 0, 0]),
        (0x5B, [0x5B, 0x75, 0xC3, 0x18, 0x00, 0, 0, 0]),
        (0x5C, [0x5C, 0x00, 0x00, 0x04, 0x00, 0, 0, 0]),
        (0x5D, [0x5D, 0x41, 0xE2, 0x01, 0x80, 0, 0, 0]),
        (0x5E, [0x5E, 0x04, 0, 0, 0, 0, 0, 0]),
    ];
    for (cs, answer) in cases {
        assert_eq!(send(&mut s, &[cs]), (vec![answer], None), "{cs:#04X}");
    }
    // The active node-ID is reported, not the pending one; FFh while unconfigured.
    send(&mut s, &[0x11, 0x09]);
    assert_eq!(
        send(&mut s, &[0x5E]),
        (vec![[0x5E, 0x04, 0, 0, 0, 0, 0, 0]], None)
    );
    let mut s = unconfigured();
    to_configuration(&mut s);
    assert_eq!(
        send(&mut s, &[0x5E]),
        (vec![[0x5E, 0xFF, 0, 0, 0, 0, 0, 0]], None)
    );
}

#[test]
fn configuration_commands_ignored_while_waiting() {
    let mut s = unconfigured();
    for f in [
        &[0x11, 0x05][..],
        &[0x13, 0x00, 0x02],
        &[0x15, 0x0A, 0x00],
        &[0x17],
        &[0x5A],
        &[0x5B],
        &[0x5C],
        &[0x5D],
        &[0x5E],
    ] {
        ignored(&mut s, &req(f));
    }
    assert_eq!(s.pending_node_id(), 0xFF);
    assert_eq!(s.pending_bit_timing(), None);
    assert_eq!(s.state(), LssState::Waiting);
}

#[test]
fn malformed_requests_ignored() {
    let mut s = unconfigured();
    // Not 8 data bytes (CANopenNode ignores DLC ≠ 8).
    ignored(&mut s, &[]);
    ignored(&mut s, &[0x04, 0x01]);
    ignored(&mut s, &[0x4C, 0, 0, 0, 0, 0, 0]);
    ignored(&mut s, &[0x4C, 0, 0, 0, 0, 0, 0, 0, 0]);
    ignored(&mut s, &[0x51, 0, 0, 0, 0, 0x80, 0, 0, 0]);
    assert_eq!(s.state(), LssState::Waiting);
    // Unknown and slave→master command specifiers.
    for cs in [
        0x00, 0x05, 0x12, 0x44, 0x45, 0x4D, 0x4E, 0x4F, 0x50, 0x52, 0x5F, 0xFF,
    ] {
        ignored(&mut s, &req(&[cs]));
    }
    // Fastscan with BitChecked 32…7Fh or 81h…, LSSSub or LSSNext > 3.
    ignored(&mut s, &req(&[0x51, 0, 0, 0, 0, 32, 0, 0]));
    ignored(&mut s, &req(&[0x51, 0, 0, 0, 0, 0x81, 0, 0]));
    ignored(&mut s, &req(&[0x51, 0, 0, 0, 0, 0xFF, 0, 0]));
    ignored(&mut s, &req(&[0x51, 0, 0, 0, 0, 0x80, 4, 0]));
    ignored(&mut s, &req(&[0x51, 0, 0, 0, 0, 0x80, 0, 4]));
    ignored(&mut s, &req(&[0x51, 0x1D, 0, 0, 0, 0, 0, 7]));
}

fn identify(s: &mut LssSlave, v: u32, p: u32, rl: u32, rh: u32, sl: u32, sh: u32) -> Vec<[u8; 8]> {
    let mut out = Vec::new();
    for (cs, value) in [
        (0x46u8, v),
        (0x47, p),
        (0x48, rl),
        (0x49, rh),
        (0x4A, sl),
        (0x4B, sh),
    ] {
        let [a, b, c, d] = value.to_le_bytes();
        let (mut r, action) = send(s, &[cs, a, b, c, d]);
        assert_eq!(action, None);
        out.append(&mut r);
    }
    out
}

#[test]
fn identify_remote_slave() {
    const FOUND: [u8; 8] = [0x4F, 0, 0, 0, 0, 0, 0, 0];
    let mut s = LssSlave::new(ADDR, 3);
    // Whole range.
    assert_eq!(
        identify(&mut s, 0x1D, 0x18C375, 0, u32::MAX, 0, u32::MAX),
        [FOUND]
    );
    // Bounds are inclusive.
    assert_eq!(
        identify(
            &mut s,
            0x1D,
            0x18C375,
            0x40000,
            0x40000,
            0x8001_E241,
            0x8001_E241
        ),
        [FOUND]
    );
    // Out of range: revision below, serial above, wrong vendor or product.
    assert!(identify(&mut s, 0x1D, 0x18C375, 0x40001, u32::MAX, 0, u32::MAX).is_empty());
    assert!(identify(&mut s, 0x1D, 0x18C375, 0, 0x3FFFF, 0, u32::MAX).is_empty());
    assert!(identify(&mut s, 0x1D, 0x18C375, 0, u32::MAX, 0x8001_E242, u32::MAX).is_empty());
    assert!(identify(&mut s, 0x1D, 0x18C375, 0, u32::MAX, 0, 0x8001_E240).is_empty());
    assert!(identify(&mut s, 0x1E, 0x18C375, 0, u32::MAX, 0, u32::MAX).is_empty());
    assert!(identify(&mut s, 0x1D, 0x18C376, 0, u32::MAX, 0, u32::MAX).is_empty());
    // Out of order: serial high bound alone does not answer.
    ignored(&mut s, &req(&[0x4B, 0xFF, 0xFF, 0xFF, 0xFF]));
    // Answered in configuration state too, with no state change.
    to_configuration(&mut s);
    assert_eq!(
        identify(&mut s, 0x1D, 0x18C375, 0, u32::MAX, 0, u32::MAX),
        [FOUND]
    );
    assert_eq!(s.state(), LssState::Configuration);
}

#[test]
fn identify_non_configured_remote_slave() {
    const FOUND: [u8; 8] = [0x50, 0, 0, 0, 0, 0, 0, 0];
    let mut s = unconfigured();
    assert_eq!(send(&mut s, &[0x4C]), (vec![FOUND], None));
    to_configuration(&mut s);
    assert_eq!(send(&mut s, &[0x4C]), (vec![FOUND], None));
    // A pending node-ID makes it configured (lely-core).
    send(&mut s, &[0x11, 0x05]);
    ignored(&mut s, &req(&[0x4C]));
    // A node with a node-ID never answers.
    ignored(&mut LssSlave::new(ADDR, 1), &req(&[0x4C]));
}

/// The bus as python-canopen's `LssMaster` sees it: every request reaches every slave, the
/// master takes the first 7E4h frame within `RESPONSE_TIMEOUT` (identical frames sent at once
/// by several slaves are one frame on CAN) and sleeps where `lss.py` sleeps.
struct Bus {
    slaves: Vec<LssSlave>,
    actions: Vec<(usize, LssAction)>,
    frames: usize,
    elapsed_ms: u64,
}

impl Bus {
    fn new(slaves: Vec<LssSlave>) -> Self {
        Bus {
            slaves,
            actions: Vec::new(),
            frames: 0,
            elapsed_ms: 0,
        }
    }

    /// `LssMaster.__send_command`: `None` is "no response" (an `LssError` if one was needed).
    fn send_command(&mut self, message: [u8; 8]) -> Option<[u8; 8]> {
        const NEED_RESPONSE: [u8; 10] =
            [0x11, 0x13, 0x17, 0x43, 0x51, 0x5A, 0x5B, 0x5C, 0x5D, 0x5E];
        self.frames += 1;
        let mut responses = Vec::new();
        for (i, s) in self.slaves.iter_mut().enumerate() {
            if let Some(a) = s.on_request(&message, &mut |r| responses.push(r)) {
                self.actions.push((i, a));
            }
        }
        if !NEED_RESPONSE.contains(&message[0]) {
            return None;
        }
        if let Some(first) = responses.first() {
            // Slaves answering the same request answer the same bytes.
            assert!(responses.iter().all(|r| r == first), "{responses:02X?}");
            Some(*first)
        } else {
            self.elapsed_ms += 500; // RESPONSE_TIMEOUT
            None
        }
    }

    fn sleep(&mut self, ms: u64) {
        self.elapsed_ms += ms;
    }

    /// `LssMaster.__send_fast_scan_message`.
    fn send_fast_scan_message(
        &mut self,
        id_number: u32,
        bit_checker: u8,
        sub: u8,
        next: u8,
    ) -> bool {
        let [a, b, c, d] = id_number.to_le_bytes();
        let message = [0x51, a, b, c, d, bit_checker, sub, next];
        matches!(self.send_command(message), Some([0x4F, ..]))
    }

    /// `LssMaster.fast_scan()`, line by line.
    fn fast_scan(&mut self) -> Option<[u32; 4]> {
        let mut lss_id = [0u32; 4];
        let mut lss_bit_check: u8 = 128;
        let mut lss_sub: u8 = 0;
        let mut lss_next: u8 = 0;
        if !self.send_fast_scan_message(lss_id[0], lss_bit_check, lss_sub, lss_next) {
            return None;
        }
        self.sleep(10);
        while lss_sub < 4 {
            let i = usize::from(lss_sub);
            lss_bit_check = 32;
            while lss_bit_check > 0 {
                lss_bit_check -= 1;
                if !self.send_fast_scan_message(lss_id[i], lss_bit_check, lss_sub, lss_next) {
                    lss_id[i] |= 1 << lss_bit_check;
                }
                self.sleep(10);
            }
            lss_next = (lss_sub + 1) & 3;
            if !self.send_fast_scan_message(lss_id[i], lss_bit_check, lss_sub, lss_next) {
                return None;
            }
            self.sleep(10);
            lss_sub += 1;
        }
        Some(lss_id)
    }

    /// `LssMaster.__send_configure`: the answer must repeat the CS and carry error 0.
    fn configure(&mut self, cs: u8, value1: u8, value2: u8) -> Result<(), String> {
        match self.send_command(req(&[cs, value1, value2])) {
            None => Err("No LSS response received".into()),
            Some([res, ..]) if res != cs => Err("Response message is not for the request".into()),
            Some([_, 0, ..]) => Ok(()),
            Some([_, e, ..]) => Err(format!("LSS Error: {e}")),
        }
    }

    fn send_switch_state_global(&mut self, mode: u8) {
        assert_eq!(self.send_command(req(&[0x04, mode])), None);
    }

    fn take_actions(&mut self) -> Vec<(usize, LssAction)> {
        std::mem::take(&mut self.actions)
    }
}

#[test]
fn fast_scan_finds_one_unconfigured_slave_then_configure_and_store() {
    let mut bus = Bus::new(vec![unconfigured()]);
    let found = bus.fast_scan();
    assert_eq!(
        found,
        Some([
            ADDR.vendor_id,
            ADDR.product_code,
            ADDR.revision,
            ADDR.serial
        ])
    );
    // 1 confirm + 4 × (32 bits + 1 check) frames; 10 ms after each, 0.5 s per bit that is 1.
    assert_eq!(bus.frames, 133);
    let ones: u32 = [
        ADDR.vendor_id,
        ADDR.product_code,
        ADDR.revision,
        ADDR.serial,
    ]
    .iter()
    .map(|p| p.count_ones())
    .sum();
    assert_eq!(bus.elapsed_ms, 133 * 10 + 500 * u64::from(ones));
    // The wrap after the serial number put the slave into configuration.
    assert_eq!(bus.slaves[0].state(), LssState::Configuration);
    assert_eq!(
        bus.take_actions(),
        [(0, LssAction::StateChanged(LssState::Configuration))]
    );

    // The usual follow-up: configure_node_id(5), store_configuration(), switch to waiting.
    bus.configure(0x11, 5, 0).expect("configure_node_id");
    bus.configure(0x17, 0, 0).expect("store_configuration");
    assert_eq!(
        bus.take_actions(),
        [
            (0, LssAction::NodeIdConfigured(5)),
            (0, LssAction::StoreConfiguration)
        ]
    );
    assert_eq!(bus.slaves[0].pending_node_id(), 5);
    bus.send_switch_state_global(0);
    // The node was unconfigured: it resets communication and boots as node 5.
    assert_eq!(
        bus.take_actions(),
        [(0, LssAction::ResetCommunication { node_id: 5 })]
    );
    let s = &bus.slaves[0];
    assert_eq!(s.state(), LssState::Waiting);
    assert_eq!((s.active_node_id(), s.pending_node_id()), (5, 5));
    // Configured now: a second scan finds nobody (the confirm request goes unanswered).
    let before = bus.frames;
    assert_eq!(bus.fast_scan(), None);
    assert_eq!(bus.frames, before + 1);
}

#[test]
fn fast_scan_finds_the_lowest_address_first() {
    let mut low = ADDR;
    low.product_code = 0x0018_C371;
    let mut high = ADDR;
    high.product_code = 0x0018_C372;
    let mut other_vendor = ADDR;
    other_vendor.vendor_id = 0x0000_0360;
    let mut bus = Bus::new(vec![
        LssSlave::new(high, UNCONFIGURED),
        LssSlave::new(other_vendor, UNCONFIGURED),
        LssSlave::new(low, UNCONFIGURED),
        LssSlave::new(ADDR, 7), // configured: keeps out of it
    ]);
    let expect = |a: LssAddress| Some([a.vendor_id, a.product_code, a.revision, a.serial]);
    let states = |bus: &Bus| bus.slaves.iter().map(LssSlave::state).collect::<Vec<_>>();
    use LssState::{Configuration as C, Waiting as W};

    for (n, (slave, address)) in [(2, low), (0, high), (1, other_vendor)]
        .into_iter()
        .enumerate()
    {
        assert_eq!(bus.fast_scan(), expect(address), "scan {n}");
        let mut want = vec![W; 4];
        want[slave] = C;
        assert_eq!(states(&bus), want);
        let node_id = 10 + n as u8;
        bus.configure(0x11, node_id, 0).expect("configure_node_id");
        bus.send_switch_state_global(0);
        assert_eq!(
            bus.take_actions(),
            [
                (slave, LssAction::StateChanged(C)),
                (slave, LssAction::NodeIdConfigured(node_id)),
                (slave, LssAction::ResetCommunication { node_id })
            ]
        );
    }
    assert_eq!(bus.fast_scan(), None);
    let ids: Vec<_> = bus.slaves.iter().map(LssSlave::active_node_id).collect();
    assert_eq!(ids, [11, 12, 10, 7]);
}

#[test]
fn configured_slave_ignores_fastscan() {
    let confirm = req(&[0x51, 0, 0, 0, 0, 0x80, 0, 0]);
    let mut s = LssSlave::new(ADDR, 1);
    ignored(&mut s, &confirm);
    let mut bus = Bus::new(vec![s]);
    assert_eq!(bus.fast_scan(), None);
    assert_eq!(bus.frames, 1);

    // lely-core behaviour on request: a configured slave in waiting state takes part.
    let mut bus = Bus::new(vec![
        LssSlave::new(ADDR, 1).with_fastscan_when_configured(true)
    ]);
    assert_eq!(
        bus.fast_scan(),
        Some([
            ADDR.vendor_id,
            ADDR.product_code,
            ADDR.revision,
            ADDR.serial
        ])
    );
    bus.send_switch_state_global(0);
    assert_eq!(
        bus.take_actions(),
        [
            (0, LssAction::StateChanged(LssState::Configuration)),
            (0, LssAction::StateChanged(LssState::Waiting))
        ]
    );
    assert_eq!(bus.slaves[0].active_node_id(), 1);
}

#[test]
fn fastscan_slave_side_steps() {
    let mut s = unconfigured();
    let fs = |id: u32, bit: u8, sub: u8, next: u8| {
        let [a, b, c, d] = id.to_le_bytes();
        req(&[0x51, a, b, c, d, bit, sub, next])
    };
    let found = [0x4F, 0, 0, 0, 0, 0, 0, 0];
    let step = |s: &mut LssSlave, f: [u8; 8]| send(s, &f);
    // Confirm: 51 00 00 00 00 80 00 00 → 4F.
    assert_eq!(step(&mut s, fs(0, 0x80, 0, 0)), (vec![found], None));
    // Vendor 1Dh: bits 31…5 are 0 → answer; bit 4 is 1 → silence for a 0 guess.
    assert_eq!(step(&mut s, fs(0, 5, 0, 0)), (vec![found], None));
    assert_eq!(step(&mut s, fs(0, 4, 0, 0)), (vec![], None));
    assert_eq!(step(&mut s, fs(0x10, 4, 0, 0)), (vec![found], None));
    // Not the part being scanned: silence.
    assert_eq!(step(&mut s, fs(0, 31, 1, 1)), (vec![], None));
    // Complete vendor: answer, move on to the product code.
    assert_eq!(step(&mut s, fs(0x1D, 0, 0, 1)), (vec![found], None));
    assert_eq!(step(&mut s, fs(0x1D, 0, 0, 1)), (vec![], None));
    assert_eq!(step(&mut s, fs(0, 31, 1, 1)), (vec![found], None));
    // Confirm restarts at the vendor-ID.
    assert_eq!(step(&mut s, fs(0, 0x80, 0, 0)), (vec![found], None));
    assert_eq!(step(&mut s, fs(0, 31, 1, 1)), (vec![], None));
    // Jump straight to the serial (LSSNext chooses): the wrap from 3 to 0 with BitChecked 0
    // is the complete match.
    assert_eq!(step(&mut s, fs(0x1D, 0, 0, 3)), (vec![found], None));
    assert_eq!(
        step(&mut s, fs(ADDR.serial, 0, 3, 0)),
        (
            vec![found],
            Some(LssAction::StateChanged(LssState::Configuration))
        )
    );
    // Fastscan is a waiting-state service.
    assert_eq!(step(&mut s, fs(0, 0x80, 0, 0)), (vec![], None));
}

#[test]
fn leaving_configuration_with_a_node_id() {
    // A configured node keeps its node-ID until the owner's next reset communication.
    let mut s = LssSlave::new(ADDR, 1);
    to_configuration(&mut s);
    send(&mut s, &[0x11, 0x20]);
    assert_eq!(
        send(&mut s, &[0x04, 0x00]),
        (vec![], Some(LssAction::StateChanged(LssState::Waiting)))
    );
    assert_eq!((s.active_node_id(), s.pending_node_id()), (1, 0x20));
    s.set_active_node_id(s.pending_node_id());
    assert_eq!(s.active_node_id(), 0x20);
    // Unconfigure (FFh): takes effect at reset communication too; then it is non-configured.
    to_configuration(&mut s);
    send(&mut s, &[0x11, 0xFF]);
    send(&mut s, &[0x04, 0x00]);
    assert!(!s.is_non_configured());
    s.set_active_node_id(s.pending_node_id());
    assert!(s.is_non_configured());
    assert_eq!(send(&mut s, &[0x4C]).0, vec![[0x50, 0, 0, 0, 0, 0, 0, 0]]);
    // Out-of-range active IDs are stored as FFh.
    s.set_active_node_id(0);
    assert_eq!(s.active_node_id(), 0xFF);
    // Unconfigured, configured to FFh again: leaving has nothing to apply.
    to_configuration(&mut s);
    send(&mut s, &[0x11, 0xFF]);
    assert_eq!(
        send(&mut s, &[0x04, 0x00]),
        (vec![], Some(LssAction::StateChanged(LssState::Waiting)))
    );
}
