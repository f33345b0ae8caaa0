//! The virtual clock: it jumps from one deadline to the next, so the same cell and inputs give
//! the same frames bit for bit. Real time is the cell loop's ([`crate::cell::poll_loop`]).

use std::time::Duration;

use canopen::CanFrame;
use od::Instant;

use crate::cell::Cell;

/// Runs `cell` on the virtual clock from 0 to `until`, feeding `inputs` (sorted by time) as
/// frames from outside the cell; every frame on the bus goes to `sink` with its virtual time.
pub fn run_virtual(
    cell: &mut Cell,
    inputs: &[(Duration, CanFrame)],
    until: Duration,
    sink: &mut dyn FnMut(Duration, &CanFrame),
) {
    let to_instant =
        |d: Duration| Instant::from_nanos(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
    let end = to_instant(until);
    let mut out = Vec::with_capacity(256);
    let mut now = Instant::ZERO;
    cell.boot(now, &mut out);
    let mut next_input = 0;
    let mut stuck = 0u32;
    loop {
        for f in out.drain(..) {
            sink(Duration::from_nanos(now.as_nanos()), &f);
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
                cell.on_frame(now, f, &mut out);
            }
            next_input += 1;
        } else {
            cell.poll(now, &mut out);
        }
    }
}
