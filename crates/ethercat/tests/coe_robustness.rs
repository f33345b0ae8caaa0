//! Whatever a master writes into the receive mailbox, the CoE server goes on: any sequence of
//! mailbox messages (bad lengths, other types, repeated counters, SDO and SDO-information requests
//! with any command byte, index and data) gets replies that are whole mailbox messages of the send
//! mailbox's size at most, never a panic; and afterwards an expedited upload of 1018h:01 is
//! answered with the dictionary's value (the ESC reference kept beside the project, §5).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use ethercat::coe::{CoeConfig, CoeServer};
use ethercat::mailbox::next_counter;
use od::{ObjectAccess, ObjectDictionary};
use proptest::prelude::*;

/// The send mailbox (SM1) size of the CMMP-AS.
const SEND_MAILBOX: usize = 0x80;

/// A CoE payload that is often close to a real request: the CoE service (SDO request 2,
/// SDO information 8, or any), a command byte, an index near the dictionary's, data.
fn coe_payload() -> impl Strategy<Value = Vec<u8>> {
    (
        prop_oneof![Just(0x20u8), Just(0x80), any::<u8>()],
        any::<u8>(),
        prop_oneof![
            Just(0x1018u16),
            Just(0x1600),
            Just(0x1C12),
            Just(0x6040),
            any::<u16>()
        ],
        any::<u8>(),
        prop::collection::vec(any::<u8>(), 0..120),
    )
        .prop_map(|(service, cmd, index, sub, data)| {
            let [il, ih] = index.to_le_bytes();
            let mut p = vec![0x00, service, cmd, il, ih, sub];
            p.extend_from_slice(&data);
            p
        })
}

/// A mailbox message: the header's length as written or any, type CoE or any, any counter.
fn message() -> impl Strategy<Value = Vec<u8>> {
    (
        coe_payload(),
        prop_oneof![3 => Just(None), 1 => any::<u16>().prop_map(Some)],
        prop_oneof![3 => Just(0x03u8), 1 => 0u8..16],
        0u8..8,
        prop_oneof![3 => Just(0x80usize), 1 => 0usize..0x100],
    )
        .prop_map(|(payload, length, kind, counter, size)| {
            let mut m = vec![0u8; size.max(6)];
            let len = length.unwrap_or(payload.len() as u16);
            m[0..2].copy_from_slice(&len.to_le_bytes());
            m[5] = kind | (counter << 4);
            let room = m.len() - 6;
            m[6..6 + payload.len().min(room)].copy_from_slice(&payload[..payload.len().min(room)]);
            m
        })
}

fn check_reply(out: &[u8], n: usize) -> Result<(), TestCaseError> {
    prop_assert!((6..=SEND_MAILBOX).contains(&n), "reply of {} bytes", n);
    let length = usize::from(u16::from_le_bytes([out[0], out[1]]));
    prop_assert!(
        length + 6 <= n,
        "header length {} in a reply of {}",
        length,
        n
    );
    Ok(())
}

fn run(
    desc: &'static od::DeviceDescription,
    cfg: CoeConfig,
    messages: &[Vec<u8>],
) -> Result<(), TestCaseError> {
    let mut od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size])
        .map_err(|e| TestCaseError::fail(format!("{e:?}")))?;
    let mut srv: CoeServer = CoeServer::new(desc, cfg);
    let mut out = [0u8; SEND_MAILBOX];
    for m in messages {
        if let Some(n) = srv.process(m, &mut od, &mut out) {
            check_reply(&out, n)?;
        }
        while let Some(n) = srv.poll(&mut out) {
            check_reply(&out, n)?;
        }
    }
    // Two uploads of 1018h:01 with fresh counters: the second is answered right whatever
    // counter the sequence left.
    let mut answer = None;
    let mut counter = 1;
    for _ in 0..2 {
        counter = next_counter(counter);
        let mut m = vec![0u8; 0x80];
        m[0..2].copy_from_slice(&10u16.to_le_bytes());
        m[5] = 0x03 | (counter << 4);
        m[6..16].copy_from_slice(&[0x00, 0x20, 0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]);
        answer = srv
            .process(&m, &mut od, &mut out)
            .map(|n| out[..n].to_vec());
        while srv.poll(&mut [0u8; SEND_MAILBOX]).is_some() {}
    }
    let r = answer.ok_or_else(|| TestCaseError::fail("no answer to the upload"))?;
    let vendor = od.read_u32(0x1018, 1).unwrap_or(0).to_le_bytes();
    prop_assert_eq!(&r[6..12], &[0x00, 0x30, 0x43, 0x18, 0x10, 0x01][..]);
    prop_assert_eq!(&r[12..16], &vendor[..], "the dictionary's vendor ID");
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn any_mailbox_messages_cmmp_as(messages in prop::collection::vec(message(), 1..40)) {
        run(&devices::CMMP_AS, CoeConfig::from_description(&devices::CMMP_AS), &messages)?;
    }

    #[test]
    fn any_mailbox_messages_full_coe(messages in prop::collection::vec(message(), 1..40)) {
        run(&devices::TESTBENCH, CoeConfig::FULL, &messages)?;
    }
}
