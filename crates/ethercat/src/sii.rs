//! SII EEPROM image (ETG.1000.6 §5.4, ETG.2010): the slave information the ESC loads at power-on
//! and the masters read through registers 0x0500–0x050F (spec §2.4, §3).
//!
//! The image is built from a device description into a caller-provided buffer, without
//! allocation. Layout (word addresses, 16-bit little-endian words):
//!
//! * words 0x00–0x07: ESC configuration area, checksum in word 7 (CRC-8, poly 0x07, init 0xFF,
//!   over words 0–6; spec §3.2);
//! * words 0x08–0x3F: identity, mailbox layout, protocols, EEPROM size, version (spec §3.1);
//! * from word 0x40: categories STRINGS (10), GENERAL (30), FMMU (40), SYNCM (41), TXPDO (50),
//!   RXPDO (51), END (0xFFFF) (spec §3.3).
//!
//! Decisions (spec §3.5 is the baseline):
//! * Sync manager addresses and mailbox sizes, group type, ports, default PDO assignment and
//!   CoE details are the device file's (`[device.ethercat]`, [`od::EthercatSlave`]); a device
//!   without that section gets the ESC reference baseline ([`SiiConfig::BASELINE`]):
//!   0x1000/0x80 (SM0), 0x1080/0x80 (SM1), 0x1100 (SM2), 0x1180 (SM3).
//! * The SII PDO categories list every mapping object of the description (1600h–17FFh,
//!   1A00h–1BFFh) with its default mapping; only the PDOs of [`SiiConfig::rx_assigned`] /
//!   [`SiiConfig::tx_assigned`] (default 1600h / 1A00h) carry an SM number, the others SM 0xFF,
//!   so SOEM's SII fall-back and ethercrab's EEPROM path compute the same SM sizes (spec §3.3,
//!   §7.1). They must match the 1C12h/1C13h defaults of the drive model.
//! * CoE details: SDO, PDO assign and PDO config always; SDO information and complete access
//!   as the device serves them ([`od::EthercatSlave::sdo_info`], `complete_access`).
//! * General bytes 14–15 are 0 (ethercrab reads its "ports" there, KickCAT a GroupIdx copy);
//!   the physical port descriptor goes at ETG.2010's offset 16–17 (the baseline 0x0011: ports
//!   0 and 1 MII, two 100Base-TX ports). ethercrab reads 16–17
//!   as the ident address, used only with flag bit 4, which is 0.
//! * No word inside the categories is 0xFFFF: KickCAT stops reading at the first such word
//!   (spec §3.4). [`build_sii`] checks it.

/// Category types (ETG.2010 Tab. 3, spec §3.3).
pub mod category {
    pub const NOP: u16 = 0;
    pub const STRINGS: u16 = 10;
    pub const DATA_TYPES: u16 = 20;
    pub const GENERAL: u16 = 30;
    pub const FMMU: u16 = 40;
    pub const SYNC_M: u16 = 41;
    pub const FMMU_EX: u16 = 42;
    pub const SYNC_UNIT: u16 = 43;
    pub const TX_PDO: u16 = 50;
    pub const RX_PDO: u16 = 51;
    pub const DC: u16 = 60;
    pub const END: u16 = 0xFFFF;
}

/// Word addresses of the fixed fields (spec §3.1).
pub mod word {
    pub const PDI_CONTROL: u16 = 0x00;
    pub const PDI_CONFIG: u16 = 0x01;
    pub const SYNC_IMPULSE_LEN: u16 = 0x02;
    pub const PDI_CONFIG2: u16 = 0x03;
    pub const STATION_ALIAS: u16 = 0x04;
    pub const CHECKSUM: u16 = 0x07;
    pub const VENDOR_ID: u16 = 0x08;
    pub const PRODUCT_CODE: u16 = 0x0A;
    pub const REVISION: u16 = 0x0C;
    pub const SERIAL: u16 = 0x0E;
    pub const BOOTSTRAP_RX_OFFSET: u16 = 0x14;
    pub const BOOTSTRAP_RX_SIZE: u16 = 0x15;
    pub const BOOTSTRAP_TX_OFFSET: u16 = 0x16;
    pub const BOOTSTRAP_TX_SIZE: u16 = 0x17;
    pub const STD_RX_OFFSET: u16 = 0x18;
    pub const STD_RX_SIZE: u16 = 0x19;
    pub const STD_TX_OFFSET: u16 = 0x1A;
    pub const STD_TX_SIZE: u16 = 0x1B;
    pub const MAILBOX_PROTOCOLS: u16 = 0x1C;
    pub const SIZE: u16 = 0x3E;
    pub const VERSION: u16 = 0x3F;
    /// First category header.
    pub const FIRST_CATEGORY: u16 = 0x40;
}

