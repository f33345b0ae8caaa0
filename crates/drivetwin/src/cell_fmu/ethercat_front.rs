//! The cell FMU's EtherCAT chains: the cell file's EtherCAT slaves (`interfaces =
//! ["ethercat"]`, `ethercat = "IFNAME"`), one chain per network interface as `drivetwin run`
//! builds them, stepped on the FMU's virtual clock, their raw sockets open while an importer
//! steps the cell.
//!
//! Time is the importer's, as for the socketcand and Modbus TCP front ends: a chain's drives
//! step at their deadlines inside a `doStep` (at one instant after the CAN buses and the
//! Modbus drives, as [`crate::cell_loop::virtual_clock::run_virtual_mixed`] orders them), and
//! a master's frame passes the chain at the clock's time when it arrives (between two steps,
//! the time the last step ended; during a step, at its end) and goes back out at once, as
//! through a line of real slaves. A slave serves its mailbox and its AL state after every
//! frame, so a master's CoE requests and state changes between two steps are answered without
//! the clock moving; what needs time (the drive's control, a DC SYNC0 event, the SM
//! watchdog) happens in the steps.
//!
//! Decisions: a drive on CANopen and EtherCAT at once is refused (its slave would reach a
//! drive of a CAN bus; the chains here have drives of their own), and so is a slave without
//! its chain's interface, neither in the cell file nor given to `drivetwin fmu --ethercat`
//! (kept in the FMU's resources, [`super::ETHERCAT_FILE`], as `drivetwin run --ethercat`
//! gives it). Each slave's drive has a CiA 402 drive's variables, named by its place in
//! the cell file (`driveK`, [`super::variables::DriveName::Section`]): its shaft, current and words
//! are read here, and its load torque and digital inputs set here, on the chain's lock.

use std::io;
use std::os::fd::AsRawFd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use canopen::CanFrame;
use mio::unix::SourceFd;
use mio::{Events, Interest, Poll, Token};
use od::Instant;

use crate::cell::config::CellFile;
use crate::cell::control::DriveViews;
use crate::cell::Vendors;
use crate::ecat::chain::SlaveChain;
use crate::ecat::link::SlaveSocket;
use crate::scenario::runner::Rig;
use crate::scenario::virtual_rig::{Probe, VirtualRig};

use super::front_ends::{lock, SharedCell};
use super::serving_thread::ServingThread;
use super::CellFmuError;

const FIRST_CHAIN: usize = 1;
/// Steps at one instant before the clock is taken as stuck.
const STUCK: u32 = 10_000;

/// A chain and the interface its slaves are on.
pub struct Chain {
    pub interface: String,
    pub chain: SlaveChain,
    /// Each slave's `[[drive]]` index in the cell file, in wire order.
    pub places: Vec<usize>,
}

type SharedChains = Arc<Mutex<Vec<Chain>>>;

fn lock_chains(chains: &SharedChains) -> MutexGuard<'_, Vec<Chain>> {
    chains
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The cell's EtherCAT chains, and the thread that serves their sockets once open.
pub struct EthercatChains {
    chains: SharedChains,
    /// Each slave's chain and position in it, chain by chain: the order of the drives'
    /// variables ([`EthercatChains::places`]).
    slots: Vec<(usize, usize)>,
    front: Option<ServingThread>,
}

impl EthercatChains {
    /// `file` without its EtherCAT slaves (the rest is the virtual rig's), and the chains of
    /// those slaves, booted at 0; `ethercat_if` is the chain of the slaves that name none, as
    /// `drivetwin run --ethercat` resolves them
    /// ([`crate::cell::interfaces::resolve_ethercat_chains`]).
    pub fn split(
        file: &CellFile,
        vendors: Vendors,
        ethercat_if: Option<&str>,
    ) -> Result<(CellFile, Self), CellFmuError> {
        let mut specs = file
            .drives(vendors)
            .map_err(|e| CellFmuError::Cell(e.to_string()))?;
        crate::cell::interfaces::resolve_ethercat_chains(file, &mut specs, ethercat_if)
            .map_err(|e| CellFmuError::Cell(e.to_string()))?;
        let mut rest = file.clone();
        rest.drive.clear();
        type Specs = Vec<(usize, crate::cell::config::DriveSpec)>;
        let mut by_interface: Vec<(String, Specs)> = Vec::new();
        for (place, (section, spec)) in file.drive.iter().zip(specs).enumerate() {
            let Some(interface) = &spec.ethercat else {
                rest.drive.push(section.clone());
                continue;
            };
            if spec.canopen {
                return Err(CellFmuError::Cell(format!(
                    "drive {} node {}: on CANopen and EtherCAT at once; in the cell FMU an \
                     EtherCAT slave is a drive of its own",
                    spec.desc.name, spec.node
                )));
            }
            let Some(interface) = interface.clone() else {
                return Err(CellFmuError::Cell(format!(
                    "drive {} node {}: an EtherCAT slave needs its chain's interface, \
                     `ethercat = \"IFNAME\"` in the cell file or `drivetwin fmu --ethercat \
                     IFNAME`",
                    spec.desc.name, spec.node
                )));
            };
            match by_interface.iter_mut().find(|(i, _)| *i == interface) {
                Some((_, specs)) => specs.push((place, spec)),
                None => by_interface.push((interface, vec![(place, spec)])),
            }
        }
        let mut chains = Vec::new();
        let mut slots = Vec::new();
        for (interface, specs) in by_interface {
            let (places, specs): (Vec<usize>, Vec<_>) = specs.into_iter().unzip();
            let mut chain = SlaveChain::new(specs)
                .map_err(|e| CellFmuError::Cell(format!("EtherCAT on {interface}: {e}")))?;
            chain.boot(Instant::ZERO);
            slots.extend((0..places.len()).map(|slave| (chains.len(), slave)));
            chains.push(Chain {
                interface,
                chain,
                places,
            });
        }
        Ok((
            rest,
            EthercatChains {
                chains: Arc::new(Mutex::new(chains)),
                slots,
                front: None,
            },
        ))
    }

