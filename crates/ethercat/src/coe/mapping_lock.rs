//! The PDO assignment and mapping are changed in Pre-Op only (ETG.1000.6 §5.6.7.4, ETG.2000 "the
//! PDO configuration is taken on Pre-Op → Safe-Op"): in Safe-Op and Op a download to 1C12h / 1C13h
//! or to a mapping object 1600h–17FFh / 1A00h–1BFFh is refused with 0800 0022h ("… because of the
//! present device state"), the code SOES and TwinCAT's slaves give. Reads stay open. Everything
//! else passes through unchanged.

use od::{AbortCode, Forwarding, ObjectAccess};

/// An [`ObjectAccess`] that refuses PDO configuration writes while `locked`.
pub struct MappingLock<'a> {
    inner: &'a mut dyn ObjectAccess,
    locked: bool,
}

impl<'a> MappingLock<'a> {
    pub fn new(inner: &'a mut dyn ObjectAccess, locked: bool) -> Self {
        MappingLock { inner, locked }
    }

    /// Whether `index` is part of the PDO configuration.
    pub const fn is_pdo_configuration(index: u16) -> bool {
        matches!(index, 0x1600..=0x17FF | 0x1A00..=0x1BFF | 0x1C12 | 0x1C13)
    }
}

impl<'a> Forwarding for MappingLock<'a> {
    type Inner = dyn ObjectAccess + 'a;

    fn inner(&self) -> &Self::Inner {
        self.inner
    }
    fn inner_mut(&mut self) -> &mut Self::Inner {
        self.inner
    }

    fn on_write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        if self.locked && Self::is_pdo_configuration(index) {
            // The entry must exist and be writable first: a missing object still aborts
            // 0602 0000h, a read-only one 0601 0002h, as in Pre-Op.
            let entry = self.inner.entry(index, sub)?;
            if !entry.access.writable() {
                return Err(AbortCode::READ_ONLY);
            }
            return Err(AbortCode::DEVICE_STATE);
        }
        self.inner.write(index, sub, data)
    }
}
