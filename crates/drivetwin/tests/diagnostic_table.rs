//! Every message of each manual's diagnostic table raised once by its number, checked over the bus
//! on the virtual clock: the EMCY frame (code, error register), 1003h:01 read back by an SDO
//! upload, the display, the reaction (statusword after it), and the acknowledgement once the
//! message is cleared. Table-driven: the expected values come from the row (`devices/*.toml`), the
//! test only knows the manual's rules for the columns.
//!
//! Vectors: CMMP-EMCY-02, CMMP-EMCY-03, CMMP-EMCY-04 (EMCY bytes and register of 31-0, 03-0,
//! 11-3), CMMP-EMCY-06 (1003h:01 newest entry), CMMP-EMCY-01 (the reset EMCY 0000h),
//! CMMP-DIAG-01 and CMMP-DIAG-02 (display "-E010-", "-170-"); the Kinco's KINCO-DIAG vectors
//! at their rows.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use canopen::CanFrame;
use drive::vendors::festo_cmmp_as::messages::{self, Number};
use drivetwin::cell::diagnostics::Planned;
use drivetwin::cell::stations::StationId;
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
    /// 2100h "no action" (17-x while 6510h:22 is 0, the CMMP-AS manual's extract, part 2 §5.7).
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
        let text = b
            .drive()
            .display()
            .expect("the CMMP-AS has its display")
            .text()
            .as_str()
            .to_string();
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
                if m.reaction == Reaction::PsOff {
                    // "PS off": output stage off at once, no fault reaction.
                    assert_eq!(b.statusword() & 0x4F, 0x08, "{number} FAULT at once");
                }
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

/// EMCY, 1003h:01 and 1001h of a message just raised, as §7 of the Nanotec and Kinco manuals
/// and CiA 301 say: code in bytes 0–1, the register with bit 0.
/// `history`: the device has 1003h (the Kinco keeps its last 8 errors itself, §7).
fn assert_emcy(b: &mut Bench, frames: &[[u8; 8]], row: &od::Diagnostic, history: bool) -> u8 {
    let number = row.number;
    let code = drive::drive::diagnostics::emcy_code(row);
    let [c0, c1] = code.to_le_bytes();
    let reg = row.register | canopen::emcy::register::GENERIC;
    assert_eq!(frames, &[[c0, c1, reg, 0, 0, 0, 0, 0]], "{number} EMCY");
    if history {
        assert_eq!(
            b.read(0x1003, 1) as u32 & 0xFFFF,
            u32::from(code),
            "{number} 1003h:01"
        );
    }
    assert_eq!(b.read(0x1001, 0) as u8, reg, "{number} 1001h");
    reg
}

/// Fault reset after the message was cleared: SWITCH ON DISABLED and the reset EMCY.
fn acknowledge(b: &mut Bench, number: &str) {
    b.drive().clear_diagnostic(number).expect("raised");
    b.write(0x6040, 0, &[0x00, 0]);
    b.run_ms(5);
    b.sent();
    b.write(0x6040, 0, &[0x80, 0]);
    b.run_ms(5);
    assert_eq!(emcy(&b.sent()), vec![[0; 8]], "{number} reset EMCY");
    assert_eq!(b.statusword() & 0x4F, 0x40, "{number} acknowledged");
}

