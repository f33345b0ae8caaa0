//! An object access standing in front of another: a protocol's view of the dictionary (PDO
//! parameters locked in a state) or a front end that acts on what a write asked for (a storage
//! request) changes what a write does, and nothing else. The entries, the reads and the
//! device's own writes are the inner access's, so every front end still sees one set of
//! objects.

use crate::{AbortCode, Entry, ObjectAccess};

/// An [`ObjectAccess`] in front of [`Forwarding::Inner`]: every access goes to the inner one,
/// a write through [`Forwarding::on_write`], the one method an implementor changes. Any
/// `Forwarding` type is an [`ObjectAccess`].
pub trait Forwarding {
    /// The access behind this one.
    type Inner: ObjectAccess + ?Sized;

    fn inner(&self) -> &Self::Inner;
    fn inner_mut(&mut self) -> &mut Self::Inner;

    /// What [`ObjectAccess::write`] does: by default the inner access's write.
    fn on_write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.inner_mut().write(index, sub, data)
    }
}

impl<T: Forwarding> ObjectAccess for T {
    fn entry(&self, index: u16, sub: u8) -> Result<&'static Entry, AbortCode> {
        self.inner().entry(index, sub)
    }
    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        self.inner().read(index, sub, buf)
    }
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.on_write(index, sub, data)
    }
    fn write_internal(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.inner_mut().write_internal(index, sub, data)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One UNSIGNED8 value at 2000h:0; writes of either kind store it.
    struct Byte(u8);

    impl ObjectAccess for Byte {
        fn entry(&self, _: u16, _: u8) -> Result<&'static Entry, AbortCode> {
            Err(AbortCode::NO_OBJECT)
        }
        fn read(&self, index: u16, _: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
            match (index, buf.first_mut()) {
                (0x2000, Some(b)) => {
                    *b = self.0;
                    Ok(1)
                }
                _ => Err(AbortCode::NO_OBJECT),
            }
        }
        fn write(&mut self, _: u16, _: u8, data: &[u8]) -> Result<(), AbortCode> {
            self.0 = *data.first().ok_or(AbortCode::LENGTH_TOO_LOW)?;
            Ok(())
        }
        fn write_internal(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
            self.write(index, sub, data)
        }
    }

    /// Changes only the write: a master's write is refused, the device's own goes through.
    struct Locked<'a>(&'a mut Byte);

    impl Forwarding for Locked<'_> {
        type Inner = Byte;
        fn inner(&self) -> &Byte {
            self.0
        }
        fn inner_mut(&mut self) -> &mut Byte {
            self.0
        }
        fn on_write(&mut self, _: u16, _: u8, _: &[u8]) -> Result<(), AbortCode> {
            Err(AbortCode::DEVICE_STATE)
        }
    }

    /// Changes nothing.
    struct Plain<'a>(&'a mut Byte);

    impl Forwarding for Plain<'_> {
        type Inner = Byte;
        fn inner(&self) -> &Byte {
            self.0
        }
        fn inner_mut(&mut self) -> &mut Byte {
            self.0
        }
    }

    #[test]
    fn only_the_hooked_write_differs() {
        let mut byte = Byte(7);
        let mut locked = Locked(&mut byte);
        let access: &mut dyn ObjectAccess = &mut locked;
        assert_eq!(access.read_u8(0x2000, 0), Some(7));
        assert_eq!(access.entry(0x2000, 0), Err(AbortCode::NO_OBJECT));
        assert_eq!(access.write(0x2000, 0, &[9]), Err(AbortCode::DEVICE_STATE));
        assert_eq!(access.read_u8(0x2000, 0), Some(7));
        assert_eq!(access.write_internal(0x2000, 0, &[5]), Ok(()));
        assert_eq!(access.read_u8(0x2000, 0), Some(5));

        let mut plain = Plain(&mut byte);
        assert_eq!(plain.write(0x2000, 0, &[11]), Ok(()));
        assert_eq!(plain.read_u8(0x2000, 0), Some(11));
    }
}
