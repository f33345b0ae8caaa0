//! The virtual clock: it jumps from one deadline to the next, so the same cell and inputs give
//! the same frames bit for bit. Real time is the cell loop's ([`crate::cell_loop`]).

use std::time::Duration;

use canopen::CanFrame;
use od::time::earliest;
use od::Instant;

use crate::cell::can_segment::CanSegment;
use crate::cell::OnBus;
use crate::ecat::chain::SlaveChain;
use crate::modbus_tcp::cell_drive::ModbusDrive;
use crate::serial::line::VirtualLine;
use crate::serial::LineDrives;

/// Runs `segment` on the virtual clock from 0 to `until`, feeding `inputs` (sorted by time) as
/// frames from outside the segment; every frame on the bus goes to `sink` with its virtual time.
/// A drive's load FMU that fails stops the run there ([`CanSegment::load_failure`]).
pub fn run_virtual(
    segment: &mut CanSegment,
    inputs: &[(Duration, CanFrame)],
    until: Duration,
    sink: &mut dyn FnMut(Duration, &CanFrame),
) {
    let to_instant =
        |d: Duration| Instant::from_nanos(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
    let end = to_instant(until);
    let mut out = Vec::with_capacity(256);
    let mut now = Instant::ZERO;
    segment.boot(now, &mut out);
    let mut next_input = 0;
    let mut stuck = 0u32;
    loop {
        for f in out.drain(..) {
            sink(Duration::from_nanos(now.as_nanos()), &f);
        }
        if segment.load_failure().is_some() {
            break;
        }
        let input_at = inputs.get(next_input).map(|(t, _)| to_instant(*t));
        let wake = match (segment.deadline(), input_at) {
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
                segment.on_frame(now, f, &mut out);
            }
            next_input += 1;
        } else {
            segment.poll(now, &mut out);
        }
    }
}

/// Something from outside the cell, at a time on the virtual clock.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Input {
    /// A frame on the cell's CAN bus.
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
    /// A frame on the cell's CAN bus (a drive's, or an input's).
    Can(&'a CanFrame),
    /// The answers of `modbus[drive]` to its latest input.
    Modbus { drive: usize, bytes: &'a [u8] },
    /// A frame of chain `chain` back to its master, as it left the last slave.
    Ethercat { chain: usize, frame: &'a [u8] },
    /// Bytes of serial line `line` that have crossed to its host by then.
    Serial { line: usize, bytes: &'a [u8] },
}

/// The segment's stations as a virtual serial line reaches them (bus 0).
struct SegmentLineDrives<'a> {
    segment: &'a mut CanSegment,
    out: &'a mut Vec<CanFrame>,
}

impl LineDrives for SegmentLineDrives<'_> {
    fn access(&mut self, at: OnBus, now: Instant, f: &mut dyn FnMut(&mut dyn od::ObjectAccess)) {
        if at.bus == 0 {
            self.segment.local_access(at.drive, now, self.out, f);
        }
    }
}

/// Runs the CAN drives of `segment`, the Modbus drives `modbus` and the EtherCAT chains `chains`
/// on one virtual clock from 0 to `until`, feeding `inputs` (sorted by time); everything the
/// cell sends goes to `sink` with its virtual time. At one instant the order is fixed: Modbus
/// cycles, then the CAN drives' timers, then the chains' timers, then the input, so the same
/// cell and inputs give the same outputs bit for bit. A slave whose drive is a CANopen drive
/// as well finds it in `segment` (bus 0).
pub fn run_virtual_mixed(
    segment: &mut CanSegment,
    modbus: &mut [ModbusDrive],
    chains: &mut [SlaveChain],
    inputs: &[(Duration, Input)],
    until: Duration,
    sink: &mut dyn FnMut(Duration, Output<'_>),
) {
    run_virtual_lines(segment, modbus, chains, &mut [], inputs, until, sink);
}

/// [`run_virtual_mixed`] with the serial lines `lines` (built by
/// `drivetwin::vendors::VENDORS.serial_lines`, [`crate::serial::SerialLines`]) on the same clock: their wire times, frame ends
/// and answers are deadlines like the others; at one instant they come after the chains and
/// before the input. A line's answers go to `sink` when they have crossed.
pub fn run_virtual_lines(
    segment: &mut CanSegment,
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
    segment.boot(now, &mut out);
    for c in chains.iter_mut() {
        c.boot_with(now, segment);
    }
    for m in modbus.iter_mut() {
        m.open_connection(now);
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
            .fold(earliest(segment.deadline(), input_at), |acc, m| {
                earliest(acc, Some(m.next_cycle()))
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
        for m in modbus.iter_mut() {
            m.cycle(now);
        }
        if segment.deadline().is_some_and(|d| d <= now) {
            segment.poll(now, &mut out);
        }
        for c in chains.iter_mut() {
            if c.deadline().is_some_and(|d| d <= now) {
                c.poll_with(now, segment);
            }
        }
        for (i, l) in lines.iter_mut().enumerate() {
            if l.deadline().is_some_and(|d| d <= now) {
                crossed.clear();
                let mut drives = SegmentLineDrives {
                    segment,
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
                    segment.on_frame(now, f, &mut out);
                }
                Some((_, Input::Modbus { drive, bytes })) => {
                    if let Some(m) = modbus.get_mut(*drive) {
                        answer.clear();
                        if let Err(reason) = m.answer(bytes, now, &mut answer) {
                            tracing::warn!(drive, %reason, "Modbus input closes the connection");
                            m.close_connection_because(reason);
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
                        if c.on_frame_with(now, &mut frame, segment).forward() {
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
                            segment.poll(now, &mut out);
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
