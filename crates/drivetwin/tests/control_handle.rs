//! The control handle of a running cell: the drives listed, objects written through it and
//! read over SDO (and the other way round), plant samples, inputs and load.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::time::Duration;

use drivetwin::can::socketcand::ServerConfig;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::control::{Interface, Plant};
use drivetwin::cell::station::Station;
use drivetwin::cell_loop::{CanBus, CellLoop, FrontEnds};
use drivetwin::modbus_tcp::cell_drive::ModbusDrive;
use drivetwin::modbus_tcp::server::ModbusConfig;
use drivetwin::vendors::festo_cmmo_st::modbus_server::FhppModbus;

/// A socketcand client in RAW mode; `sdo` sends a request to node 1 and returns its answer's
/// 8 data bytes.
struct Client(TcpStream);

impl Client {
    fn connect(addr: std::net::SocketAddr) -> Client {
        let mut s = TcpStream::connect(addr).expect("connect");
        s.set_read_timeout(Some(Duration::from_secs(5)))
            .expect("timeout");
        let mut buf = [0u8; 256];
        for (send, expect) in [
            (None, "< hi >"),
            (Some("< open vcan0 >"), "< ok >"),
            (Some("< rawmode >"), "< ok >"),
        ] {
            if let Some(m) = send {
                s.write_all(m.as_bytes()).expect("write");
            }
            let n = s.read(&mut buf).expect("reply");
            assert_eq!(String::from_utf8_lossy(&buf[..n]), expect);
        }
        std::thread::sleep(Duration::from_millis(50));
        Client(s)
    }

    fn sdo(&mut self, request: [u8; 8]) -> [u8; 8] {
        let hex: Vec<String> = request.iter().map(|b| format!("{b:02X}")).collect();
        let msg = format!("< send 601 8 {} >", hex.join(" "));
        self.0.write_all(msg.as_bytes()).expect("write");
        let mut text = String::new();
        let mut buf = [0u8; 1024];
        loop {
            let n = self.0.read(&mut buf).expect("answer");
            text.push_str(&String::from_utf8_lossy(&buf[..n]));
            // `< frame 581 SEC.USEC DATA >`
            if let Some(at) = text.find("< frame 581 ") {
                if let Some(end) = text[at..].find(" >") {
                    let fields: Vec<&str> = text[at..at + end].split_whitespace().collect();
                    let data = fields.last().expect("data");
                    let mut out = [0u8; 8];
                    for (i, b) in out.iter_mut().enumerate() {
                        *b = u8::from_str_radix(&data[2 * i..2 * i + 2], 16).expect("hex");
                    }
                    return out;
                }
            }
        }
    }
}

#[test]
fn one_dictionary_seen_through_the_handle_and_over_sdo() {
    let cmmp = devices::by_name("cmmp-as").expect("cmmp-as");
    let drive =
        Station::with_settings(cmmp, 1, None, vec![], Some(Default::default())).expect("drive");
    let cmmo = devices::by_name("cmmo-st").expect("cmmo-st");
    let od = od::ObjectDictionary::new(cmmo, 1, vec![0u8; cmmo.storage_size]).expect("od");
    let dev = drive::vendors::festo_cmmo_st::device::FhppDevice::new(od, Default::default());
    let can = TcpListener::bind("127.0.0.1:0").expect("bind");
    let can_addr = can.local_addr().expect("addr");
    let mb = TcpListener::bind("127.0.0.1:0").expect("bind");
    let front = FrontEnds {
        buses: vec![CanBus {
            socketcand: Some((can, ServerConfig::new("vcan0"))),
            ..CanBus::default()
        }],
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

    let drives = handle.drives().expect("drives");
    assert_eq!(drives.len(), 2);
    assert_eq!(drives[0].device, "cmmp-as");
    assert_eq!(drives[0].interface, Interface::CanOpen { node: 1 });
    assert_eq!(drives[1].device, "cmmo-st");
    assert_eq!(drives[1].interface, Interface::ModbusTcp);

    // Written through the handle, read over SDO: 607Ah target position.
    let mut client = Client::connect(can_addr);
    handle
        .write(0, 0x607A, 0, &4321i32.to_le_bytes())
        .expect("write");
    let answer = client.sdo([0x40, 0x7A, 0x60, 0, 0, 0, 0, 0]);
    assert_eq!(answer[0], 0x43, "{answer:02X?}");
    assert_eq!(
        i32::from_le_bytes([answer[4], answer[5], answer[6], answer[7]]),
        4321
    );
    // Written over SDO, read through the handle: 6060h modes of operation.
    let answer = client.sdo([0x2F, 0x60, 0x60, 0, 3, 0, 0, 0]);
    assert_eq!(answer[0], 0x60, "{answer:02X?}");
    assert_eq!(handle.read(0, 0x6060, 0).expect("read"), vec![3]);
    // A write the dictionary refuses is refused through the handle as well.
    assert!(handle.write(0, 0x1000, 0, &[0, 0, 0, 0]).is_err());

    // The plant: samples at the requested rate, inputs and load.
    let before = handle.plant(0).expect("plant");
    let Plant::Servo { digital_inputs, .. } = before.plant else {
        panic!("a servo: {before:?}");
    };
    handle.set_inputs(0, 0x0030, 0).expect("inputs");
    handle.set_load(0, 0.1).expect("load");
    let samples = handle
        .subscribe(0, Duration::from_millis(5))
        .expect("subscribe");
    let got: Vec<_> = (0..5)
        .map(|_| {
            samples
                .recv_timeout(Duration::from_secs(2))
                .expect("sample")
        })
        .collect();
    assert!(got.windows(2).all(|w| w[1].at > w[0].at), "{got:?}");
    let Plant::Servo {
        digital_inputs: forced,
        ..
    } = got[4].plant
    else {
        panic!("a servo");
    };
    assert_ne!(
        forced, digital_inputs,
        "DIN4 / DIN5 forced low shows in 60FDh"
    );
    let stepper = handle.plant(1).expect("CMMO-ST plant");
    assert!(
        matches!(stepper.plant, Plant::Stepper { .. }),
        "{stepper:?}"
    );

    stop.stop();
    thread.join().expect("joins").expect("runs");
    assert!(handle.drives().is_err(), "the cell has stopped");
}
