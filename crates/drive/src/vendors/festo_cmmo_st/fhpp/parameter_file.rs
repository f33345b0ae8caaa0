//! The CMMO-ST parameter file (manual C.4.3): "the data container of the complete parameter
//! set", moved by the EFPC file transfer and kept in the permanent memory (the "EEPROM").
//!
//! The manual gives the parts but not their content. The English edition's Fig. C.2 (the
//! figure is missing from the Chinese edition) draws **a 256-byte header, n bytes of data
//! ("objects") and a 2-byte CRC check value**. The content is decided here:
//!
//! | Offset | Size | Field (little-endian, like the file transfer's user data, C.4.3) |
//! |---|---|---|
//! | 0 | 4 | magic `FHPF` |
//! | 4 | 2 | format version, 1 |
//! | 6 | 2 | header length, 256 |
//! | 8 | 4 | data length n |
//! | 12 | 4 | number of entries |
//! | 16 | 4 | layout fingerprint: CRC-32/ISO-HDLC over (index u16, sub u8, data type u16, slot size u32) of every entry, LE, in dictionary order |
//! | 20 | 32 | personality name (`cmmo-st`), 00h-padded |
//! | 52 | 204 | reserved, 0 |
//! | 256 | n | the value of every storable entry in dictionary order, each in a fixed slot: its little-endian bytes (the type's size); a string or domain as a u16 length + its capacity |
//! | 256 + n | 2 | CRC-16/IBM-3740 (CCITT-FALSE) over header and data, LE |
//!
//! Why not `od::parameter_file` (the text form `IIII:SS=HEX` of the CiA drives): the file
//! crosses the 6-byte EFPC segments, one cyclic exchange each. The text form needs about 15
//! bytes per entry (≈ 40 KiB, 6500 packets for the 2618 storable entries of the CMMO-ST),
//! the binary slots 7.5 KiB (1260 packets), and the manual's figure is binary with a CRC.
//! Untagged slots are safe because the layout fingerprint ties a file to one dictionary
//! layout: the manual's "transfer between identical motor controllers" (C.4.3) and its
//! compatibility check "after the header and at load time" (C.4.4) are both this check.

use crc::{Crc, CRC_16_IBM_3740, CRC_32_ISO_HDLC};
use od::{DeviceDescription, Entry, ObjectDictionary, Value};

use super::parameter_channel::FileError;

/// Length of the header (English manual Fig. C.2).
pub const HEADER_LEN: usize = 256;
/// Length of the CRC check value (English manual Fig. C.2).
pub const CRC_LEN: usize = 2;
/// First bytes of every file.
pub const MAGIC: [u8; 4] = *b"FHPF";
/// Format version written and accepted.
pub const VERSION: u16 = 1;
/// Largest file the permanent memory and the download buffer hold (the CMMO-ST's is 7577
/// bytes).
pub const CAPACITY: usize = 12 * 1024;

const NAME_OFFSET: usize = 20;
const NAME_LEN: usize = 32;

/// A parameter file in memory.
pub type FileBuffer = heapless::Vec<u8, CAPACITY>;

const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);
const CRC32: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

/// Why a file is refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FormatError {
    /// Shorter than header + CRC, or longer than [`CAPACITY`].
    Size(usize),
    /// Not `FHPF`, or a header length other than 256.
    Magic,
    /// A format version this firmware does not read.
    Version(u16),
    /// Made for another personality or another dictionary layout (incompatible, C.4.4).
    Incompatible,
    /// Header, data length and file size disagree.
    Length,
    /// The CRC check value does not match.
    Crc,
    /// A value outside its entry's limits (object index, sub-index).
    Value(u16, u8),
}

impl FormatError {
    /// The type-2 transfer error a download ends with (Tab. C.11): a wrong size is a read
    /// error (0x05, "invalid file length"), a size mismatch 0x07, everything else means the
    /// file cannot be written (0x06, as diagnostic 27h tells the user to check the file's
    /// version against the firmware).
    pub const fn transfer_error(self) -> FileError {
        match self {
            FormatError::Size(_) => FileError::Read,
            FormatError::Length => FileError::Amount,
            _ => FileError::Write,
        }
    }
}

/// What the header says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    pub version: u16,
    pub data_len: u32,
    pub entries: u32,
    pub layout: u32,
}

impl Header {
    /// The whole file's size.
    pub const fn file_len(&self) -> usize {
        HEADER_LEN + self.data_len as usize + CRC_LEN
    }
}

