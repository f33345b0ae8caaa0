//! A bounds-checked cursor over an output buffer.

/// The output buffer is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Full;

pub(crate) struct Writer<'a> {
    buf: &'a mut [u8],
    pos: usize,
}

impl<'a> Writer<'a> {
    pub(crate) fn new(buf: &'a mut [u8]) -> Self {
        Writer { buf, pos: 0 }
    }

    pub(crate) fn len(&self) -> usize {
        self.pos
    }

    pub(crate) fn remaining(&self) -> usize {
        self.buf.len().saturating_sub(self.pos)
    }

    pub(crate) fn u8(&mut self, v: u8) -> Result<(), Full> {
        let slot = self.buf.get_mut(self.pos).ok_or(Full)?;
        *slot = v;
        self.pos += 1;
        Ok(())
    }

    pub(crate) fn u16(&mut self, v: u16) -> Result<(), Full> {
        self.bytes(&v.to_be_bytes())
    }

    pub(crate) fn bytes(&mut self, v: &[u8]) -> Result<(), Full> {
        let end = self.pos.checked_add(v.len()).ok_or(Full)?;
        let dst = self.buf.get_mut(self.pos..end).ok_or(Full)?;
        dst.copy_from_slice(v);
        self.pos = end;
        Ok(())
    }

    /// Overwrites one byte already written.
    pub(crate) fn patch(&mut self, at: usize, v: u8) -> Result<(), Full> {
        if at >= self.pos {
            return Err(Full);
        }
        let slot = self.buf.get_mut(at).ok_or(Full)?;
        *slot = v;
        Ok(())
    }
}
