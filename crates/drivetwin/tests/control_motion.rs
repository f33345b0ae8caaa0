//! The control handle's requests for the console's pages: samples of named objects read on
//! the loop with every plant sample, the CMMO-ST's FHPP telegram and Device Control, and the
//! console's motion sequences run on a real cell.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::time::Duration;

use drive::vendors::festo_cmmo_st::fhpp::Authority;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::control::ControlHandle;
use drivetwin::cell::station::Station;
use drivetwin::cell_loop::{CanBus, CellLoop, FrontEnds};
use drivetwin::modbus_tcp::cell_drive::ModbusDrive;
use drivetwin::modbus_tcp::server::ModbusConfig;
use drivetwin::vendors::festo_cmmo_st::fhpp_console::{fhpp, FhppRequest};
use drivetwin::vendors::festo_cmmo_st::fhpp_motion;
use drivetwin::vendors::festo_cmmo_st::modbus_server::FhppModbus;
use drivetwin::web::motion::{self, Handle};

fn cell() -> (ControlHandle, impl FnOnce()) {
    cell_of("cmmp-as")
}

fn cell_of(device: &str) -> (ControlHandle, impl FnOnce()) {
    let cmmp = devices::by_name(device).expect("device");
    let drive =
        Station::with_settings(cmmp, 1, None, vec![], Some(Default::default())).expect("drive");
    let cmmo = devices::by_name("cmmo-st").expect("cmmo-st");
    let od = od::ObjectDictionary::new(cmmo, 1, vec![0u8; cmmo.storage_size]).expect("od");
    let dev = drive::vendors::festo_cmmo_st::device::FhppDevice::new(od, Default::default());
    let mb = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let front = FrontEnds {
        buses: vec![CanBus::default()],
        modbus: vec![ModbusDrive::new(
            mb,
            Box::new(FhppModbus::new(dev, None)),
            ModbusConfig::default(),
        )],
        ..FrontEnds::default()
    };
    let cell_loop = CellLoop::new(CanCell::one_bus(vec![drive]), front).expect("loop");
    let handle = cell_loop.control_handle();
    let stop = cell_loop.stop_handle();
    let thread = std::thread::spawn(move || cell_loop.run().map(|_| ()));
    (handle, move || {
        stop.stop();
        let _ = thread.join();
    })
}

#[test]
fn named_objects_come_with_every_plant_sample() {
    let (handle, stop) = cell();
    handle
        .write(0, 0x607A, 0, &1234i32.to_le_bytes())
        .expect("write");
    let rx = handle
        .subscribe_objects(
            0,
            Duration::from_millis(2),
            &[(0x607A, 0), (0x6041, 0), (0x1008, 0)],
        )
        .expect("subscribe");
    let got: Vec<_> = (0..10)
        .map(|_| rx.recv_timeout(Duration::from_secs(2)).expect("sample"))
        .collect();
    for s in &got {
        assert_eq!(s.values[0].get(), Some(&1234i32.to_le_bytes()[..]));
        assert_eq!(
            s.values[1].get().map(<[u8]>::len),
            Some(2),
            "6041h, 2 bytes"
        );
        assert_eq!(
            s.values[2].get(),
            None,
            "1008h is longer than 8 bytes: left out"
        );
        assert_eq!(s.values[3].get(), None, "not named");
    }
    assert!(got.windows(2).all(|w| w[1].plant.at > w[0].plant.at));
    stop();
}

#[test]
fn cia402_jog_on_a_running_cell_turns_the_motor() {
    let (handle, stop) = cell();
    let io = Handle {
        handle: &handle,
        drive: 0,
    };
    assert!(matches!(
        motion::jog(&io, 300),
        Err(motion::MotionError::NotEnabled(_))
    ));
    let sw = motion::enable(&io).expect("enable");
    assert_eq!(sw & 0x6F, 0x27);
    motion::jog(&io, 300).expect("jog");
    std::thread::sleep(Duration::from_millis(300));
    let drivetwin::cell::control::Plant::Servo { velocity_rpm, .. } =
        handle.plant(0).expect("plant").plant
    else {
        panic!("a servo");
    };
    assert!(velocity_rpm > 100.0, "{velocity_rpm}");
    motion::disable(&io).expect("disable");
    stop();
}