fn slot_len(e: &Entry) -> usize {
    e.storage_len()
}

/// The entries a file carries: every storable one (commands such as PNU 125/127 are not).
pub fn file_entries(desc: &'static DeviceDescription) -> impl Iterator<Item = &'static Entry> {
    desc.entries().filter(|e| e.storable)
}

/// The layout fingerprint of a personality (see the module documentation).
pub fn layout_fingerprint(desc: &'static DeviceDescription) -> u32 {
    let mut d = CRC32.digest();
    for e in file_entries(desc) {
        d.update(&e.index.to_le_bytes());
        d.update(&[e.sub]);
        d.update(&(e.data_type as u16).to_le_bytes());
        d.update(&(slot_len(e) as u32).to_le_bytes());
    }
    d.finalize()
}

/// The header of a personality's file.
pub fn header_for(desc: &'static DeviceDescription) -> Header {
    let (mut n, mut len) = (0u32, 0usize);
    for e in file_entries(desc) {
        n += 1;
        len += slot_len(e);
    }
    Header {
        version: VERSION,
        data_len: len as u32,
        entries: n,
        layout: layout_fingerprint(desc),
    }
}

fn push(out: &mut FileBuffer, bytes: &[u8]) -> Result<(), FormatError> {
    out.extend_from_slice(bytes)
        .map_err(|()| FormatError::Size(CAPACITY + 1))
}

fn push_zeros(out: &mut FileBuffer, n: usize) -> Result<(), FormatError> {
    for _ in 0..n {
        out.push(0).map_err(|_| FormatError::Size(CAPACITY + 1))?;
    }
    Ok(())
}

/// Writes the file of `desc` into `out`, with each entry's bytes from `value` (LE, at most
/// the entry's capacity; shorter is zero-padded).
pub fn write_file<'a>(
    desc: &'static DeviceDescription,
    value: impl Fn(&'static Entry) -> &'a [u8],
    out: &mut FileBuffer,
) -> Result<(), FormatError> {
    let h = header_for(desc);
    if h.file_len() > CAPACITY {
        return Err(FormatError::Size(h.file_len()));
    }
    out.clear();
    push(out, &MAGIC)?;
    push(out, &h.version.to_le_bytes())?;
    push(out, &(HEADER_LEN as u16).to_le_bytes())?;
    push(out, &h.data_len.to_le_bytes())?;
    push(out, &h.entries.to_le_bytes())?;
    push(out, &h.layout.to_le_bytes())?;
    let name = desc.name.as_bytes();
    let name = name.get(..NAME_LEN).unwrap_or(name);
    push(out, name)?;
    push_zeros(out, HEADER_LEN - NAME_OFFSET - name.len())?;
    for e in file_entries(desc) {
        let cap = e.capacity as usize;
        let v = value(e);
        let v = v.get(..cap).unwrap_or(v);
        if e.is_variable() {
            push(out, &(v.len() as u16).to_le_bytes())?;
        }
        push(out, v)?;
        push_zeros(out, cap - v.len())?;
    }
    let crc = CRC16.checksum(out);
    push(out, &crc.to_le_bytes())
}

/// The file of the dictionary's current values (PNU 127:2 "save").
pub fn from_dictionary<S: AsRef<[u8]> + AsMut<[u8]>>(
    od: &ObjectDictionary<S>,
    out: &mut FileBuffer,
) -> Result<(), FormatError> {
    write_file(od.description(), |e| od.raw(e), out)
}

/// The file of the factory settings (the dictionary's defaults): what the permanent memory
/// holds before the first save and after "delete EEPROM" (PNU 127:1).
pub fn factory(desc: &'static DeviceDescription, out: &mut FileBuffer) -> Result<(), FormatError> {
    write_file(desc, |e| e.default, out)
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    let mut a = [0u8; 2];
    if let Some(s) = b.get(at..at + 2) {
        a.copy_from_slice(s);
    }
    u16::from_le_bytes(a)
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    let mut a = [0u8; 4];
    if let Some(s) = b.get(at..at + 4) {
        a.copy_from_slice(s);
    }
    u32::from_le_bytes(a)
}

/// Checks the first [`HEADER_LEN`] bytes against the personality: the check the drive makes
/// "directly after the header" (C.4.4).
pub fn check_header(desc: &'static DeviceDescription, bytes: &[u8]) -> Result<Header, FormatError> {
    let head = bytes
        .get(..HEADER_LEN)
        .ok_or(FormatError::Size(bytes.len()))?;
    if head.get(..4) != Some(&MAGIC[..]) || usize::from(u16_at(head, 6)) != HEADER_LEN {
        return Err(FormatError::Magic);
    }
    let h = Header {
        version: u16_at(head, 4),
        data_len: u32_at(head, 8),
        entries: u32_at(head, 12),
        layout: u32_at(head, 16),
    };
    if h.version != VERSION {
        return Err(FormatError::Version(h.version));
    }
    let name = desc.name.as_bytes();
    let stored = head.get(NAME_OFFSET..NAME_OFFSET + NAME_LEN).unwrap_or(&[]);
    let stored_name = stored.split(|b| *b == 0).next().unwrap_or(&[]);
    let want = header_for(desc);
    if stored_name != name.get(..NAME_LEN).unwrap_or(name)
        || h.layout != want.layout
        || h.entries != want.entries
    {
        return Err(FormatError::Incompatible);
    }
    if h.data_len != want.data_len {
        return Err(FormatError::Length);
    }
    Ok(h)
}

/// Iterates the data slots of a checked file: entry and its value bytes.
fn slots<'f>(
    desc: &'static DeviceDescription,
    file: &'f [u8],
) -> impl Iterator<Item = (&'static Entry, &'f [u8])> {
    let mut at = HEADER_LEN;
    file_entries(desc).map(move |e| {
        let slot = file.get(at..at + slot_len(e)).unwrap_or(&[]);
        at += slot_len(e);
        let bytes = if e.is_variable() {
            let n = usize::from(u16_at(slot, 0)).min(e.capacity as usize);
            slot.get(2..2 + n).unwrap_or(&[])
        } else {
            slot
        };
        (e, bytes)
    })
}

