//! One frame through several slaves, as it travels through a line of ESCs.

use super::*;

/// Pass one Ethernet frame through `slaves` in ring order, as the frame travels through a
/// line of ESCs: auto-increment addresses and working counters add up. Returns the first
/// slave's outcome (a frame one slave drops goes no further).
pub fn process_chain(slaves: &mut [Esc<'_>], now: Instant, frame: &mut [u8]) -> FrameOutcome {
    let mut first = None;
    for s in slaves.iter_mut() {
        let o = s.process(now, frame);
        let outcome = *first.get_or_insert(o);
        if !o.forward() {
            return outcome;
        }
    }
    first.unwrap_or(FrameOutcome::Processed { datagrams: 0 })
}

/// [`process_chain`] with one hook per slave (`hooks[i]` for `slaves[i]`; slaves without a
/// hook accept every transition).
pub fn process_chain_with<H: AlHook>(
    slaves: &mut [Esc<'_>],
    hooks: &mut [H],
    now: Instant,
    frame: &mut [u8],
) -> FrameOutcome {
    let mut first = None;
    let mut hooks = hooks.iter_mut();
    for s in slaves.iter_mut() {
        let o = match hooks.next() {
            Some(h) => s.process_with(now, frame, h),
            None => s.process(now, frame),
        };
        let outcome = *first.get_or_insert(o);
        if !o.forward() {
            return outcome;
        }
    }
    first.unwrap_or(FrameOutcome::Processed { datagrams: 0 })
}
