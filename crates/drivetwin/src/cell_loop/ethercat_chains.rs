//! EtherCAT chains on the loop: a frame from the master passes the chain's slaves and goes
//! back out at once; a slave that is a CANopen drive of the cell as well reaches that drive.

use std::io;
use std::time::{Duration, Instant, SystemTime};

use mio::{Events, Token};

use super::turn_log::Part;
use super::{cell_time, CellLoop, ChainState, FIRST_CHAIN, FRAMES_PER_TURN};
use crate::cell::can_cell::CanCell;
use crate::cell::link::{At, FrontLink};
use crate::cell::wire_faults::Verdict;

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
        // A loop that spins gives no CPU to a master when it sleeps: it exchanges at once.
        let may_defer = !self.busy_poll;
        for turn in 0..=FRAMES_PER_TURN {
            let Some(chain) = self.chains.get_mut(c) else {
                break;
            };
            if turn == FRAMES_PER_TURN {
                // More may wait: read on next turn, after the other sockets.
                self.chains_to_read |= chain_bit(c);
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
            self.turns.mark(Part::Pass);
            let now = Instant::now();
            // The frame's time is its arrival at the wire where the kernel stamped it: a
            // frame that waited while the loop was busy or held off its CPU came before the
            // SYNC0 events that fell due meanwhile, as on a device.
            let arrived = chain.socket().arrived().map_or(now, |a| arrival(a, now));
            let t = cell_time(self.origin, chain.pace.frame(arrived));
            // The exchange after the frame before comes first, at that frame's time.
            if Self::settle(chain, &mut self.cell) {
                self.turns.exchange();
                self.turns.exchange_on_path();
            }
            self.turns.mark(Part::Exchange);
            match chain.link.receive(At::on_clock(t), f) {
                Verdict::Pass => {}
                // Lost, or held by the chain's link until its time.
                Verdict::Lost | Verdict::Corrupt | Verdict::Delay(_) => continue,
            }
            let own = !chain.chain.has_bus_drives();
            shared |= !own;
            if chain.chain.wake_by().is_some_and(|w| w <= t) {
                // A frame carries what the devices posted by its arrival: a SYNC0 event that
                // fell due before it runs first (a master's DC loop and its following-error
                // check read those inputs), and a step past its grace (`STEP_GRACE`). A
                // step still within its grace is the frame's own: its exchange steps the
                // drive to the frame's time after the answer, as the frame is the free-run
                // time base. Other chains, the CAN drives and the timers wait until after
                // the answer.
                chain.chain.poll_with(t, &mut self.cell);
                self.turns.poll();
                self.turns.mark(Part::CatchUp);
                Self::hand_off_saves(chain, &mut self.cell);
            }
            if Self::pass_chain(chain, f, t, &mut self.cell, own && may_defer) {
                self.turns.exchange();
            }
            // A late answer held the master's next frame back ([`SlaveChain::answered`]).
            let answered = cell_time(self.origin, Instant::now());
            chain.chain.answered(t, answered);
            self.turns.frame();
            self.turns.mark(Part::Pass);
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
                self.cell.poll(b, t, &mut out);
                self.drives_sent(b, now, &mut out);
                self.out = out;
            }
        }
    }

    /// One frame through chain `chain` and back out on its socket; then the chain's devices
    /// take their outputs and run their drives, while the answer is already on its way. With
    /// `defer`, that exchange waits for [`settle`](Self::settle): the loop runs it before
    /// anything reads the chain again, or between the master's frames, so that a master
    /// sharing the loop's CPU runs first. It runs at the frame's time `t` either way: a
    /// drive's step, its outputs and inputs do not depend on when the loop gets to it.
    /// A chain whose drives are CAN drives of the cell as well exchanges at once: their
    /// TPDOs go out on the bus in real time. Whether the exchange ran.
    pub(super) fn pass_chain(
        chain: &mut ChainState,
        f: &mut [u8],
        t: od::Instant,
        buses: &mut CanCell,
        defer: bool,
    ) -> bool {
        if chain.chain.pass_with(t, f, buses).forward() {
            // Out on the wire, then copied to the trace; a failed send is logged by the
            // interface.
            let _ = chain.link.transmit(At::on_clock(t), f);
        }
        if defer {
            chain.pace.defer(t);
            false
        } else {
            chain.chain.exchange_with(t, buses);
            Self::hand_off_saves(chain, buses);
            true
        }
    }

    /// Runs chain `chain`'s pending exchange, if any ([`pass_chain`](Self::pass_chain));
    /// whether one ran.
    fn settle(chain: &mut ChainState, buses: &mut CanCell) -> bool {
        let pending = chain.pace.take();
        if let Some(t) = pending {
            let start = Instant::now();
            chain.chain.exchange_with(t, buses);
            chain.pace.exchanged(start.elapsed());
            Self::hand_off_saves(chain, buses);
        }
        pending.is_some()
    }

    /// The saves chain `chain`'s slaves asked for go to its saver, which writes each file
    /// beside the loop (one of a drive that is a CANopen node as well on the loop, as its
    /// node saves); each save done goes back to its slave, whose held CoE reply goes out.
    /// Run after every exchange and poll of the chain, where a slave serves its mailbox.
    pub(super) fn hand_off_saves(chain: &mut ChainState, buses: &mut CanCell) {
        while let Some(req) = chain.chain.take_save() {
            chain.saver.start(req.slave, req.job);
        }
        while let Some((slave, result)) = chain.saver.finished() {
            chain.chain.saved(slave, result, buses);
        }
    }

    /// Runs every chain's pending exchange: before a turn's timers, events and requests
    /// read the devices, and before the loop stops.
    pub(super) fn settle_chains(&mut self) {
        for chain in &mut self.chains {
            if Self::settle(chain, &mut self.cell) {
                self.turns.exchange();
            }
        }
    }

    /// The SYNC0 events every chain's devices have run so far ([`turn_log`](super::turn_log)).
    pub(super) fn sync0_total(&self) -> u64 {
        self.chains
            .iter()
            .flat_map(|c| (0..c.chain.len()).filter_map(|i| c.chain.device(i)))
            .map(|d| d.sync_monitor().events)
            .sum()
    }

    /// A frame a `delay` fault held back arrives at chain `c` at `t`.
    pub(super) fn ethercat_frame(&mut self, c: usize, mut frame: Vec<u8>, t: od::Instant) {
        if let Some(chain) = self.chains.get_mut(c) {
            let buses = &mut self.cell;
            Self::settle(chain, buses);
            let _ = Self::pass_chain(chain, &mut frame, t, buses, false);
        }
    }
}

/// The instant of the loop's clock at which a frame the kernel stamped `stamp` (wall-clock
/// time) arrived, read at `now`: at most `now`.
fn arrival(stamp: SystemTime, now: Instant) -> Instant {
    let waited = SystemTime::now()
        .duration_since(stamp)
        .unwrap_or(Duration::ZERO);
    now.checked_sub(waited).unwrap_or(now)
}

/// Chain `c`'s bit in the loop's set of chains to read on: chains from the 32nd on share the
/// last bit (each of them is then read, and one with nothing waiting reads nothing), so that
/// none is left unread.
pub(super) fn chain_bit(c: usize) -> u32 {
    1 << c.min(31)
}
