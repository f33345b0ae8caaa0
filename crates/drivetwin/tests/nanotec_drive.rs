//! `drivetwin drive`, the CLI's CiA 402 master, against a Nanotec SMCI47-S twin (`drivetwin
//! run --device nanotec-smci47s --node 34`) over socketcand, both the real binary: the
//! master must not need the CMMP-AS's objects. A Nanotec has no 606Ch, 6077h, 6078h, 60FFh
//! or 6087h and no profile velocity mode (Nanotec §9.43: 6502h = 6Bh): the
//! state is printed without them, `velocity` runs in VL (6060h = 2, 6042h), `torque --slope`
//! names the missing 6087h, and torque mode in open loop is refused with the reason (ch. 8).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

const NODE: &str = "34";

/// One `drivetwin run` with its socketcand server on a free loopback port; SIGTERM on drop.
struct Twin {
    child: Child,
    addr: String,
    state_dir: PathBuf,
}

impl Twin {
    fn start(device: &str) -> Twin {
        let port = TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("a free port")
            .port();
        let addr = format!("127.0.0.1:{port}");
        let state_dir = std::env::temp_dir().join(format!(
            "drivetwin-nanotec-drive-{}-{port}",
            std::process::id()
        ));
        std::fs::create_dir_all(&state_dir).expect("state dir");
        let mut child = Command::new(binary())
            .args([
                "run",
                "--socketcand",
                &addr,
                "--channel",
                "vcan0",
                "--state-dir",
            ])
            .arg(&state_dir)
            .args(["--device", device, "--node", NODE])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("drivetwin run starts");
        let stdout = child.stdout.take().expect("stdout");
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if line.starts_with("socketcand server on") {
                    let _ = tx.send(());
                }
            }
        });
        rx.recv_timeout(Duration::from_secs(10))
            .expect("drivetwin printed 'socketcand server on'");
        Twin {
            child,
            addr,
            state_dir,
        }
    }

    /// `drivetwin drive 34 ARGS` against this twin.
    fn drive(&self, args: &[&str]) -> Output {
        Command::new(binary())
            .args(["drive", NODE])
            .args(args)
            .args(["--socketcand", &self.addr, "--channel", "vcan0"])
            .output()
            .expect("drivetwin drive runs")
    }

    /// `drive ARGS`, which must succeed; its standard output.
    fn drive_ok(&self, args: &[&str]) -> String {
        let out = self.drive(args);
        assert!(
            out.status.success(),
            "drive {args:?}: {:?}\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    /// `drive state --json` as JSON.
    fn state(&self) -> serde_json::Value {
        let text = self.drive_ok(&["state", "--json"]);
        serde_json::from_str(text.trim()).expect("JSON state")
    }
}

impl Drop for Twin {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.state_dir);
    }
}

fn binary() -> &'static Path {
    Path::new(env!("CARGO_BIN_EXE_drivetwin"))
}

/// The shaft's speed over `seconds` from two `drive state` readings, as the least and the
/// most it can be given how long each reading took (units/s): a loaded machine delays the
/// commands, not the simulated motor.
fn speed(twin: &Twin, seconds: f64) -> (f64, f64) {
    let t0 = Instant::now();
    let a = int(&twin.state(), "position");
    let t1 = Instant::now();
    std::thread::sleep(Duration::from_secs_f64(seconds));
    let t2 = Instant::now();
    let b = int(&twin.state(), "position");
    let t3 = Instant::now();
    let moved = (b - a) as f64;
    let (least, most) = (
        moved / (t3 - t0).as_secs_f64(),
        moved / (t2 - t1).as_secs_f64().max(1e-3),
    );
    (least.min(most), least.max(most))
}

/// The speed over `seconds` can lie in `low..=high` units/s.
fn assert_speed(twin: &Twin, seconds: f64, low: f64, high: f64) {
    let (least, most) = speed(twin, seconds);
    assert!(
        least <= high && most >= low,
        "{least:.0} … {most:.0} units/s, not in {low} … {high}"
    );
}

fn int(v: &serde_json::Value, key: &str) -> i64 {
    v[key].as_i64().unwrap_or_else(|| panic!("{key} in {v}"))
}

