//! The cell loop over real loopback TCP: one thread owns the drives and every socket.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::time::{Duration, Instant};

use drivetwin::can::socketcand::ServerConfig;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::station::Station;
use drivetwin::cell_loop::{CanBus, CellLoop, FrontEnds, StopHandle, MAX_PENDING};

fn start() -> (SocketAddr, StopHandle, std::thread::JoinHandle<()>) {
    let desc = devices::by_name("cmmp-as").expect("cmmp-as");
    let drive = Station::new(desc, 1, None, vec![]).expect("drive");
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("addr");
    let mut config = ServerConfig::new("vcan0");
    config.stream_delay = Duration::from_millis(20);
    let front = FrontEnds {
        buses: vec![CanBus {
            socketcand: Some((listener, config)),
            ..CanBus::default()
        }],
        ..FrontEnds::default()
    };
    let cell_loop = CellLoop::new(CanCell::one_bus(vec![drive]), front).expect("loop");
    let stop = cell_loop.stop_handle();
    let thread = std::thread::spawn(move || {
        cell_loop.run().expect("runs");
    });
    (addr, stop, thread)
}

/// A client in RAW mode, past the stream delay.
fn raw_client(addr: SocketAddr) -> TcpStream {
    let mut s = TcpStream::connect(addr).expect("connect");
    s.set_nodelay(true).expect("nodelay");
    s.set_read_timeout(Some(Duration::from_secs(5)))
        .expect("timeout");
    let mut buf = [0u8; 256];
    for (send, expect) in [
        (None, "< hi >"),
        (Some("< open vcan0 >"), "< ok >"),
        (Some("< rawmode >"), "< ok >"),
    ] {
        if let Some(send) = send {
            s.write_all(send.as_bytes()).expect("write");
        }
        let n = s.read(&mut buf).expect("read");
        assert_eq!(String::from_utf8_lossy(&buf[..n]), expect);
    }
    std::thread::sleep(Duration::from_millis(50));
    s
}

/// Sends an expedited SDO upload of 1000h and reads until node 1's answer.
fn sdo_upload_1000(s: &mut TcpStream) -> String {
    s.write_all(b"< send 601 8 40 00 10 00 00 00 00 00 >")
        .expect("write");
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    loop {
        let n = s.read(&mut buf).expect("answer in time");
        assert!(n > 0, "server closed");
        got.extend_from_slice(&buf[..n]);
        let text = String::from_utf8_lossy(&got).into_owned();
        if let Some(at) = text.find("< frame 581 ") {
            if let Some(end) = text[at..].find('>') {
                return text[at..at + end + 1].to_owned();
            }
        }
    }
}

#[test]
fn sdo_round_trip_through_the_loop() {
    let (addr, stop, thread) = start();
    let mut c = raw_client(addr);
    let answer = sdo_upload_1000(&mut c);
    // CiA 301: 43h = expedited upload of 4 bytes, of 1000h sub 0.
    assert!(
        answer.ends_with(" 43001000") || answer.contains(" 43001000"),
        "{answer}"
    );
    stop.stop();
    thread.join().expect("loop ends");
}

#[test]
fn a_client_that_does_not_read_is_dropped_and_never_delays_the_others() {
    let (addr, stop, thread) = start();
    let mut slow = raw_client(addr);
    let mut probe = raw_client(addr);
    // A third client floods the bus; the slow one is sent every frame and reads none; the
    // probe's SDO round trips go on meanwhile.
    let mut flooder = raw_client(addr);
    let flood = std::thread::spawn(move || {
        let frame = b"< send 123 8 01 02 03 04 05 06 07 08 >";
        let mut batch = Vec::new();
        for _ in 0..1000 {
            batch.extend_from_slice(frame);
        }
        for _ in 0..(4 * MAX_PENDING / 40 + 100_000) / 1000 {
            if flooder.write_all(&batch).is_err() {
                break;
            }
        }
    });
    let started = Instant::now();
    let mut worst = Duration::ZERO;
    let mut probes = 0;
    while !flood.is_finished() || probes < 5 {
        let t = Instant::now();
        sdo_upload_1000(&mut probe);
        worst = worst.max(t.elapsed());
        probes += 1;
        std::thread::sleep(Duration::from_millis(5));
    }
    flood.join().expect("flooder");
    // Each turn of the loop reads at most 64 KiB of the flood before the probe's turn.
    assert!(worst < Duration::from_secs(1), "an answer took {worst:?}");
    // The slow client was dropped: after what the kernel held, the stream ends.
    slow.set_read_timeout(Some(Duration::from_secs(5)))
        .expect("timeout");
    let mut buf = vec![0u8; 1 << 20];
    let mut ended = false;
    while started.elapsed() < Duration::from_secs(60) {
        match slow.read(&mut buf) {
            Ok(0) | Err(_) => {
                ended = true;
                break;
            }
            Ok(_) => {}
        }
    }
    assert!(ended, "the slow client is disconnected");
    stop.stop();
    thread.join().expect("loop ends");
}