/// Mailbox protocol bits of word 0x1C.
pub mod mailbox_protocol {
    pub const AOE: u16 = 0x0001;
    pub const EOE: u16 = 0x0002;
    pub const COE: u16 = 0x0004;
    pub const FOE: u16 = 0x0008;
    pub const SOE: u16 = 0x0010;
    pub const VOE: u16 = 0x0020;
}

/// CoE details bits of the GENERAL category (byte 5).
pub mod coe_details {
    pub const SDO: u8 = 0x01;
    pub const SDO_INFO: u8 = 0x02;
    pub const PDO_ASSIGN: u8 = 0x04;
    pub const PDO_CONFIG: u8 = 0x08;
    pub const PDO_UPLOAD: u8 = 0x10;
    pub const SDO_COMPLETE_ACCESS: u8 = 0x20;
}

/// FMMU usage bytes of the FMMU category.
pub mod fmmu_usage {
    pub const UNUSED: u8 = 0x00;
    pub const OUTPUTS: u8 = 0x01;
    pub const INPUTS: u8 = 0x02;
    pub const MAILBOX_STATE: u8 = 0x03;
}

/// SM type byte (byte 7) of a SYNCM entry.
pub mod sm_type {
    pub const UNUSED: u8 = 0;
    pub const MAILBOX_OUT: u8 = 1;
    pub const MAILBOX_IN: u8 = 2;
    pub const OUTPUTS: u8 = 3;
    pub const INPUTS: u8 = 4;
}

/// SM control bytes (spec §2.6): mailbox write / read, buffered write with watchdog / read.
pub const SM0_CONTROL: u8 = 0x26;
pub const SM1_CONTROL: u8 = 0x22;
pub const SM2_CONTROL: u8 = 0x64;
pub const SM3_CONTROL: u8 = 0x20;
/// SM enable byte of the SII: bit 0 only (SOEM copies it into the activate register, §2.6).
pub const SM_ENABLE: u8 = 0x01;

/// Bytes of the SII image of the baseline ([`SiiConfig::BASELINE`]): 2 KiB (16 kbit, word
/// 0x3E = 15).
pub const DEFAULT_IMAGE_SIZE: usize = 2048;

/// Why an image could not be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SiiError {
    /// The buffer cannot hold the image (or is smaller than 128 bytes / not a multiple of 128).
    BufferTooSmall,
    /// A string is longer than 255 bytes.
    StringTooLong,
    /// More than 255 distinct strings.
    TooManyStrings,
    /// An assigned PDO index has no mapping object in the description.
    PdoNotFound(u16),
    /// A mapping object's default count exceeds its sub-entries or 255.
    BadMapping(u16),
    /// The default process data of SM2 do not fit three buffers below the SM3 start, or an SM
    /// window overlaps another.
    SmOverlap,
    /// A word inside the categories would read 0xFFFF (would stop KickCAT's SII read).
    ReservedWord(u16),
}

/// How the image is laid out beyond what the device description says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SiiConfig<'a> {
    /// Word 0: PDI control (low byte) and ESC configuration (high byte).
    pub pdi_control: u16,
    /// Word 1.
    pub pdi_config: u16,
    /// Word 2: SYNC impulse length in 10 ns.
    pub sync_impulse_len: u16,
    /// Word 4: configured station alias (loaded into 0x0012 at power-on).
    pub station_alias: u16,
    /// Words 0x0E–0x0F.
    pub serial_number: u32,
    /// SM0, the standard receive mailbox (master → slave): start address and size.
    pub mailbox_out: (u16, u16),
    /// SM1, the standard send mailbox (slave → master): start address and size.
    pub mailbox_in: (u16, u16),
    /// SM2 (process-data outputs) start address.
    pub outputs_start: u16,
    /// SM3 (process-data inputs) start address.
    pub inputs_start: u16,
    /// Word 0x1C, see [`mailbox_protocol`].
    pub mailbox_protocols: u16,
    /// GENERAL byte 5, see [`coe_details`].
    pub coe_details: u8,
    /// GENERAL byte 9: CiA 402 axes.
    pub ds402_channels: u8,
    /// GENERAL byte 11.
    pub flags: u8,
    /// GENERAL bytes 12–13: current taken from the E-bus, mA.
    pub ebus_current_ma: i16,
    /// GENERAL bytes 16–17 (ETG.2010 PhysicalPort): 4 bits per port, 1 = MII.
    pub physical_ports: u16,
    /// Group type string (ESI `GroupType`), GENERAL GroupIdx.
    pub group_type: &'a str,
    /// Long device name (GENERAL NameIdx); empty: the description's product name.
    pub device_name: &'a str,
    /// RxPDOs assigned to SM2 by default (1C12h).
    pub rx_assigned: &'a [u16],
    /// TxPDOs assigned to SM3 by default (1C13h).
    pub tx_assigned: &'a [u16],
    /// Word 0x3F.
    pub version: u16,
}

