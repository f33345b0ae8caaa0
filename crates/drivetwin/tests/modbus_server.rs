//! The Modbus TCP server over real loopback sockets: raw-TCP clients, and pymodbus's client
//! (which nobody here wrote) when `python3 -c "import pymodbus"` works (`pip install
//! pymodbus`); that test is skipped, with a message, otherwise. Every test runs against both
//! transports: the tokio server (`modbus_server`) and the cycle thread's
//! (`modbus_cycle_server`).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::net::SocketAddr;
use std::process::Stdio;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use drivetwin::modbus_tcp::cycle_server;
use drivetwin::modbus_tcp::server::{serve, ModbusConfig};
use modbus::{
    CloseReason, ConformityLevel, ConnectionEvent, Exception, ReadDeviceIdCode, RegisterMap,
};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::process::Command;
use tokio::task::JoinHandle;
use tokio::time::{sleep, timeout, Instant};

/// The CMMO-ST image as the manual lays it out (§4.3.2): start address 0, 4 registers
/// (FHPP Standard) or 8 (FHPP + FPC); writes go to the outputs, reads come from the inputs.
/// A connection that times out raises 47h when Modbus holds control, else 48h (§4.3.4).
struct Cmmo {
    outputs: [u16; 8],
    inputs: [u16; 8],
    fault: u8,
    /// Modbus holds control authority (PNU 125 = 1).
    control: bool,
    events: Vec<ConnectionEvent>,
    diagnostics: Vec<u8>,
}

impl Cmmo {
    fn new() -> Cmmo {
        Cmmo {
            outputs: [0; 8],
            inputs: [0x1004, 0x0100, 0x0000, 0x2710, 0, 0, 0, 0],
            fault: 0,
            control: true,
            events: Vec::new(),
            diagnostics: Vec::new(),
        }
    }

    fn check(address: u16, quantity: usize) -> Result<usize, Exception> {
        if address != 0 {
            return Err(Exception::IllegalDataAddress);
        }
        match quantity {
            4 | 8 => Ok(quantity),
            _ => Err(Exception::IllegalDataValue),
        }
    }
}

impl RegisterMap for Cmmo {
    fn read(&mut self, address: u16, out: &mut [u16]) -> Result<(), Exception> {
        let n = Cmmo::check(address, out.len())?;
        out.copy_from_slice(&self.inputs[..n]);
        Ok(())
    }

    fn write(&mut self, address: u16, values: &[u16]) -> Result<(), Exception> {
        let n = Cmmo::check(address, values.len())?;
        self.outputs[..n].copy_from_slice(values);
        // a stand-in for the device: ENABLE + STOP → SCON 13h, SPOS 05h
        if values[0] >> 8 & 0x03 == 0x03 {
            self.inputs[0] = 0x1305;
        }
        Ok(())
    }

    fn exception_status(&mut self) -> Result<u8, Exception> {
        Ok(self.fault)
    }

    fn device_id(&self, object: u8) -> Option<&[u8]> {
        Some(match object {
            0x00 => b"Festo AG & Co. KG",
            0x01 => b"CMMO-ST-C5-1-LKP",
            0x02 => b"V1.5.2",
            0x03 => b"http://www.festo.com",
            0x04 => b"CMMO-ST-C5-1-LKP",
            0x06 => b"drivetwin",
            _ => return None,
        })
    }

    fn conformity_level(&self, requested: ReadDeviceIdCode) -> ConformityLevel {
        match requested {
            ReadDeviceIdCode::Basic => ConformityLevel::BASIC_STREAM,
            _ => ConformityLevel::REGULAR_STREAM,
        }
    }

    fn connection_event(&mut self, event: ConnectionEvent) {
        if event == ConnectionEvent::Closed(CloseReason::WatchdogExpired) {
            self.diagnostics
                .push(if self.control { 0x47 } else { 0x48 });
        }
        self.events.push(event);
    }
}

/// Which transport serves the map.
#[derive(Debug, Clone, Copy)]
enum Io {
    Async,
    CycleThread,
}

