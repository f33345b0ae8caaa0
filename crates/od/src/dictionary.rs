//! The values of one drive's dictionary, and the CiA 301 access rules every front end obeys.

use crate::cob_id::CobIdObject;
use crate::{AbortCode, Behaviour, DataType, DeviceDescription, Entry, Value};

/// What every front end sees of a drive: the object dictionary, with its access rules.
/// Device logic implements it by wrapping an [`ObjectDictionary`]; protocols never know more.
pub trait ObjectAccess {
    /// The description of an entry, or the abort a master gets for a missing one.
    fn entry(&self, index: u16, sub: u8) -> Result<&'static Entry, AbortCode>;
    /// Reads the value into `buf`; returns its length.
    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode>;
    /// Writes a whole value, checking access, length and range. Nothing changes on error.
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode>;
    /// The device's own write: no access check (error register, history, actual values), only
    /// the length must fit.
    fn write_internal(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode>;

    fn read_u8(&self, index: u16, sub: u8) -> Option<u8> {
        let mut b = [0u8; 1];
        matches!(self.read(index, sub, &mut b), Ok(1)).then_some(b[0])
    }
    fn read_u16(&self, index: u16, sub: u8) -> Option<u16> {
        let mut b = [0u8; 2];
        matches!(self.read(index, sub, &mut b), Ok(2)).then(|| u16::from_le_bytes(b))
    }
    fn read_u32(&self, index: u16, sub: u8) -> Option<u32> {
        let mut b = [0u8; 4];
        matches!(self.read(index, sub, &mut b), Ok(4)).then(|| u32::from_le_bytes(b))
    }
}

/// A request that only the runtime can carry out (it owns files and resets).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StorageRequest {
    /// "save" written to 1010h:`sub` (1 = all parameters, CiA 301 §7.5.2.13).
    Save { sub: u8 },
    /// "load" written to 1011h:`sub`; the defaults are already back in the current set.
    Restore { sub: u8 },
}

/// "save" as a little-endian UNSIGNED32 (CiA 301 §7.5.2.13; CMMP-AS Tab. 5.2).
pub const SAVE_SIGNATURE: u32 = 0x6576_6173;
/// "load" (CiA 301 §7.5.2.14; CMMP-AS Tab. 5.1).
pub const LOAD_SIGNATURE: u32 = 0x6461_6F6C;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StorageTooSmall {
    pub needed: usize,
    pub given: usize,
}

/// The current values of one drive. `S` is the byte buffer: a `Vec<u8>` on a host, a
/// `[u8; N]` on a microcontroller. A clone is a copy of the values (a fuzz target starts each
/// input from a copy of one dictionary built with its defaults).
#[derive(Clone)]
pub struct ObjectDictionary<S> {
    desc: &'static DeviceDescription,
    node_id: u8,
    data: S,
    request: Option<StorageRequest>,
    /// How many stores the bytes have taken ([`ObjectDictionary::stores`]).
    stores: u64,
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> ObjectDictionary<S> {
    /// A dictionary holding every default, for the node `node_id` (1…127).
    pub fn new(
        desc: &'static DeviceDescription,
        node_id: u8,
        data: S,
    ) -> Result<Self, StorageTooSmall> {
        let given = data.as_ref().len();
        if given < desc.storage_size {
            return Err(StorageTooSmall {
                needed: desc.storage_size,
                given,
            });
        }
        let mut od = ObjectDictionary {
            desc,
            node_id,
            data,
            request: None,
            stores: 0,
        };
        od.load_defaults(|_| true);
        Ok(od)
    }

    pub fn description(&self) -> &'static DeviceDescription {
        self.desc
    }
    pub fn node_id(&self) -> u8 {
        self.node_id
    }
    /// Changes the node-ID; node-relative defaults follow at the next `load_defaults`.
    pub fn set_node_id(&mut self, node_id: u8) {
        self.node_id = node_id;
    }