#[test]
fn drive_enables_moves_and_reports_a_nanotec_without_cmmp_objects() {
    let twin = Twin::start("nanotec-smci47s");
    // The state: no 606Ch / 6077h / 6078h, said as such, not an SDO abort.
    let text = twin.drive_ok(&["state"]);
    assert!(
        text.starts_with("SWITCH ON DISABLED (statusword 0260h)"),
        "{text}"
    );
    assert!(text.contains("velocity n/a (no 606Ch)"), "{text}");
    assert!(
        text.contains("current n/a (no 6078h) torque n/a (no 6077h)"),
        "{text}"
    );
    let s = twin.state();
    assert!(
        s["velocity"].is_null() && s["current_permille"].is_null(),
        "{s}"
    );

    let text = twin.drive_ok(&["enable"]);
    assert!(
        text.starts_with("OPERATION ENABLED (statusword 0237h)"),
        "{text}"
    );

    // PP: 4000 user units = 2 output revolutions at the default feed 2000 / rev (§6).
    let text = twin.drive_ok(&[
        "move",
        "4000",
        "--velocity",
        "4000",
        "--accel",
        "20000",
        "--decel",
        "20000",
        "--wait",
        "--timeout-ms",
        "10000",
    ]);
    assert!(text.contains("target reached"), "{text}");
    let s = twin.state();
    assert_eq!(int(&s, "mode"), 1);
    assert!((int(&s, "position") - 4000).abs() <= 2, "{s}");

    // A relative move from there.
    twin.drive_ok(&[
        "move",
        "-1000",
        "--relative",
        "--wait",
        "--timeout-ms",
        "10000",
    ]);
    assert!((int(&twin.state(), "position") - 3000).abs() <= 2);
}

#[test]
fn drive_velocity_runs_a_nanotec_in_vl() {
    let twin = Twin::start("nanotec-smci47s");
    twin.drive_ok(&["enable"]);
    // 604Ch = 60 / 2000 (§6.10): 1000 user units = 30 min⁻¹ = 1000 increments/s.
    let out = twin.drive(&["velocity", "1000", "--wait", "--timeout-ms", "10000"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let note = String::from_utf8_lossy(&out.stderr);
    assert!(note.contains("velocity mode VL (6060h = 2)"), "{note}");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("mode 2 "), "{text}");
    assert!(text.contains("(6044h)"), "{text}");
    // 1000 VL units = 1000 units/s: the plant turns at that speed.
    assert_speed(&twin, 0.5, 900.0, 1100.0);
    let b = twin.state();
    // 6044h shows a value in closed loop only (§6.5); the factory drive runs open loop.
    assert_eq!(int(&b, "velocity"), 0, "{b}");
    assert_eq!(b["velocity_object"], "6044h");
    // Beyond 6042h's s16: a usage error before anything is written.
    let out = twin.drive(&["velocity", "40000"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("6042h"));
    // Stop.
    twin.drive_ok(&["velocity", "0", "--wait", "--timeout-ms", "10000"]);
    let a = int(&twin.state(), "position");
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(int(&twin.state(), "position"), a, "standing");
}

#[test]
fn drive_torque_on_a_nanotec_names_what_is_missing() {
    let twin = Twin::start("nanotec-smci47s");
    twin.drive_ok(&["enable"]);
    // No 6087h: refused before the mode changes.
    let out = twin.drive(&["torque", "300", "--slope", "1000"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("torque slope (6087h:00h does not exist)"),
        "{err}"
    );
    // Open loop: 6060h = 4 refused with 0800 0022h, and the reason.
    let out = twin.drive(&["torque", "300"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("refused mode 4"), "{err}");
    assert!(err.contains("closed loop on (200Ah = 1"), "{err}");
    // Closed loop on (2001h = 1, §11.2), then torque moves the motor up to 607Fh.
    let sdo = |args: &[&str]| {
        let out = Command::new(binary())
            .args(["sdo", "write", NODE])
            .args(args)
            .args(["--socketcand", &twin.addr, "--channel", "vcan0"])
            .output()
            .expect("drivetwin sdo");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    sdo(&["2001", "0", "1", "--type", "u8"]);
    sdo(&["607F", "0", "120", "--type", "u32"]);
    let text = twin.drive_ok(&["torque", "300"]);
    assert!(text.contains("mode 4 "), "{text}");
    std::thread::sleep(Duration::from_millis(300));
    // 120 min⁻¹ = 2 rev/s = 4000 units/s, the limit the torque fades into.
    assert_speed(&twin, 0.5, 3500.0, 4100.0);
}
