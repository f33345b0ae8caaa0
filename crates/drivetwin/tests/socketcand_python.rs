//! Interop: python-can's own socketcand client (which nobody here wrote) against our server.
//! Skipped, with a message, when `python3` with python-can >= 4.3.1 is not installed
//! (`pip install 'python-can>=4.3.1'`).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::process::Stdio;
use std::time::Duration;

use canopen::CanFrame;
use drivetwin::can::bus::Bus;
use drivetwin::can::socketcand::serve;
use tokio::net::TcpListener;
use tokio::process::Command;

const CLIENT: &str = r#"
import sys, time, can
host, port = sys.argv[1], int(sys.argv[2])
bus = can.Bus(interface="socketcand", host=host, port=port, channel="vcan0")
bus.send(can.Message(arbitration_id=0x605, data=[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0], is_extended_id=False))
bus.send(can.Message(arbitration_id=0x1ABCDE, data=[0xA5], is_extended_id=True))
bus.send(can.Message(arbitration_id=0x705, data=[], is_extended_id=False))
got = []
deadline = time.time() + 10
while len(got) < 3 and time.time() < deadline:
    m = bus.recv(0.5)
    if m is not None:
        got.append(m)
for m in got:
    print("RX %X %d %s" % (m.arbitration_id, int(m.is_extended_id), m.data.hex()))
bus.shutdown()
"#;

async fn python_can_available() -> bool {
    let check = Command::new("python3")
        .args([
            "-c",
            "import can,sys; v=tuple(int(x) for x in can.__version__.split('.')[:3]); sys.exit(0 if v >= (4,3,1) else 1)",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .await;
    matches!(check, Ok(status) if status.success())
}

#[tokio::test]
async fn python_can_socketcand_client_round_trip() {
    if !python_can_available().await {
        println!("SKIPPED: python3 with python-can >= 4.3.1 not available");
        return;
    }
    let bus = Bus::new(256);
    let mut drive = bus.port();
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let addr = listener.local_addr().expect("addr");
    let server = tokio::spawn(serve(listener, bus.clone(), "vcan0"));

    let child = Command::new("python3")
        .arg("-c")
        .arg(CLIENT)
        .arg(addr.ip().to_string())
        .arg(addr.port().to_string())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .expect("spawn python3");

    // What python-can sent.
    let mut from_python = Vec::new();
    for _ in 0..3 {
        let got = tokio::time::timeout(Duration::from_secs(15), drive.recv())
            .await
            .expect("python-can frame in time")
            .expect("frame");
        from_python.push(got.frame);
    }
    assert_eq!(
        from_python,
        vec![
            CanFrame::new(0x605, &[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]).expect("frame"),
            CanFrame::with_id(0x1ABCDE, true, &[0xA5]).expect("frame"),
            CanFrame::new(0x705, &[]).expect("frame"),
        ]
    );

    // What python-can receives.
    drive.send(CanFrame::new(0x585, &[0x43, 0x18, 0x10, 0x01, 0x92, 0x01, 0, 0]).expect("f"));
    drive.send(CanFrame::with_id(0x18FF_0001, true, &[1, 2, 3]).expect("frame"));
    drive.send(CanFrame::new(0x080, &[]).expect("frame"));

    let out = tokio::time::timeout(Duration::from_secs(30), child.wait_with_output())
        .await
        .expect("python finishes")
        .expect("python output");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "python failed:\n{stdout}\n{stderr}");
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(
        lines,
        vec![
            "RX 585 0 4318100192010000",
            "RX 18FF0001 1 010203",
            "RX 80 0 "
        ],
        "stdout:\n{stdout}\nstderr:\n{stderr}"
    );
    server.abort();
}
