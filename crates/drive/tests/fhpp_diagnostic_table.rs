//! CMMO-ST App. D, every message raised once by its number ("2Fh") with the factory error
//! management (PNU 242 / 246 defaults, `devices/cmmo-st.toml` decision D8), seen in the FHPP
//! telegram and the parameters (FHPP-DIAG-03, FHPP-FPC-13, FHPP-MB-05):
//! an error sets SCON.FAULT, PNU 205 and the 7-segment display, goes to the diagnostic memory
//! (PNU 200), and CCON.RESET acknowledges it as its "Ack" column says once it is cleared; a
//! warning sets SCON.WARN and PNU 221 until cleared; an information or event only logs.

mod fhpp_bench;
use drive::stepper::StepperMode;
use drive::vendors::festo_cmmo_st::diagnostics::{self, Class, Diagnostic};
use drive::vendors::festo_cmmo_st::fhpp::{Ack, Ccon, Cpos, InputData, OutputData, Scon};
use drive::vendors::festo_cmmo_st::seven_segment::SevenSegment;
use fhpp_bench::{Bench, ENABLED};
use od::ObjectAccess;

fn pnu(n: u16) -> u16 {
    0x2000 + n
}

/// CCON.RESET rising edge with ENABLE off, then RESET away again.
fn reset(b: &mut Bench) -> InputData {
    b.send(OutputData::record(Ccon(0), Cpos::HALT, 0));
    b.send(OutputData::record(Ccon::RESET, Cpos::HALT, 0));
    b.send(OutputData::record(Ccon(0), Cpos::HALT, 0))
}

#[test]
fn every_app_d_message_raised_by_number() {
    let rows = diagnostics::table();
    assert_eq!(rows.len(), 57, "App. D lists 57 numbers");
    for row in rows {
        let number = row.number;
        let d = Diagnostic::of(row).expect("an App. D row");
        let code = d.code;
        let mut b = Bench::with_mode(StepperMode::ClosedLoop);
        b.enable_record();
        b.home_here();
        let logged_before = b.dev.read_u8(pnu(204), 4).unwrap_or(0);
        let class = b.dev.raise_diagnostic(number).expect("a row");
        assert_eq!(
            class,
            d.class(d.default_handling(), d.default_reaction()),
            "{number} class"
        );
        let i = b.send(OutputData::record(ENABLED, Cpos::HALT, 0));
        b.run(300);
        let i2 = b.input();
        let logged = b.dev.read_u8(pnu(204), 4).unwrap_or(0) > logged_before
            || b.dev.read_u16(pnu(201), 1) == Some(u16::from(code));
        match class {
            Class::Fault(_) => {
                assert!(i2.scon.contains(Scon::FAULT), "{number} SCON.FAULT: {i:?}");
                assert_eq!(
                    b.dev.read_u16(pnu(205), 1),
                    Some(u16::from(code)),
                    "{number} PNU 205"
                );
                assert_eq!(b.dev.fault_number(), code, "{number} FC 07h");
                assert_eq!(b.dev.seven_segment(), SevenSegment::Error(code), "{number}");
                // PNU 200 event 01h "incoming", PNU 201 the number.
                assert_eq!(
                    (b.dev.read_u8(pnu(200), 1), b.dev.read_u16(pnu(201), 1)),
                    (Some(1), Some(u16::from(code))),
                    "{number} memory"
                );
                assert!(b.dev.diagnostic_active(code));
                // App. D "Imm": RESET acknowledges with the cause still raised; the others
                // wait for it to be cleared ("Reset": not even then, a software reset).
                let i = reset(&mut b);
                assert_eq!(
                    i.scon.contains(Scon::FAULT),
                    d.ack != Ack::Immediately,
                    "{number} RESET with the cause present ({:?})",
                    d.ack
                );
                b.dev.clear_diagnostic(number).expect("raised");
                let i = reset(&mut b);
                assert_eq!(
                    i.scon.contains(Scon::FAULT),
                    d.ack == Ack::NotAckable,
                    "{number} RESET after the cause ({:?})",
                    d.ack
                );
            }
            Class::Warning => {
                assert!(i2.scon.contains(Scon::WARN), "{number} SCON.WARN");
                assert!(!i2.scon.contains(Scon::FAULT), "{number} no fault");
                assert_eq!(
                    b.dev.seven_segment(),
                    SevenSegment::Warning(code),
                    "{number}"
                );
                let word = b.dev.read_u32(pnu(221), code / 32 + 1).unwrap_or(0);
                assert_ne!(word & (1 << (code % 32)), 0, "{number} PNU 221");
                b.dev.clear_diagnostic(number).expect("raised");
                let i = b.send(OutputData::record(ENABLED, Cpos::HALT, 0));
                assert!(!i.scon.contains(Scon::WARN), "{number} warning over");
            }
            Class::Information | Class::Event => {
                assert!(!i2.scon.contains(Scon::FAULT) && !i2.scon.contains(Scon::WARN));
                assert!(logged, "{number} in the diagnostic memory");
                b.dev.clear_diagnostic(number).expect("raised");
            }
        }
    }
}