impl SiiConfig<'static> {
    /// The ESC reference baseline of spec §3.5: one CiA 402 axis, two MII
    /// ports, CoE with SDO information, no complete access, PDOs 1600h / 1A00h on SM2 / SM3.
    pub const BASELINE: SiiConfig<'static> = SiiConfig {
        pdi_control: 0x0005,
        pdi_config: 0,
        sync_impulse_len: 0,
        station_alias: 0,
        serial_number: 0,
        mailbox_out: (0x1000, 0x0080),
        mailbox_in: (0x1080, 0x0080),
        outputs_start: 0x1100,
        inputs_start: 0x1180,
        mailbox_protocols: mailbox_protocol::COE,
        coe_details: coe_details::SDO
            | coe_details::SDO_INFO
            | coe_details::PDO_ASSIGN
            | coe_details::PDO_CONFIG,
        ds402_channels: 1,
        flags: 0,
        ebus_current_ma: 0,
        physical_ports: 0x0011,
        group_type: "Drives",
        device_name: "",
        rx_assigned: &[0x1600],
        tx_assigned: &[0x1A00],
        version: 1,
    };

    /// The layout of `desc`'s device file (`[device.ethercat]`) on the baseline; the baseline
    /// alone for a description without an EtherCAT section.
    pub fn from_description(desc: &od::DeviceDescription) -> Self {
        let Some(e) = desc.ethercat else {
            return Self::BASELINE;
        };
        let mut coe = coe_details::SDO | coe_details::PDO_ASSIGN | coe_details::PDO_CONFIG;
        if e.sdo_info {
            coe |= coe_details::SDO_INFO;
        }
        if e.complete_access {
            coe |= coe_details::SDO_COMPLETE_ACCESS;
        }
        SiiConfig {
            pdi_control: e.pdi_control,
            mailbox_out: e.mailbox_out,
            mailbox_in: e.mailbox_in,
            outputs_start: e.outputs_start,
            inputs_start: e.inputs_start,
            coe_details: coe,
            ds402_channels: e.ds402_channels,
            physical_ports: e.physical_ports,
            group_type: e.group_type,
            rx_assigned: e.rx_assigned,
            tx_assigned: e.tx_assigned,
            version: e.version,
            ..Self::BASELINE
        }
    }
}

impl Default for SiiConfig<'static> {
    fn default() -> Self {
        Self::BASELINE
    }
}

/// Direction of a PDO.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PdoDir {
    /// RxPDO, outputs (master → slave), mapping objects 1600h–17FFh, SM2.
    Rx,
    /// TxPDO, inputs (slave → master), mapping objects 1A00h–1BFFh, SM3.
    Tx,
}

impl PdoDir {
    pub const fn mapping_range(self) -> core::ops::RangeInclusive<u16> {
        match self {
            PdoDir::Rx => 0x1600..=0x17FF,
            PdoDir::Tx => 0x1A00..=0x1BFF,
        }
    }
    pub const fn sm(self) -> u8 {
        match self {
            PdoDir::Rx => 2,
            PdoDir::Tx => 3,
        }
    }
    pub const fn category(self) -> u16 {
        match self {
            PdoDir::Rx => category::RX_PDO,
            PdoDir::Tx => category::TX_PDO,
        }
    }
    fn assigned<'a>(self, cfg: &SiiConfig<'a>) -> &'a [u16] {
        match self {
            PdoDir::Rx => cfg.rx_assigned,
            PdoDir::Tx => cfg.tx_assigned,
        }
    }
}

/// One default mapping entry of a PDO mapping object, decoded from `index << 16 | sub << 8 | bits`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MappedEntry {
    pub index: u16,
    pub sub: u8,
    pub bits: u8,
}