    /// Puts the default value back into every entry `filter` selects.
    pub fn load_defaults(&mut self, filter: impl Fn(&Entry) -> bool) {
        for e in self.desc.entries() {
            if filter(e) {
                self.set_default(e);
            }
        }
    }

    fn set_default(&mut self, e: &'static Entry) {
        if e.default_plus_node_id {
            let mut b = [0u8; 8];
            let n = e.default.len().min(8);
            if let (Some(dst), Some(src)) = (b.get_mut(..n), e.default.get(..n)) {
                dst.copy_from_slice(src);
            }
            let v = u64::from_le_bytes(b).wrapping_add(u64::from(self.node_id));
            let bytes = v.to_le_bytes();
            self.store(e, bytes.get(..n).unwrap_or(&[]));
        } else {
            self.store(e, e.default);
        }
    }

    /// CiA 301 1011h: the storable parameters `sub` covers go back to their defaults
    /// (1 = all, 2 = communication 1000h–1FFFh, 3 = application 6000h–9FFFh, 4+ = manufacturer).
    pub fn restore_defaults(&mut self, sub: u8) {
        self.load_defaults(|e| {
            e.storable && !e.kept_on_restore && parameter_group_contains(sub, e.index)
        });
    }

    /// The pending save or restore request, if a master asked for one.
    pub fn take_request(&mut self) -> Option<StorageRequest> {
        self.request.take()
    }

    /// A save the device logic asks for through an object of its own (Kinco Store_Data
    /// 2FF0h:01 = 1): carried out by the runtime as a write of "save" to 1010h:`sub`.
    pub fn request_save(&mut self, sub: u8) {
        self.request = Some(StorageRequest::Save { sub });
    }

    /// How many stores the dictionary has taken: every change of its bytes goes through
    /// [`ObjectDictionary::store`] (the writes, `set_value`, the defaults), so what device
    /// logic derived from the dictionary holds while this count stands.
    pub fn stores(&self) -> u64 {
        self.stores
    }

    /// The raw bytes of an entry (the current length for strings and domains).
    pub fn raw(&self, e: &Entry) -> &[u8] {
        let data = self.data.as_ref();
        let off = e.offset as usize;
        if e.is_variable() {
            let len = data
                .get(off..off + 2)
                .and_then(|b| <[u8; 2]>::try_from(b).ok())
                .map(|b| u16::from_le_bytes(b) as usize)
                .unwrap_or(0)
                .min(e.capacity as usize);
            data.get(off + 2..off + 2 + len).unwrap_or(&[])
        } else {
            data.get(off..off + e.capacity as usize).unwrap_or(&[])
        }
    }

    /// Stores bytes without any access or range check: device logic updating its own
    /// read-only objects, or stored parameters coming back. Over-long data is cut.
    #[inline]
    pub fn store(&mut self, e: &Entry, bytes: &[u8]) {
        self.stores = self.stores.wrapping_add(1);
        let data = self.data.as_mut();
        let off = e.offset as usize;
        let cap = e.capacity as usize;
        if e.is_variable() {
            let len = bytes.len().min(cap);
            if let Some(dst) = data.get_mut(off..off + 2) {
                dst.copy_from_slice(&(len as u16).to_le_bytes());
            }
            if let (Some(dst), Some(src)) = (data.get_mut(off + 2..off + 2 + len), bytes.get(..len))
            {
                dst.copy_from_slice(src);
            }
        } else if let Some(dst) = data.get_mut(off..off + cap) {
            // The integer widths as moves of their size; else byte loops, not fill +
            // copy_from_slice: values are 1–8 bytes and this runs for every actual value in
            // every drive cycle, where library memset/memcpy calls cost more than the copy.
            let moved = match cap {
                1 => copy_exact::<1>(dst, bytes),
                2 => copy_exact::<2>(dst, bytes),
                4 => copy_exact::<4>(dst, bytes),
                8 => copy_exact::<8>(dst, bytes),
                _ => false,
            };
            if !moved {
                let mut src = bytes.iter();
                for d in dst.iter_mut() {
                    *d = src.next().copied().unwrap_or(0);
                }
            }
        }
    }

