//! What a master takes from an SII image it has read word by word (spec §3):
//! when it has read enough, the identity, the standard mailbox, the device name and the sync
//! manager defaults. The image layout and the category walk are [`crate::sii`]'s.

use crate::esc::MailboxLayout;
use crate::sii::{self, category, word};
use crate::sync_manager::SyncManager;

/// The most a master reads (SOEM caches at most 4 KiB, `EC_MAXEEPBUF`; spec §3.4).
pub const MAX_IMAGE: usize = 4096;

/// Bytes of one SYNC_M category entry.
const SM_ENTRY_LEN: usize = 8;

/// Whether `image` (the first `image.len()` bytes of the EEPROM) holds the whole category
/// list up to its END marker. An image that reaches [`MAX_IMAGE`] counts as complete, as
/// does a category list that runs past it.
pub fn is_complete(image: &[u8]) -> bool {
    if image.len() >= MAX_IMAGE {
        return true;
    }
    let mut at = u32::from(word::FIRST_CATEGORY);
    loop {
        // Header: type word (END has nothing after it), then the length word.
        if (at as usize + 1) * 2 > image.len() {
            return false;
        }
        if sii::read_word(image, at) == category::END {
            return true;
        }
        if (at as usize + 2) * 2 > image.len() {
            return false;
        }
        at += 2 + u32::from(sii::read_word(image, at + 1));
        if at as usize * 2 >= MAX_IMAGE {
            return true;
        }
    }
}

/// Identity words 0x08–0x0F (spec §3.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Identity {
    pub vendor_id: u32,
    pub product_code: u32,
    pub revision: u32,
    pub serial: u32,
}

fn read_u32(image: &[u8], at: u16) -> u32 {
    let lo = u32::from(sii::read_word(image, u32::from(at)));
    let hi = u32::from(sii::read_word(image, u32::from(at) + 1));
    lo | (hi << 16)
}

pub fn identity(image: &[u8]) -> Identity {
    Identity {
        vendor_id: read_u32(image, word::VENDOR_ID),
        product_code: read_u32(image, word::PRODUCT_CODE),
        revision: read_u32(image, word::REVISION),
        serial: read_u32(image, word::SERIAL),
    }
}

/// The standard mailbox (words 0x18–0x1B), `None` without one (receive size 0).
pub fn mailbox(image: &[u8]) -> Option<MailboxLayout> {
    MailboxLayout::from_sii(image)
}

/// Mailbox protocols (word 0x1C: 0x0004 CoE, …).
pub fn mailbox_protocols(image: &[u8]) -> u16 {
    sii::read_word(image, u32::from(word::MAILBOX_PROTOCOLS))
}

fn find(image: &[u8], kind: u16) -> Option<&[u8]> {
    sii::categories(image)
        .find(|c| c.kind == kind)
        .map(|c| c.data)
}

/// The device name: string 1 of the STRINGS category, as SOEM takes it (spec §3.3).
pub fn name(image: &[u8]) -> Option<&[u8]> {
    sii::string_at(find(image, category::STRINGS)?, 1)
}

/// Sync manager `n` as the SYNC_M category describes it: start, default length, control
/// byte, enable bit (spec §3.3); status and PDI control 0, as a master writes them.
pub fn sync_manager(image: &[u8], n: usize) -> Option<SyncManager> {
    let data = find(image, category::SYNC_M)?;
    let e = data.get(n * SM_ENTRY_LEN..(n + 1) * SM_ENTRY_LEN)?;
    let start = u16::from_le_bytes([*e.first()?, *e.get(1)?]);
    let length = u16::from_le_bytes([*e.get(2)?, *e.get(3)?]);
    Some(SyncManager::new(
        start,
        length,
        *e.get(4)?,
        e.get(6)? & sii::SM_ENABLE != 0,
    ))
}

/// The mailbox sync managers SM0 (receive) and SM1 (send) a master writes before Pre-Op:
/// start and length from words 0x18–0x1B (ethercrab and KickCAT take the length from
/// there), control bytes from SYNC_M when it has them, else the usual 0x26 / 0x22
/// (spec §2.6), both enabled.
pub fn mailbox_sync_managers(image: &[u8]) -> Option<[SyncManager; 2]> {
    let m = mailbox(image)?;
    let control = |n: usize, default: u8| sync_manager(image, n).map_or(default, |s| s.control);
    Some([
        SyncManager::new(m.rx_offset, m.rx_size, control(0, sii::SM0_CONTROL), true),
        SyncManager::new(m.tx_offset, m.tx_size, control(1, sii::SM1_CONTROL), true),
    ])
}
