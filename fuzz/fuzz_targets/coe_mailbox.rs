//! Mailbox messages into the CoE server of a CMMP-AS (SDO, SDO information, segmented
//! transfers, any command byte, any length): no panic, every reply is a whole mailbox
//! message that fits the send mailbox.
#![no_main]

use ethercat::coe::{CoeConfig, CoeServer};
use libfuzzer_sys::fuzz_target;
use od::ObjectDictionary;

/// The send mailbox (SM1) size of the CMMP-AS.
const SEND_MAILBOX: usize = 0x80;

fn check_reply(out: &[u8], n: usize) {
    assert!((6..=SEND_MAILBOX).contains(&n), "reply of {n} bytes");
    let length = usize::from(u16::from_le_bytes([out[0], out[1]]));
    assert!(length + 6 <= n, "header length {length} in a reply of {n}");
}

/// The input: one byte (odd: the full CoE of the test bench, even: the CMMP-AS's), then
/// messages, each a little-endian u16 length (at most 256) and the message bytes.
fn run(data: &[u8]) {
    let Some((kind, mut data)) = data.split_first() else {
        return;
    };
    let (desc, cfg) = if kind & 1 == 1 {
        (&devices::TESTBENCH, CoeConfig::FULL)
    } else {
        (&devices::CMMP_AS, CoeConfig::from_description(&devices::CMMP_AS))
    };
    let Ok(mut od) = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]) else {
        return;
    };
    let mut srv: CoeServer = CoeServer::new(desc, cfg);
    let mut out = [0u8; SEND_MAILBOX];
    while let [lo, hi, rest @ ..] = data {
        let len = usize::from(u16::from_le_bytes([*lo, *hi]) % 257).min(rest.len());
        let (m, rest) = rest.split_at(len);
        if let Some(n) = srv.process(m, &mut od, &mut out) {
            check_reply(&out, n);
        }
        while let Some(n) = srv.poll(&mut out) {
            check_reply(&out, n);
        }
        data = rest;
    }
}

fuzz_target!(|data: &[u8]| run(data));
