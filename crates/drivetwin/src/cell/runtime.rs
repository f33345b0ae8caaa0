//! The runtime owns the clock: real time on tokio, or a virtual clock that jumps from one
//! deadline to the next, so the same cell and inputs give the same frames bit for bit.

use std::future::Future;
use std::time::Duration;

use canopen::CanFrame;
use od::Instant;

use tokio::sync::mpsc;

use crate::can::bus::Bus;
use crate::cell::ci_console::ConsoleRequest;
use crate::cell::Cell;

/// Runs `cell` on `bus` in real time until `shutdown` completes; lines typed at a drive's CI
/// terminal come in on `console`.
pub async fn run_realtime(
    mut cell: Cell,
    bus: Bus,
    mut console: Option<mpsc::Receiver<ConsoleRequest>>,
    shutdown: impl Future<Output = ()>,
) {
    let mut port = bus.port();
    let start = tokio::time::Instant::now();
    let now = || Instant::from_nanos(u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX));
    let mut out: Vec<CanFrame> = Vec::with_capacity(256);
    cell.boot(now(), &mut out);
    tokio::pin!(shutdown);
    loop {
        for f in out.drain(..) {
            port.send(f);
        }
        let wake = cell
            .deadline()
            .map(|d| start + Duration::from_nanos(d.as_nanos()))
            .unwrap_or_else(|| tokio::time::Instant::now() + Duration::from_secs(3600));
        tokio::select! {
            biased;
            _ = &mut shutdown => break,
            f = port.recv() => match f {
                Some(bf) => {
                    cell.on_frame(now(), &bf.frame, &mut out);
                }
                None => break,
            },
            req = next_request(&mut console) => match req {
                Some(req) => {
                    let reply = cell
                        .ci_line(req.drive, now(), &req.line, &mut out)
                        .unwrap_or_else(canopen::ci_terminal::syntax_error);
                    // The client may have gone meanwhile: nothing to answer then.
                    let _ = req.reply.send(reply);
                }
                None => console = None,
            },
            _ = tokio::time::sleep_until(wake) => {
                cell.poll(now(), &mut out);
            }
        }
    }
}

/// The next console line, or never without a console.
async fn next_request(
    console: &mut Option<mpsc::Receiver<ConsoleRequest>>,
) -> Option<ConsoleRequest> {
    match console {
        Some(rx) => rx.recv().await,
        None => std::future::pending().await,
    }
}

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