/// A client that sends a few bytes and closes at once: the close arrives with the data in one
/// readiness event (the loop's poll is edge-triggered), and the loop still reads to the end of
/// file and closes its side. (Found by the soak run: every such client left a descriptor open.)
#[test]
fn a_client_that_sends_and_closes_at_once_is_closed() {
    let (addr, stop, thread) = start();
    for garbage in [
        &b"B"[..],
        b"\x01\x02\x03",
        b"< open vcan0 ><",
        b"nonsense without brackets",
    ] {
        let mut s = TcpStream::connect(addr).expect("connect");
        s.set_read_timeout(Some(Duration::from_secs(3)))
            .expect("timeout");
        let mut buf = [0u8; 64];
        let n = s.read(&mut buf).expect("greeting");
        assert_eq!(&buf[..n], b"< hi >");
        s.write_all(garbage).expect("write");
        s.shutdown(std::net::Shutdown::Write).expect("half close");
        // Whatever the server answers, it then closes: read reaches end of file.
        let started = Instant::now();
        loop {
            match s.read(&mut buf) {
                Ok(0) => break,
                Ok(_) => {}
                Err(e) => panic!(
                    "{garbage:?}: no end of file after {:?}: {e}",
                    started.elapsed()
                ),
            }
        }
    }
    stop.stop();
    thread.join().expect("loop thread");
}

#[test]
fn two_buses_on_one_loop_keep_their_frames_apart() {
    let desc = devices::by_name("cmmp-as").expect("cmmp-as");
    let mut buses = Vec::new();
    let mut cell = CanCell::new();
    let mut addrs = Vec::new();
    for _ in 0..2 {
        // Node 1 on each bus: node-IDs are per bus.
        let drive = Station::new(desc, 1, None, vec![]).expect("drive");
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        addrs.push(listener.local_addr().expect("addr"));
        let mut config = ServerConfig::new("vcan0");
        config.stream_delay = Duration::from_millis(20);
        buses.push(CanBus {
            socketcand: Some((listener, config)),
            ..CanBus::default()
        });
        cell.add_bus(vec![drive]);
    }
    let cell_loop = CellLoop::new(
        cell,
        FrontEnds {
            buses,
            ..FrontEnds::default()
        },
    )
    .expect("loop");
    let stop = cell_loop.stop_handle();
    let thread = std::thread::spawn(move || {
        let cell = cell_loop.run().expect("runs");
        assert_eq!(cell.buses.len(), 2);
        assert_eq!(cell.stations.len(), 2);
    });
    let mut a = raw_client(addrs[0]);
    let mut a2 = raw_client(addrs[0]);
    let mut b = raw_client(addrs[1]);
    // A frame on bus A reaches A's other client, not B's.
    a.write_all(b"< send 123 2 AA BB >").expect("write");
    let mut buf = [0u8; 4096];
    let n = a2.read(&mut buf).expect("A2 sees it");
    assert!(String::from_utf8_lossy(&buf[..n]).contains("< frame 123 "));
    b.set_read_timeout(Some(Duration::from_millis(200)))
        .expect("timeout");
    match b.read(&mut buf) {
        Ok(n) => assert!(
            !String::from_utf8_lossy(&buf[..n]).contains("frame 123"),
            "bus B stays apart"
        ),
        Err(e) => assert!(matches!(
            e.kind(),
            std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
        )),
    }
    b.set_read_timeout(Some(Duration::from_secs(5)))
        .expect("timeout");
    // Each bus's node 1 answers its own client.
    assert!(sdo_upload_1000(&mut a).contains(" 43001000"));
    assert!(sdo_upload_1000(&mut b).contains(" 43001000"));
    stop.stop();
    thread.join().expect("loop ends");
}
