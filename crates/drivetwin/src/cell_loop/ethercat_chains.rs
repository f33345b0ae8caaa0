//! EtherCAT chains on the loop: a frame from the master passes the chain's slaves and goes
//! back out at once; a slave that is a CANopen drive of the cell as well reaches that drive.
//!
//! After the answer the chain's devices take their outputs, run their drives and post their
//! inputs (`SlaveChain::exchange_with`). For a long chain that is tens of microseconds (64
//! drives stepped), and a master that shares the loop's CPU (a PLC task beside its drives'
//! twin, or any master under a loop at a real-time priority) would read its answer only after
//! it. When the devices' part costs more than [`DEFER_ABOVE`] and the turn woke for frames
//! alone, the loop sleeps first and runs it [`EXCHANGE_DELAY`] later, or before anything else
//! touches the chain: the next frame's pass, the timers, the control handle. It runs with the
//! frame's time, so what the devices see, and every byte of the next answer, stays the same.

use std::io;
use std::time::{Duration, Instant};

use mio::{Events, Token};

use super::{cell_time, BusState, CellLoop, ChainState, FIRST_CHAIN, FRAMES_PER_TURN};
use crate::cell::link::{At, FrontLink};
use crate::cell::station::Station;
use crate::cell::stations::{StationId, Stations};
use crate::cell::wire_faults::Verdict;
use crate::cell::OnBus;
use crate::ecat::chain::BusDrives;

/// The cell's CAN buses as the EtherCAT chains see them: where a slave that is a CANopen
/// drive as well finds its drive (the bus names it, the cell's list holds it).
pub(super) struct Buses<'a> {
    pub(super) buses: &'a [BusState],
    pub(super) stations: &'a mut Stations,
}

impl BusDrives for Buses<'_> {
    fn station(&mut self, at: OnBus) -> Option<&mut Station> {
        let id = self.buses.get(at.bus)?.segment.member(at.drive)?;
        self.stations.station_mut(id)
    }

    fn in_cell(&mut self, id: StationId) -> Option<&mut Station> {
        self.stations.station_mut(id)
    }
}

/// The devices' part of a frame (`SlaveChain::exchange_with`), waiting while the master
/// reads its answer.
pub(super) struct ExchangeDue {
    /// The frame's time: the devices run as if at once after it.
    at: od::Instant,
    /// The loop wakes for it by then at the latest.
    pub(super) by: Instant,
}

/// A devices' part that took longer than this the last time is run after the loop's next
/// sleep: it costs more than arming the loop's timer (3.4 µs on the measuring VM,
/// docs/performance.md) and the extra wake-up. A chain of a few drives exchanges at once, as
/// before.
pub(super) const DEFER_ABOVE: Duration = Duration::from_micros(10);

/// How long after its frame a deferred devices' part runs at the latest: long enough for a
/// master on the same CPU to take its answer and go back to sleep, short against a 250 µs
/// cycle.
pub(super) const EXCHANGE_DELAY: Duration = Duration::from_micros(50);

/// How long a `--busy-poll` turn looks at the chains' receive rings before it polls the
/// other sockets (a system call) and does the rest of its work: a frame that lands meanwhile
/// is answered from the ring at once, without a wake-up or a system call before its pass.
/// Long enough that a master's frame nearly always finds the loop spinning, short enough that
/// a CAN frame or a console request waits no longer than a drive step's grace allows.
pub(super) const RING_SPIN: Duration = Duration::from_micros(50);

impl CellLoop {
    /// With `--busy-poll`: spins on the chains' receive rings until a frame waits in one
    /// (then answers it, and every other waiting, at once) or until `until`. Each look is a
    /// load from memory; a chain without a ring is read by the turn's poll alone.
    pub(super) fn spin_on_rings(&mut self, until: Instant) {
        if !self
            .chains
            .iter()
            .any(|c| c.link.inner().inner().frame_waits().is_some())
        {
            return;
        }
        loop {
            let mut answered = false;
            for c in 0..self.chains.len() {
                let waits = self
                    .chains
                    .get(c)
                    .and_then(|ch| ch.link.inner().inner().frame_waits())
                    .unwrap_or(false);
                if waits {
                    self.read_ethercat(c);
                    answered = true;
                }
            }
            if answered || Instant::now() >= until {
                return;
            }
            std::hint::spin_loop();
        }
    }

    /// The chains whose sockets `events` name (with `--busy-poll` every chain, without
    /// waiting for an event) read and answer their frames: the first thing of a turn, before
    /// the drives step, the timers run and the other sockets are served.
    pub(super) fn answer_frames(&mut self, events: &Events) {
        for c in 0..self.chains.len() {
            let token = Token(FIRST_CHAIN + c);
            if self.busy_poll || events.iter().any(|e| e.token() == token) {
                self.read_ethercat(c);
            }
        }
    }

