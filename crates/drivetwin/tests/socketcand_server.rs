//! The socketcand server over real TCP on 127.0.0.1: handshake exactly as python-can checks
//! it, frame exchange between clients and bus ports, and robustness against bad clients.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::net::SocketAddr;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use canopen::CanFrame;
use drivetwin::can::bus::{Bus, BusFrame, Port};
use drivetwin::can::socketcand::{serve_with, Decoder, Message, ServerConfig};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

const STEP: Duration = Duration::from_secs(3);

async fn start_server(bus: &Bus) -> (SocketAddr, tokio::task::JoinHandle<()>) {
    start_server_with(bus, ServerConfig::new("vcan0")).await
}

async fn start_server_with(
    bus: &Bus,
    config: ServerConfig,
) -> (SocketAddr, tokio::task::JoinHandle<()>) {
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let addr = listener.local_addr().expect("addr");
    let task = tokio::spawn(serve_with(listener, bus.clone(), config));
    (addr, task)
}

struct Client {
    stream: TcpStream,
    decoder: Decoder,
}

impl Client {
    async fn connect(addr: SocketAddr) -> Client {
        let stream = TcpStream::connect(addr).await.expect("connect");
        stream.set_nodelay(true).expect("nodelay");
        Client {
            stream,
            decoder: Decoder::new(),
        }
    }

    async fn send(&mut self, text: &str) {
        self.stream.write_all(text.as_bytes()).await.expect("write");
    }

    /// One `recv(256)` must return exactly `expected`, as python-can's `_expect_msg` demands.
    async fn expect_exact(&mut self, expected: &str) {
        let mut buf = [0u8; 256];
        let n = tokio::time::timeout(STEP, self.stream.read(&mut buf))
            .await
            .expect("reply in time")
            .expect("read");
        let got = String::from_utf8_lossy(buf.get(..n).unwrap_or(&[])).into_owned();
        assert_eq!(got, expected);
    }

    async fn handshake(&mut self) {
        self.expect_exact("< hi >").await;
        self.send("< open vcan0 >").await;
        self.expect_exact("< ok >").await;
        self.send("< rawmode >").await;
        self.expect_exact("< ok >").await;
    }

    /// The next message within `wait`, or `None` on timeout.
    async fn next_within(&mut self, wait: Duration) -> Option<Message> {
        let deadline = tokio::time::Instant::now() + wait;
        loop {
            if let Some(result) = self.decoder.next_message() {
                return Some(result.expect("server sends well-formed messages"));
            }
            let mut buf = [0u8; 1024];
            let read = tokio::time::timeout_at(deadline, self.stream.read(&mut buf)).await;
            match read {
                Err(_elapsed) => return None,
                Ok(Ok(0)) => panic!("server closed the connection"),
                Ok(Ok(n)) => self.decoder.push(buf.get(..n).unwrap_or(&[])),
                Ok(Err(e)) => panic!("read error: {e}"),
            }
        }
    }

    async fn next(&mut self) -> Message {
        self.next_within(STEP).await.expect("a message in time")
    }

    async fn next_frame(&mut self) -> (CanFrame, Duration) {
        match self.next().await {
            Message::Frame { frame, timestamp } => (frame, timestamp),
            other => panic!("expected a frame, got {other:?}"),
        }
    }

    async fn expect_error(&mut self) -> String {
        match self.next().await {
            Message::Error(text) => text,
            other => panic!("expected an error, got {other:?}"),
        }
    }

    async fn expect_silence(&mut self, wait: Duration) {
        if let Some(m) = self.next_within(wait).await {
            panic!("expected nothing, got {m:?}");
        }
    }

    /// Raw text of whatever arrives next (for byte-exact format checks).
    async fn read_text(&mut self) -> String {
        let mut buf = [0u8; 1024];
        let n = tokio::time::timeout(STEP, self.stream.read(&mut buf))
            .await
            .expect("data in time")
            .expect("read");
        String::from_utf8_lossy(buf.get(..n).unwrap_or(&[])).into_owned()
    }

    /// True once the server has closed the connection (EOF) within `wait`.
    async fn closed_within(&mut self, wait: Duration) -> bool {
        let mut buf = [0u8; 256];
        let deadline = tokio::time::Instant::now() + wait;
        loop {
            match tokio::time::timeout_at(deadline, self.stream.read(&mut buf)).await {
                Err(_) => return false,
                Ok(Ok(0)) | Ok(Err(_)) => return true,
                Ok(Ok(_)) => continue,
            }
        }
    }
}

