//! Process data (the manual's extract kept beside the project, `cmmp-as-1-communication.md`
//! §2): the layout of SM2 (outputs) and SM3 (inputs) and the copy of the mapped objects
//! between the process images and the dictionary.
//!
//! * On Pre-Op → Safe-Op the device takes the PDO assignment (1C12h / 1C13h when the
//!   dictionary has them, else the SII defaults 1600h / 1A00h: the CMMP-AS maps its EtherCAT
//!   process data with the CANopen mapping objects 1600h–1603h / 1A00h–1A03h) and computes
//!   the bit layout of SM2 (outputs) and SM3 (inputs) from the mapping entries. A mapping the
//!   dictionary refuses is refused with 0x0025 (outputs) / 0x0024 (inputs); SM2 / SM3 sizes
//!   that do not match it with 0x001D / 0x001E ([`Esc::check_process_data`]).
//! * PDO assignment and mapping are written in Pre-Op only ([`ethercat::coe::MappingLock`]);
//!   the layout is taken on Pre-Op → Safe-Op, and with it what each frame's copy needs: the
//!   dictionary entry an input reads where its value is the stored bytes (resolved once, not
//!   looked up by index in every cycle), and whether an object lies on whole bytes (copied
//!   as bytes, not bit by bit).

use ethercat::{AlStatusCode, Esc};
use od::dictionary::stored_read_entry;
use od::pdo_rules::{check_map_entry, MapEntry};
use od::{DeviceDescription, Entry, ObjectAccess};

use crate::cell::device_model::Model;

use super::slave::Bound;

/// PDO assignment objects (ETG.1000.6): SM2 (RxPDO) and SM3 (TxPDO).
const RX_ASSIGN: u16 = 0x1C12;
const TX_ASSIGN: u16 = 0x1C13;

/// One mapped object in a process image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MapItem {
    pub index: u16,
    pub sub: u8,
    /// Bit offset in the process image.
    pub offset: usize,
    pub bits: u8,
    /// A dummy entry (RxPDO gap): skipped.
    pub dummy: bool,
}

impl MapItem {
    /// Where the object lies on whole bytes of the image: its first byte and length.
    fn whole_bytes(&self) -> Option<(usize, usize)> {
        (self.offset.is_multiple_of(8) && self.bits.is_multiple_of(8))
            .then(|| (self.offset / 8, usize::from(self.bits / 8)))
    }
}

/// The process-data layout taken on Pre-Op → Safe-Op.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Layout {
    /// SM2, master → device.
    pub outputs: Vec<MapItem>,
    /// SM3, device → master.
    pub inputs: Vec<MapItem>,
    pub output_bytes: u16,
    pub input_bytes: u16,
    /// For each of `inputs`, the entry whose stored bytes are what a read of it returns.
    sources: Sources,
}

/// The entries the inputs read their bytes from ([`stored_read_entry`]), one per input item, in
/// the description they were resolved in; `None` where a read goes through the dictionary's
/// access every time. Two are equal when they name the same entries.
#[derive(Debug, Clone, Default)]
struct Sources {
    desc: Option<&'static DeviceDescription>,
    entries: Vec<Option<&'static Entry>>,
}

impl PartialEq for Sources {
    fn eq(&self, other: &Self) -> bool {
        let same = |a: Option<&'static Entry>, b: Option<&'static Entry>| match (a, b) {
            (Some(a), Some(b)) => core::ptr::eq(a, b),
            (None, None) => true,
            _ => false,
        };
        self.entries.len() == other.entries.len()
            && self
                .entries
                .iter()
                .zip(&other.entries)
                .all(|(a, b)| same(*a, *b))
    }
}

impl Eq for Sources {}

