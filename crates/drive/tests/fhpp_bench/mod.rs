//! The CMMO-ST device on the virtual clock, shared by the FHPP test files: an output
//! telegram in, FHPP cycles of 1 ms run, the input telegram out. Each file adds its own
//! helpers in an `impl Bench` block of its own.
#![allow(dead_code)]
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use drive::stepper::StepperMode;
use drive::vendors::festo_cmmo_st::device::{FhppDevice, FhppSettings};
use drive::vendors::festo_cmmo_st::fhpp::{Ccon, Cpos, InputData, OutputData, Spos};
use od::{Instant, ObjectDictionary};

/// CCON ENABLE + STOP, record selection.
pub const ENABLED: Ccon = Ccon(0x03);

pub struct Bench {
    pub dev: FhppDevice<Vec<u8>>,
    pub t_ms: u64,
}

impl Bench {
    /// A CMMO-ST with the dictionary's defaults and `settings`, one cycle run.
    pub fn with_settings(settings: FhppSettings) -> Self {
        let desc = &devices::CMMO_ST;
        let od = ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]).unwrap();
        let mut b = Bench {
            dev: FhppDevice::new(od, settings),
            t_ms: 0,
        };
        b.run(1);
        b
    }

    /// A CMMO-ST with the stepper in `mode` and everything else at the defaults.
    pub fn with_mode(mode: StepperMode) -> Self {
        Bench::with_settings(FhppSettings {
            mode,
            ..FhppSettings::default()
        })
    }

    /// ENABLE + STOP in record selection.
    pub fn enable_record(&mut self) -> InputData {
        self.send(OutputData::record(ENABLED, Cpos::HALT, 0))
    }

    /// Homing with the configured method (−35 "current position" by default) through
    /// CPOS.HOM: ACK at the start, then MC with REF.
    pub fn home_here(&mut self) {
        let i = self.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::HOM, 0));
        assert!(i.spos.contains(Spos::ACK), "{i:?}");
        let i = self.until(100, |i| i.spos.contains(Spos::MC | Spos::REF));
        assert!(i.spos.contains(Spos::REF));
        self.send(OutputData::record(ENABLED, Cpos::HALT, 0));
    }

    /// `ms` FHPP cycles.
    pub fn run(&mut self, ms: u64) {
        for _ in 0..ms {
            self.dev.step(Instant::from_millis(self.t_ms));
            self.t_ms += 1;
        }
    }

    /// The output telegram, then two cycles; returns the input telegram.
    pub fn send(&mut self, out: OutputData) -> InputData {
        self.dev.set_outputs(&out.to_bytes()).unwrap();
        self.run(2);
        self.input()
    }

    /// START as a PLC pulses it (Tab. 5.5 start handshake): `out` with HALT, then with START
    /// rising, then START away again; returns the input telegram of the START cycle.
    pub fn start(&mut self, out: OutputData) -> InputData {
        let halt = OutputData {
            cpos: Cpos(out.cpos.0 & !Cpos::START.0) | Cpos::HALT,
            ..out
        };
        self.send(halt);
        let i = self.send(OutputData {
            cpos: halt.cpos | Cpos::START,
            ..out
        });
        self.send(halt);
        i
    }

    pub fn input(&self) -> InputData {
        InputData::from_bytes(self.dev.inputs())
    }

    /// Runs until `pred` holds (at most `max_ms`); returns the input telegram.
    pub fn until(&mut self, max_ms: u64, pred: impl Fn(&InputData) -> bool) -> InputData {
        for _ in 0..max_ms {
            let i = self.input();
            if pred(&i) {
                return i;
            }
            self.run(1);
        }
        panic!("condition not met in {max_ms} ms: {:?}", self.input());
    }
}