    /// Reads EtherCAT frames of chain `c` until none waits (at most [`FRAMES_PER_TURN`]):
    /// each passes the chain and goes back out at once, as through a line of real slaves.
    pub(super) fn read_ethercat(&mut self, c: usize) {
        let mut frame = std::mem::take(&mut self.frame);
        let mut shared = false;
        for turn in 0..=FRAMES_PER_TURN {
            let Some(chain) = self.chains.get_mut(c) else {
                break;
            };
            if turn == FRAMES_PER_TURN {
                // More may wait: read on next turn, after the other sockets.
                self.chains_to_read.push(c);
                break;
            }
            let n = match chain.socket().try_recv(&mut frame) {
                Ok(Some(n)) => n,
                Ok(None) => continue,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    tracing::error!(interface = chain.socket().interface(), error = %e, "EtherCAT receive failed");
                    break;
                }
            };
            let Some(f) = frame.get_mut(..n) else {
                continue;
            };
            let t = cell_time(self.origin, Instant::now());
            match chain.link.receive(At::on_clock(t), f) {
                Verdict::Pass => {}
                // Lost, or held by the chain's link until its time.
                Verdict::Lost | Verdict::Corrupt | Verdict::Delay(_) => continue,
            }
            shared |= chain.chain.has_bus_drives();
            let buses = &mut Buses {
                buses: &self.buses,
                stations: &mut self.stations,
            };
            // The previous frame's devices' part, if it waits, comes before this frame.
            Self::finish_exchange(chain, buses);
            if chain.chain.overdue(t) {
                // A frame carries what the devices posted by its arrival: a SYNC0 event that
                // fell due before it (or a step past its grace) runs first (a master's DC
                // loop and its following-error check read those inputs). Other chains, the
                // CAN drives and the timers wait until after the answer.
                chain.chain.poll_with(t, buses);
            }
            Self::pass_chain(chain, f, t, buses, !self.busy_poll);
        }
        self.frame = frame;
        if shared {
            // A value the master wrote may be due in a TPDO (on change): the CANopen side of
            // the chain's shared drives looks at once.
            let now = Instant::now();
            let t = self.now(now);
            for b in 0..self.buses.len() {
                let on_bus = self
                    .chains
                    .get(c)
                    .is_some_and(|ch| ch.chain.has_drives_on_bus(b));
                if !on_bus {
                    continue;
                }
                let mut out = std::mem::take(&mut self.out);
                if let Some(bus) = self.buses.get_mut(b) {
                    bus.segment.poll(&mut self.stations, t, &mut out);
                }
                self.drives_sent(b, now, &mut out);
                self.out = out;
            }
        }
    }

    /// One frame through chain `chain` and back out on its socket; then the chain's devices
    /// take their outputs and run their drives, while the answer is already on its way. With
    /// `defer`, a devices' part that costs more than [`DEFER_ABOVE`] waits for the loop's
    /// next wake-up ([`ExchangeDue`]); a chain whose drives are CANopen drives as well
    /// exchanges at once (their TPDOs look at the values the master wrote right after).
    pub(super) fn pass_chain(
        chain: &mut ChainState,
        f: &mut [u8],
        t: od::Instant,
        buses: &mut Buses<'_>,
        defer: bool,
    ) {
        Self::finish_exchange(chain, buses);
        if chain.chain.pass_with(t, f, buses).forward() {
            // Out on the wire, then copied to the trace; a failed send is logged by the
            // interface.
            let _ = chain.link.transmit(At::on_clock(t), f);
        }
        if defer && chain.exchange_cost > DEFER_ABOVE && !chain.chain.has_bus_drives() {
            chain.exchange = Some(ExchangeDue {
                at: t,
                by: Instant::now() + EXCHANGE_DELAY,
            });
        } else {
            Self::exchange(chain, t, buses);
        }
    }

    /// The devices' part of a frame at `t`, its cost kept for the next frame's choice.
    fn exchange(chain: &mut ChainState, t: od::Instant, buses: &mut Buses<'_>) {
        let start = Instant::now();
        chain.chain.exchange_with(t, buses);
        chain.exchange_cost = start.elapsed();
    }

    /// Runs chain `chain`'s deferred devices' part, if one waits.
    pub(super) fn finish_exchange(chain: &mut ChainState, buses: &mut Buses<'_>) {
        if let Some(due) = chain.exchange.take() {
            Self::exchange(chain, due.at, buses);
        }
    }

    /// Runs every deferred devices' part: before the timers, the other sockets and the
    /// control handle see the chains.
    pub(super) fn finish_exchanges(&mut self) {
        for chain in &mut self.chains {
            Self::finish_exchange(
                chain,
                &mut Buses {
                    buses: &self.buses,
                    stations: &mut self.stations,
                },
            );
        }
    }

    /// Whether the turn woke for the chains' frames alone, a devices' part waits and nothing
    /// else is due: then the loop goes back to sleep at once (its deadline the devices'
    /// part's), and a master on the same CPU runs before it. A timer that is due ends the
    /// skipping, so a master that sends without pause does not hold the rest of the loop off.
    pub(super) fn frames_alone(&self, events: &Events) -> bool {
        !self.busy_poll
            && !events.is_empty()
            && self.chains_to_read.is_empty()
            && self.chains.iter().any(|c| c.exchange.is_some())
            && events
                .iter()
                .all(|e| (FIRST_CHAIN..FIRST_CHAIN + self.chains.len()).contains(&e.token().0))
            && self.deadline().is_none_or(|d| d > Instant::now())
    }

    /// A frame a `delay` fault held back arrives at chain `c` at `t`.
    pub(super) fn ethercat_frame(&mut self, c: usize, mut frame: Vec<u8>, t: od::Instant) {
        if let Some(chain) = self.chains.get_mut(c) {
            Self::pass_chain(
                chain,
                &mut frame,
                t,
                &mut Buses {
                    buses: &self.buses,
                    stations: &mut self.stations,
                },
                false,
            );
        }
    }
}