impl MappedEntry {
    pub const fn from_u32(v: u32) -> Self {
        MappedEntry {
            index: (v >> 16) as u16,
            sub: (v >> 8) as u8,
            bits: v as u8,
        }
    }
    /// The mapped entry's description (`None` for padding or an unknown object).
    pub fn entry(&self, desc: &od::DeviceDescription) -> Option<&'static od::Entry> {
        if self.index == 0 {
            return None;
        }
        desc.entry(self.index, self.sub)
    }
}

fn le_u32(bytes: &[u8]) -> u32 {
    let mut b = [0u8; 4];
    for (d, s) in b.iter_mut().zip(bytes) {
        *d = *s;
    }
    u32::from_le_bytes(b)
}

/// The default mapping of a PDO mapping object: sub 0 gives the count, subs 1… the entries.
/// Errors when the count names a missing sub-entry.
pub fn default_mapping(
    obj: &od::Object,
) -> Result<impl Iterator<Item = MappedEntry> + Clone + '_, SiiError> {
    let count = obj
        .entry(0)
        .map(|e| le_u32(e.default))
        .ok_or(SiiError::BadMapping(obj.index))?;
    if count > 255 {
        return Err(SiiError::BadMapping(obj.index));
    }
    let count = count as u8;
    for sub in 1..=count {
        if obj.entry(sub).is_none() {
            return Err(SiiError::BadMapping(obj.index));
        }
    }
    Ok((1..=count).filter_map(move |sub| {
        obj.entry(sub)
            .map(|e| MappedEntry::from_u32(le_u32(e.default)))
    }))
}

/// Sum of the default mapping bit lengths of the PDOs `assigned`.
pub fn assigned_bits(desc: &od::DeviceDescription, assigned: &[u16]) -> Result<u32, SiiError> {
    let mut bits = 0u32;
    for &index in assigned {
        let obj = desc.object(index).ok_or(SiiError::PdoNotFound(index))?;
        for m in default_mapping(obj)? {
            bits += u32::from(m.bits);
        }
    }
    Ok(bits)
}

/// The PDO mapping objects of `dir` in the description.
pub fn pdo_objects(
    desc: &od::DeviceDescription,
    dir: PdoDir,
) -> impl Iterator<Item = &'static od::Object> + Clone {
    let range = dir.mapping_range();
    let objects: &'static [od::Object] = desc.objects;
    objects.iter().filter(move |o| range.contains(&o.index))
}

/// A PDO's display name, shared by the SII and the ESI export: the PDOs assigned by default
/// are "Outputs" / "Inputs", as ESI files of drives require ("Name must be 'Outputs' for RxPDO
/// and 'Inputs' for TxPDO"); the optional ones "RxPDO n" / "TxPDO n"
/// with n counted from 1 (1601h = RxPDO 2, as CiA 301 numbers them).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PdoName {
    buf: [u8; 12],
    len: u8,
}

impl PdoName {
    pub fn new(dir: PdoDir, index: u16, assigned: bool) -> Self {
        let mut buf = [0u8; 12];
        let prefix: &[u8] = match (dir, assigned) {
            (PdoDir::Rx, true) => b"Outputs",
            (PdoDir::Tx, true) => b"Inputs",
            (PdoDir::Rx, false) => b"RxPDO ",
            (PdoDir::Tx, false) => b"TxPDO ",
        };
        let mut len = 0usize;
        for (d, s) in buf.iter_mut().zip(prefix) {
            *d = *s;
            len += 1;
        }
        if !assigned {
            let n = u32::from(index.wrapping_sub(*dir.mapping_range().start())) + 1;
            let mut digits = [0u8; 5];
            let mut k = 0;
            let mut v = n;
            loop {
                if let Some(d) = digits.get_mut(k) {
                    *d = b'0' + (v % 10) as u8;
                }
                k += 1;
                v /= 10;
                if v == 0 || k == digits.len() {
                    break;
                }
            }
            for i in (0..k).rev() {
                if let (Some(d), Some(s)) = (buf.get_mut(len), digits.get(i)) {
                    *d = *s;
                    len += 1;
                }
            }
        }
        PdoName {
            buf,
            len: len as u8,
        }
    }
    pub fn as_bytes(&self) -> &[u8] {
        self.buf.get(..usize::from(self.len)).unwrap_or(&[])
    }
    pub fn as_str(&self) -> &str {
        core::str::from_utf8(self.as_bytes()).unwrap_or("")
    }
}