    /// How many chains, and the slaves of each, with its interface.
    pub fn chains(&self) -> Vec<(String, usize)> {
        lock_chains(&self.chains)
            .iter()
            .map(|c| (c.interface.clone(), c.chain.len()))
            .collect()
    }

    /// Each slave's `[[drive]]` index in the cell file, chain by chain in wire order: the
    /// names of their variables, in the order of [`EthercatChains::probe_into`]'s slaves.
    pub fn places(&self) -> Vec<usize> {
        let chains = lock_chains(&self.chains);
        self.slots
            .iter()
            .filter_map(|(c, i)| chains.get(*c)?.places.get(*i).copied())
            .collect()
    }

    /// Runs `f` on the drive of slave `slave` (of [`EthercatChains::places`]' order).
    pub(super) fn with_drive<T>(
        &self,
        slave: usize,
        f: impl FnOnce(&mut crate::cell::device_model::Model) -> Option<T>,
    ) -> Option<T> {
        let (c, i) = *self.slots.get(slave)?;
        let mut chains = lock_chains(&self.chains);
        f(chains.get_mut(c)?.chain.model_mut(i)?)
    }

    /// The outputs of every slave's drive, in [`EthercatChains::places`]' order, into `out`.
    pub fn probe_into(&self, out: &mut [Probe]) {
        let chains = lock_chains(&self.chains);
        for (slot, (c, i)) in out.iter_mut().zip(&self.slots) {
            if let Some(p) = chains
                .get(*c)
                .and_then(|c| c.chain.model(*i))
                .and_then(Probe::of_model)
            {
                *slot = p;
            }
        }
    }

    /// What slave `slave`'s drive's display shows, by the vendors' `display`.
    pub fn display(&self, slave: usize, views: &DriveViews) -> Option<String> {
        self.with_drive(slave, |m| {
            (views.display)(m.drive()?).map(|s| s.text().to_string())
        })
    }

    /// Slave `slave`'s load torque on its motor shaft (a scenario's `load`).
    pub fn set_load_torque(&self, slave: usize, torque_nm: f64) -> Result<(), String> {
        self.with_drive(slave, |m| {
            m.drive_mut()?
                .axis_mut()
                .motor_mut()
                .set_load_torque(torque_nm);
            Some(())
        })
        .ok_or_else(|| "the drive has no simulated motor".to_string())
    }

    /// Slave `slave`'s digital input `din` forced to `level` (a scenario's `din`).
    pub fn force_input(&self, slave: usize, din: u8, level: bool) -> Result<(), String> {
        self.with_drive(slave, |m| {
            let d = m.drive_mut()?;
            let (mask, levels) = d.forced_inputs();
            let bit = 1u16.checked_shl(u32::from(din))?;
            d.force_inputs(mask | bit, if level { levels | bit } else { levels & !bit });
            Some(())
        })
        .ok_or_else(|| "the drive has no simulated inputs".to_string())
    }