    /// The decoded value of a numeric entry, `None` if it is missing or not numeric.
    pub fn value(&self, index: u16, sub: u8) -> Option<Value> {
        let e = self.desc.entry(index, sub)?;
        Value::decode(e.data_type, self.raw(e))
    }

    /// The value of an unsigned or boolean entry as `u64`.
    pub fn get_unsigned(&self, index: u16, sub: u8) -> Option<u64> {
        match self.value(index, sub)? {
            Value::Unsigned(u) => Some(u),
            Value::Bool(b) => Some(b as u64),
            Value::Signed(s) => u64::try_from(s).ok(),
            Value::Real(_) => None,
        }
    }

    /// Sets a numeric entry from device logic, bypassing access rights (not range).
    pub fn set_value(&mut self, index: u16, sub: u8, v: Value) -> Result<(), AbortCode> {
        let e = self.desc.entry(index, sub).ok_or(AbortCode::NO_OBJECT)?;
        let mut b = [0u8; 8];
        let n = v
            .encode(e.data_type, &mut b)
            .ok_or(AbortCode::INVALID_VALUE)?;
        self.store(e, b.get(..n).unwrap_or(&[]));
        Ok(())
    }

    /// Every entry a save (1010h:`sub`) writes, with its current bytes.
    pub fn storable_values(&self, sub: u8) -> impl Iterator<Item = (&'static Entry, &[u8])> {
        self.desc
            .entries()
            .filter(move |e| e.storable && parameter_group_contains(sub, e.index))
            .map(move |e| (e, self.raw(e)))
    }

