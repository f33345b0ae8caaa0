//! An EtherCAT wire for tests and benchmarks: a veth pair whose twin-side end sits in a private
//! network namespace, with the real `drivetwin` binary running there as the slave
//! (`ip netns exec NS drivetwin run --ethercat IF`), and the master-side end left in this
//! namespace for the master under test.
//!
//! Both guards undo what they did when dropped, also while a test panics: [`TwinProcess`]
//! stops the child, [`Veth`] deletes the link (its peer goes with it) and the namespace.
//! [`VethPair`] is a pair with both ends here, for a cell loop in the test's own process.
//! Shared by the tests and benchmarks that need a wire through `#[path]`, so not every item
//! is used by all.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How long the twin may take to print its `running` line.
const START_TIMEOUT: Duration = Duration::from_secs(10);
/// How long the twin may take to stop after SIGTERM.
const STOP_TIMEOUT: Duration = Duration::from_secs(5);

/// Why the wire cannot be built here; the caller prints it and skips.
#[derive(Debug)]
pub struct Unavailable(pub String);

impl std::fmt::Display for Unavailable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// A veth pair, one end (`twin_if`) inside the namespace `ns`, the other (`master_if`) here.
#[derive(Debug)]
pub struct Veth {
    pub ns: String,
    pub twin_if: String,
    pub master_if: String,
}

fn ip(args: &[&str]) -> Result<(), String> {
    let out = Command::new("ip")
        .args(args)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| format!("ip {}: {e}", args.join(" ")))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "ip {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}

/// A tag for names no other test, bench or suite running at the same time uses: the process
/// id and a counter.
fn unique_tag() -> String {
    static SERIAL: AtomicU32 = AtomicU32::new(0);
    format!(
        "{}{}",
        std::process::id(),
        SERIAL.fetch_add(1, Ordering::Relaxed)
    )
}

/// A veth pair `master_if` – `twin_if` in this namespace.
fn add_pair(master_if: &str, twin_if: &str) -> Result<(), String> {
    ip(&[
        "link", "add", master_if, "type", "veth", "peer", "name", twin_if,
    ])
}

impl Veth {
    /// Create a uniquely named namespace and veth pair (names carry the process id and a
    /// counter, so parallel tests, benches and the pysoem suite do not collide).
    pub fn create() -> Result<Veth, Unavailable> {
        if !platform::process::is_root() {
            return Err(Unavailable(
                "EtherCAT over veth needs root (network namespace, raw sockets)".into(),
            ));
        }
        if Command::new("ip")
            .arg("-V")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_err()
        {
            return Err(Unavailable("`ip` (iproute2) is not installed".into()));
        }
        let tag = unique_tag();
        // Interface names: at most 15 bytes ("dcA" + 7-digit pid + counter fits).
        let veth = Veth {
            ns: format!("dtw-ecrab-{tag}"),
            twin_if: format!("dcA{tag}"),
            master_if: format!("dcB{tag}"),
        };
        ip(&["netns", "add", &veth.ns]).map_err(Unavailable)?;
        // From here on, Drop cleans up whatever part was created.
        add_pair(&veth.master_if, &veth.twin_if)
            .map_err(|e| Unavailable(format!("cannot create the veth pair: {e}")))?;
        let steps: [&[&str]; 3] = [
            &["link", "set", &veth.twin_if, "netns", &veth.ns],
            &["-n", &veth.ns, "link", "set", &veth.twin_if, "up"],
            &["link", "set", &veth.master_if, "up"],
        ];
        for step in steps {
            ip(step).map_err(|e| Unavailable(format!("cannot create the veth pair: {e}")))?;
        }
        Ok(veth)
    }
}

impl Drop for Veth {
    fn drop(&mut self) {
        // Deleting one end deletes its peer; errors are ignored (a step may never have run).
        let _ = ip(&["link", "del", &self.master_if]);
        let _ = ip(&["netns", "del", &self.ns]);
    }
}

/// A veth pair with both ends in this namespace and up: a cell loop in this process serves
/// the chain on `twin_if`, the master under test opens `master_if`. Deleted on drop.
#[derive(Debug)]
pub struct VethPair {
    pub twin_if: String,
    pub master_if: String,
}