fn frame(id: u16, data: &[u8]) -> CanFrame {
    CanFrame::new(id, data).expect("frame")
}

fn now() -> Duration {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .expect("clock after 1970")
}

#[tokio::test]
async fn frame_from_one_client_reaches_the_other_not_the_sender() {
    let bus = Bus::new(256);
    let (addr, _server) = start_server(&bus).await;
    let mut a = Client::connect(addr).await;
    let mut b = Client::connect(addr).await;
    a.handshake().await;
    b.handshake().await;

    a.send("< send 123 3 11 22 33 >").await;
    let before = now();
    let (got, ts) = b.next_frame().await;
    assert_eq!(got, frame(0x123, &[0x11, 0x22, 0x33]));
    assert!(
        ts <= before + Duration::from_secs(1) && ts + Duration::from_secs(5) >= before,
        "timestamp {ts:?} is wall time ({before:?})"
    );
    // python-can style: lowercase unpadded bytes, DLC as hex digit.
    b.send("< send 7ff 2 a ff >").await;
    assert_eq!(a.next_frame().await.0, frame(0x7FF, &[0x0A, 0xFF]));
    // Neither sender hears itself.
    a.expect_silence(Duration::from_millis(200)).await;
    b.expect_silence(Duration::from_millis(50)).await;
}

#[tokio::test]
async fn bus_port_frames_reach_every_client_with_exact_format() {
    let bus = Bus::new(256);
    let (addr, _server) = start_server(&bus).await;
    let mut a = Client::connect(addr).await;
    let mut b = Client::connect(addr).await;
    a.handshake().await;
    b.handshake().await;
    let drive = bus.port();
    // Let the post-handshake pause pass so each frame arrives in its own segment.
    tokio::time::sleep(Duration::from_millis(200)).await;

    drive.send(frame(
        0x581,
        &[0x4B, 0x41, 0x60, 0x00, 0x37, 0x02, 0x00, 0x00],
    ));
    for client in [&mut a, &mut b] {
        let text = client.read_text().await;
        assert!(text.starts_with("< frame 581 "), "{text}");
        assert!(text.ends_with(" 4B41600037020000 >"), "{text}");
        let parts: Vec<&str> = text.split(' ').collect();
        let ts = parts.get(3).copied().unwrap_or_default();
        let (sec, usec) = ts.split_once('.').expect("SEC.USEC");
        assert!(sec.len() >= 10 && usec.len() == 6, "{text}");
    }

    // Zero-length data: two spaces before '>'.
    drive.send(frame(0x705, &[]));
    for client in [&mut a, &mut b] {
        let text = client.read_text().await;
        assert!(text.starts_with("< frame 705 "), "{text}");
        assert!(text.ends_with("  >"), "{text}");
    }

    // Extended: 8 hex digits.
    drive.send(CanFrame::with_id(0xABCDE, true, &[0xFF]).expect("frame"));
    for client in [&mut a, &mut b] {
        let text = client.read_text().await;
        assert!(text.starts_with("< frame 000ABCDE "), "{text}");
        assert!(text.ends_with(" FF >"), "{text}");
    }

    // Remote frames are not forwarded (socketcand does not either).
    drive.send(CanFrame::remote(0x705, 1));
    drive.send(frame(0x080, &[]));
    for client in [&mut a, &mut b] {
        assert_eq!(client.next_frame().await.0, frame(0x080, &[]));
    }
}

