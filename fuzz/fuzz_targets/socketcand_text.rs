//! Bytes from a socketcand client, in any pieces, into the server's decoder: no panic, the
//! buffer stays bounded, and every message it accepts formats to text that decodes to a
//! message of the same text.
#![no_main]

use drivetwin::can::socketcand::codec::Decoder;
use libfuzzer_sys::fuzz_target;

const MAX_LEN: usize = 256;

/// The input: one byte, the size of the pieces the text arrives in (0 counts as 1), then
/// the text.
fn run(data: &[u8]) {
    let Some((cut, text)) = data.split_first() else {
        return;
    };
    let mut d = Decoder::with_max_len(MAX_LEN);
    for piece in text.chunks(usize::from(*cut).max(1)) {
        d.push(piece);
        while let Some(r) = d.next_message() {
            if let Ok(m) = r {
                let text = m.to_string();
                let mut again = Decoder::new();
                again.push(text.as_bytes());
                // Free text (an `< error ... >` body) is sanitised when formatted, so the
                // formatted text, not the message, is what must come back unchanged.
                match again.next_message() {
                    Some(Ok(m2)) => assert_eq!(m2.to_string(), text),
                    other => panic!("{text:?} decodes to {other:?}"),
                }
            }
        }
        assert!(
            d.pending() <= MAX_LEN + 1,
            "decoder holds {} bytes",
            d.pending()
        );
    }
}

fuzz_target!(|data: &[u8]| run(data));