    /// Opens each chain's raw socket (`AF_PACKET`: root or `CAP_NET_RAW`, the interface in
    /// the importer's network namespace) and serves them on a thread.
    pub fn open(&mut self, shared: &SharedCell) -> Result<(), CellFmuError> {
        let interfaces: Vec<String> = lock_chains(&self.chains)
            .iter()
            .map(|c| c.interface.clone())
            .collect();
        if interfaces.is_empty() {
            return Ok(());
        }
        let front_end = |what: String| {
            move |source: io::Error| CellFmuError::FrontEnd {
                what: what.clone(),
                source,
            }
        };
        let mut sockets = Vec::new();
        for interface in &interfaces {
            let socket = SlaveSocket::open(interface)
                .map_err(front_end(format!("EtherCAT on {interface}")))?;
            sockets.push(socket);
        }
        let poll = Poll::new().map_err(front_end("poll".into()))?;
        let waker = ServingThread::waker(&poll).map_err(front_end("poll".into()))?;
        for (c, s) in sockets.iter().enumerate() {
            poll.registry()
                .register(
                    &mut SourceFd(&s.as_raw_fd()),
                    Token(FIRST_CHAIN + c),
                    Interest::READABLE,
                )
                .map_err(front_end("poll".into()))?;
            tracing::info!(interface = s.interface(), "cell FMU: EtherCAT chain");
        }
        let shared = Arc::clone(shared);
        let chains = Arc::clone(&self.chains);
        let thread = ServingThread::spawn("cell-fmu-ethercat", waker, move |stop| {
            Server {
                poll,
                sockets,
                shared,
                chains,
                stop,
            }
            .run()
        })
        .map_err(front_end("thread".into()))?;
        self.front = Some(thread);
        Ok(())
    }

    /// Runs `rig` and the chains to `t`, from deadline to deadline: at one instant the rig's
    /// drives first, then the chains.
    pub fn run_until(
        &self,
        rig: &mut VirtualRig,
        t: Duration,
        seen: &mut dyn FnMut(usize, Duration, &CanFrame),
    ) {
        let mut chains = lock_chains(&self.chains);
        if chains.is_empty() {
            rig.run_until(t, seen);
            return;
        }
        let end = Instant::from_nanos(u64::try_from(t.as_nanos()).unwrap_or(u64::MAX));
        let mut stuck = 0u32;
        loop {
            let next = chains
                .iter()
                .filter_map(|c| c.chain.deadline())
                .min()
                .filter(|d| *d <= end);
            let Some(next) = next else { break };
            stuck = if next <= rig.now() { stuck + 1 } else { 0 };
            if stuck > STUCK {
                tracing::error!(at = ?rig.now(), "EtherCAT chain stuck on a deadline that does not advance");
                break;
            }
            let at = next.max(rig.now());
            rig.run_until(Duration::from_nanos(at.as_nanos()), seen);
            for c in chains.iter_mut() {
                if c.chain.due(at) {
                    c.chain.poll(at);
                }
            }
        }
        rig.run_until(t, seen);
    }
}

struct Server {
    poll: Poll,
    sockets: Vec<SlaveSocket>,
    shared: SharedCell,
    chains: SharedChains,
    stop: Arc<AtomicBool>,
}

impl Server {
    fn run(mut self) {
        let mut events = Events::with_capacity(16);
        let mut frame = vec![0u8; crate::ecat::MAX_FRAME];
        while !self.stop.load(Ordering::Acquire) {
            if let Err(e) = self.poll.poll(&mut events, None) {
                if e.kind() == io::ErrorKind::Interrupted {
                    continue;
                }
                tracing::error!(error = %e, "cell FMU: EtherCAT front end stops");
                return;
            }
            for event in events.iter() {
                if let Some(c) = event.token().0.checked_sub(FIRST_CHAIN) {
                    self.read(c, &mut frame);
                }
            }
        }
    }

    /// Frames of chain `c` until none waits: each passes the chain at the clock's time and
    /// goes back out at once.
    fn read(&mut self, c: usize, frame: &mut [u8]) {
        loop {
            let Some(socket) = self.sockets.get_mut(c) else {
                return;
            };
            let n = match socket.try_recv(frame) {
                Ok(Some(n)) => n,
                Ok(None) => continue,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    tracing::error!(interface = socket.interface(), error = %e, "EtherCAT receive failed");
                    return;
                }
            };
            let Some(f) = frame.get_mut(..n) else {
                continue;
            };
            let forward = {
                let mut guard = lock(&self.shared);
                let now = guard.rig.now();
                let mut chains = lock_chains(&self.chains);
                let Some(chain) = chains.get_mut(c) else {
                    return;
                };
                // What fell due by the frame's time runs first (as in the cell loop).
                if chain.chain.due(now) {
                    chain.chain.poll(now);
                }
                let forward = chain.chain.on_frame(now, f).forward();
                guard.stale = true;
                forward
            };
            if forward {
                if let Err(e) = socket.send(f) {
                    tracing::error!(interface = socket.interface(), error = %e, "EtherCAT send failed");
                }
            }
        }
    }
}
