//! Bytes on the RS232 line of a Kinco FD3 (the Kinco manual's extract kept beside the project,
//! spec/kinco-fd-cd.md §2.1-2.2: 10-byte telegrams, ID, an expedited SDO and the negated-sum
//! checksum) with pauses between them, point to point or in a ring: no panic; every answer is a
//! whole telegram with a right checksum from the drive's own station, and in a ring every
//! complete telegram is passed on unchanged first.
#![no_main]

use drive::vendors::kinco::rs232::{checksum_ok, KincoRs232, Response, DEFAULT_GAP, TELEGRAM_LEN};
use libfuzzer_sys::fuzz_target;
use od::{Instant, ObjectDictionary};

/// The input: byte 0 chooses the station (bits 0-6) and the ring (bit 7); then records, each
/// `FF n` (a pause of n ms, up to 255, past the 20 ms gap or not) or `n` and n % 32 bytes
/// received at once.
fn run(data: &[u8]) {
    let Some((&setup, mut data)) = data.split_first() else {
        return;
    };
    let station = setup & 0x7F;
    let ring = setup & 0x80 != 0;
    let d = &devices::KINCO_FD3;
    let Ok(mut od) = ObjectDictionary::new(d, 1, vec![0; d.storage_size]) else {
        return;
    };
    let mut port = KincoRs232::new(station, ring);
    let mut now = Instant::ZERO;
    let mut sent: Vec<u8> = Vec::new();
    while let [tag, rest @ ..] = data {
        if *tag == 0xFF {
            let Some((&ms, rest)) = rest.split_first() else {
                break;
            };
            now = now + core::time::Duration::from_millis(u64::from(ms));
            if let Some(t) = port.deadline() {
                assert!(
                    t <= now + DEFAULT_GAP,
                    "a partial telegram waits at most the gap"
                );
            }
            data = rest;
            continue;
        }
        let n = usize::from(tag % 32).min(rest.len());
        let (bytes, rest) = rest.split_at(n);
        sent.clear();
        port.on_bytes(now, bytes, &mut od, &mut |b| sent.extend_from_slice(b));
        assert_eq!(
            sent.len() % TELEGRAM_LEN,
            0,
            "whole telegrams only: {sent:02X?}"
        );
        for t in sent.chunks_exact(TELEGRAM_LEN) {
            let mut t10 = [0u8; TELEGRAM_LEN];
            t10.copy_from_slice(t);
            if !ring {
                assert!(checksum_ok(&t10), "answers carry a right checksum");
                assert!(
                    Response::parse(&t10, station).is_some(),
                    "an answer of station {station}: {t10:02X?}"
                );
            }
        }
        data = rest;
    }
}

fuzz_target!(|data: &[u8]| run(data));