    fn check_value(e: &Entry, data: &[u8]) -> Result<(), AbortCode> {
        if let Some(size) = e.data_type.fixed_size() {
            if data.len() > size {
                return Err(AbortCode::LENGTH_TOO_HIGH);
            }
            if data.len() < size {
                return Err(AbortCode::LENGTH_TOO_LOW);
            }
            let v = Value::decode(e.data_type, data).ok_or(AbortCode::LENGTH_MISMATCH)?;
            if e.data_type == DataType::Boolean && data.first().is_some_and(|b| *b > 1) {
                return Err(AbortCode::INVALID_VALUE);
            }
            if let Some(max) = e.max {
                if v.compare(max) == Some(core::cmp::Ordering::Greater) {
                    return Err(AbortCode::VALUE_TOO_HIGH);
                }
            }
            if let Some(min) = e.min {
                if v.compare(min) == Some(core::cmp::Ordering::Less) {
                    return Err(AbortCode::VALUE_TOO_LOW);
                }
            }
            if let (Some(mask), Value::Unsigned(u)) = (e.allowed_bits, v) {
                if u & !mask != 0 {
                    return Err(AbortCode::INVALID_VALUE);
                }
            }
        } else if data.len() > e.capacity as usize {
            return Err(AbortCode::LENGTH_TOO_HIGH);
        }
        Ok(())
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> ObjectDictionary<S> {
    /// An object whose two sub-indices are a min and a max keeps them ordered: 0609 0036h.
    fn check_order(&self, e: &Entry, data: &[u8]) -> Result<(), AbortCode> {
        let Some((lo, hi)) = self.desc.object(e.index).and_then(|o| o.min_max) else {
            return Ok(());
        };
        let other = match e.sub {
            s if s == lo => hi,
            s if s == hi => lo,
            _ => return Ok(()),
        };
        let (Some(new), Some(current)) =
            (Value::decode(e.data_type, data), self.value(e.index, other))
        else {
            return Ok(());
        };
        let (min, max) = if e.sub == lo {
            (new, current)
        } else {
            (current, new)
        };
        let max_limit = match max {
            Value::Signed(s) => crate::Limit::Signed(s),
            Value::Unsigned(u) => crate::Limit::Unsigned(u),
            Value::Real(r) => crate::Limit::Real(r),
            Value::Bool(b) => crate::Limit::Unsigned(u64::from(b)),
        };
        if min.compare(max_limit) == Some(core::cmp::Ordering::Greater) {
            return Err(AbortCode::MAX_LESS_THAN_MIN);
        }
        Ok(())
    }
}

/// Which indices a store/restore sub-index covers (CiA 301 §7.5.2.13).
fn parameter_group_contains(sub: u8, index: u16) -> bool {
    match sub {
        1 => true,
        2 => (0x1000..0x2000).contains(&index),
        3 => (0x6000..0xA000).contains(&index),
        _ => (0x2000..0x6000).contains(&index),
    }
}

fn signature(data: &[u8]) -> Option<u32> {
    Some(u32::from_le_bytes(data.try_into().ok()?))
}

/// The entry whose stored bytes ([`ObjectDictionary::raw`]) are exactly what
/// [`ObjectAccess::read`] of `index`:`sub` returns in a dictionary of `desc`, in any state: a
/// readable value of at most 8 bytes (a process-data value) that neither reads as zeros
/// (`ReadsZero`) nor is an error-history entry, whose read depends on the count in sub-index
/// 0. A caller that reads the object every cycle resolves it once and copies its bytes;
/// `None`: read it through the dictionary every time. Kept beside `read`, whose cases it
/// mirrors.
pub fn stored_read_entry(
    desc: &'static DeviceDescription,
    index: u16,
    sub: u8,
) -> Option<&'static Entry> {
    let e = desc.entry(index, sub)?;
    let history = sub > 0
        && desc
            .entry(index, 0)
            .is_some_and(|c| c.behaviour == Behaviour::ErrorHistoryCount);
    let fixed = e.data_type.fixed_size().is_some_and(|n| n <= 8);
    (e.access.readable() && e.behaviour != Behaviour::ReadsZero && !history && fixed).then_some(e)
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> ObjectAccess for ObjectDictionary<S> {
    fn entry(&self, index: u16, sub: u8) -> Result<&'static Entry, AbortCode> {
        let obj = self.desc.object(index).ok_or(AbortCode::NO_OBJECT)?;
        obj.entry(sub).ok_or(AbortCode::NO_SUB_INDEX)
    }

    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        let e = self.entry(index, sub)?;
        if !e.access.readable() {
            return Err(AbortCode::WRITE_ONLY);
        }
        if sub > 0 {
            if let Some(count) = self.desc.entry(index, 0) {
                if count.behaviour == Behaviour::ErrorHistoryCount
                    && u64::from(sub)
                        > Value::decode(count.data_type, self.raw(count))
                            .and_then(|v| match v {
                                Value::Unsigned(u) => Some(u),
                                _ => None,
                            })
                            .unwrap_or(0)
                {
                    // CiA 301 §7.5.2.4 (CCT Emergency 03): no error stored there yet.
                    return Err(AbortCode::NO_DATA);
                }
            }
        }
        let zeros = [0u8; 8];
        let src = match e.behaviour {
            Behaviour::ReadsZero => zeros.get(..e.capacity as usize).unwrap_or(&zeros),
            _ => self.raw(e),
        };
        let dst = buf.get_mut(..src.len()).ok_or(AbortCode::OUT_OF_MEMORY)?;
        dst.copy_from_slice(src);
        Ok(src.len())
    }