/// Runs each named test (an `async fn(Io)`) once per transport.
macro_rules! on_both_transports {
    ($($name:ident),* $(,)?) => {
        mod async_io {
            $(#[tokio::test]
            async fn $name() {
                super::$name(super::Io::Async).await
            })*
        }
        mod cycle_thread {
            $(#[tokio::test]
            async fn $name() {
                super::$name(super::Io::CycleThread).await
            })*
        }
    };
}

on_both_transports!(
    a_client_that_does_not_read_is_dropped,
    reads_writes_identification_and_exceptions,
    a_second_client_is_refused_while_one_is_connected,
    watchdog_fires_and_closes_the_connection,
    watchdog_off_keeps_an_idle_connection,
    bad_clients_do_not_disturb_the_server,
    pymodbus_client_against_the_server
);

/// A running server, stopped when dropped.
struct Server {
    addr: SocketAddr,
    map: Arc<Mutex<Cmmo>>,
    task: Option<JoinHandle<()>>,
    thread: Option<(Arc<AtomicBool>, std::thread::JoinHandle<()>)>,
    /// Device cycles the cycle thread has run (0 with the async server, which has none).
    steps: Arc<AtomicU64>,
}

impl Drop for Server {
    fn drop(&mut self) {
        if let Some(task) = &self.task {
            task.abort();
        }
        if let Some((stop, thread)) = self.thread.take() {
            stop.store(true, Ordering::Relaxed);
            let _ = thread.join();
        }
    }
}

async fn start(io: Io, config: ModbusConfig) -> Server {
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let addr = listener.local_addr().expect("addr");
    let map = Arc::new(Mutex::new(Cmmo::new()));
    let steps = Arc::new(AtomicU64::new(0));
    match io {
        Io::Async => {
            let task = tokio::spawn(serve(listener, Arc::clone(&map), config));
            Server {
                addr,
                map,
                task: Some(task),
                thread: None,
                steps,
            }
        }
        Io::CycleThread => {
            let listener = listener.into_std().expect("std listener");
            let stop = Arc::new(AtomicBool::new(false));
            let (thread_map, thread_stop) = (Arc::clone(&map), Arc::clone(&stop));
            let thread_steps = Arc::clone(&steps);
            let thread = std::thread::spawn(move || {
                let period = Duration::from_millis(1);
                cycle_server::serve(listener, &thread_map, &config, period, &thread_stop, |_| {
                    thread_steps.fetch_add(1, Ordering::Relaxed);
                })
            });
            Server {
                addr,
                map,
                task: None,
                thread: Some((stop, thread)),
                steps,
            }
        }
    }
}

impl Server {
    fn events(&self) -> Vec<ConnectionEvent> {
        self.map.lock().expect("map").events.clone()
    }

    /// Waits until the map has seen `n` events.
    async fn wait_events(&self, n: usize) -> Vec<ConnectionEvent> {
        let deadline = Instant::now() + Duration::from_secs(3);
        loop {
            let events = self.events();
            if events.len() >= n || Instant::now() > deadline {
                return events;
            }
            sleep(Duration::from_millis(5)).await;
        }
    }
}

fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).expect("hex byte"))
        .collect()
}

async fn connect(addr: SocketAddr) -> TcpStream {
    TcpStream::connect(addr).await.expect("connect")
}

/// Reads one response ADU.
async fn read_adu(stream: &mut TcpStream) -> Vec<u8> {
    let mut head = [0u8; 6];
    timeout(Duration::from_secs(3), stream.read_exact(&mut head))
        .await
        .expect("response in time")
        .expect("response header");
    let len = usize::from(u16::from_be_bytes([head[4], head[5]]));
    let mut rest = vec![0u8; len];
    timeout(Duration::from_secs(3), stream.read_exact(&mut rest))
        .await
        .expect("response in time")
        .expect("response body");
    [head.to_vec(), rest].concat()
}

async fn transact(stream: &mut TcpStream, request: &str) -> Vec<u8> {
    stream.write_all(&hex(request)).await.expect("write");
    read_adu(stream).await
}