fn in_limits(e: &Entry, bytes: &[u8]) -> bool {
    let Some(v) = Value::decode(e.data_type, bytes) else {
        return true; // strings and domains have no limits
    };
    let above = e
        .max
        .is_some_and(|m| v.compare(m) == Some(core::cmp::Ordering::Greater));
    let below = e
        .min
        .is_some_and(|m| v.compare(m) == Some(core::cmp::Ordering::Less));
    !above && !below
}

/// Checks a whole file: size, header, CRC and every value against its limits (the check
/// "at load time", C.4.4). Nothing is stored.
pub fn check(desc: &'static DeviceDescription, file: &[u8]) -> Result<Header, FormatError> {
    if file.len() < HEADER_LEN + CRC_LEN || file.len() > CAPACITY {
        return Err(FormatError::Size(file.len()));
    }
    let h = check_header(desc, file)?;
    if h.file_len() != file.len() {
        return Err(FormatError::Length);
    }
    let (body, crc) = file.split_at(file.len() - CRC_LEN);
    if CRC16.checksum(body) != u16_at(crc, 0) {
        return Err(FormatError::Crc);
    }
    if let Some((e, _)) = slots(desc, file).find(|(e, b)| !in_limits(e, b)) {
        return Err(FormatError::Value(e.index, e.sub));
    }
    Ok(h)
}

/// Loads a file's values into the dictionary, the entries `filter` selects (all-or-nothing:
/// the file is checked first).
pub fn load<S: AsRef<[u8]> + AsMut<[u8]>>(
    od: &mut ObjectDictionary<S>,
    file: &[u8],
    filter: impl Fn(&Entry) -> bool,
) -> Result<(), FormatError> {
    let desc = od.description();
    check(desc, file)?;
    for (e, bytes) in slots(desc, file) {
        if filter(e) {
            od.store(e, bytes);
        }
    }
    Ok(())
}

/// Error-management PNUs (234, 238, 242, 246): PNU 127:4 does not load them (C.4.4).
pub const ERROR_MANAGEMENT_PNUS: [u16; 4] = [234, 238, 242, 246];

fn is_error_management(e: &Entry) -> bool {
    ERROR_MANAGEMENT_PNUS
        .iter()
        .any(|pnu| e.index.checked_sub(0x2000) == Some(*pnu))
}

/// The sub-indices of PNU 127 "data memory control" (Tab. B.20) and the value each needs.
pub mod data_memory {
    /// Sub 1: delete the EEPROM (factory settings at the next restart), value 10h.
    pub const DELETE: u8 = 1;
    /// Sub 2: save the active values into the EEPROM, value 01h.
    pub const SAVE: u8 = 2;
    /// Sub 3: reset the device (EEPROM → active), value 10h. Only the parameter part of the
    /// restart is carried out here (all stored values, error management included, become
    /// active); the FHPP state machine and the reference are not reset.
    pub const RESET: u8 = 3;
    /// Sub 4: load the parameter values from the parameter file, value 10h.
    pub const LOAD: u8 = 4;
}