impl core::fmt::Display for PdoName {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// CRC-8 of the ESC configuration area: polynomial 0x07, initial value 0xFF, no reflection, no
/// final XOR (spec §3.2).
pub fn crc8(data: &[u8]) -> u8 {
    let mut crc = 0xFFu8;
    for &b in data {
        crc ^= b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ 0x07
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// The checksum word 7 must hold for the first 14 bytes of `image` (words 0–6).
pub fn config_checksum(image: &[u8]) -> u16 {
    let mut area = [0xFFu8; 14];
    for (d, s) in area.iter_mut().zip(image) {
        *d = *s;
    }
    u16::from(crc8(&area))
}

/// Word `word_addr` of `image`; 0xFFFF beyond the image (an erased EEPROM, spec §2.4).
pub fn read_word(image: &[u8], word_addr: u32) -> u16 {
    let i = word_addr as usize * 2;
    match image.get(i..i + 2) {
        Some(&[lo, hi]) => u16::from_le_bytes([lo, hi]),
        _ => 0xFFFF,
    }
}

/// What the ESC puts into its data registers 0x0508… after a read command at `word_addr`:
/// `out.len()` bytes (4 or 8, register 0x0502 bit 6) of consecutive words, 0xFF beyond the image.
pub fn read_into(image: &[u8], word_addr: u32, out: &mut [u8]) {
    for (k, pair) in out.chunks_mut(2).enumerate() {
        let w = read_word(image, word_addr.wrapping_add(k as u32)).to_le_bytes();
        for (d, s) in pair.iter_mut().zip(w) {
            *d = s;
        }
    }
}

/// A master's write command: one word at `word_addr`. Words beyond the image are refused.
pub fn write_word(image: &mut [u8], word_addr: u32, value: u16) -> Result<(), SiiError> {
    let i = word_addr as usize * 2;
    match image.get_mut(i..i + 2) {
        Some(w) => {
            w.copy_from_slice(&value.to_le_bytes());
            Ok(())
        }
        None => Err(SiiError::BufferTooSmall),
    }
}

/// Sets the configured station alias (word 4) and recomputes the checksum (word 7), as
/// ethercrab's `set_alias_address` does.
pub fn set_station_alias(image: &mut [u8], alias: u16) -> Result<(), SiiError> {
    write_word(image, u32::from(word::STATION_ALIAS), alias)?;
    let crc = config_checksum(image);
    write_word(image, u32::from(word::CHECKSUM), crc)
}

/// One category of an image, as [`categories`] finds it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Category<'a> {
    pub kind: u16,
    /// Word address of the category header.
    pub word_addr: u32,
    /// The data (length word × 2 bytes, cut at the image end).
    pub data: &'a [u8],
}

/// Walks the categories from word 0x40 to the END marker (or the image end).
pub fn categories(image: &[u8]) -> Categories<'_> {
    Categories {
        image,
        word_addr: u32::from(word::FIRST_CATEGORY),
    }
}

/// Iterator of [`categories`].
#[derive(Debug, Clone)]
pub struct Categories<'a> {
    image: &'a [u8],
    word_addr: u32,
}

impl<'a> Iterator for Categories<'a> {
    type Item = Category<'a>;
    fn next(&mut self) -> Option<Category<'a>> {
        let kind = read_word(self.image, self.word_addr);
        if kind == category::END {
            return None;
        }
        let len = read_word(self.image, self.word_addr + 1);
        let start = (self.word_addr as usize + 2) * 2;
        let end = (start + usize::from(len) * 2).min(self.image.len());
        let data = self.image.get(start..end).unwrap_or(&[]);
        let c = Category {
            kind,
            word_addr: self.word_addr,
            data,
        };
        self.word_addr += 2 + u32::from(len);
        Some(c)
    }
}

/// The string at 1-based `index` of a STRINGS category's data (`None` for 0 or out of range).
pub fn string_at(strings: &[u8], index: u8) -> Option<&[u8]> {
    if index == 0 {
        return None;
    }
    let count = *strings.first()?;
    let mut pos = 1usize;
    for i in 1..=count {
        let len = usize::from(*strings.get(pos)?);
        let s = strings.get(pos + 1..pos + 1 + len)?;
        if i == index {
            return Some(s);
        }
        pos += 1 + len;
    }
    None
}