impl Bound<'_> {
    /// The PDO assignment of SM2 or SM3: 1C12h / 1C13h from the dictionary when it has
    /// them, else the SII's defaults.
    pub(super) fn assignment(&self, rx: bool) -> Result<Vec<u16>, ()> {
        let index = if rx { RX_ASSIGN } else { TX_ASSIGN };
        let model: &Model = self.model;
        if model.entry(index, 0).is_err() {
            let d = if rx {
                self.dev.sii.rx_assigned
            } else {
                self.dev.sii.tx_assigned
            };
            return Ok(d.to_vec());
        }
        let count = read_unsigned(model, index, 0).ok_or(())?;
        (1..=count)
            .map(|sub| {
                let sub = u8::try_from(sub).map_err(|_| ())?;
                read_unsigned(model, index, sub)
                    .and_then(|v| u16::try_from(v).ok())
                    .ok_or(())
            })
            .collect()
    }

    /// The items of one direction from the current mapping objects, and the bit length.
    pub(super) fn map(&self, rx: bool) -> Result<(Vec<MapItem>, usize), ()> {
        let model: &Model = self.model;
        let desc = model.od().description();
        let mut items = Vec::new();
        let mut offset = 0usize;
        for pdo in self.assignment(rx)? {
            let count = read_unsigned(model, pdo, 0).ok_or(())?;
            for sub in 1..=count {
                let sub = u8::try_from(sub).map_err(|_| ())?;
                let v = read_unsigned(model, pdo, sub).ok_or(())?;
                let v = u32::try_from(v).map_err(|_| ())?;
                if v == 0 {
                    continue;
                }
                check_map_entry(desc, !rx, v).map_err(|_| ())?;
                let m = MapEntry::from_u32(v);
                items.push(MapItem {
                    index: m.index,
                    sub: m.sub,
                    offset,
                    bits: m.bits,
                    dummy: m.is_dummy(),
                });
                offset += usize::from(m.bits);
            }
        }
        Ok((items, offset))
    }

    /// The layout the current dictionary gives, or the AL status code that refuses it.
    pub(super) fn compute_layout(&self) -> Result<Layout, AlStatusCode> {
        let (outputs, out_bits) = self
            .map(true)
            .map_err(|()| AlStatusCode::INVALID_OUTPUT_MAPPING)?;
        let (inputs, in_bits) = self
            .map(false)
            .map_err(|()| AlStatusCode::INVALID_INPUT_MAPPING)?;
        let desc = self.model.od().description();
        let entries = inputs
            .iter()
            .map(|i| {
                (!i.dummy)
                    .then(|| stored_read_entry(desc, i.index, i.sub))
                    .flatten()
            })
            .collect();
        Ok(Layout {
            sources: Sources {
                desc: Some(desc),
                entries,
            },
            outputs,
            inputs,
            output_bytes: u16::try_from(out_bits.div_ceil(8))
                .map_err(|_| AlStatusCode::INVALID_OUTPUT_MAPPING)?,
            input_bytes: u16::try_from(in_bits.div_ceil(8))
                .map_err(|_| AlStatusCode::INVALID_INPUT_MAPPING)?,
        })
    }

    /// Writes the mapped objects of an output buffer into the device.
    pub(super) fn apply_outputs(&mut self, data: &[u8]) {
        let Some(layout) = &self.dev.layout else {
            return;
        };
        let mut value = [0u8; 8];
        for item in layout.outputs.iter().filter(|i| !i.dummy) {
            let n = usize::from(item.bits).div_ceil(8);
            let Some(v) = value.get_mut(..n) else {
                continue;
            };
            let whole = item
                .whole_bytes()
                .and_then(|(at, len)| data.get(at..at + len));
            match whole {
                Some(bytes) => v.copy_from_slice(bytes),
                None => get_bits(data, item.offset, item.bits, v),
            }
            if self.model.write(item.index, item.sub, v).is_err() {
                self.dev.write_errors += 1;
            }
        }
    }

    /// Reads the mapped objects into the input buffer and hands it to the ESC.
    pub(super) fn post_inputs(&mut self, esc: &mut Esc<'_>) {
        let dev = &mut *self.dev;
        let Some(layout) = &dev.layout else {
            return;
        };
        dev.inputs.clear();
        dev.inputs.resize(usize::from(layout.input_bytes), 0);
        // The stored bytes are what a read returns where the dictionary is the drive's own
        // (a register-image device reads through its own access) and the one the entries
        // were resolved in.
        let od = match &*self.model {
            Model::Plain(_) | Model::Drive(_) => Some(self.model.od()),
            Model::RegisterImage(_) => None,
        }
        .filter(|od| {
            layout
                .sources
                .desc
                .is_some_and(|d| core::ptr::eq(od.description(), d))
        });
        let mut value = [0u8; 8];
        for (i, item) in layout.inputs.iter().enumerate() {
            value.fill(0);
            match (od, layout.sources.entries.get(i).copied().flatten()) {
                (Some(od), Some(e)) => {
                    let raw = od.raw(e);
                    if let Some(v) = value.get_mut(..raw.len()) {
                        v.copy_from_slice(raw);
                    }
                }
                // A value that cannot be read leaves zeros, as a real PDI would leave stale
                // data.
                _ => {
                    let _ = self.model.read(item.index, item.sub, &mut value);
                }
            }
            let whole = item
                .whole_bytes()
                .and_then(|(at, len)| Some((dev.inputs.get_mut(at..at + len)?, value.get(..len)?)));
            match whole {
                Some((dst, src)) => dst.copy_from_slice(src),
                None => set_bits(&mut dev.inputs, item.offset, item.bits, &value),
            }
        }
        if !dev.inputs.is_empty() {
            let _ = esc.set_inputs(&dev.inputs);
        }
    }
}