/// The permanent memory (the "EEPROM") of the drive: one parameter file. Empty until the
/// first save or download, which means the factory settings: the twin starts from the
/// dictionary's defaults, so that is what its EEPROM holds at power-on.
#[derive(Clone)]
pub struct PermanentMemory {
    /// The stored file; empty until first needed, then the factory file.
    file: FileBuffer,
    /// No save or download since power-on or the last delete.
    factory: bool,
    /// Counts the changes of the stored file (save, download, delete), so that a host that
    /// keeps the memory on disk sees when to write it.
    generation: u32,
}

impl Default for PermanentMemory {
    fn default() -> Self {
        PermanentMemory {
            file: FileBuffer::new(),
            factory: true,
            generation: 0,
        }
    }
}

impl PermanentMemory {
    /// The stored file (the factory file if nothing was stored).
    pub fn file(&mut self, desc: &'static DeviceDescription) -> Result<&[u8], FormatError> {
        if self.file.is_empty() {
            factory(desc, &mut self.file)?;
        }
        Ok(&self.file)
    }

    /// Whether a save or a download has put a file there since power-on or the last delete.
    pub fn is_factory(&self) -> bool {
        self.factory
    }

    /// Changes when the stored file changes (save, download, delete).
    pub fn generation(&self) -> u32 {
        self.generation
    }

    /// The file a save or download stored; `None` when the memory holds the factory settings
    /// (nothing stored, or deleted).
    pub fn stored(&self) -> Option<&[u8]> {
        (!self.factory && !self.file.is_empty()).then_some(&self.file[..])
    }

    /// Power-on from a memory kept by the host: `file` (a parameter file, checked) is what
    /// the EEPROM holds, and its values become active, error management included.
    pub fn power_on_from<S: AsRef<[u8]> + AsMut<[u8]>>(
        &mut self,
        od: &mut ObjectDictionary<S>,
        file: &[u8],
    ) -> Result<(), FormatError> {
        self.replace(od.description(), file)?;
        self.activate(od, true)
    }

    /// PNU 127:2: the active values become the permanent ones.
    pub fn save<S: AsRef<[u8]> + AsMut<[u8]>>(
        &mut self,
        od: &ObjectDictionary<S>,
    ) -> Result<(), FormatError> {
        from_dictionary(od, &mut self.file)?;
        self.factory = false;
        self.generation = self.generation.wrapping_add(1);
        Ok(())
    }

    /// PNU 127:1: the EEPROM is deleted; the factory settings come back at the next restart.
    pub fn delete(&mut self) {
        self.file.clear();
        self.factory = true;
        self.generation = self.generation.wrapping_add(1);
    }

    /// A downloaded file, already checked, replaces the stored one (C.4.4).
    pub fn replace(
        &mut self,
        desc: &'static DeviceDescription,
        file: &[u8],
    ) -> Result<(), FormatError> {
        check(desc, file)?;
        self.file.clear();
        push(&mut self.file, file)?;
        self.factory = false;
        self.generation = self.generation.wrapping_add(1);
        Ok(())
    }

    /// The stored values become active: all of them (restart, PNU 127:3) or all but error
    /// management (PNU 127:4, C.4.4 "does not apply changed error-management parameters").
    pub fn activate<S: AsRef<[u8]> + AsMut<[u8]>>(
        &mut self,
        od: &mut ObjectDictionary<S>,
        error_management: bool,
    ) -> Result<(), FormatError> {
        let file = self.file(od.description())?;
        load(od, file, |e| error_management || !is_error_management(e))
    }

    /// A PNU 127 write (the value was checked by the dictionary's limits): carries out the
    /// command. Returns whether the active values changed.
    pub fn command<S: AsRef<[u8]> + AsMut<[u8]>>(
        &mut self,
        sub: u8,
        od: &mut ObjectDictionary<S>,
    ) -> Result<bool, FormatError> {
        match sub {
            data_memory::DELETE => {
                self.delete();
                Ok(false)
            }
            data_memory::SAVE => self.save(od).map(|()| false),
            data_memory::RESET => self.activate(od, true).map(|()| true),
            data_memory::LOAD => self.activate(od, false).map(|()| true),
            _ => Ok(false),
        }
    }
}
