//! The virtual clock: it jumps from one deadline to the next, so the same cell and inputs give
//! the same frames bit for bit. Real time is the cell loop's ([`crate::cell_loop`]).
//!
//! What the cell file plans for the drives is on the cell's timeline
//! ([`CanCell::carry_out_plans`]): at one instant the changes due come first, before the
//! Modbus cycles and the buses' timers, as in the cell loop.

use std::time::Duration;

use canopen::CanFrame;
use od::time::earliest;
use od::Instant;

use crate::cell::can_cell::CanCell;
use crate::cell::stations::StationId;
use crate::ecat::chain::SlaveChain;
use crate::modbus_tcp::cell_drive::ModbusDrive;
use crate::serial::line::VirtualLine;
use crate::serial::LineDrives;

/// Runs the buses of `cell` on the virtual clock from 0 to `until`, feeding `inputs` (sorted by
/// time) as frames from outside the cell on its first bus; every frame on a bus goes to `sink`
/// with its virtual time. A drive's load FMU that fails stops the run there
/// ([`CanCell::load_failure`]).
pub fn run_virtual(
    cell: &mut CanCell,
    inputs: &[(Duration, CanFrame)],
    until: Duration,
    sink: &mut dyn FnMut(Duration, &CanFrame),
) {
    let to_instant =
        |d: Duration| Instant::from_nanos(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
    let end = to_instant(until);
    let mut out = Vec::with_capacity(256);
    let mut now = Instant::ZERO;
    boot(cell, now, &mut out);
    let mut next_input = 0;
    let mut stuck = 0u32;
    loop {
        for f in out.drain(..) {
            sink(Duration::from_nanos(now.as_nanos()), &f);
        }
        if cell.load_failure().is_some() {
            break;
        }
        let input_at = inputs.get(next_input).map(|(t, _)| to_instant(*t));
        let wake = match (cell.deadline(), input_at) {
            (Some(a), Some(b)) => a.min(b),
            (Some(a), None) => a,
            (None, Some(b)) => b,
            (None, None) => break,
        };
        if wake > end {
            break;
        }
        // A deadline that does not move would spin forever: give up loudly instead.
        stuck = if wake <= now { stuck + 1 } else { 0 };
        if stuck > 10_000 {
            tracing::error!(at = ?now, "virtual clock stuck on a deadline that does not advance");
            break;
        }
        now = wake.max(now);
        if input_at == Some(wake) {
            if let Some((_, f)) = inputs.get(next_input) {
                sink(Duration::from_nanos(now.as_nanos()), f);
                cell.on_frame(0, now, f, &mut out);
            }
            next_input += 1;
        } else {
            cell.carry_out_plans(now);
            poll_due(cell, now, &mut out);
        }
    }
}

/// Boots the drives of every bus, in bus order.
fn boot(cell: &mut CanCell, now: Instant, out: &mut Vec<CanFrame>) {
    for b in 0..cell.buses.len() {
        cell.boot(b, now, out);
    }
}

/// Runs the timers of every bus due by `now`, in bus order.
fn poll_due(cell: &mut CanCell, now: Instant, out: &mut Vec<CanFrame>) {
    for b in 0..cell.buses.len() {
        if cell.deadline_of(b).is_some_and(|d| d <= now) {
            cell.poll(b, now, out);
        }
    }
}

/// Something from outside the cell, at a time on the virtual clock.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Input {
    /// A frame on the cell's (first) CAN bus.
    Can(CanFrame),
    /// Bytes on the Modbus TCP connection of `modbus[drive]`.
    Modbus { drive: usize, bytes: Vec<u8> },
    /// An Ethernet frame from the master of EtherCAT chain `chain`.
    Ethercat { chain: usize, frame: Vec<u8> },
    /// Bytes the host writes on serial line `line` (RS232 / RS485), at once; they cross the
    /// wire at its bit rate.
    Serial { line: usize, bytes: Vec<u8> },
}