/// Whether the server closed the connection (end of file or reset) within `within`.
async fn closed_within(stream: &mut TcpStream, within: Duration) -> bool {
    let mut buf = [0u8; 64];
    match timeout(within, stream.read(&mut buf)).await {
        Ok(Ok(0)) | Ok(Err(_)) => true,
        Ok(Ok(n)) => panic!("unexpected {n} bytes: {:02X?}", &buf[..n]),
        Err(_) => false,
    }
}

/// Connects, retrying while the previous client's connection is being wound down.
async fn connect_served(addr: SocketAddr) -> TcpStream {
    let deadline = Instant::now() + Duration::from_secs(3);
    loop {
        let mut s = connect(addr).await;
        s.write_all(&hex("00 63 00 00 00 02 00 07"))
            .await
            .expect("write");
        let mut head = [0u8; 9];
        if let Ok(Ok(_)) = timeout(Duration::from_secs(1), s.read_exact(&mut head)).await {
            assert_eq!(head[7], 0x07);
            return s;
        }
        assert!(Instant::now() < deadline, "never served");
        sleep(Duration::from_millis(20)).await;
    }
}

async fn reads_writes_identification_and_exceptions(io: Io) {
    let server = start(io, ModbusConfig::default()).await;
    let mut c = connect(server.addr).await;

    // FHPP-MB-01: enable, record 1
    let r = transact(
        &mut c,
        "00 01 00 00 00 0F 00 10 00 00 00 04 08 03 01 01 00 00 00 00 00",
    )
    .await;
    assert_eq!(r, hex("00 01 00 00 00 06 00 10 00 00 00 04"));
    assert_eq!(
        server.map.lock().expect("map").outputs[..4],
        [0x0301, 0x0100, 0, 0]
    );
    // FHPP-MB-02: SCON 13h, SPOS 05h
    let r = transact(&mut c, "00 02 00 00 00 06 00 03 00 00 00 04").await;
    assert_eq!(r, hex("00 02 00 00 00 0B 00 03 08 13 05 01 00 00 00 27 10"));
    // FHPP-MB-03 layout: 0x17 writes, then reads
    let r = transact(
        &mut c,
        "00 03 00 00 00 13 00 17 00 00 00 04 00 00 00 04 08 43 03 00 64 00 00 27 10",
    )
    .await;
    assert_eq!(r, hex("00 03 00 00 00 0B 00 17 08 13 05 01 00 00 00 27 10"));
    assert_eq!(
        server.map.lock().expect("map").outputs[..4],
        [0x4303, 0x0064, 0, 0x2710]
    );
    // FHPP-MB-05: exception status
    assert_eq!(
        transact(&mut c, "00 05 00 00 00 02 00 07").await,
        hex("00 05 00 00 00 03 00 07 00")
    );
    server.map.lock().expect("map").fault = 0x2F;
    assert_eq!(
        transact(&mut c, "00 05 00 00 00 02 00 07").await,
        hex("00 05 00 00 00 03 00 07 2F")
    );
    // FHPP-MB-06: basic identification
    let r = transact(&mut c, "00 06 00 00 00 05 00 2B 0E 01 00").await;
    assert_eq!(
        r[..14],
        hex("00 06 00 00 00 35 00 2B 0E 01 01 00 00 03")[..]
    );
    assert_eq!(&r[14..33], b"\x00\x11Festo AG & Co. KG");
    // regular identification: 6 objects, conformity 02
    let r = transact(&mut c, "00 06 00 00 00 05 00 2B 0E 02 00").await;
    assert_eq!(r[7..14], hex("2B 0E 02 02 00 00 06")[..]);

    // FHPP-MB-07 and friends: exceptions, and the connection carries on
    for (req, resp) in [
        (
            "00 07 00 00 00 06 00 03 00 01 00 04",
            "00 07 00 00 00 03 00 83 02",
        ),
        (
            "00 07 00 00 00 06 00 03 00 00 00 05",
            "00 07 00 00 00 03 00 83 03",
        ),
        (
            "00 07 00 00 00 06 00 03 00 00 00 7E",
            "00 07 00 00 00 03 00 83 03",
        ),
        (
            "00 07 00 00 00 06 00 06 00 00 00 01",
            "00 07 00 00 00 03 00 86 01",
        ),
        ("00 07 00 00 00 02 00 41", "00 07 00 00 00 03 00 C1 01"),
        (
            "00 08 00 00 00 07 00 10 00 00 00 01 02",
            "00 08 00 00 00 03 00 90 03",
        ),
        (
            "00 08 00 00 00 0B 00 10 00 00 00 02 04 00 00 00 00",
            "00 08 00 00 00 03 00 90 03",
        ),
        (
            "00 09 00 00 00 0F 00 17 00 00 00 04 00 02 00 02 04 00 00 00 00",
            "00 09 00 00 00 03 00 97 02",
        ),
        (
            "00 0A 00 00 00 05 00 2B 0E 04 00",
            "00 0A 00 00 00 03 00 AB 03",
        ),
        (
            "00 0A 00 00 00 05 00 2B 0D 01 00",
            "00 0A 00 00 00 03 00 AB 01",
        ),
    ] {
        assert_eq!(transact(&mut c, req).await, hex(resp), "request {req}");
    }

    // pipelined: three requests in one segment, three responses in order
    let burst = [
        hex("00 21 00 00 00 02 00 07"),
        hex("00 22 00 00 00 06 00 03 00 00 00 04"),
        hex("00 23 00 00 00 06 00 03 00 05 00 04"),
    ]
    .concat();
    c.write_all(&burst).await.expect("write");
    assert_eq!(read_adu(&mut c).await[..2], [0x00, 0x21]);
    assert_eq!(read_adu(&mut c).await[..2], [0x00, 0x22]);
    assert_eq!(read_adu(&mut c).await, hex("00 23 00 00 00 03 00 83 02"));

    // one request in pieces, with pauses
    let req = hex("00 31 00 00 00 06 FF 03 00 00 00 04");
    for piece in [&req[..3], &req[3..7], &req[7..]] {
        c.write_all(piece).await.expect("write");
        sleep(Duration::from_millis(20)).await;
    }
    let r = read_adu(&mut c).await;
    assert_eq!(
        r[..9],
        hex("00 31 00 00 00 0B FF 03 08")[..],
        "unit id echoed"
    );

    drop(c);
    let events = server.wait_events(2).await;
    assert_eq!(
        events,
        [
            ConnectionEvent::Opened,
            ConnectionEvent::Closed(CloseReason::Peer)
        ]
    );
}

