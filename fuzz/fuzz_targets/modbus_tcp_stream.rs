//! A Modbus TCP byte stream cut into reads anywhere, into the framer and the server: no
//! panic, every answer is a whole ADU (MBAP length consistent), and the framer's buffer
//! stays bounded.
#![no_main]

use libfuzzer_sys::fuzz_target;
use modbus::{handle_adu, Exception, Framer, RegisterMap, MAX_ADU_LEN};

/// 100 holding registers; anything else is an illegal address.
struct Registers([u16; 100]);

impl Registers {
    fn range(address: u16, n: usize) -> core::result::Result<core::ops::Range<usize>, Exception> {
        let start = usize::from(address);
        let end = start + n;
        if end > 100 {
            return Err(Exception::IllegalDataAddress);
        }
        Ok(start..end)
    }
}

impl RegisterMap for Registers {
    fn read(&mut self, address: u16, out: &mut [u16]) -> core::result::Result<(), Exception> {
        let r = Self::range(address, out.len())?;
        out.copy_from_slice(&self.0[r]);
        Ok(())
    }

    fn write(&mut self, address: u16, values: &[u16]) -> core::result::Result<(), Exception> {
        let r = Self::range(address, values.len())?;
        self.0[r].copy_from_slice(values);
        Ok(())
    }

    fn exception_status(&mut self) -> core::result::Result<u8, Exception> {
        Ok(self.0[0] as u8)
    }
}

/// The input: one byte, the size of the reads the stream is cut into (0 counts as 1), then
/// the stream.
fn run(data: &[u8]) {
    let Some((cut, stream)) = data.split_first() else {
        return;
    };
    let mut map = Registers([0; 100]);
    let mut framer = Framer::default();
    let mut response = [0u8; MAX_ADU_LEN];
    for mut chunk in stream.chunks(usize::from(*cut).max(1)) {
        while !chunk.is_empty() {
            let taken = framer.push(chunk);
            chunk = &chunk[taken..];
            loop {
                let adu = match framer.next_adu() {
                    Ok(Some(adu)) => adu,
                    Ok(None) => break,
                    // A bad header closes the connection; the next client starts afresh.
                    Err(_) => {
                        framer.clear();
                        break;
                    }
                };
                if let Ok(len) = handle_adu(adu, &mut map, &mut response) {
                    assert!((8..=MAX_ADU_LEN).contains(&len), "answer of {len} bytes");
                    let mbap = usize::from(u16::from_be_bytes([response[4], response[5]]));
                    assert_eq!(mbap + 6, len, "MBAP length of the answer");
                }
            }
            assert!(
                framer.buffered() <= MAX_ADU_LEN,
                "the framer holds one ADU at most"
            );
            if taken == 0 {
                break;
            }
        }
    }
}

fuzz_target!(|data: &[u8]| run(data));