impl VethPair {
    /// Create a uniquely named pair (names carry the process id and a counter).
    pub fn create() -> Result<VethPair, Unavailable> {
        if !platform::process::is_root() {
            return Err(Unavailable(
                "EtherCAT over veth needs root (raw sockets)".into(),
            ));
        }
        let tag = unique_tag();
        let pair = VethPair {
            twin_if: format!("dpA{tag}"),
            master_if: format!("dpB{tag}"),
        };
        add_pair(&pair.master_if, &pair.twin_if)
            .map_err(|e| Unavailable(format!("cannot create a veth pair: {e}")))?;
        // From here on, Drop deletes the pair.
        for end in [&pair.twin_if, &pair.master_if] {
            ip(&["link", "set", end, "up"])
                .map_err(|e| Unavailable(format!("cannot bring {end} up: {e}")))?;
        }
        Ok(pair)
    }
}

impl Drop for VethPair {
    fn drop(&mut self) {
        // Deleting one end deletes its peer.
        let _ = ip(&["link", "del", &self.master_if]);
    }
}

/// The real `drivetwin` binary running `run --ethercat` inside the veth's namespace.
#[derive(Debug)]
pub struct TwinProcess {
    child: Option<Child>,
    /// Every stdout line so far (a thread keeps reading, so the pipe never fills).
    lines: Arc<Mutex<Vec<String>>>,
    log: PathBuf,
}

impl TwinProcess {
    /// Start `binary run --ethercat <twin_if>` in the namespace and wait for its banner
    /// (`EtherCAT on IF: 1 slave(s)` then `running`). Its stderr (tracing) goes to a log file
    /// kept only when the caller panics.
    pub fn start(binary: &Path, veth: &Veth, extra: &[String]) -> Result<TwinProcess, String> {
        Self::start_chain(binary, veth, extra, 1)
    }

    /// [`TwinProcess::start`] for a chain of `slaves` (a cell file among `extra`), whose banner
    /// counts them.
    pub fn start_chain(
        binary: &Path,
        veth: &Veth,
        extra: &[String],
        slaves: usize,
    ) -> Result<TwinProcess, String> {
        let log = std::env::temp_dir().join(format!("drivetwin-{}.log", veth.ns));
        let log_file = std::fs::File::create(&log).map_err(|e| format!("{log:?}: {e}"))?;
        let mut child = Command::new("ip")
            .args(["netns", "exec", &veth.ns])
            .arg(binary)
            .args(["run", "--ethercat", &veth.twin_if])
            .args(extra)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(log_file)
            .spawn()
            .map_err(|e| format!("cannot start {binary:?}: {e}"))?;
        let stdout = child.stdout.take().ok_or("no stdout pipe")?;
        let lines = Arc::new(Mutex::new(Vec::new()));
        let (started_tx, started_rx) = mpsc::channel();
        {
            let lines = Arc::clone(&lines);
            std::thread::spawn(move || {
                for line in BufReader::new(stdout).lines() {
                    let Ok(line) = line else { break };
                    let running = line.starts_with("running");
                    if let Ok(mut l) = lines.lock() {
                        l.push(line);
                    }
                    if running {
                        let _ = started_tx.send(());
                    }
                }
            });
        }
        let mut twin = TwinProcess {
            child: Some(child),
            lines,
            log,
        };
        if started_rx.recv_timeout(START_TIMEOUT).is_err() {
            return Err(format!(
                "drivetwin did not start: {:?} / {}",
                twin.lines(),
                twin.stderr()
            ));
        }
        let banner = format!("EtherCAT on {}: {slaves} slave", veth.twin_if);
        if !twin.lines().iter().any(|l| l.contains(&banner)) {
            twin.kill();
            return Err(format!("no `{banner}` in {:?}", twin.lines()));
        }
        Ok(twin)
    }

    /// The twin's process id (drivetwin itself: `ip netns exec` execs it).
    pub fn pid(&self) -> Option<u32> {
        self.child.as_ref().map(Child::id)
    }

    /// The stdout lines printed so far.
    pub fn lines(&self) -> Vec<String> {
        self.lines.lock().map(|l| l.clone()).unwrap_or_default()
    }