/// An unsigned value of the dictionary (at most 8 bytes), `None` when it cannot be read.
pub(super) fn read_unsigned(dev: &dyn ObjectAccess, index: u16, sub: u8) -> Option<u64> {
    let mut b = [0u8; 8];
    let n = dev.read(index, sub, &mut b).ok()?;
    (n <= 8).then(|| u64::from_le_bytes(b))
}

/// Copies `bits` bits from `src` at bit offset `offset` into `dst` (LSB first).
fn get_bits(src: &[u8], offset: usize, bits: u8, dst: &mut [u8]) {
    dst.fill(0);
    for i in 0..usize::from(bits) {
        let s = offset + i;
        let bit = src.get(s / 8).map(|b| (b >> (s % 8)) & 1).unwrap_or(0);
        if let Some(d) = dst.get_mut(i / 8) {
            *d |= bit << (i % 8);
        }
    }
}

/// Copies the low `bits` bits of `src` into `dst` at bit offset `offset` (LSB first).
fn set_bits(dst: &mut [u8], offset: usize, bits: u8, src: &[u8]) {
    for i in 0..usize::from(bits) {
        let bit = src.get(i / 8).map(|b| (b >> (i % 8)) & 1).unwrap_or(0);
        let d = offset + i;
        if let Some(b) = dst.get_mut(d / 8) {
            *b = (*b & !(1 << (d % 8))) | (bit << (d % 8));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use drive::drive::DriveSettings;
    use od::{Instant, ObjectDictionary};

    /// The inputs' direct copy reads what a read through the dictionary returns, for every
    /// entry of every personality it takes (a drive run a few cycles, so that its published
    /// values are not only defaults), and leaves the error history to the dictionary.
    #[test]
    fn stored_values_are_what_a_read_returns() {
        for desc in devices::ALL.iter().copied() {
            let Ok(od) = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]) else {
                panic!("{}: no dictionary", desc.name);
            };
            let mut model = Model::new(od, Some(DriveSettings::default()));
            model.step(Instant::from_millis(5));
            let mut taken = 0;
            for e in desc.entries() {
                let Some(source) = stored_read_entry(desc, e.index, e.sub) else {
                    continue;
                };
                taken += 1;
                let mut b = [0u8; 8];
                let n = model.read(e.index, e.sub, &mut b);
                let raw = model.od().raw(source);
                assert_eq!(
                    n.ok().and_then(|n| b.get(..n)),
                    Some(raw),
                    "{} {:04X}h:{:02X}h",
                    desc.name,
                    e.index,
                    e.sub
                );
            }
            assert!(taken > 0, "{}", desc.name);
            if desc.entry(0x1003, 1).is_some() {
                assert!(
                    stored_read_entry(desc, 0x1003, 1).is_none(),
                    "{}",
                    desc.name
                );
            }
        }
    }
}