    fn write_internal(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let e = self.entry(index, sub)?;
        match e.data_type.fixed_size() {
            Some(n) if data.len() > n => return Err(AbortCode::LENGTH_TOO_HIGH),
            Some(n) if data.len() < n => return Err(AbortCode::LENGTH_TOO_LOW),
            None if data.len() > e.capacity as usize => return Err(AbortCode::LENGTH_TOO_HIGH),
            _ => {}
        }
        self.store(e, data);
        Ok(())
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let e = self.entry(index, sub)?;
        if !e.access.writable() {
            return Err(AbortCode::READ_ONLY);
        }
        match e.behaviour {
            Behaviour::StoreSignature | Behaviour::RestoreSignature => {
                let sig = match data.len() {
                    4 => signature(data),
                    n if n > 4 => return Err(AbortCode::LENGTH_TOO_HIGH),
                    _ => return Err(AbortCode::LENGTH_TOO_LOW),
                };
                let (want, req) = if e.behaviour == Behaviour::StoreSignature {
                    (SAVE_SIGNATURE, StorageRequest::Save { sub })
                } else {
                    (LOAD_SIGNATURE, StorageRequest::Restore { sub })
                };
                // CMMP-AS §5.1 and CiA 301: a wrong signature is refused with 0800 0020h.
                if sig != Some(want) {
                    return Err(AbortCode::CANNOT_STORE);
                }
                if let StorageRequest::Restore { sub } = req {
                    self.restore_defaults(sub);
                }
                self.request = Some(req);
                Ok(())
            }
            Behaviour::ErrorHistoryCount => {
                Self::check_value(e, data)?;
                // CiA 301 §7.5.2.4: only 0 may be written; it clears the history.
                if data.iter().any(|b| *b != 0) {
                    return Err(AbortCode::INVALID_VALUE);
                }
                if let Some(obj) = self.desc.object(index) {
                    for entry in obj.entries {
                        self.store(entry, &[]);
                    }
                }
                Ok(())
            }
            Behaviour::ReadsZero => Self::check_value(e, data),
            Behaviour::PdoCobId
            | Behaviour::PdoTransmissionType
            | Behaviour::PdoInhibitTime
            | Behaviour::PdoEventTimer
            | Behaviour::PdoSyncStart
            | Behaviour::PdoMapCount
            | Behaviour::PdoMapEntry => {
                // Length first, then the PDO rules (their abort codes win over a plain range
                // error: CCT PDO 25 expects 0604 0042h for too many entries), then the range.
                let size = e.data_type.fixed_size().unwrap_or(0);
                if data.len() > size {
                    return Err(AbortCode::LENGTH_TOO_HIGH);
                }
                if data.len() < size {
                    return Err(AbortCode::LENGTH_TOO_LOW);
                }
                let store = self.check_pdo_write(e, data)?;
                Self::check_value(e, data)?;
                match store {
                    Some(v) => {
                        let b = v.to_le_bytes();
                        self.store(e, b.get(..data.len()).unwrap_or(data));
                    }
                    None => self.store(e, data),
                }
                Ok(())
            }
            Behaviour::Plain => {
                Self::check_value(e, data)?;
                if let (Some(obj), Ok(new)) =
                    (CobIdObject::of(index, sub), <[u8; 4]>::try_from(data))
                {
                    let current = self.read_u32(index, sub).unwrap_or(0);
                    obj.check(current, u32::from_le_bytes(new))?;
                }
                self.check_order(e, data)?;
                let data = if e.data_type == DataType::VisibleString {
                    // A string ends at its first NUL (CiA 301 §7.1.6.3).
                    let end = data.iter().position(|b| *b == 0).unwrap_or(data.len());
                    data.get(..end).unwrap_or(data)
                } else {
                    data
                };
                self.store(e, data);
                Ok(())
            }
        }
    }
}

/// The first `N` bytes of `src` into `dst` when `dst` has exactly `N` bytes and `src` at
/// least `N`; `false` (nothing copied) otherwise.
#[inline(always)]
fn copy_exact<const N: usize>(dst: &mut [u8], src: &[u8]) -> bool {
    let src = src.get(..N).and_then(|s| <&[u8; N]>::try_from(s).ok());
    match (<&mut [u8; N]>::try_from(dst), src) {
        (Ok(d), Some(s)) => {
            *d = *s;
            true
        }
        _ => false,
    }
}