/// Nanotec §7.1 (NT-PP-06 for 0800h), every code, with 2020h = 1 (legacy, the default) at standstill: "Power Off"
/// is FAULT at once, "–" the EMCY alone, the drive stays enabled (and the EMCY 0000h when the
/// cause is cleared).
#[test]
fn nanotec_every_section_7_1_code_over_the_bus() {
    use drive::vendors::nanotec::{Reaction as NtReaction, REACTIONS};
    for device in ["nanotec-smci47s", "nanotec-pd4n"] {
        let all = devices::by_name(device).expect("device").diagnostics;
        // The §7.1 rows: 2020h selects their reaction ("configurable").
        let rows: Vec<_> = all
            .iter()
            .filter(|r| r.reaction == Reaction::Configurable)
            .collect();
        assert_eq!(rows.len(), 12, "§7.1 lists 12 codes");
        let mut b = Bench::device(device, None);
        assert_eq!(b.read(0x2020, 0), 1, "legacy format by default");
        for row in rows {
            let number = row.number;
            let code = row.code.expect("§7.1 codes");
            let reaction = REACTIONS
                .iter()
                .find(|r| r.code == code)
                .map(|r| r.reaction(true, false))
                .expect("§7.1 row");
            b.enable();
            b.sent();
            b.drive().raise_diagnostic(number).expect("a row");
            b.run_ms(5);
            let frames = emcy(&b.sent());
            assert_emcy(&mut b, &frames, row, true);
            b.run_ms(200);
            match reaction {
                NtReaction::PowerOff | NtReaction::QuickStopPowerOff => {
                    assert_eq!(b.statusword() & 0x4F, 0x08, "{device} {number} FAULT");
                    acknowledge(&mut b, number);
                }
                NtReaction::MessageOnly | NtReaction::QuickStop => {
                    assert_eq!(
                        b.statusword() & 0x6F,
                        if reaction == NtReaction::QuickStop {
                            0x07
                        } else {
                            0x27
                        },
                        "{device} {number} keeps its state"
                    );
                    b.drive().clear_diagnostic(number).expect("raised");
                    b.run_ms(5);
                    assert_eq!(emcy(&b.sent()), vec![[0; 8]], "{number} EMCY 0000h");
                    // Back to a known state for the next row.
                    b.write(0x6040, 0, &[0x06, 0]);
                    b.run_ms(5);
                }
            }
        }
    }
}

/// Nanotec §7.2 (§17), every CiA code the firmware names (0000h, the reset EMCY, is no
/// row): raised by its name, the EMCY with its code and register (bit 4 for the
/// communication codes 81xxh / 82xxh), 1003h:01, and the reaction the row's decision gives:
/// "ps_off" FAULT at once, "quick_stop" the quick-stop ramp while moving, then FAULT,
/// "warning" the EMCY only (the drive keeps moving; EMCY 0000h when cleared).
#[test]
fn nanotec_every_section_7_2_code_over_the_bus() {
    for device in ["nanotec-smci47s", "nanotec-pd4n"] {
        let rows: Vec<_> = devices::by_name(device)
            .expect("device")
            .diagnostics
            .iter()
            .filter(|r| r.reaction != Reaction::Configurable)
            .collect();
        assert_eq!(rows.len(), 33, "§7.2 lists 34 codes, 0000h is the reset");
        let mut b = Bench::device(device, None);
        for row in rows {
            let number = row.number;
            let code = row.code.expect("§7.2 codes");
            assert_eq!(row.text, format!("CAN_EMERGENCY_ERROR_CODE_{number}"));
            let communication = (0x8100..0x8300).contains(&code);
            assert_eq!(row.register, if communication { 0x11 } else { 0x01 });
            b.enable();
            // Moving in VL, so a quick stop has a ramp to run.
            b.write(0x6060, 0, &[2]);
            b.write(0x6042, 0, &2000i16.to_le_bytes());
            b.run_ms(300);
            b.sent();
            b.drive().raise_diagnostic(number).expect("a row");
            b.run_ms(2);
            let frames = emcy(&b.sent());
            assert_emcy(&mut b, &frames, row, true);
            match row.reaction {
                Reaction::PsOff => {
                    assert_eq!(
                        b.statusword() & 0x4F,
                        0x08,
                        "{device} {number} FAULT at once"
                    );
                    acknowledge(&mut b, number);
                }
                Reaction::QuickStop => {
                    assert_eq!(
                        b.statusword() & 0x4F,
                        0x0F & 0x4F,
                        "{device} {number} fault reaction active (the ramp)"
                    );
                    b.run_ms(500);
                    assert_eq!(b.statusword() & 0x4F, 0x08, "{device} {number} FAULT");
                    acknowledge(&mut b, number);
                }
                _ => {
                    assert_eq!(
                        b.statusword() & 0x6F,
                        0x27,
                        "{device} {number} keeps running"
                    );
                    b.drive().clear_diagnostic(number).expect("raised");
                    b.run_ms(5);
                    assert_eq!(emcy(&b.sent()), vec![[0; 8]], "{number} EMCY 0000h");
                    b.write(0x6040, 0, &[0x06, 0]);
                    b.run_ms(5);
                }
            }
            b.write(0x6042, 0, &0i16.to_le_bytes());
        }
    }
}

