//! CiA 301 §7.3.5: the CAN-IDs no configurable COB-ID may use, and the write rules of the
//! COB-ID objects of SYNC (1005h), TIME (1012h) and EMCY (1014h), §7.5.2.5 / .16 / .17.
//! The PDO COB-IDs follow the same restriction through `pdo_rules`.
//!
//! Decisions: a write that CiA 301 forbids is aborted with 0609 0030h ("invalid value"), as
//! CANopenNode answers it; only 11-bit identifiers exist here (bit 29 = 1 is refused), and no
//! drivetwin personality produces SYNC or TIME, so their "generate" bit is refused too.

use crate::AbortCode;

/// CAN-IDs reserved for NMT, SYNC / EMCY of node 0, the default SDO, LSS and NMT error
/// control (CiA 301 §7.3.5): 000h, 001h–07Fh, 101h–180h, 581h–5FFh, 601h–67Fh, 6E0h–6FFh,
/// 701h–77Fh, 780h–7FFh.
pub fn restricted_can_id(id: u32) -> bool {
    matches!(
        id,
        0x000..=0x07F | 0x101..=0x180 | 0x581..=0x5FF | 0x601..=0x67F | 0x6E0..=0x6FF | 0x701..=0x7FF
    )
}

/// Bit 29 of a COB-ID: a 29-bit identifier.
const EXTENDED: u32 = 1 << 29;
/// Bits 11…28: the upper part of a 29-bit identifier, 0 for an 11-bit one.
const UPPER_ID: u32 = 0x1FFF_F800;
const CAN_ID: u32 = 0x7FF;

/// Which COB-ID object a write goes to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CobIdObject {
    /// 1005h: bit 30 "generate" (this device a SYNC producer).
    Sync,
    /// 1012h: bit 31 "consume", bit 30 "produce".
    Time,
    /// 1014h: bit 31 "invalid" (no EMCY sent).
    Emcy,
}

impl CobIdObject {
    /// The COB-ID object at `index`, sub-index 0.
    pub fn of(index: u16, sub: u8) -> Option<Self> {
        match (index, sub) {
            (0x1005, 0) => Some(CobIdObject::Sync),
            (0x1012, 0) => Some(CobIdObject::Time),
            (0x1014, 0) => Some(CobIdObject::Emcy),
            _ => None,
        }
    }

    /// Checks the write of `new` over `current`.
    pub fn check(self, current: u32, new: u32) -> Result<(), AbortCode> {
        if new & (EXTENDED | UPPER_ID) != 0 {
            return Err(AbortCode::INVALID_VALUE);
        }
        let id = new & CAN_ID;
        let used = match self {
            CobIdObject::Sync | CobIdObject::Time if new & (1 << 30) != 0 => {
                // No personality here produces SYNC or TIME.
                return Err(AbortCode::INVALID_VALUE);
            }
            CobIdObject::Sync => true,
            CobIdObject::Time => new & (1 << 31) != 0,
            CobIdObject::Emcy => {
                let valid = new & (1 << 31) == 0;
                // §7.5.2.17: bits 0…29 may not change while the EMCY exists (bit 31 = 0).
                if valid && current & (1 << 31) == 0 && id != current & CAN_ID {
                    return Err(AbortCode::INVALID_VALUE);
                }
                valid
            }
        };
        if used && restricted_can_id(id) {
            return Err(AbortCode::INVALID_VALUE);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn restricted_ranges_of_cia_301_7_3_5() {
        for id in [
            0x000, 0x001, 0x002, 0x07F, 0x101, 0x180, 0x581, 0x5FF, 0x601, 0x67F,
        ] {
            assert!(restricted_can_id(id), "{id:03X}h");
        }
        for id in [0x6E0, 0x6FF, 0x701, 0x77F, 0x780, 0x7FF] {
            assert!(restricted_can_id(id), "{id:03X}h");
        }
        for id in [
            0x080, 0x081, 0x0FF, 0x100, 0x181, 0x580, 0x600, 0x680, 0x6DF, 0x700,
        ] {
            assert!(!restricted_can_id(id), "{id:03X}h");
        }
    }

    #[test]
    fn sync_refuses_restricted_ids_generate_and_29_bit() {
        let sync = CobIdObject::Sync;
        assert_eq!(sync.check(0x80, 0x81), Ok(()));
        assert_eq!(sync.check(0x80, 0x80), Ok(()));
        for bad in [
            0x000,
            0x001,
            0x002,
            0x701,
            0x4000_0080,
            0x2000_0080,
            0x0000_1080,
        ] {
            assert_eq!(
                sync.check(0x80, bad),
                Err(AbortCode::INVALID_VALUE),
                "{bad:08X}h"
            );
        }
    }

    #[test]
    fn emcy_id_changes_only_while_invalid() {
        let emcy = CobIdObject::Emcy;
        assert_eq!(emcy.check(0x81, 0x8000_0081), Ok(()), "switched off");
        assert_eq!(
            emcy.check(0x8000_0081, 0x8000_0090),
            Ok(()),
            "new id while off"
        );
        assert_eq!(emcy.check(0x8000_0090, 0x90), Ok(()), "switched on");
        assert_eq!(
            emcy.check(0x81, 0x90),
            Err(AbortCode::INVALID_VALUE),
            "changed while on"
        );
        assert_eq!(
            emcy.check(0x8000_0081, 0x601),
            Err(AbortCode::INVALID_VALUE)
        );
        assert_eq!(
            emcy.check(0x8000_0081, 0x8000_0601),
            Ok(()),
            "restricted while off"
        );
    }
}
