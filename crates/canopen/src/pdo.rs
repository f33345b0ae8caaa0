//! Process data objects at run time (CiA 301 §7.2.2): RPDOs received into the dictionary,
//! TPDOs sampled from it on SYNC, on change (with the inhibit time and, where the personality
//! has them, transmit masks), on an event timer or cyclically.

use core::time::Duration;

use heapless::Vec;
use od::pdo_rules::MapEntry;
use od::{Cia301Options, Instant, ObjectAccess};

use crate::CanFrame;

/// Most PDOs per direction.
pub const MAX_PDOS: usize = 8;
/// Most entries per PDO mapping.
pub const MAX_ENTRIES: usize = 8;
/// How often event-driven TPDOs are sampled for changes.
pub const SAMPLE_PERIOD: Duration = Duration::from_millis(1);

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Mapped {
    index: u16,
    sub: u8,
    bytes: u8,
    dummy: bool,
}

#[derive(Debug, Clone, Default)]
struct Config {
    cob: u16,
    valid: bool,
    ttype: u8,
    inhibit_100us: u16,
    event_ms: u16,
    map: Vec<Mapped, MAX_ENTRIES>,
    len: usize,
}

impl Config {
    fn load(od: &dyn ObjectAccess, comm: u16) -> Option<Self> {
        let cob = od.read_u32(comm, 1)?;
        let mut cfg = Config {
            cob: (cob & 0x7FF) as u16,
            valid: cob & 0x8000_0000 == 0,
            ttype: od.read_u8(comm, 2).unwrap_or(255),
            inhibit_100us: od.read_u16(comm, 3).unwrap_or(0),
            event_ms: od.read_u16(comm, 5).unwrap_or(0),
            ..Config::default()
        };
        let n = od.read_u8(comm + 0x200, 0).unwrap_or(0);
        for sub in 1..=n {
            let Some(v) = od.read_u32(comm + 0x200, sub) else {
                break;
            };
            let m = MapEntry::from_u32(v);
            let bytes = m.bits / 8;
            let _ = cfg.map.push(Mapped {
                index: m.index,
                sub: m.sub,
                bytes,
                dummy: m.is_dummy(),
            });
            cfg.len += usize::from(bytes);
        }
        // CiA 301: a PDO without mapping or longer than 8 bytes does not exist.
        if cfg.map.is_empty() || cfg.len > 8 {
            cfg.valid = false;
        }
        Some(cfg)
    }
}

#[derive(Debug, Clone, Default)]
struct Tpdo {
    cfg: Config,
    /// What was sent last (`None` before the first transmission in Operational).
    last: Option<[u8; 8]>,
    last_sent: Option<Instant>,
    /// A change waits for the inhibit time.
    pending: bool,
    sync_count: u8,
    next_event: Option<Instant>,
    /// Transmit mask (bit k gates PDO bit k), all ones without mask objects.
    mask: u64,
}

#[derive(Debug, Clone, Default)]
struct Rpdo {
    cfg: Config,
    /// Synchronous RPDO data waiting for the next SYNC.
    buffered: Option<[u8; 8]>,
}

/// What the PDO layer reports to the node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PdoEvent {
    /// An RPDO arrived shorter than its mapping (EMCY 8210h, CiA 301 §7.2.2.2).
    LengthError { rpdo: u8 },
    /// An RPDO arrived with the right length again after a length error.
    LengthOk { rpdo: u8 },
    /// An RPDO arrived longer than its mapping: processed, EMCY 8220h.
    LengthExceeded { rpdo: u8 },
}

#[derive(Debug, Default)]
pub struct Pdos {
    rx: Vec<Rpdo, MAX_PDOS>,
    tx: Vec<Tpdo, MAX_PDOS>,
    opts: Cia301Options,
    operational: bool,
    next_sample: Option<Instant>,
}

fn sample(od: &dyn ObjectAccess, cfg: &Config) -> [u8; 8] {
    let mut data = [0u8; 8];
    let mut pos = 0usize;
    for m in &cfg.map {
        let n = usize::from(m.bytes);
        if let Some(dst) = data.get_mut(pos..pos + n) {
            if !m.dummy {
                // A mapped object that cannot be read leaves zeros, the frame still goes out.
                let _ = od.read(m.index, m.sub, dst);
            }
        }
        pos += n;
    }
    data
}

impl Pdos {
    pub fn new(opts: Cia301Options) -> Self {
        Pdos {
            opts,
            ..Pdos::default()
        }
    }