/// What the cell sent, at a time on the virtual clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Output<'a> {
    /// A frame on one of the cell's CAN buses (a drive's, or an input's).
    Can(&'a CanFrame),
    /// The answers of `modbus[drive]` to its latest input.
    Modbus { drive: usize, bytes: &'a [u8] },
    /// A frame of chain `chain` back to its master, as it left the last slave.
    Ethercat { chain: usize, frame: &'a [u8] },
    /// Bytes of serial line `line` that have crossed to its host by then.
    Serial { line: usize, bytes: &'a [u8] },
}

/// The cell's stations as a virtual serial line reaches them.
struct CellLineDrives<'a> {
    cell: &'a mut CanCell,
    out: &'a mut Vec<CanFrame>,
}

impl LineDrives for CellLineDrives<'_> {
    fn access(
        &mut self,
        at: StationId,
        now: Instant,
        f: &mut dyn FnMut(&mut dyn od::ObjectAccess),
    ) {
        self.cell.local_access(at, now, self.out, f);
    }
}

/// Runs the CAN buses of `cell`, the Modbus drives `modbus` and the EtherCAT chains `chains`
/// on one virtual clock from 0 to `until`, feeding `inputs` (sorted by time); everything the
/// cell sends goes to `sink` with its virtual time. At one instant the order is fixed: the
/// planned changes due (the cell's timeline, every station's), Modbus cycles, then the CAN buses' timers (in bus order), then the chains' timers, then the input,
/// so the same cell and inputs give the same outputs bit for bit. The chains join the cell
/// first ([`SlaveChain::join_cell`]): their own drives become stations of its list, and a slave
/// whose drive is a CANopen node of a bus names that very station.
pub fn run_virtual_mixed(
    cell: &mut CanCell,
    modbus: &mut [ModbusDrive],
    chains: &mut [SlaveChain],
    inputs: &[(Duration, Input)],
    until: Duration,
    sink: &mut dyn FnMut(Duration, Output<'_>),
) {
    run_virtual_lines(cell, modbus, chains, &mut [], inputs, until, sink);
}

/// [`run_virtual_mixed`] with the serial lines `lines` (built by
/// `drivetwin::vendors::VENDORS.serial_lines`, [`crate::serial::SerialLines`]) on the same clock: their wire times, frame ends
/// and answers are deadlines like the others; at one instant they come after the chains and
/// before the input. A line's answers go to `sink` when they have crossed.
pub fn run_virtual_lines(
    cell: &mut CanCell,
    modbus: &mut [ModbusDrive],
    chains: &mut [SlaveChain],
    lines: &mut [VirtualLine],
    inputs: &[(Duration, Input)],
    until: Duration,
    sink: &mut dyn FnMut(Duration, Output<'_>),
) {
    let mut crossed = Vec::with_capacity(256);
    let to_instant =
        |d: Duration| Instant::from_nanos(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
    let at = |now: Instant| Duration::from_nanos(now.as_nanos());
    let end = to_instant(until);
    let mut out = Vec::with_capacity(256);
    let mut answer = Vec::with_capacity(256);
    let mut frame = Vec::with_capacity(crate::ecat::MAX_FRAME);
    let mut now = Instant::ZERO;
    for c in chains.iter_mut() {
        c.join_cell(cell);
    }
    // The Modbus drives become stations of the cell (those that joined before keep theirs).
    for m in modbus.iter_mut() {
        m.join(&mut cell.stations);
    }
    boot(cell, now, &mut out);
    for c in chains.iter_mut() {
        c.boot_with(now, cell);
    }
    for m in modbus.iter_mut() {
        m.open_connection(now, &mut cell.stations);
    }
    let mut next_input = 0;
    let mut stuck = 0u32;
    loop {
        for f in out.drain(..) {
            sink(at(now), Output::Can(&f));
        }
        let input_at = inputs.get(next_input).map(|(t, _)| to_instant(*t));
        let wake = modbus
            .iter()
            .fold(earliest(cell.deadline(), input_at), |acc, m| {
                earliest(acc, m.next_cycle(&cell.stations))
            });
        let wake = chains
            .iter()
            .fold(wake, |acc, c| earliest(acc, c.deadline()));
        let wake = lines
            .iter()
            .fold(wake, |acc, l| earliest(acc, l.deadline()));
        let Some(wake) = wake else {
            break;
        };
        if wake > end {
            break;
        }
        // A deadline that does not move would spin forever: give up loudly instead.
        stuck = if wake <= now { stuck + 1 } else { 0 };
        if stuck > 10_000 {
            tracing::error!(at = ?now, "virtual clock stuck on a deadline that does not advance");
            break;
        }
        now = wake.max(now);
        cell.carry_out_plans(now);
        for m in modbus.iter_mut() {
            m.cycle(now, &mut cell.stations);
        }
        poll_due(cell, now, &mut out);
        for c in chains.iter_mut() {
            if c.deadline().is_some_and(|d| d <= now) {
                c.poll_with(now, cell);
                save_at_once(c, cell);
            }
        }
        for (i, l) in lines.iter_mut().enumerate() {
            if l.deadline().is_some_and(|d| d <= now) {
                crossed.clear();
                let mut drives = CellLineDrives {
                    cell,
                    out: &mut out,
                };
                l.due(now, &mut drives, &mut crossed);
                if !crossed.is_empty() {
                    sink(
                        at(now),
                        Output::Serial {
                            line: i,
                            bytes: &crossed,
                        },
                    );
                }
            }
        }
        if input_at == Some(wake) {
            match inputs.get(next_input) {
                Some((_, Input::Can(f))) => {
                    sink(at(now), Output::Can(f));
                    cell.on_frame(0, now, f, &mut out);
                }
                Some((_, Input::Modbus { drive, bytes })) => {
                    if let Some(m) = modbus.get_mut(*drive) {
                        answer.clear();
                        if let Err(reason) = m.answer(bytes, now, &mut answer, &mut cell.stations) {
                            tracing::warn!(drive, %reason, "Modbus input closes the connection");
                            m.close_connection_because(reason, &mut cell.stations);
                        }
                        sink(
                            at(now),
                            Output::Modbus {
                                drive: *drive,
                                bytes: &answer,
                            },
                        );
                    }
                }
                Some((_, Input::Ethercat { chain, frame: f })) => {
                    if let Some(c) = chains.get_mut(*chain) {
                        frame.clear();
                        frame.extend_from_slice(f);
                        let shared = c.has_bus_drives();
                        let forward = c.on_frame_with(now, &mut frame, cell).forward();
                        save_at_once(c, cell);
                        if forward {
                            sink(
                                at(now),
                                Output::Ethercat {
                                    chain: *chain,
                                    frame: &frame,
                                },
                            );
                        }
                        if shared {
                            // As the cell loop does: the CANopen side looks at once.
                            for b in 0..cell.buses.len() {
                                cell.poll(b, now, &mut out);
                            }
                        }
                    }
                }
                Some((_, Input::Serial { line, bytes })) => {
                    if let Some(l) = lines.get_mut(*line) {
                        l.input(now, bytes);
                    }
                }
                None => {}
            }
            next_input += 1;
        }
    }
}

/// The saves the chain's slaves asked for, written at once on the virtual clock (no time
/// passes on it while a file is written, and the same inputs give the same frames).
fn save_at_once(chain: &mut SlaveChain, cell: &mut CanCell) {
    while let Some(req) = chain.take_save() {
        let result = req.job.run();
        chain.saved(req.slave, result, cell);
    }
}