struct Writer<'b> {
    buf: &'b mut [u8],
    pos: usize,
}

impl Writer<'_> {
    fn u8(&mut self, v: u8) -> Result<(), SiiError> {
        let slot = self.buf.get_mut(self.pos).ok_or(SiiError::BufferTooSmall)?;
        *slot = v;
        self.pos += 1;
        Ok(())
    }
    fn u16(&mut self, v: u16) -> Result<(), SiiError> {
        self.bytes(&v.to_le_bytes())
    }
    fn u32(&mut self, v: u32) -> Result<(), SiiError> {
        self.bytes(&v.to_le_bytes())
    }
    fn bytes(&mut self, b: &[u8]) -> Result<(), SiiError> {
        let d = self
            .buf
            .get_mut(self.pos..self.pos + b.len())
            .ok_or(SiiError::BufferTooSmall)?;
        d.copy_from_slice(b);
        self.pos += b.len();
        Ok(())
    }
    fn zeros(&mut self, n: usize) -> Result<(), SiiError> {
        for _ in 0..n {
            self.u8(0)?;
        }
        Ok(())
    }
    fn put_u16_at(&mut self, at: usize, v: u16) -> Result<(), SiiError> {
        let d = self
            .buf
            .get_mut(at..at + 2)
            .ok_or(SiiError::BufferTooSmall)?;
        d.copy_from_slice(&v.to_le_bytes());
        Ok(())
    }
    /// Writes a category header with a placeholder length; returns where the data starts.
    fn begin(&mut self, kind: u16) -> Result<usize, SiiError> {
        self.u16(kind)?;
        self.u16(0)?;
        Ok(self.pos)
    }
    /// Pads to a whole word and patches the length word.
    fn end(&mut self, data_start: usize) -> Result<(), SiiError> {
        if !(self.pos - data_start).is_multiple_of(2) {
            self.u8(0)?;
        }
        let words = (self.pos - data_start) / 2;
        let words = u16::try_from(words).map_err(|_| SiiError::BufferTooSmall)?;
        self.put_u16_at(data_start - 2, words)
    }
}

/// The STRINGS category being written: strings are de-duplicated, so asking again for the
/// same text gives the same index.
struct Strings {
    /// Position of the count byte.
    start: usize,
    count: u8,
}

impl Strings {
    fn find(&self, buf: &[u8], end: usize, s: &[u8]) -> Option<u8> {
        let table = buf.get(self.start..end)?;
        (1..=self.count).find(|&i| string_at(table, i) == Some(s))
    }
    fn intern(&mut self, w: &mut Writer<'_>, s: &[u8]) -> Result<u8, SiiError> {
        if s.is_empty() {
            return Ok(0);
        }
        if let Some(i) = self.find(w.buf, w.pos, s) {
            return Ok(i);
        }
        let len = u8::try_from(s.len()).map_err(|_| SiiError::StringTooLong)?;
        if self.count == u8::MAX {
            return Err(SiiError::TooManyStrings);
        }
        w.u8(len)?;
        w.bytes(s)?;
        self.count += 1;
        if let Some(c) = w.buf.get_mut(self.start) {
            *c = self.count;
        }
        Ok(self.count)
    }
}

/// String indices of the fixed strings.
struct Names {
    order: u8,
    name: u8,
    group: u8,
}

/// Visits every PDO of both directions with its name and its default entries, in the order
/// the PDO categories list them.
fn for_each_pdo_string(
    desc: &od::DeviceDescription,
    cfg: &SiiConfig<'_>,
    mut f: impl FnMut(&[u8]) -> Result<(), SiiError>,
) -> Result<(), SiiError> {
    for dir in [PdoDir::Tx, PdoDir::Rx] {
        for obj in pdo_objects(desc, dir) {
            let assigned = dir.assigned(cfg).contains(&obj.index);
            f(PdoName::new(dir, obj.index, assigned).as_bytes())?;
            for m in default_mapping(obj)? {
                if let Some(e) = m.entry(desc) {
                    f(e.name.as_bytes())?;
                }
            }
        }
    }
    Ok(())
}

