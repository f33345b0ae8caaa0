//! SDO simulation over the CI terminal (CMMP-AS §3.2.3), answered from the CMMP-AS dictionary.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use drive::vendors::festo_cmmp_as::ci_terminal::{execute, CiTerminal, ANSWER_END};
use od::{ObjectDictionary, Value};
use proptest::prelude::*;

fn od() -> ObjectDictionary<Vec<u8>> {
    let d = &devices::CMMP_AS;
    ObjectDictionary::new(d, 1, vec![0; d.storage_size]).expect("storage sized")
}

fn ci(od: &mut ObjectDictionary<Vec<u8>>, line: &str) -> String {
    execute(line.as_bytes(), od).as_str().to_owned()
}

/// CMMP-CI-01: `?606100` with modes_of_operation_display = 1 → `=606100:01`.
#[test]
fn cmmp_ci_01_read_8_bit() {
    let mut od = od();
    od.set_value(0x6061, 0, Value::Signed(1)).unwrap();
    assert_eq!(ci(&mut od, "?606100"), "=606100:01");
}

/// CMMP-CI-02: `=604000:000F` writes the controlword and echoes the command.
#[test]
fn cmmp_ci_02_write_16_bit_echoes() {
    let mut od = od();
    assert_eq!(ci(&mut od, "=604000:000F"), "=604000:000F");
    assert_eq!(od.get_unsigned(0x6040, 0), Some(0x000F));
    // Read back in the 16-bit form; lower-case digits are accepted, the answer is upper case.
    assert_eq!(ci(&mut od, "?604000"), "=604000:000F");
    assert_eq!(ci(&mut od, "=604000:00ab"), "=604000:00AB");
}

/// CMMP-CI-03: `?609301` → `=609301:00000001` (position factor numerator, default 1).
#[test]
fn cmmp_ci_03_read_32_bit() {
    let mut od = od();
    assert_eq!(ci(&mut od, "?609301"), "=609301:00000001");
    // A 32-bit write, then the value most significant digit first.
    assert_eq!(ci(&mut od, "=609302:00000013"), "=609302:00000013");
    assert_eq!(ci(&mut od, "=609301:12345678"), "=609301:12345678");
    assert_eq!(od.get_unsigned(0x6093, 1), Some(0x1234_5678));
}

/// CMMP-CI-04: `=604100:0000` (write to the read-only statusword) → `!06010002`; the same
/// form for all three write sizes.
#[test]
fn cmmp_ci_04_write_error_is_the_abort_code() {
    let mut od = od();
    assert_eq!(ci(&mut od, "=604100:0000"), "!06010002");
    assert_eq!(ci(&mut od, "=604100:00"), "!06010002");
    assert_eq!(ci(&mut od, "=604100:00000000"), "!06010002");
    // Read errors the same way: no such object, no such sub-index.
    assert_eq!(ci(&mut od, "?5FFF00"), "!06020000");
    assert_eq!(ci(&mut od, "?180005"), "!06090011");
}

#[test]
fn wrong_size_and_bad_syntax_get_an_abort_code() {
    let mut od = od();
    // An 8-bit write to a 16-bit object: the SDO length abort, value unchanged.
    let r = ci(&mut od, "=604000:0F");
    assert!(r.starts_with("!0607001"), "{r}");
    assert_eq!(od.get_unsigned(0x6040, 0), Some(0));
    // A string has no CI form.
    assert_eq!(ci(&mut od, "?100800"), "!06010000");
    for bad in [
        "",
        "?",
        "?6061",
        "?60610",
        "?6061000",
        "?60G100",
        "=604000",
        "=604000:",
        "=604000:0",
        "=604000:000",
        "=604000 000F",
        "=604000:000F0",
        "604000:000F",
        "? 606100",
        "=604000;000F",
    ] {
        assert_eq!(ci(&mut od, bad), "!05040001", "{bad:?}");
    }
}

#[test]
fn terminal_cuts_lines_and_survives_garbage() {
    let mut od = od();
    od.set_value(0x6061, 0, Value::Signed(1)).unwrap();
    let mut t = CiTerminal::default();
    let mut replies = Vec::new();
    let input = b"\r\n?606100\r\n\n?609301\r=604000:000F\n".iter();
    for &b in input {
        if let Some(r) = t.on_byte(b, &mut od) {
            replies.push(r.as_str().to_owned());
        }
    }
    assert_eq!(replies, ["=606100:01", "=609301:00000001", "=604000:000F"]);
    // An overlong line is one error, and the next line works again.
    replies.clear();
    for &b in b"?60610000000000000000000000000000000\n?606100\n" {
        if let Some(r) = t.on_byte(b, &mut od) {
            replies.push(r.as_str().to_owned());
        }
    }
    assert_eq!(replies, ["!05040001", "=606100:01"]);
}

/// A request ends with CR, LF or CR LF: each gets exactly one answer (no answer to the empty
/// line between CR and LF), and an answer ends with CR alone, as the device's.
#[test]
fn each_request_ending_gets_one_answer_ended_with_cr() {
    let mut od = od();
    od.set_value(0x6061, 0, Value::Signed(1)).unwrap();
    let mut t = CiTerminal::default();
    for ending in [&b"\r"[..], b"\n", b"\r\n"] {
        let mut wire = Vec::new();
        for &b in b"?606100"
            .iter()
            .chain(ending)
            .chain(b"=604000:0006")
            .chain(ending)
        {
            if let Some(r) = t.on_byte(b, &mut od) {
                wire.extend_from_slice(r.as_bytes());
                wire.push(ANSWER_END);
            }
        }
        assert_eq!(wire, b"=606100:01\r=604000:0006\r", "ending {ending:?}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1024, ..ProptestConfig::default() })]

    /// Any byte stream (every byte value, lines of any length, often a command character
    /// first): no panic, and every answer is a read/write echo (`=`) or an error (`!`).
    #[test]
    fn any_byte_stream_gets_well_formed_answers(
        lines in prop::collection::vec(
            (prop_oneof![Just(b'?'), Just(b'='), any::<u8>()],
             prop::collection::vec(any::<u8>(), 0..24)),
            1..40,
        )
    ) {
        let mut od = od();
        let mut t = CiTerminal::default();
        for (first, rest) in &lines {
            for &b in std::iter::once(first).chain(rest).chain([&b'\n']) {
                if let Some(r) = t.on_byte(b, &mut od) {
                    prop_assert!(r.starts_with('=') || r.starts_with('!'), "{}", r);
                }
            }
        }
    }
}
