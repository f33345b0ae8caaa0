//! The CMMO-ST's own supervision of its plant's physics (`drive::vendors::festo_cmmo_st::plant_supervision`):
//! App. D 33h, 15h and 16h from the output stage's temperature (PNU 1066 against PNU 1068),
//! 06h from the encoder.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod fhpp_bench;
use drive::encoder_fault::EncoderFault;
use drive::stepper::StepperMode;
use drive::thermal::ThermalData;
use drive::vendors::festo_cmmo_st::fhpp::{Ccon, Cpos, OutputData, Scon};
use drive::vendors::festo_cmmo_st::seven_segment::SevenSegment;
use fhpp_bench::Bench;
use od::ObjectAccess;

fn bench() -> Bench {
    let mut b = Bench::with_mode(StepperMode::ClosedLoop);
    b.dev.set_thermal_data(ThermalData {
        stage_time_constant_s: 1.0,
        ..ThermalData::default()
    });
    b
}

/// CCON.RESET rising edge (enable off), then away again.
fn reset(b: &mut Bench) {
    let ccon = Ccon(0x00);
    b.send(OutputData::record(ccon, Cpos::HALT, 0));
    b.send(OutputData::record(ccon | Ccon::RESET, Cpos::HALT, 0));
    b.send(OutputData::record(ccon, Cpos::HALT, 0));
}

fn stage(b: &Bench) -> i8 {
    b.dev.read_u8(0x2000 + 1066, 1).unwrap() as i8
}

/// A hot cabinet: 33h (SCON.WARN) within 5 K of PNU 1068:2, then 15h (SCON.FAULT); the
/// acknowledgement (CCON.RESET) is refused until the stage is back in range.
#[test]
fn a_hot_output_stage_warns_33h_then_faults_15h() {
    let mut b = bench();
    b.enable_record();
    assert_eq!(stage(&b), 25);
    b.dev.set_ambient_temperature(100.0);
    let mut warned = None;
    for ms in 0..5000 {
        b.run(1);
        let i = b.input();
        if warned.is_none() && i.scon.contains(Scon::WARN) {
            assert!(!i.scon.contains(Scon::FAULT), "{i:?}");
            assert!(b.dev.diagnostic_active(0x33));
            warned = Some(ms);
        }
        if i.scon.contains(Scon::FAULT) {
            assert!(warned.is_some(), "33h before 15h");
            break;
        }
    }
    assert_eq!(b.dev.fault_number(), 0x15);
    assert_eq!(b.dev.seven_segment(), SevenSegment::showing(Some(0x15), 0));
    assert!(stage(&b) >= 85, "PNU 1066 shows it");
    // Still hot: CCON.RESET does not acknowledge it.
    reset(&mut b);
    assert_eq!(b.dev.fault_number(), 0x15);
    b.dev.set_ambient_temperature(25.0);
    b.run(10_000);
    reset(&mut b);
    assert_eq!(b.dev.fault_number(), 0, "acknowledged once cooled");
    assert!(!b.input().scon.contains(Scon::WARN));
}

/// A freezing cabinet: 16h below PNU 1068:1.
#[test]
fn a_cold_output_stage_is_16h() {
    let mut b = bench();
    b.dev.set_ambient_temperature(-30.0);
    b.run(5000);
    assert_eq!(b.dev.fault_number(), 0x16);
}

/// A pulled encoder cable: 06h.
#[test]
fn a_pulled_encoder_cable_is_06h() {
    let mut b = bench();
    b.enable_record();
    b.dev.set_encoder_fault(EncoderFault::Disconnected);
    b.run(5);
    assert_eq!(b.dev.fault_number(), 0x06);
    assert!(b.input().scon.contains(Scon::FAULT));
}

/// The messages are the device file's (`[device.plant]`): `devices/cmmo-st.toml` with its
/// plant table edited, built as the program builds a file it reads at run time, raises what
/// the keys say: 16h for a hot stage where `stage_over` names it, nothing for a freezing one
/// without `stage_under`.
#[test]
fn the_supervision_raises_what_the_device_file_names() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../devices/cmmo-st.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let edited = text
        .replacen("stage_over = \"15h\"", "stage_over = \"16h\"", 1)
        .replacen("stage_under = \"16h\"\n", "", 1);
    let desc = devdesc::runtime::leak(&devdesc::parse(&edited, "cmmo-st.toml").unwrap());
    let bench = |ambient: f64| {
        let od = od::ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]).unwrap();
        let mut b = Bench {
            dev: drive::vendors::festo_cmmo_st::device::FhppDevice::new(od, Default::default()),
            t_ms: 0,
        };
        b.dev.set_thermal_data(ThermalData {
            stage_time_constant_s: 1.0,
            ..ThermalData::default()
        });
        b.run(1);
        b.dev.set_ambient_temperature(ambient);
        b.run(5000);
        b
    };
    let hot = bench(100.0);
    assert_eq!(hot.dev.fault_number(), 0x16, "stage_over = 16h");
    assert!(!hot.dev.diagnostic_active(0x15));
    let cold = bench(-30.0);
    assert_eq!(cold.dev.fault_number(), 0, "no stage_under");
    assert!(!cold.dev.diagnostic_active(0x16));
}
