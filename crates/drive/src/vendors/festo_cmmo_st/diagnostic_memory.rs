//! The diagnostic memory (manual §7.1.3, Tab. 7.5/7.6, PNU 200…204): a ring of 200 entries,
//! the newest overwriting the oldest, read newest first (subindex 1 = newest).
//!
//! Each entry holds the event type (PNU 200), the diagnostic number (PNU 201), the time stamp
//! in ms since power-on (PNU 202, the device's own clock, wrapping at 2³² ms) and the additional
//! information (PNU 203, always 0 here: it is for Festo service). The entry counter and the
//! message text are not visible over FHPP; the counter is kept (it is not reset by a clear).
//!
//! A start-up event 3Dh (type 07h "switch-on") is written at power-on, after a clear and when
//! the time stamp wraps, but not when the newest entry already is one (App. D 3Dh).

use super::diagnostics::code;

/// Capacity of the memory (§7.1.3).
pub const CAPACITY: usize = 200;
/// PNU 201 of an empty (invalid) entry.
pub const INVALID_NUMBER: u16 = 0xFFFF;

/// PNU 200: the type of an entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EventType {
    /// 00h: "no fault (or the message has been deleted)". Decision: written when a logged
    /// fault goes (acknowledged, or its cause gone for a warning-free fault), the outgoing
    /// counterpart of 01h — the manual's "new / existing events" (Tab. B.4 PNU 200…299).
    Gone,
    /// 01h: a new fault.
    Fault,
    /// 05h: a warning.
    Warning,
    /// 07h: switch-on (the 3Dh start-up event).
    SwitchOn,
    /// 09h: an information (PNU 246 bit 6). Decision: logged like the others although §7.1.2
    /// says information is shown only by FCT and the web server: PNU 200 defines the type.
    Information,
}

impl EventType {
    /// The PNU 200 value.
    pub const fn value(self) -> u8 {
        match self {
            EventType::Gone => 0x00,
            EventType::Fault => 0x01,
            EventType::Warning => 0x05,
            EventType::SwitchOn => 0x07,
            EventType::Information => 0x09,
        }
    }
}

/// One entry as PNU 200…203 show it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Entry {
    pub event: EventType,
    /// Diagnostic number (PNU 201).
    pub number: u16,
    /// Time stamp \[ms since power-on\] (PNU 202).
    pub time_ms: u32,
    /// Additional information (PNU 203).
    pub info: u32,
    /// Running counter (not readable over FHPP; survives a clear).
    pub counter: u32,
}

/// The ring buffer.
#[derive(Debug, Clone)]
pub struct DiagnosticMemory {
    entries: [Option<Entry>; CAPACITY],
    /// Slot of the next write.
    head: usize,
    len: usize,
    counter: u32,
    /// Time stamp of the last write, to detect the 32-bit wrap.
    last_ms: u32,
}

impl Default for DiagnosticMemory {
    fn default() -> Self {
        DiagnosticMemory {
            entries: [None; CAPACITY],
            head: 0,
            len: 0,
            counter: 0,
            last_ms: 0,
        }
    }
}

impl DiagnosticMemory {
    /// Power-on: an empty memory with the start-up event at `time_ms`.
    pub fn power_on(time_ms: u32) -> Self {
        let mut m = DiagnosticMemory::default();
        m.start_up(time_ms);
        m
    }

    /// Number of valid entries (PNU 204:4).
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Entry `n` counted from the newest (0 = newest = PNU subindex 1).
    pub fn get(&self, n: usize) -> Option<&Entry> {
        if n >= self.len {
            return None;
        }
        let slot = (self.head + CAPACITY - 1 - n) % CAPACITY;
        self.entries.get(slot)?.as_ref()
    }