    /// Re-reads every PDO's configuration (after a download or an NMT change). TPDO state is
    /// kept for PDOs whose configuration did not change.
    pub fn reload(&mut self, od: &dyn ObjectAccess) {
        let mut i = 0u16;
        while let Some(cfg) = Config::load(od, 0x1400 + i) {
            match self.rx.get_mut(usize::from(i)) {
                Some(r) => {
                    if r.cfg.cob != cfg.cob || r.cfg.valid != cfg.valid || r.cfg.map != cfg.map {
                        r.buffered = None;
                    }
                    r.cfg = cfg;
                }
                None => {
                    if self
                        .rx
                        .push(Rpdo {
                            cfg,
                            buffered: None,
                        })
                        .is_err()
                    {
                        break;
                    }
                }
            }
            i += 1;
        }
        let mut i = 0u16;
        while let Some(cfg) = Config::load(od, 0x1800 + i) {
            let mask = self.mask(od, i);
            match self.tx.get_mut(usize::from(i)) {
                Some(t) => {
                    if t.cfg.cob != cfg.cob
                        || t.cfg.valid != cfg.valid
                        || t.cfg.map != cfg.map
                        || t.cfg.ttype != cfg.ttype
                    {
                        t.last = None;
                        t.pending = false;
                        t.sync_count = 0;
                        t.next_event = None;
                    }
                    t.cfg = cfg;
                    t.mask = mask;
                }
                None => {
                    let t = Tpdo {
                        cfg,
                        mask,
                        ..Tpdo::default()
                    };
                    if self.tx.push(t).is_err() {
                        break;
                    }
                }
            }
            i += 1;
        }
    }

    fn mask(&self, od: &dyn ObjectAccess, n: u16) -> u64 {
        match self.opts.tpdo_transmit_mask_index {
            // `tpdo_transmit_mask_index`: low word = PDO bytes 0–3, high word = bytes 4–7.
            Some(base) => {
                let lo = od.read_u32(base + n, 1).unwrap_or(u32::MAX);
                let hi = od.read_u32(base + n, 2).unwrap_or(u32::MAX);
                u64::from(lo) | (u64::from(hi) << 32)
            }
            None => u64::MAX,
        }
    }

    /// NMT Operational entered or left: TPDO triggers start afresh.
    pub fn set_operational(&mut self, now: Instant, operational: bool) {
        self.operational = operational;
        for t in self.tx.iter_mut() {
            t.last = None;
            t.pending = false;
            t.sync_count = 0;
            t.next_event = None;
            t.last_sent = None;
        }
        for r in self.rx.iter_mut() {
            r.buffered = None;
        }
        self.next_sample = operational.then_some(now);
    }

    /// A frame that may be an RPDO; `None` if it was none of this node's.
    pub fn on_frame(&mut self, frame: &CanFrame, od: &mut dyn ObjectAccess) -> Option<PdoEvent> {
        let cob = frame.cob_id()?;
        if !self.operational || frame.rtr {
            return None;
        }
        let (n, r) = self
            .rx
            .iter_mut()
            .enumerate()
            .find(|(_, r)| r.cfg.valid && r.cfg.cob == cob)?;
        let rpdo = n as u8 + 1;
        let payload = frame.payload();
        if payload.len() < r.cfg.len {
            // CiA 301 §7.2.2.2: a short RPDO is not processed.
            return Some(PdoEvent::LengthError { rpdo });
        }
        let event = if payload.len() > r.cfg.len {
            PdoEvent::LengthExceeded { rpdo }
        } else {
            PdoEvent::LengthOk { rpdo }
        };
        let mut data = [0u8; 8];
        if let (Some(dst), Some(src)) = (data.get_mut(..r.cfg.len), payload.get(..r.cfg.len)) {
            dst.copy_from_slice(src);
        }
        if r.cfg.ttype <= 240 {
            // Synchronous: takes effect at the next SYNC (CiA 301 §7.2.2.2).
            r.buffered = Some(data);
        } else {
            apply(od, &r.cfg, &data);
        }
        Some(event)
    }