#[tokio::test]
async fn client_frames_reach_bus_ports_in_order() {
    let bus = Bus::new(256);
    let (addr, _server) = start_server(&bus).await;
    let mut drive = bus.port();
    let mut a = Client::connect(addr).await;
    a.handshake().await;

    let mut burst = String::new();
    for i in 0..50u8 {
        burst.push_str(&format!("< send 601 2 {i:x} 0 >"));
    }
    burst.push_str("< send 705 0  >"); // python-canopen's guarding request
    burst.push_str("< send 12345678 2 1 2 >");
    burst.push_str("< send 00000123 0 >");
    burst.push_str("< send 705 1 >"); // python-can's RTR with DLC 1
    a.send(&burst).await;

    for i in 0..50u8 {
        let got = recv(&mut drive).await;
        assert_eq!(got.frame, frame(0x601, &[i, 0]));
        assert_ne!(got.source, drive.id());
    }
    assert_eq!(recv(&mut drive).await.frame, frame(0x705, &[]));
    assert_eq!(
        recv(&mut drive).await.frame,
        CanFrame::with_id(0x1234_5678, true, &[1, 2]).expect("frame")
    );
    assert_eq!(
        recv(&mut drive).await.frame,
        CanFrame::with_id(0x123, true, &[]).expect("frame")
    );
    let rtr = recv(&mut drive).await.frame;
    assert!(rtr.rtr && rtr.id == 0x705 && rtr.len == 1 && !rtr.extended);
    assert_eq!(
        bus.stats().frames,
        54,
        "every accepted send is exactly one bus frame"
    );
}

async fn recv(port: &mut Port) -> BusFrame {
    tokio::time::timeout(STEP, port.recv())
        .await
        .expect("frame in time")
        .expect("frame")
}

#[tokio::test]
async fn garbage_from_one_client_does_not_disturb_another() {
    let bus = Bus::new(256);
    let (addr, _server) = start_server(&bus).await;
    let drive = bus.port();
    let mut good = Client::connect(addr).await;
    let mut bad = Client::connect(addr).await;
    good.handshake().await;
    bad.handshake().await;

    // Malformed messages: each gets an error reply, the session carries on.
    for junk in [
        "< send 800 0 >",                   // standard id out of range
        "< send 20000000 0 >",              // extended id out of range
        "< send 123456789 0 >",             // too many digits
        "< send xyz 1 00 >",                // not hex
        "< send 123 9 1 2 3 4 5 6 7 8 9 >", // DLC > 8
        "< send 123 2 1 >",                 // DLC mismatch
        "< send 123 1 100 >",               // byte too long
        "< send 123 >",                     // missing DLC
        "< frobnicate >",                   // unknown command
        "< >",                              // empty
    ] {
        bad.send(junk).await;
        let text = bad.expect_error().await;
        assert!(!text.is_empty(), "{junk}");
    }
    // Binary garbage outside brackets is dropped silently.
    bad.stream
        .write_all(&[0xFF, 0x00, 0x13, b'x', b'>', b'>', 0x80])
        .await
        .expect("write");
    // Non-ASCII inside brackets is an error.
    bad.stream
        .write_all(b"< send 123 1 \xff >")
        .await
        .expect("write");
    assert_eq!(bad.expect_error().await, "message is not printable ASCII");
    // An over-long message without '>' is dropped with an error.
    let long = format!("< send {}", "1 ".repeat(1500));
    bad.send(&long).await;
    assert_eq!(bad.expect_error().await, "message too long");
    bad.send(" 2 3 >").await; // the tail of the long message is garbage
                              // ... and the same client can still send valid frames.
    bad.send("< send 181 1 aa >").await;
    assert_eq!(good.next_frame().await.0, frame(0x181, &[0xAA]));
    bad.send("< echo >").await;
    assert_eq!(bad.next().await, Message::Echo);

    // The good client never saw any of it, and still works both ways.
    drive.send(frame(0x182, &[1]));
    assert_eq!(good.next_frame().await.0, frame(0x182, &[1]));
    assert_eq!(bad.next_frame().await.0, frame(0x182, &[1]));
    good.send("< send 183 0 >").await;
    assert_eq!(bad.next_frame().await.0, frame(0x183, &[]));
    good.expect_silence(Duration::from_millis(100)).await;
    assert_eq!(
        bus.stats().frames,
        3,
        "no malformed message reached the bus"
    );
}

#[tokio::test]
async fn wrong_channel_gets_error_and_close() {
    let bus = Bus::new(16);
    let (addr, _server) = start_server(&bus).await;
    let mut c = Client::connect(addr).await;
    c.expect_exact("< hi >").await;
    c.send("< open can0 >").await;
    c.expect_exact("< error could not open bus >").await;
    assert!(
        c.closed_within(STEP).await,
        "server closes after refusing the bus"
    );
    // The server still serves others.
    let mut d = Client::connect(addr).await;
    d.handshake().await;
}

