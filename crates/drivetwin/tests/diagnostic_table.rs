//! Every message of each manual's diagnostic table raised once by its number, checked over the
//! bus on the virtual clock (issue 16 point 3): the EMCY frame (code, error register), 1003h:01
//! read back by an SDO upload, the display, the reaction (statusword after it), and the
//! acknowledgement once the message is cleared. Table-driven: the expected values come from
//! the row (`devices/*.toml`), the test only knows the manual's rules for the columns.
//!
//! Vectors: CMMP-EMCY-02/03/04 (EMCY bytes and register of 31-0, 03-0, 11-3), CMMP-EMCY-06
//! (1003h:01 newest entry), CMMP-EMCY-01 (the reset EMCY 0000h), CMMP-DIAG-01/02 (display
//! "-E010-", "-170-").

use canopen::CanFrame;
use drive::messages::{self, Number};
use od::Reaction;

#[path = "support/can_bench.rs"]
mod can_bench;

use can_bench::CanBench as Bench;

fn emcy(frames: &[CanFrame]) -> Vec<[u8; 8]> {
    frames
        .iter()
        .filter(|f| f.id == 0x081)
        .map(|f| f.data)
        .collect()
}

/// What App. B and §5.18 say a message does with the factory 2100h settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Expect {
    /// EMCY, then FAULT (output stage off at once or after the quick-stop ramp).
    Fault,
    /// 200Fh, statusword bit 7 and the display's "-mms-", no EMCY, the drive keeps running.
    Warning,
    /// A diagnostic-memory entry only.
    LogOnly,
    /// 2100h "no action" (17-x while 6510h:22 is 0, cmmp-as-2 §5.7).
    Nothing,
}

fn cmmp_expect(m: &messages::Message) -> Expect {
    match m.reaction {
        Reaction::Ignore => Expect::LogOnly,
        Reaction::Warning => Expect::Warning,
        _ if m.number.main == 17 => Expect::Nothing,
        _ => Expect::Fault,
    }
}

/// CMMP-AS App. B.3, every row: raise by number, see it on the bus, clear, acknowledge.
#[test]
fn cmmp_as_every_app_b_message_over_the_bus() {
    let rows: Vec<messages::Message> = messages::messages().collect();
    assert_eq!(
        rows.len(),
        messages::table().len(),
        "every number is main-sub"
    );
    assert!(rows.len() >= 230, "App. B.3 complete: {}", rows.len());
    let mut b = Bench::new(None);
    for m in &rows {
        let number = m.row.number;
        let expect = cmmp_expect(m);
        b.enable();
        b.sent();
        let memory_before = b.drive().diagnostic_memory().count();
        b.drive()
            .raise_diagnostic(number)
            .expect("a row of the table");
        b.run_ms(2);
        let frames = emcy(&b.sent());
        let text = b.drive().display().text().as_str().to_string();
        match expect {
            Expect::Fault => {
                let [c0, c1] = m.code.to_le_bytes();
                let reg = m.row.register | canopen::emcy::register::GENERIC;
                assert_eq!(frames, vec![[c0, c1, reg, 0, 0, 0, 0, 0]], "{number} EMCY");
                assert_eq!(
                    b.read(0x1003, 1) as u32,
                    u32::from(m.code),
                    "{number} 1003h:01"
                );
                assert_eq!(b.read(0x1001, 0) as u8, reg, "{number} 1001h");
                assert_eq!(
                    text,
                    format!("-E{:02}{}-", m.number.main, m.number.sub),
                    "{number} display"
                );
                b.run_ms(400);
                assert_eq!(b.statusword() & 0x4F, 0x08, "{number} FAULT");
                // The cause stays: the fault reset does not acknowledge it.
                b.write(0x6040, 0, &[0x00, 0]);
                b.run_ms(2);
                b.write(0x6040, 0, &[0x80, 0]);
                b.run_ms(2);
                assert_eq!(b.statusword() & 0x4F, 0x08, "{number} still FAULT");
                b.drive().clear_diagnostic(number).expect("raised");
                b.write(0x6040, 0, &[0x00, 0]);
                b.run_ms(2);
                b.sent();
                b.write(0x6040, 0, &[0x80, 0]);
                b.run_ms(2);
                // (an SDO clears the frames collected: the EMCY first)
                assert_eq!(emcy(&b.sent()), vec![[0; 8]], "{number} reset EMCY");
                assert_eq!(b.statusword() & 0x4F, 0x40, "{number} acknowledged");
            }
            Expect::Warning => {
                assert!(frames.is_empty(), "{number}: no EMCY for a warning");
                assert_eq!(text, format!("-{:02}{}-", m.number.main, m.number.sub));
                let w = b.read(0x200F, 0) as u16;
                assert_eq!(
                    messages::decode_warning_code(w),
                    (
                        Number {
                            main: m.number.main,
                            sub: m.number.sub & 0x0F
                        },
                        true
                    ),
                    "{number} 200Fh"
                );
                assert_ne!(b.statusword() & 0x80, 0, "{number} statusword bit 7");
                assert_eq!(b.statusword() & 0x6F, 0x27, "{number} keeps running");
                b.drive().clear_diagnostic(number).expect("raised");
                b.run_ms(2);
                assert_eq!(b.statusword() & 0x80, 0, "{number} warning over");
            }
            Expect::LogOnly | Expect::Nothing => {
                assert!(frames.is_empty(), "{number}: no EMCY");
                assert_eq!(b.statusword() & 0x6F, 0x27, "{number} keeps running");
                let logged = b.drive().diagnostic_memory().count() > memory_before
                    || b.drive().diagnostic_memory().count() == 16;
                assert_eq!(
                    b.drive()
                        .diagnostic_memory()
                        .last()
                        .is_some_and(|e| e.number == m.number)
                        && logged,
                    expect == Expect::LogOnly,
                    "{number} memory entry"
                );
                b.drive().clear_diagnostic(number).expect("raised");
            }
        }
        assert!(
            b.drive().raised_diagnostics().next().is_none(),
            "{number} cleared"
        );
    }
}