async fn a_second_client_is_refused_while_one_is_connected(io: Io) {
    let server = start(io, ModbusConfig::default()).await;
    let mut first = connect_served(server.addr).await;

    let mut second = connect(server.addr).await;
    // it may get to send, but never gets an answer: the server closes it at once
    let _ = second.write_all(&hex("00 01 00 00 00 02 00 07")).await;
    assert!(
        closed_within(&mut second, Duration::from_secs(2)).await,
        "second client closed"
    );

    // the first one is undisturbed
    assert_eq!(
        transact(&mut first, "00 02 00 00 00 02 00 07").await,
        hex("00 02 00 00 00 03 00 07 00")
    );

    // once it is gone, the next client is served
    drop(first);
    let mut third = connect_served(server.addr).await;
    assert_eq!(
        transact(&mut third, "00 03 00 00 00 02 00 07").await,
        hex("00 03 00 00 00 03 00 07 00")
    );
    let events = server.events();
    assert_eq!(
        events,
        [
            ConnectionEvent::Opened,
            ConnectionEvent::Closed(CloseReason::Peer),
            ConnectionEvent::Opened
        ],
        "the refused client never became the connection"
    );
}

async fn watchdog_fires_and_closes_the_connection(io: Io) {
    let server = start(io, ModbusConfig::with_watchdog_ms(100)).await;

    // requests every 40 ms keep the connection alive for well over the timeout
    let mut c = connect(server.addr).await;
    let t0 = Instant::now();
    for i in 0..10u8 {
        if i > 0 {
            sleep(Duration::from_millis(40)).await;
        }
        let req = format!("00 {i:02X} 00 00 00 02 00 07");
        assert_eq!(transact(&mut c, &req).await[..2], [0x00, i]);
    }
    assert!(t0.elapsed() >= Duration::from_millis(360));
    // then silence: closed after ~100 ms, with diagnostic 47h (Modbus held control)
    let silent = Instant::now();
    assert!(
        closed_within(&mut c, Duration::from_secs(2)).await,
        "closed by the watchdog"
    );
    let waited = silent.elapsed();
    assert!(
        waited >= Duration::from_millis(90),
        "not before the timeout: {waited:?}"
    );
    let events = server.wait_events(2).await;
    assert_eq!(
        events,
        [
            ConnectionEvent::Opened,
            ConnectionEvent::Closed(CloseReason::WatchdogExpired)
        ]
    );
    assert_eq!(server.map.lock().expect("map").diagnostics, [0x47]);

    // a client that connects and never sends is as silent: 48h without control authority
    server.map.lock().expect("map").control = false;
    let mut mute = connect(server.addr).await;
    assert!(closed_within(&mut mute, Duration::from_secs(2)).await);
    server.wait_events(4).await;
    assert_eq!(server.map.lock().expect("map").diagnostics, [0x47, 0x48]);

    // a client that stops half-way through an MBAP header is closed the same way
    let mut stuck = connect(server.addr).await;
    stuck.write_all(&hex("00 01 00")).await.expect("write");
    assert!(closed_within(&mut stuck, Duration::from_secs(2)).await);
    server.wait_events(6).await;
    assert_eq!(
        server.map.lock().expect("map").diagnostics,
        [0x47, 0x48, 0x48]
    );

    // and the server goes on serving
    let mut next = connect_served(server.addr).await;
    assert_eq!(
        transact(&mut next, "00 07 00 00 00 02 00 07").await[..2],
        [0x00, 0x07]
    );
}