/// Builds the SII image of `desc` into `out` and returns the bytes used (through the END
/// marker). The rest of `out` is filled with 0xFF (erased EEPROM); word 0x3E gives
/// `out.len()` as the EEPROM size, so pass the whole EEPROM (e.g. [`DEFAULT_IMAGE_SIZE`] bytes,
/// a multiple of 128, at most 4 KiB for SOEM's cache, spec §3.4).
pub fn build_sii(
    desc: &od::DeviceDescription,
    cfg: &SiiConfig<'_>,
    out: &mut [u8],
) -> Result<usize, SiiError> {
    if out.len() < 128 || !out.len().is_multiple_of(128) || out.len() > 128 * 0x1_0000 {
        return Err(SiiError::BufferTooSmall);
    }
    out.fill(0);
    let size_word = (out.len() / 128 - 1) as u16;

    // Process-data sizes of the default assignment.
    let out_bytes = assigned_bits(desc, cfg.rx_assigned)?.div_ceil(8);
    let in_bytes = assigned_bits(desc, cfg.tx_assigned)?.div_ceil(8);
    let out_len = u16::try_from(out_bytes).map_err(|_| SiiError::SmOverlap)?;
    let in_len = u16::try_from(in_bytes).map_err(|_| SiiError::SmOverlap)?;
    check_windows(cfg, out_len, in_len)?;

    let mut w = Writer { buf: out, pos: 0 };

    // Words 0x00–0x07: ESC configuration area.
    w.u16(cfg.pdi_control)?;
    w.u16(cfg.pdi_config)?;
    w.u16(cfg.sync_impulse_len)?;
    w.u16(0)?; // extended PDI configuration
    w.u16(cfg.station_alias)?;
    w.u16(0)?;
    w.u16(0)?;
    let crc = config_checksum(w.buf);
    w.u16(crc)?;
    // Words 0x08–0x0F: identity.
    w.u32(desc.vendor_id)?;
    w.u32(desc.product_code)?;
    w.u32(desc.revision)?;
    w.u32(cfg.serial_number)?;
    // Words 0x10–0x13: execution delay, port delays, reserved.
    w.zeros(8)?;
    // Words 0x14–0x17: bootstrap mailboxes (not supported).
    w.zeros(8)?;
    // Words 0x18–0x1B: standard mailboxes.
    w.u16(cfg.mailbox_out.0)?;
    w.u16(cfg.mailbox_out.1)?;
    w.u16(cfg.mailbox_in.0)?;
    w.u16(cfg.mailbox_in.1)?;
    w.u16(cfg.mailbox_protocols)?;
    // Words 0x1D–0x3D reserved.
    w.zeros((0x3E - 0x1D) * 2)?;
    w.u16(size_word)?;
    w.u16(cfg.version)?;
    let first_category = w.pos;

    // STRINGS.
    let data = w.begin(category::STRINGS)?;
    let mut strings = Strings {
        start: data,
        count: 0,
    };
    w.u8(0)?;
    let order = strings.intern(&mut w, desc.product_name.as_bytes())?;
    let long = if cfg.device_name.is_empty() {
        desc.product_name
    } else {
        cfg.device_name
    };
    let name = strings.intern(&mut w, long.as_bytes())?;
    let group = strings.intern(&mut w, cfg.group_type.as_bytes())?;
    for_each_pdo_string(desc, cfg, |s| strings.intern(&mut w, s).map(|_| ()))?;
    w.end(data)?;
    let strings_end = w.pos;
    let names = Names { order, name, group };

    // GENERAL (ETG.2010 Tab. 4, spec §3.3).
    let data = w.begin(category::GENERAL)?;
    w.u8(names.group)?;
    w.u8(0)?; // image
    w.u8(names.order)?;
    w.u8(names.name)?;
    w.u8(0)?; // reserved
    w.u8(cfg.coe_details)?;
    w.u8(u8::from(cfg.mailbox_protocols & mailbox_protocol::FOE != 0))?;
    w.u8(u8::from(cfg.mailbox_protocols & mailbox_protocol::EOE != 0))?;
    w.u8(0)?; // SoE channels
    w.u8(cfg.ds402_channels)?;
    w.u8(0)?; // SysmanClass
    w.u8(cfg.flags)?;
    w.bytes(&cfg.ebus_current_ma.to_le_bytes())?;
    w.zeros(2)?; // 14: GroupIdx copy / ethercrab "ports": 0, see the module notes
    w.u16(cfg.physical_ports)?;
    w.zeros(14)?; // physical memory address, reserved
    w.end(data)?;

    // FMMU: outputs, inputs, mailbox state (spec §3.3 baseline 01 02 03 00).
    let data = w.begin(category::FMMU)?;
    w.bytes(&[
        fmmu_usage::OUTPUTS,
        fmmu_usage::INPUTS,
        fmmu_usage::MAILBOX_STATE,
        fmmu_usage::UNUSED,
    ])?;
    w.end(data)?;

    // SYNCM: SM0…SM3.
    let data = w.begin(category::SYNC_M)?;
    let sms = [
        (
            cfg.mailbox_out.0,
            cfg.mailbox_out.1,
            SM0_CONTROL,
            sm_type::MAILBOX_OUT,
        ),
        (
            cfg.mailbox_in.0,
            cfg.mailbox_in.1,
            SM1_CONTROL,
            sm_type::MAILBOX_IN,
        ),
        (cfg.outputs_start, out_len, SM2_CONTROL, sm_type::OUTPUTS),
        (cfg.inputs_start, in_len, SM3_CONTROL, sm_type::INPUTS),
    ];
    for (start, len, control, kind) in sms {
        w.u16(start)?;
        w.u16(len)?;
        w.u8(control)?;
        w.u8(0)?;
        w.u8(SM_ENABLE)?;
        w.u8(kind)?;
    }
    w.end(data)?;

    // TXPDO, then RXPDO.
    for dir in [PdoDir::Tx, PdoDir::Rx] {
        if pdo_objects(desc, dir).next().is_none() {
            continue;
        }
        let data = w.begin(dir.category())?;
        for obj in pdo_objects(desc, dir) {
            let assigned = dir.assigned(cfg).contains(&obj.index);
            let count = default_mapping(obj)?.count();
            let count = u8::try_from(count).map_err(|_| SiiError::BadMapping(obj.index))?;
            let pdo_name = PdoName::new(dir, obj.index, assigned);
            let name_idx = lookup(&strings, &w, strings_end, pdo_name.as_bytes());
            w.u16(obj.index)?;
            w.u8(count)?;
            w.u8(if assigned { dir.sm() } else { 0xFF })?;
            w.u8(0)?; // DC sync
            w.u8(name_idx)?;
            // Flags: bit 1 "default" for the PDOs of the default assignment.
            w.u16(if assigned { 0x0002 } else { 0 })?;
            for m in default_mapping(obj)? {
                let (name_idx, data_type) = match m.entry(desc) {
                    Some(e) => (
                        lookup(&strings, &w, strings_end, e.name.as_bytes()),
                        e.data_type.code() as u8,
                    ),
                    None => (0, 0),
                };
                w.u16(m.index)?;
                w.u8(m.sub)?;
                w.u8(name_idx)?;
                w.u8(data_type)?;
                w.u8(m.bits)?;
                w.u16(0)?; // flags
            }
        }
        w.end(data)?;
    }

    let end_marker = w.pos;
    w.u16(category::END)?;
    let used = w.pos;

    // No 0xFFFF word before END (KickCAT's read stops at the first one, spec §3.4).
    let mut a = first_category;
    while a < end_marker {
        let v = read_word(w.buf, (a / 2) as u32);
        if v == 0xFFFF {
            return Err(SiiError::ReservedWord((a / 2) as u16));
        }
        a += 2;
    }
    if let Some(rest) = w.buf.get_mut(used..) {
        rest.fill(0xFF);
    }
    Ok(used)
}

fn lookup(strings: &Strings, w: &Writer<'_>, strings_end: usize, s: &[u8]) -> u8 {
    if s.is_empty() {
        return 0;
    }
    strings.find(w.buf, strings_end, s).unwrap_or(0)
}

/// SM windows must not overlap; SM2 and SM3 are 3-buffered (spec §3.3: 3 × length).
fn check_windows(cfg: &SiiConfig<'_>, out_len: u16, in_len: u16) -> Result<(), SiiError> {
    let win = |start: u16, len: u16, bufs: u32| {
        let s = u32::from(start);
        (s, s + u32::from(len) * bufs)
    };
    let w = [
        win(cfg.mailbox_out.0, cfg.mailbox_out.1, 1),
        win(cfg.mailbox_in.0, cfg.mailbox_in.1, 1),
        win(cfg.outputs_start, out_len, 3),
        win(cfg.inputs_start, in_len, 3),
    ];
    for (i, a) in w.iter().enumerate() {
        if a.1 > 0x1_0000 {
            return Err(SiiError::SmOverlap);
        }
        for b in w.iter().skip(i + 1) {
            if a.0 < b.1 && b.0 < a.1 {
                return Err(SiiError::SmOverlap);
            }
        }
    }
    Ok(())
}