#[tokio::test]
async fn handshake_replies_are_never_coalesced_with_traffic() {
    let bus = Bus::new(1024);
    let (addr, _server) = start_server(&bus).await;
    // Busy bus: a frame every millisecond.
    let flood = {
        let port = bus.port();
        tokio::spawn(async move {
            let mut i: u8 = 0;
            loop {
                port.send(frame(0x181, &[i]));
                i = i.wrapping_add(1);
                tokio::time::sleep(Duration::from_millis(1)).await;
            }
        })
    };
    for _ in 0..5 {
        let mut c = Client::connect(addr).await;
        // Each reply must be the whole of one read, as python-can's recv(256) checks.
        c.handshake().await;
        let (got, _) = c.next_frame().await;
        assert_eq!(got.id, 0x181);
        // Frames then arrive in bus order.
        let mut last = got.data[0];
        for _ in 0..20 {
            let (f, _) = c.next_frame().await;
            assert_eq!(f.data[0], last.wrapping_add(1));
            last = f.data[0];
        }
    }
    flood.abort();
}

#[tokio::test]
async fn abrupt_disconnects_and_half_open_clients_are_harmless() {
    let bus = Bus::new(256);
    let (addr, server) = start_server(&bus).await;
    let drive = bus.port();
    let mut survivor = Client::connect(addr).await;
    survivor.handshake().await;

    for i in 0..20 {
        let mut c = Client::connect(addr).await;
        match i % 4 {
            0 => {}                         // connect, say nothing, leave
            1 => c.send("< open vc").await, // leave mid-message
            2 => c.handshake().await,       // leave while streaming
            _ => {
                c.handshake().await;
                c.send("< send 123 8 1 2 3").await; // leave mid-frame
            }
        }
        drop(c);
    }
    for i in 0..10u8 {
        drive.send(frame(0x190, &[i]));
    }
    for i in 0..10u8 {
        assert_eq!(survivor.next_frame().await.0, frame(0x190, &[i]));
    }
    survivor.send("< send 191 0 >").await;
    let mut drive = drive;
    assert_eq!(recv(&mut drive).await.frame, frame(0x191, &[]));
    assert!(!server.is_finished());
}

#[tokio::test]
async fn modes_bcm_control_and_config_commands() {
    let bus = Bus::new(64);
    let (addr, _server) = start_server(&bus).await;
    let mut c = Client::connect(addr).await;
    c.expect_exact("< hi >").await;
    c.send("< vcan0 B 1000000 875 0 0 0 0 1 0 >").await;
    c.expect_exact("< ok >").await;
    c.send("< vcan0 C 0 0 0 >").await;
    c.expect_exact("< ok >").await;
    c.send("< open vcan0 >").await;
    c.expect_exact("< ok >").await;
    // BCM (default): no streaming.
    let drive = bus.port();
    drive.send(frame(0x181, &[1]));
    c.expect_silence(Duration::from_millis(150)).await;
    c.send("< bcmmode >").await;
    c.expect_exact("< ok >").await;
    c.send("< controlmode >").await;
    c.expect_exact("< ok >").await;
    c.send("< statistics 20 >").await;
    match c.next().await {
        Message::Stat { rpackets, .. } => assert_eq!(rpackets, 1),
        other => panic!("expected stat, got {other:?}"),
    }
    c.send("< rawmode >").await;
    // Stat messages may still be in flight before the ok.
    loop {
        match c.next().await {
            Message::Stat { .. } => continue,
            Message::Ok => break,
            other => panic!("unexpected {other:?}"),
        }
    }
    drive.send(frame(0x182, &[2]));
    assert_eq!(c.next_frame().await.0, frame(0x182, &[2]));
}

#[tokio::test]
async fn too_many_clients_are_refused_politely() {
    let bus = Bus::new(64);
    let mut config = ServerConfig::new("vcan0");
    config.max_clients = 2;
    let (addr, _server) = start_server_with(&bus, config).await;
    let mut a = Client::connect(addr).await;
    let mut b = Client::connect(addr).await;
    a.handshake().await;
    b.handshake().await;
    let mut c = Client::connect(addr).await;
    c.expect_exact("< error too many clients >").await;
    assert!(c.closed_within(STEP).await);
    drop(a);
    // Once a slot frees up, new clients are served again.
    let deadline = tokio::time::Instant::now() + STEP;
    loop {
        let mut d = Client::connect(addr).await;
        if d.read_text().await == "< hi >" {
            break;
        }
        assert!(tokio::time::Instant::now() < deadline, "slot never freed");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}