    /// Entries, newest first.
    pub fn iter(&self) -> impl Iterator<Item = &Entry> + '_ {
        (0..self.len).filter_map(move |n| self.get(n))
    }

    /// Writes an entry at `time_ms`. A time stamp smaller than the previous one means the
    /// 32-bit millisecond clock wrapped: a start-up event goes first (PNU 202).
    pub fn log(&mut self, event: EventType, number: u16, time_ms: u32) {
        if time_ms < self.last_ms {
            self.start_up(time_ms);
        }
        self.push(event, number, time_ms);
    }

    /// Clears the memory (PNU 204:3 = 1) and writes the start-up event; the counter runs on.
    pub fn clear(&mut self, time_ms: u32) {
        self.entries = [None; CAPACITY];
        self.head = 0;
        self.len = 0;
        self.start_up(time_ms);
    }

    /// The clock reached `time_ms` (called every cycle): writes the wrap event when it wrapped.
    pub fn tick(&mut self, time_ms: u32) {
        if time_ms < self.last_ms {
            self.start_up(time_ms);
        }
        self.last_ms = time_ms;
    }

    fn start_up(&mut self, time_ms: u32) {
        let newest_is_start_up = self
            .get(0)
            .is_some_and(|e| e.number == u16::from(code::START_UP));
        if newest_is_start_up {
            self.last_ms = time_ms;
            return;
        }
        self.push(EventType::SwitchOn, u16::from(code::START_UP), time_ms);
    }

    fn push(&mut self, event: EventType, number: u16, time_ms: u32) {
        self.counter = self.counter.wrapping_add(1);
        if let Some(slot) = self.entries.get_mut(self.head) {
            *slot = Some(Entry {
                event,
                number,
                time_ms,
                info: 0,
                counter: self.counter,
            });
        }
        self.head = (self.head + 1) % CAPACITY;
        self.len = (self.len + 1).min(CAPACITY);
        self.last_ms = time_ms;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn newest_first_and_ring_overwrite() {
        let mut m = DiagnosticMemory::power_on(0);
        for i in 0..250u16 {
            m.log(EventType::Fault, i, u32::from(i) + 1);
        }
        assert_eq!(m.len(), CAPACITY);
        assert_eq!(m.get(0).map(|e| e.number), Some(249));
        assert_eq!(m.get(199).map(|e| e.number), Some(50));
        assert!(m.get(200).is_none());
        assert_eq!(m.get(0).map(|e| e.counter), Some(251));
    }

    /// FHPP-DIAG-04: PNU 204:3 clears and writes 3Dh; not twice in a row.
    #[test]
    fn clear_writes_one_start_up_event_and_keeps_the_counter() {
        let mut m = DiagnosticMemory::power_on(0);
        m.log(EventType::Warning, 0x37, 5);
        m.clear(10);
        assert_eq!(m.len(), 1);
        let e = m.get(0).copied().unwrap();
        assert_eq!(
            (e.event, e.number, e.time_ms, e.counter),
            (EventType::SwitchOn, 0x3D, 10, 3)
        );
        m.clear(11);
        assert_eq!(m.len(), 1, "not written twice in a row");
    }

    /// FHPP-DIAG-04: a start-up event is not written when the newest entry already is one.
    #[test]
    fn no_second_start_up_event_in_a_row() {
        let mut m = DiagnosticMemory::power_on(7);
        m.tick(3); // the clock wrapped: would be a start-up event
        assert_eq!(m.len(), 1);
        m.clear(4);
        assert_eq!(m.len(), 1);
        assert_eq!(m.get(0).map(|e| (e.number, e.time_ms)), Some((0x3D, 4)));
        m.log(EventType::Warning, 0x48, 5);
        m.tick(1);
        assert_eq!(m.len(), 3, "after another entry it is written again");
        assert_eq!(m.get(0).map(|e| e.number), Some(0x3D));
    }

    #[test]
    fn time_stamp_wrap_writes_a_start_up_event() {
        let mut m = DiagnosticMemory::power_on(0);
        m.log(EventType::Fault, 0x2F, u32::MAX - 1);
        m.tick(3);
        assert_eq!(m.get(0).map(|e| (e.number, e.time_ms)), Some((0x3D, 3)));
    }
}