/// Kinco §7 (FD3 over CANopen), every bit of Error_State and Error_State2 with an EMCY code: output stage off
/// (FAULT), the EMCY, 1003h, the bit in 2601h / 2602h (2601h bit 0 for Error_State2) and the
/// LED code of ch. 8, each KINCO-DIAG vector named at its row ([`kinco_diag_vector`]).
#[test]
fn kinco_every_section_7_error_over_the_bus() {
    use drive::vendors::kinco::{ErrorWord, KincoError};
    // The CD3 has no fieldbus port (serial only): the same table, reached over RS232.
    let fd3 = devices::by_name("kinco-fd3").expect("device").diagnostics;
    assert_eq!(
        devices::by_name("kinco-cd3").expect("device").diagnostics,
        fd3
    );
    for device in ["kinco-fd3"] {
        let rows = devices::by_name(device).expect("device").diagnostics;
        assert_eq!(rows.len(), 26, "15 Error_State + 11 Error_State2 bits");
        let mut b = Bench::device(device, None);
        // A bus master's set-up: no DIN owns the controlword (Kinco L1287).
        b.write(0x2010, 0x03, &[0, 0]);
        b.write(0x2010, 0x05, &[0, 0]);
        for row in rows {
            let number = row.number;
            let e = KincoError::of(row).expect("Error_State[2].bit");
            let mask = b.read(0x2605, if e.word == ErrorWord::State { 1 } else { 4 }) as u16;
            b.enable();
            b.sent();
            b.drive().raise_diagnostic(number).expect("a row");
            b.run_ms(5);
            let frames = emcy(&b.sent());
            if mask & (1 << e.bit) == 0 {
                assert!(frames.is_empty(), "{device} {number} masked");
                b.drive().clear_diagnostic(number).expect("raised");
                continue;
            }
            assert_emcy(&mut b, &frames, row, false);
            // Store_Mask_ON / ON2 (2605h:02 / :05): the error history keeps it.
            let store = b.read(0x2605, if e.word == ErrorWord::State { 2 } else { 5 }) as u16;
            assert_eq!(
                b.drive()
                    .as_kinco()
                    .expect("a Kinco")
                    .error_history()
                    .last()
                    == Some(e.emcy.unwrap_or(0)),
                store & (1 << e.bit) != 0,
                "{device} {number} error history"
            );
            let (state, state2) = (b.read(0x2601, 0) as u16, b.read(0x2602, 0) as u16);
            let led = b
                .drive()
                .as_kinco()
                .expect("a Kinco")
                .kinco_led()
                .expect("an error on the panel");
            let id = kinco_diag_vector(e.word, e.bit);
            match e.word {
                ErrorWord::State => {
                    assert_eq!(state, 1 << e.bit, "{device} {number} 2601h");
                    assert_eq!(&led, row.display.as_bytes(), "{id} {device} {number} LED");
                }
                ErrorWord::State2 => {
                    assert_eq!((state, state2), (1, 1 << e.bit), "{device} {number}");
                    assert_eq!(&led, b"000.1", "{id} {device} {number} LED: extended error");
                    assert_eq!(
                        drive::vendors::kinco::led_code(e.bit).as_slice(),
                        row.display.as_bytes(),
                        "{id} {device} {number} d1.16"
                    );
                }
            }
            assert_eq!(b.statusword() & 0x4F, 0x08, "{device} {number} FAULT");
            acknowledge(&mut b, number);
        }
    }
}