    /// A SYNC arrived: buffered RPDOs take effect, synchronous TPDOs are counted and sent.
    pub fn on_sync(
        &mut self,
        now: Instant,
        od: &mut dyn ObjectAccess,
        out: &mut dyn FnMut(CanFrame),
    ) {
        if !self.operational {
            return;
        }
        for r in self.rx.iter_mut() {
            if let Some(data) = r.buffered.take() {
                apply(od, &r.cfg, &data);
            }
        }
        for t in self.tx.iter_mut().filter(|t| t.cfg.valid) {
            match t.cfg.ttype {
                0 => {
                    // Acyclic synchronous: sent at the SYNC after a change.
                    let data = sample(od, &t.cfg);
                    if changed(t, &data) {
                        send(t, now, data, out);
                    }
                }
                n @ 1..=240 => {
                    t.sync_count = t.sync_count.saturating_add(1);
                    if t.sync_count >= n {
                        t.sync_count = 0;
                        let data = sample(od, &t.cfg);
                        send(t, now, data, out);
                    }
                }
                _ => {}
            }
        }
    }

    /// Event-driven and cyclic TPDOs. Returns the next deadline.
    pub fn poll(
        &mut self,
        now: Instant,
        od: &dyn ObjectAccess,
        out: &mut dyn FnMut(CanFrame),
    ) -> Option<Instant> {
        if !self.operational {
            return None;
        }
        let due = self.next_sample.is_some_and(|t| now >= t);
        let cyclic_inhibit = self.opts.tpdo_254_cyclic_inhibit;
        let mut deadline: Option<Instant> = None;
        for t in self
            .tx
            .iter_mut()
            .filter(|t| t.cfg.valid && t.cfg.ttype >= 254)
        {
            let inhibit = Duration::from_micros(u64::from(t.cfg.inhibit_100us) * 100);
            if t.cfg.ttype == 254 && cyclic_inhibit {
                // `tpdo_254_cyclic_inhibit`: FEh sends cyclically, the period is the inhibit time.
                if inhibit.is_zero() {
                    continue;
                }
                let next = t.last_sent.map(|l| l + inhibit).unwrap_or(now);
                if now >= next {
                    let data = sample(od, &t.cfg);
                    send(t, now, data, out);
                    deadline = od::time::earliest(deadline, Some(now + inhibit));
                } else {
                    deadline = od::time::earliest(deadline, Some(next));
                }
                continue;
            }
            if due {
                let data = sample(od, &t.cfg);
                if changed(t, &data) {
                    t.pending = true;
                }
            }
            if let Some(e) = t.next_event {
                if now >= e {
                    t.pending = true;
                }
            }
            if t.pending {
                let ready = t.last_sent.map(|l| l + inhibit).unwrap_or(now);
                if now >= ready {
                    let data = sample(od, &t.cfg);
                    send(t, now, data, out);
                } else {
                    deadline = od::time::earliest(deadline, Some(ready));
                }
            }
            if t.cfg.event_ms > 0 {
                let period = Duration::from_millis(u64::from(t.cfg.event_ms));
                let e = t.last_sent.map(|l| l + period).unwrap_or(now + period);
                t.next_event = Some(e);
                deadline = od::time::earliest(deadline, Some(e));
            }
        }
        let any_event = self.tx.iter().any(|t| {
            t.cfg.valid && (t.cfg.ttype == 255 || (t.cfg.ttype == 254 && !cyclic_inhibit))
        });
        if due {
            self.next_sample = any_event.then(|| now + SAMPLE_PERIOD);
        } else if self.next_sample.is_none() && any_event {
            self.next_sample = Some(now + SAMPLE_PERIOD);
        }
        od::time::earliest(deadline, self.next_sample)
    }
}

fn changed(t: &Tpdo, data: &[u8; 8]) -> bool {
    match t.last {
        None => true,
        Some(last) => (u64::from_le_bytes(last) ^ u64::from_le_bytes(*data)) & t.mask != 0,
    }
}

fn send(t: &mut Tpdo, now: Instant, data: [u8; 8], out: &mut dyn FnMut(CanFrame)) {
    let mut frame = CanFrame::full(t.cfg.cob, data);
    frame.len = t.cfg.len as u8;
    out(frame);
    t.last = Some(data);
    t.last_sent = Some(now);
    t.pending = false;
}

/// Writes RPDO data into the mapped objects, in mapping order; dummies skip bytes.
fn apply(od: &mut dyn ObjectAccess, cfg: &Config, data: &[u8; 8]) {
    let mut pos = 0usize;
    for m in &cfg.map {
        let n = usize::from(m.bytes);
        if !m.dummy {
            if let Some(bytes) = data.get(pos..pos + n) {
                // The mapping was checked when it was made; a value the object refuses now
                // (range) is dropped, as a real device drops it.
                let _ = od.write(m.index, m.sub, bytes);
            }
        }
        pos += n;
    }
}
