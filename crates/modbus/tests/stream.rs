//! The Modbus TCP stream is one byte stream (the Messaging Implementation Guide: TCP keeps no
//! message boundaries): however a client's requests are cut into reads — one byte at a time,
//! several ADUs in one read, an ADU across reads — the server gives the same answers, in
//! order, and leaves the registers the same as when each ADU comes whole.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use modbus::client;
use modbus::{handle_adu, Exception, Framer, RegisterMap, MAX_ADU_LEN};
use proptest::prelude::*;

/// 100 holding registers; anything else is an illegal address.
#[derive(Debug, Clone, PartialEq)]
struct Registers(Vec<u16>);

impl Registers {
    fn range(&self, address: u16, n: usize) -> Result<std::ops::Range<usize>, Exception> {
        let start = usize::from(address);
        let end = start + n;
        if end > self.0.len() {
            return Err(Exception::IllegalDataAddress);
        }
        Ok(start..end)
    }
}

impl RegisterMap for Registers {
    fn read(&mut self, address: u16, out: &mut [u16]) -> Result<(), Exception> {
        let r = self.range(address, out.len())?;
        out.copy_from_slice(&self.0[r]);
        Ok(())
    }

    fn write(&mut self, address: u16, values: &[u16]) -> Result<(), Exception> {
        let r = self.range(address, values.len())?;
        self.0[r].copy_from_slice(values);
        Ok(())
    }

    fn exception_status(&mut self) -> Result<u8, Exception> {
        Ok(self.0[0] as u8)
    }
}

/// One request as a client builds it; addresses and quantities run past the 100 registers
/// now and then, so exception answers are part of the stream.
fn request() -> impl Strategy<Value = Vec<u8>> {
    let address = 0u16..110;
    let values = prop::collection::vec(any::<u16>(), 1..12);
    (
        any::<u16>(),
        prop_oneof![
            (address.clone(), 1u16..12).prop_map(|(a, q)| (3u8, a, q, Vec::new(), 0u16)),
            (address.clone(), values.clone()).prop_map(|(a, v)| (16, a, 0, v, 0)),
            (address.clone(), 1u16..12, values, 0u16..110)
                .prop_map(|(a, q, v, w)| (23, a, q, v, w)),
            Just((7, 0, 0, Vec::new(), 0)),
        ],
    )
        .prop_map(|(tid, (fc, a, q, v, w))| {
            let mut buf = [0u8; MAX_ADU_LEN];
            let n = match fc {
                3 => client::read_holding_registers(&mut buf, tid, 1, a, q),
                16 => client::write_multiple_registers(&mut buf, tid, 1, a, &v),
                23 => client::read_write_multiple_registers(&mut buf, tid, 1, a, q, w, &v),
                _ => client::read_exception_status(&mut buf, tid, 1),
            }
            .expect("a request the client can build");
            buf[..n].to_vec()
        })
}

/// Answers every ADU of `reads` fed through a framer, in order.
fn serve(reads: &[&[u8]], map: &mut Registers) -> Vec<Vec<u8>> {
    let mut framer = Framer::new();
    let mut answers = Vec::new();
    let mut out = [0u8; MAX_ADU_LEN];
    for mut bytes in reads.iter().copied() {
        while !bytes.is_empty() {
            let taken = framer.push(bytes);
            bytes = &bytes[taken..];
            while let Ok(Some(adu)) = framer.next_adu() {
                let n = handle_adu(adu, map, &mut out).expect("a valid ADU is answered");
                answers.push(out[..n].to_vec());
            }
        }
    }
    answers
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn any_cut_of_the_stream_gives_the_same_answers(
        requests in prop::collection::vec(request(), 1..20),
        cuts in prop::collection::vec(1usize..40, 0..60),
    ) {
        // Each ADU whole.
        let mut whole = Registers((0..100).collect());
        let one_by_one: Vec<&[u8]> = requests.iter().map(Vec::as_slice).collect();
        let expected = serve(&one_by_one, &mut whole);
        prop_assert_eq!(expected.len(), requests.len(), "one answer per request");
        // The same bytes cut at arbitrary places (and the rest in one read).
        let stream: Vec<u8> = requests.concat();
        let mut reads = Vec::new();
        let mut rest = stream.as_slice();
        for n in cuts {
            if rest.is_empty() {
                break;
            }
            let (head, tail) = rest.split_at(n.min(rest.len()));
            reads.push(head);
            rest = tail;
        }
        reads.push(rest);
        let mut cut = Registers((0..100).collect());
        prop_assert_eq!(serve(&reads, &mut cut), expected);
        prop_assert_eq!(cut, whole);
    }
}
