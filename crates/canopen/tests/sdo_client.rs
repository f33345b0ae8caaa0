//! The SDO client against the SDO server, frame by frame on the test bench personality:
//! every transfer the client knows completes, and the server's aborts reach the client.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;
use canopen::sdo_client::{Progress, SdoClientError};
use canopen::SdoClient;
use common::*;
use od::AbortCode;

fn bench() -> Bench {
    Bench::new(&devices::TESTBENCH, 1)
}

/// Runs one transfer to its end; returns the uploaded bytes and the requests sent.
fn run(
    b: &mut Bench,
    c: &mut SdoClient,
    first: [u8; 8],
    value: &[u8],
) -> (Result<Vec<u8>, SdoClientError>, Vec<[u8; 8]>) {
    let mut got = Vec::new();
    let mut sent = vec![first];
    let mut request = first;
    loop {
        let response = b.sdo1(&request);
        match c.on_response(&response, value) {
            Ok(Progress::Next { data, request: r }) => {
                got.extend_from_slice(data);
                sent.push(r);
                request = r;
            }
            Ok(Progress::Done { data }) => {
                got.extend_from_slice(data);
                return (Ok(got), sent);
            }
            Err(e) => return (Err(e), sent),
        }
    }
}

#[test]
fn expedited_round_trips() {
    let mut b = bench();
    let mut c = SdoClient::new();
    let first = c.upload(0x1018, 2);
    assert_eq!(run(&mut b, &mut c, first, &[]).0, Ok(vec![1, 0, 0, 0]));

    let value = (-100i16).to_le_bytes();
    let first = c.download(0x2003, 0, &value);
    let (r, sent) = run(&mut b, &mut c, first, &value);
    assert_eq!((r, sent.len()), (Ok(vec![]), 1));
    let first = c.upload(0x2003, 0);
    assert_eq!(run(&mut b, &mut c, first, &[]).0, Ok(value.to_vec()));
    assert!(c.is_idle());
}

#[test]
fn segmented_round_trips() {
    let mut b = bench();
    let mut c = SdoClient::new();
    let first = c.upload(0x1008, 0);
    let (r, sent) = run(&mut b, &mut c, first, &[]);
    assert_eq!(r, Ok(b"drivetwin test bench".to_vec()));
    assert_eq!(sent.len(), 4, "initiate and three segments");

    for len in [0usize, 5, 7, 14, 15, 1000] {
        let value: Vec<u8> = (0..len).map(|i| (i * 7 + 3) as u8).collect();
        let first = c.download(0x2000, 0, &value);
        let (r, sent) = run(&mut b, &mut c, first, &value);
        assert_eq!(r, Ok(vec![]), "{len} bytes");
        // An empty value still has its one (empty, last) segment.
        assert_eq!(sent.len(), 1 + len.div_ceil(7).max(1), "{len} bytes");
        let first = c.upload(0x2000, 0);
        assert_eq!(run(&mut b, &mut c, first, &[]).0, Ok(value), "{len} bytes");
    }
}

#[test]
fn the_servers_aborts_reach_the_client() {
    let mut b = bench();
    let mut c = SdoClient::new();
    let first = c.upload(0x2100, 0);
    assert_eq!(
        run(&mut b, &mut c, first, &[]).0,
        Err(SdoClientError::Abort(AbortCode::NO_OBJECT))
    );
    let first = c.download(0x1018, 1, &[1, 0, 0, 0]);
    assert_eq!(
        run(&mut b, &mut c, first, &[1, 0, 0, 0]).0,
        Err(SdoClientError::Abort(AbortCode::READ_ONLY))
    );
    // The server takes the next transfer after both.
    let first = c.upload(0x1018, 2);
    assert_eq!(run(&mut b, &mut c, first, &[]).0, Ok(vec![1, 0, 0, 0]));
}

#[test]
fn a_client_abort_frees_the_server() {
    let mut b = bench();
    let mut c = SdoClient::new();
    let first = c.upload(0x1008, 0);
    let r = b.sdo1(&first);
    assert!(matches!(c.on_response(&r, &[]), Ok(Progress::Next { .. })));
    let abort = c.abort(AbortCode::GENERAL).unwrap();
    assert_eq!(abort, [0x80, 0x08, 0x10, 0, 0, 0, 0, 0x08]);
    assert!(b.sdo(&abort).is_empty(), "a client abort has no answer");
    let first = c.upload(0x1018, 2);
    assert_eq!(run(&mut b, &mut c, first, &[]).0, Ok(vec![1, 0, 0, 0]));
}
