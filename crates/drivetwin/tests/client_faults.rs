//! Faults on one socketcand client of a bus (`FrontEnd::Client(port)`, REST
//! `/api/wire/client/{port}/faults`): drop and delay of the frames that client sends and of
//! those the bus sends it, the other clients untouched.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod web_rig;

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::time::{Duration, Instant};

use drivetwin::can::socketcand::ServerConfig;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::wire_faults::{FaultSpec, FrontEnd, WireRequest};
use drivetwin::cell_loop::{CanBus, FrontEnds};

struct Client {
    s: TcpStream,
    text: String,
}

impl Client {
    fn connect(addr: SocketAddr) -> Client {
        let s = TcpStream::connect(addr).expect("connect");
        s.set_read_timeout(Some(Duration::from_millis(20)))
            .expect("timeout");
        let mut c = Client {
            s,
            text: String::new(),
        };
        c.wait_for("< hi >", Duration::from_secs(2));
        c.send("< open vcan0 >");
        c.wait_for("< ok >", Duration::from_secs(2));
        c.send("< rawmode >");
        c.wait_for("< ok >", Duration::from_secs(2));
        c
    }

    fn port(&self) -> u16 {
        self.s.local_addr().expect("local").port()
    }

    fn send(&mut self, text: &str) {
        self.s.write_all(text.as_bytes()).expect("send");
    }

    /// Reads until `needle` has come (and takes what came up to it); false after `wait`.
    fn wait_for(&mut self, needle: &str, wait: Duration) -> bool {
        let end = Instant::now() + wait;
        loop {
            if let Some(i) = self.text.find(needle) {
                self.text.drain(..i + needle.len());
                return true;
            }
            if Instant::now() >= end {
                return false;
            }
            let mut buf = [0u8; 1024];
            if let Ok(n) = self.s.read(&mut buf) {
                self.text
                    .push_str(&String::from_utf8_lossy(buf.get(..n).unwrap_or(&[])));
            }
        }
    }
}

/// A CMMP-AS, node 1, on a bus with a socketcand server.
fn cell() -> (web_rig::Running, SocketAddr) {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("addr");
    let bus = CanBus {
        socketcand: Some((listener, ServerConfig::new("vcan0"))),
        ..CanBus::default()
    };
    let can = CanCell::one_bus(vec![web_rig::station("cmmp-as", 1)]);
    let front = FrontEnds {
        buses: vec![bus],
        ..FrontEnds::default()
    };
    (web_rig::start(can, front, None), addr)
}

fn fault(json: serde_json::Value) -> drivetwin::cell::wire_faults::WireFault {
    let spec: FaultSpec = serde_json::from_value(json).expect("spec");
    spec.to_fault().expect("fault")
}

/// SDO upload of 1000h device type from a client; its answer is 581h.
const REQUEST: &str = "< send 601 8 40 00 10 00 00 00 00 00 >";
const ANSWER: &str = "< frame 581 ";

#[test]
fn a_dropping_client_is_cut_off_alone() {
    let (running, addr) = cell();
    let mut a = Client::connect(addr);
    let mut b = Client::connect(addr);
    a.send(REQUEST);
    assert!(a.wait_for(ANSWER, Duration::from_secs(2)), "A answered");
    assert!(b.wait_for(ANSWER, Duration::from_secs(2)), "B sees it too");
    running
        .handle
        .wire(WireRequest::Add {
            front: FrontEnd::Client(a.port()),
            fault: fault(serde_json::json!({"fault": "drop"})),
        })
        .expect("added");
    // A's request is lost: nobody sees an answer.
    a.send(REQUEST);
    assert!(
        !b.wait_for(ANSWER, Duration::from_millis(300)),
        "A's frame dropped"
    );
    // B's request is answered to B, not to A.
    b.send(REQUEST);
    assert!(b.wait_for(ANSWER, Duration::from_secs(2)), "B answered");
    assert!(
        !a.wait_for(ANSWER, Duration::from_millis(300)),
        "nothing reaches A"
    );
    running
        .handle
        .wire(WireRequest::Clear {
            front: FrontEnd::Client(a.port()),
        })
        .expect("cleared");
    a.send(REQUEST);
    assert!(a.wait_for(ANSWER, Duration::from_secs(2)), "A again");
    // A client that is not connected has no faults.
    let gone = running.handle.wire(WireRequest::Add {
        front: FrontEnd::Client(1),
        fault: fault(serde_json::json!({"fault": "drop"})),
    });
    assert!(gone.is_err(), "{gone:?}");
}

#[test]
fn a_delayed_client_gets_its_answers_late() {
    let (running, addr) = cell();
    let mut a = Client::connect(addr);
    let mut b = Client::connect(addr);
    running
        .handle
        .wire(WireRequest::Add {
            front: FrontEnd::Client(a.port()),
            fault: fault(serde_json::json!({"fault": "delay", "delay": "300ms"})),
        })
        .expect("added");
    let t0 = Instant::now();
    b.send(REQUEST);
    assert!(b.wait_for(ANSWER, Duration::from_secs(2)), "B at once");
    let b_took = t0.elapsed();
    assert!(a.wait_for(ANSWER, Duration::from_secs(2)), "A later");
    let a_took = t0.elapsed();
    assert!(b_took < Duration::from_millis(250), "{b_took:?}");
    assert!(a_took >= Duration::from_millis(300), "{a_took:?}");
}

/// A client's frames keep their order: when its delay ends while a frame is still held, the
/// next one it sends waits behind that frame (a TCP stream never reorders).
#[test]
fn a_client_s_frames_keep_their_order_when_its_delay_ends() {
    let (running, addr) = cell();
    let mut a = Client::connect(addr);
    let mut b = Client::connect(addr);
    running
        .handle
        .wire(WireRequest::Add {
            front: FrontEnd::Client(a.port()),
            fault: fault(serde_json::json!({"fault": "delay", "delay": "300ms"})),
        })
        .expect("added");
    // 1000h device type, held 300 ms (the loop has read it before the fault ends).
    a.send(REQUEST);
    std::thread::sleep(Duration::from_millis(50));
    running
        .handle
        .wire(WireRequest::Clear {
            front: FrontEnd::Client(a.port()),
        })
        .expect("cleared");
    // 1018h sub 1 vendor-ID, sent with no fault: behind the held one all the same.
    a.send("< send 601 8 40 18 10 01 00 00 00 00 >");
    let first = "4000100000000000 >";
    let second = "4018100100000000 >";
    // Had the second overtaken the first, waiting for the first would take the second with
    // it and nothing would be left to find.
    assert!(
        b.wait_for(first, Duration::from_secs(2)),
        "B sees the first"
    );
    assert!(
        b.wait_for(second, Duration::from_secs(2)),
        "and the second after it"
    );
}