/// The vector of the vector catalogue kept beside the project, §4.7 an Error_State /
/// Error_State2 bit is the example of ("" for the bits without one).
fn kinco_diag_vector(word: drive::vendors::kinco::ErrorWord, bit: u8) -> &'static str {
    use drive::vendors::kinco::ErrorWord::{State, State2};
    match (word, bit) {
        (State, 0) => "KINCO-DIAG-01",
        (State, 5) => "KINCO-DIAG-02",
        (State, 9) => "KINCO-DIAG-03",
        (State, 15) => "KINCO-DIAG-04",
        (State2, 0 | 9) => "KINCO-DIAG-06",
        (State2, 15) => "KINCO-DIAG-07",
        _ => "",
    }
}

/// The cell's own way in (what scenarios and the cell file use): `CanCell::raise_diagnostic`,
/// and `[[drive.diagnostic]]` planned on the cell's clock: 43-0 at 50 ms, cleared at 80 ms.
#[test]
fn cell_raises_planned_messages_on_its_clock() {
    use drivetwin::cell::config::CellFile;
    let file: CellFile = toml::from_str(
        r#"
        [[drive]]
        device = "cmmp-as"
        node = 1
        [[drive.diagnostic]]
        at_ms = 50
        number = "43-0"
        [[drive.diagnostic]]
        at_ms = 80
        number = "43-0"
        action = "clear"
        "#,
    )
    .expect("a cell file");
    let spec = file
        .drives(drivetwin::vendors::VENDORS.runtime)
        .expect("valid")
        .remove(0);
    assert_eq!(spec.diagnostics.len(), 2);
    let mut b = Bench::new(None);
    let id = b.cell.buses[0].members()[0];
    for p in spec.diagnostics {
        let at = od::Instant::from_millis(p.at_ms);
        b.cell.plan(at, id, Planned::Diagnostic(p));
    }
    b.enable();
    b.sent();
    let now_ms = b.now.as_nanos() / 1_000_000;
    assert!(now_ms < 45, "enabled at {now_ms} ms");
    b.run_ms(48 - now_ms);
    assert!(emcy(&b.sent()).is_empty(), "nothing before 50 ms");
    b.run_ms(4);
    assert_eq!(
        emcy(&b.sent()),
        vec![[0x81, 0x80, 0x01, 0, 0, 0, 0, 0]],
        "43-0 8081h"
    );
    assert_eq!(
        b.cell
            .diagnostics(id)
            .expect("drive 0")
            .iter()
            .filter(|s| s.active)
            .count(),
        1
    );
    b.run_ms(40);
    assert!(
        b.drive().raised_diagnostics().next().is_none(),
        "cleared at 80 ms"
    );
    // And directly: an unknown number is refused, a known one raised.
    assert!(b.cell.raise_diagnostic(id, "99-9").is_err());
    assert!(
        b.cell
            .raise_diagnostic(StationId::from_index(b.cell.stations.len()), "43-0")
            .is_err(),
        "no such station"
    );
    assert_eq!(
        b.cell.raise_diagnostic(id, "08-2").map(|r| r.code),
        Ok(Some(0x7382))
    );
}

/// A cell file naming a message the device does not have is refused at load.
#[test]
fn cell_file_refuses_unknown_numbers() {
    use drivetwin::cell::config::CellFile;
    let file: CellFile = toml::from_str(
        "[[drive]]\ndevice = \"nanotec-pd4n\"\n[[drive.diagnostic]]\nat_ms = 1\nnumber = \"08-2\"\n",
    )
    .expect("parses");
    let e = file
        .drives(drivetwin::vendors::VENDORS.runtime)
        .expect_err("refused");
    assert!(e.to_string().contains("08-2"), "{e}");
}
