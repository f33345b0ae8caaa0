//! The SDO abort message over CoE (spec §6.5) and the abort codes ETG.1000.6
//! adds to CiA 301 for complete access and the mailbox.
//!
//! ```text
//! mailbox header (length 10, CoE) | CoE header 0x2000 | 0x80 | index | sub | code (u32)
//! ```
//!
//! The CoE header carries service 2 (SDO *request*), not 3: SOEM recognises an abort only in
//! its "not an SDO response" branch and would take a service-3 abort of a download for a
//! successful write (spec §6.5).

use od::AbortCode;

use super::service;

/// 0601 0004h: complete access not supported for this object (ETG.1000.6, spec §6.5).
pub const CA_NOT_SUPPORTED: AbortCode = AbortCode(0x0601_0004);
/// 0601 0005h: object length exceeds mailbox size (ETG.1000.6, spec §6.5).
pub const LENGTH_EXCEEDS_MAILBOX: AbortCode = AbortCode(0x0601_0005);

/// SDO command byte of an abort.
pub const ABORT_COMMAND: u8 = 0x80;

/// Write the CoE part of an abort (10 bytes) into `p`; returns 10.
pub fn encode(p: &mut [u8], index: u16, sub: u8, code: AbortCode) -> Option<usize> {
    let [il, ih] = index.to_le_bytes();
    let [c0, c1, c2, c3] = code.0.to_le_bytes();
    p.get_mut(..10)?.copy_from_slice(&[
        0x00,
        service::SDO_REQUEST << 4,
        ABORT_COMMAND,
        il,
        ih,
        sub,
        c0,
        c1,
        c2,
        c3,
    ]);
    Some(10)
}