#[test]
fn fhpp_device_control_gates_the_console_telegram() {
    let (handle, stop) = cell();
    let s = fhpp(&handle, 1, FhppRequest::DeviceControl(true)).expect("fhpp");
    assert_eq!(s.authority, Authority::WebServer);
    assert_eq!(s.refused, None);
    let io = Handle {
        handle: &handle,
        drive: 1,
    };
    assert_eq!(
        fhpp_motion::fhpp_enable(&io),
        Err(fhpp_motion::FhppMotionError::WebServerHasControl)
    );
    let s = fhpp(&handle, 1, FhppRequest::DeviceControl(false)).expect("fhpp");
    assert_eq!(s.authority, Authority::Fieldbus);
    let s = fhpp_motion::fhpp_enable(&io).expect("enable");
    assert_eq!(s.inputs[0] & 0x01, 0x01, "SCON.ENABLED");
    // CCON.LOCK = 1 (§5.3.2 Tab. 5.14): the web server cannot take device control.
    let mut out = s.outputs;
    out[0] |= 0x20;
    fhpp(&handle, 1, FhppRequest::SetOutputs(out)).expect("lock");
    std::thread::sleep(Duration::from_millis(20));
    let s = fhpp(&handle, 1, FhppRequest::DeviceControl(true)).expect("fhpp");
    assert_eq!((s.authority, s.refused), (Authority::Fieldbus, Some(0x0B)));
    // The CAN drive has no FHPP side.
    assert!(fhpp(&handle, 0, FhppRequest::Status).is_err());
    stop();
}

#[test]
fn the_same_sequences_drive_the_nanotec_and_kinco_drives() {
    for device in ["nanotec-pd4n", "nanotec-smci47s", "kinco-fd3", "kinco-cd3"] {
        let (handle, stop) = cell_of(device);
        let io = Handle {
            handle: &handle,
            drive: 0,
        };
        if device.starts_with("kinco") {
            // Kinco §6: at the factory the digital inputs own the controlword; the drive refuses
            // the console as it refuses any master, until 2010h:03 / :05 give it to the bus.
            assert_eq!(
                motion::enable(&io),
                Err(motion::MotionError::Refused {
                    index: 0x6040,
                    sub: 0,
                    error: drivetwin::cell::control::ControlError::Abort(
                        od::AbortCode::LOCAL_CONTROL
                    )
                }),
                "{device}"
            );
            // The drive says why: DIN1's Enable owns the controlword (L1287).
            let why = handle
                .refusal(0, drive::drive::refusal::Request::Enable)
                .expect("refusal");
            assert!(
                why.is_some_and(|w| w.to_string().starts_with("DIN1 has the function Enable")),
                "{device}: {why:?}"
            );
            handle.write(0, 0x2010, 3, &[0, 0]).expect("2010h:03");
            handle.write(0, 0x2010, 5, &[0, 0]).expect("2010h:05");
        }
        let sw = motion::enable(&io).unwrap_or_else(|e| panic!("{device}: {e}"));
        assert_eq!(sw & 0x6F, 0x27, "{device}");
        motion::jog(&io, 100).unwrap_or_else(|e| panic!("{device}: jog: {e}"));
        motion::move_to(&io, 1000, true).unwrap_or_else(|e| panic!("{device}: move: {e}"));
        motion::home(&io).unwrap_or_else(|e| panic!("{device}: home: {e}"));
        motion::disable(&io).unwrap_or_else(|e| panic!("{device}: disable: {e}"));
        stop();
    }
}