async fn watchdog_off_keeps_an_idle_connection(io: Io) {
    let server = start(io, ModbusConfig::with_watchdog_ms(0)).await;
    let mut c = connect_served(server.addr).await;
    assert!(
        !closed_within(&mut c, Duration::from_millis(400)).await,
        "still open"
    );
    assert_eq!(
        transact(&mut c, "00 01 00 00 00 02 00 07").await,
        hex("00 01 00 00 00 03 00 07 00")
    );
}

async fn bad_clients_do_not_disturb_the_server(io: Io) {
    let server = start(io, ModbusConfig::with_watchdog_ms(500)).await;

    // not Modbus at all: dropped
    let mut http = connect(server.addr).await;
    http.write_all(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n")
        .await
        .expect("write");
    assert!(
        closed_within(&mut http, Duration::from_secs(2)).await,
        "HTTP client dropped"
    );

    // a length field no ADU can have (0 and FFFFh): dropped
    for req in [
        "00 01 00 00 00 00 00 03",
        "00 01 00 00 FF FF 00 03 00 00 00 04",
    ] {
        let mut c = connect_served(server.addr).await;
        c.write_all(&hex(req)).await.expect("write");
        assert!(
            closed_within(&mut c, Duration::from_secs(2)).await,
            "{req}: dropped"
        );
    }

    // protocol identifier ≠ 0: the ADUs before it are answered, then dropped
    let mut c = connect_served(server.addr).await;
    let burst = [
        hex("00 01 00 00 00 02 00 07"),
        hex("00 02 00 01 00 02 00 07"),
    ]
    .concat();
    c.write_all(&burst).await.expect("write");
    assert_eq!(read_adu(&mut c).await, hex("00 01 00 00 00 03 00 07 00"));
    assert!(
        closed_within(&mut c, Duration::from_secs(2)).await,
        "protocol 1: dropped"
    );

    // a length field too short for the request: the PDU it delimits is answered (03)
    let mut c = connect_served(server.addr).await;
    c.write_all(&hex("00 05 00 00 00 04 00 03 00 00"))
        .await
        .expect("write");
    assert_eq!(read_adu(&mut c).await, hex("00 05 00 00 00 03 00 83 03"));
    // a length field too long: the server waits for the rest; the next bytes complete it,
    // and it is answered as what it then is (0x03 with 6 data bytes: 03)
    c.write_all(&hex("00 06 00 00 00 08 00 03 00 00 00 04"))
        .await
        .expect("write");
    c.write_all(&hex("00 07")).await.expect("write");
    assert_eq!(read_adu(&mut c).await, hex("00 06 00 00 00 03 00 83 03"));
    drop(c);

    // truncated MBAP header, then the client goes away
    let mut c = connect_served(server.addr).await;
    c.write_all(&hex("00 01 00 00 00")).await.expect("write");
    drop(c);

    // random bytes with a plausible header, over and over
    let mut c = connect_served(server.addr).await;
    let mut x = 0x1234_5678u32;
    for i in 0..200u16 {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        let body: Vec<u8> = (0..(x % 12) as usize + 1)
            .map(|k| (x >> (k % 4 * 8)) as u8)
            .collect();
        let mut req = i.to_be_bytes().to_vec();
        req.extend_from_slice(&[0, 0]);
        req.extend_from_slice(&((body.len() + 1) as u16).to_be_bytes());
        req.push(0);
        req.extend_from_slice(&body);
        c.write_all(&req).await.expect("write");
        let r = read_adu(&mut c).await;
        assert_eq!(r[..2], i.to_be_bytes(), "every ADU answered, in order");
    }
    drop(c);

    // a well-behaved client is served as if nothing happened
    let mut good = connect_served(server.addr).await;
    let r = transact(&mut good, "00 02 00 00 00 06 00 03 00 00 00 04").await;
    assert_eq!(r[..9], hex("00 02 00 00 00 0B 00 03 08")[..]);
    let events = server.events();
    let protocol_errors = events
        .iter()
        .filter(|e| **e == ConnectionEvent::Closed(CloseReason::ProtocolError))
        .count();
    assert_eq!(protocol_errors, 4, "{events:?}");
}

// ---- pymodbus -----------------------------------------------------------------------------

const PYMODBUS_CLIENT: &str = r#"
import sys, time
from pymodbus.client import ModbusTcpClient
host, port = sys.argv[1], int(sys.argv[2])
c = ModbusTcpClient(host, port=port, timeout=3, retries=0)
assert c.connect(), "connect"
r = c.write_registers(0, [0x0301, 0x0100, 0, 0], device_id=0)
print("WRITE", r.isError())
r = c.read_holding_registers(0, count=4, device_id=0)
print("READ", " ".join("%04X" % v for v in r.registers))
r = c.readwrite_registers(read_address=0, read_count=4, write_address=0, values=[0x4303, 0x0064, 0, 0x2710], device_id=0)
print("RW", " ".join("%04X" % v for v in r.registers))
r = c.read_exception_status(device_id=0)
print("STATUS", r.status)
r = c.read_device_information(read_code=1, object_id=0, device_id=0)
print("DEVID", r.conformity, r.more_follows, " | ".join("%d=%s" % (k, v.decode()) for k, v in sorted(r.information.items())))
r = c.read_device_information(read_code=2, object_id=0, device_id=0)
print("DEVID2", r.conformity, " ".join(str(k) for k in sorted(r.information)))
r = c.read_holding_registers(1, count=4, device_id=0)
print("EXC_ADDR", r.isError(), r.exception_code)
r = c.read_holding_registers(0, count=5, device_id=0)
print("EXC_QTY", r.isError(), r.exception_code)
r = c.read_coils(0, count=1, device_id=0)
print("EXC_FC", r.isError(), r.exception_code)
time.sleep(0.6)
try:
    r = c.read_holding_registers(0, count=4, device_id=0)
    print("AFTER_WATCHDOG", "error" if r.isError() else "answered")
except Exception as e:
    print("AFTER_WATCHDOG", "closed", type(e).__name__)
c.close()
"#;

/// A client that sends requests but never reads the answers fills the server's socket; the
/// server drops it after the write timeout (bounded memory), the device's cycle goes on
/// meanwhile, and the next client is served.
async fn a_client_that_does_not_read_is_dropped(io: Io) {
    let config = ModbusConfig {
        write_timeout: Duration::from_millis(300),
        ..ModbusConfig::default()
    };
    let server = start(io, config).await;
    let socket = tokio::net::TcpSocket::new_v4().expect("socket");
    socket
        .set_recv_buffer_size(4096)
        .expect("small receive buffer");
    let mut c = socket.connect(server.addr).await.expect("connect");
    // Device identification, regular: 11 bytes asked, about 100 answered.
    let request = hex("00 01 00 00 00 05 00 2B 0E 02 00").repeat(64);
    let mut stalled = false;
    for _ in 0..20_000 {
        match timeout(Duration::from_millis(500), c.write_all(&request)).await {
            Ok(Ok(())) => {}
            // the server no longer reads: its answers are stuck
            Err(_) => {
                stalled = true;
                break;
            }
            // or it has dropped us already
            Ok(Err(_)) => {
                stalled = true;
                break;
            }
        }
    }
    assert!(
        stalled,
        "a server that answers into a full socket must stop reading"
    );
    let steps_before = server.steps.load(Ordering::Relaxed);
    let events = server.wait_events(2).await;
    assert_eq!(
        events,
        [
            ConnectionEvent::Opened,
            ConnectionEvent::Closed(CloseReason::Transport)
        ]
    );
    if matches!(io, Io::CycleThread) {
        sleep(Duration::from_millis(50)).await;
        assert!(
            server.steps.load(Ordering::Relaxed) > steps_before + 10,
            "the device steps while a client stalls"
        );
    }
    drop(c);
    let mut next = connect_served(server.addr).await;
    let r = transact(&mut next, "00 02 00 00 00 06 00 03 00 00 00 04").await;
    assert_eq!(r[7], 0x03);
}

async fn pymodbus_available() -> bool {
    let check = Command::new("python3")
        .args(["-c", "import pymodbus.client"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .await;
    matches!(check, Ok(status) if status.success())
}

async fn pymodbus_client_against_the_server(io: Io) {
    if !pymodbus_available().await {
        println!("SKIPPED: python3 with pymodbus not available (pip install pymodbus)");
        return;
    }
    let server = start(io, ModbusConfig::with_watchdog_ms(300)).await;
    let output = timeout(
        Duration::from_secs(30),
        Command::new("python3")
            .arg("-c")
            .arg(PYMODBUS_CLIENT)
            .arg(server.addr.ip().to_string())
            .arg(server.addr.port().to_string())
            .output(),
    )
    .await
    .expect("pymodbus client in time")
    .expect("run python3");
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "client failed:\n{stdout}\n{stderr}"
    );
    println!("pymodbus client:\n{stdout}");
    let lines: Vec<&str> = stdout.lines().collect();
    let expected = [
        "WRITE False",
        "READ 1305 0100 0000 2710",
        "RW 1305 0100 0000 2710",
        "STATUS 0",
        "DEVID 1 0 0=Festo AG & Co. KG | 1=CMMO-ST-C5-1-LKP | 2=V1.5.2",
        "DEVID2 2 0 1 2 3 4 6",
        "EXC_ADDR True 2",
        "EXC_QTY True 3",
        "EXC_FC True 1",
    ];
    assert_eq!(
        lines[..expected.len()],
        expected,
        "stdout:\n{stdout}\nstderr:\n{stderr}"
    );
    assert!(
        lines[expected.len()].starts_with("AFTER_WATCHDOG")
            && !lines[expected.len()].contains("answered"),
        "the watchdog closed the silent client: {stdout}"
    );
    assert_eq!(
        server.map.lock().expect("map").outputs[..4],
        [0x4303, 0x0064, 0, 0x2710]
    );
    assert_eq!(server.map.lock().expect("map").diagnostics, [0x47]);
}