    /// The twin's stderr so far.
    pub fn stderr(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// Stop it as Ctrl-C would (SIGTERM) and check it says `stopped` and exits with 0.
    pub fn stop(mut self) -> Result<(), String> {
        self.stop_here()
    }

    /// [`stop`](Self::stop), and what the twin printed as it stopped: its timers' lateness
    /// and its loop's longest turns.
    pub fn stop_reporting(mut self) -> Result<Vec<String>, String> {
        self.stop_here()?;
        Ok(self.stopping_report())
    }

    fn stop_here(&mut self) -> Result<(), String> {
        let Some(mut child) = self.child.take() else {
            return Err("already stopped".into());
        };
        let status = terminate(&mut child);
        // The reader thread sees EOF once the child is gone; give it a moment to catch up.
        let deadline = Instant::now() + Duration::from_secs(1);
        while !self.lines().iter().any(|l| l == "stopped") && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(10));
        }
        match status {
            Some(s) if s.success() && self.lines().iter().any(|l| l == "stopped") => Ok(()),
            Some(s) => Err(format!(
                "drivetwin ended with {s}, output {:?}, stderr {}",
                self.lines(),
                self.stderr()
            )),
            None => Err("drivetwin did not stop on SIGTERM".into()),
        }
    }

    fn kill(&mut self) {
        if let Some(mut child) = self.child.take() {
            let _ = terminate(&mut child);
        }
    }

    /// The lines the twin printed as it stopped (its timers' lateness and the longest
    /// turns of its loop, `drivetwin run`), once its stdout has ended.
    fn stopping_report(&self) -> Vec<String> {
        let deadline = Instant::now() + Duration::from_secs(1);
        while !self.lines().iter().any(|l| l == "stopped") && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(10));
        }
        let lines = self.lines();
        let from = lines
            .iter()
            .position(|l| l.contains(" loop: "))
            .unwrap_or(lines.len());
        lines
            .get(from..)
            .map(<[String]>::to_vec)
            .unwrap_or_default()
    }
}

/// SIGTERM, wait up to [`STOP_TIMEOUT`], then SIGKILL; `None` if it had to be killed.
fn terminate(child: &mut Child) -> Option<ExitStatus> {
    if let Ok(Some(status)) = child.try_wait() {
        return Some(status);
    }
    // `ip netns exec` execs the binary, so the child's pid is drivetwin's.
    // Our own, not yet reaped child: the pid cannot have been reused.
    let _ = platform::process::terminate(child.id());
    let deadline = Instant::now() + STOP_TIMEOUT;
    while Instant::now() < deadline {
        match child.try_wait() {
            Ok(Some(status)) => return Some(status),
            Ok(None) => std::thread::sleep(Duration::from_millis(10)),
            Err(_) => break,
        }
    }
    let _ = child.kill();
    let _ = child.wait();
    None
}

impl Drop for TwinProcess {
    fn drop(&mut self) {
        self.kill();
        if std::thread::panicking() {
            // Where a late answer went, from the twin's side.
            for line in self.stopping_report() {
                eprintln!("drivetwin: {line}");
            }
            eprintln!("drivetwin log kept at {}", self.log.display());
        } else {
            let _ = std::fs::remove_file(&self.log);
        }
    }
}

/// The wire with the twin running on it. Field order matters: the twin stops before the
/// veth pair goes away.
#[derive(Debug)]
pub struct EcatWire {
    pub twin: TwinProcess,
    pub veth: Veth,
}

impl EcatWire {
    /// Build the wire and start the twin (`extra`: more `drivetwin run` options).
    /// `Err(Unavailable)` means skip (not root, no `ip`, no veth support); a twin that does
    /// not start is a panic, i.e. a failure.
    pub fn start(binary: &Path, extra: &[String]) -> Result<EcatWire, Unavailable> {
        let veth = Veth::create()?;
        let twin = match TwinProcess::start(binary, &veth, extra) {
            Ok(t) => t,
            Err(e) => panic!("{e}"),
        };
        Ok(EcatWire { twin, veth })
    }

    /// The interface the master opens.
    pub fn master_if(&self) -> &str {
        &self.veth.master_if
    }
}
