//! A bounds-checked little-endian reader over the file's bytes. Every length read from the file
//! passes through here, so a truncated or hostile file becomes an error with an offset, never an
//! out-of-bounds access or a huge allocation.

use crate::error::{PResult, ParseError};

/// Longest string (grid name, type name, metadata key) accepted: anything longer is corrupt.
pub const MAX_STRING: usize = 1 << 20;

#[derive(Clone)]
pub(crate) struct Cursor<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    pub fn new(data: &'a [u8], pos: usize) -> Self {
        Cursor { data, pos }
    }

    pub fn pos(&self) -> usize {
        self.pos
    }

    pub fn offset(&self) -> u64 {
        self.pos as u64
    }

    pub fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    pub fn seek(&mut self, pos: u64, what: &str) -> PResult<()> {
        if pos > self.data.len() as u64 {
            return Err(ParseError::corrupt(
                self.offset(),
                format!(
                    "{what} offset {pos} is past the end of the file ({} bytes)",
                    self.data.len()
                ),
            ));
        }
        self.pos = pos as usize;
        Ok(())
    }

    pub fn take(&mut self, n: usize, what: &str) -> PResult<&'a [u8]> {
        if n > self.remaining() {
            return Err(ParseError::corrupt(
                self.offset(),
                format!(
                    "truncated: {what} needs {n} bytes but only {} remain",
                    self.remaining()
                ),
            ));
        }
        let s = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    fn array<const N: usize>(&mut self, what: &str) -> PResult<[u8; N]> {
        let s = self.take(N, what)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }

    pub fn u8(&mut self, what: &str) -> PResult<u8> {
        Ok(self.array::<1>(what)?[0])
    }
    pub fn u32(&mut self, what: &str) -> PResult<u32> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }
    pub fn i32(&mut self, what: &str) -> PResult<i32> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }
    pub fn i64(&mut self, what: &str) -> PResult<i64> {
        Ok(i64::from_le_bytes(self.array(what)?))
    }
    pub fn f32(&mut self, what: &str) -> PResult<f32> {
        Ok(f32::from_le_bytes(self.array(what)?))
    }
    pub fn f64(&mut self, what: &str) -> PResult<f64> {
        Ok(f64::from_le_bytes(self.array(what)?))
    }
    pub fn vec3d(&mut self, what: &str) -> PResult<[f64; 3]> {
        Ok([self.f64(what)?, self.f64(what)?, self.f64(what)?])
    }
    pub fn coord(&mut self, what: &str) -> PResult<[i32; 3]> {
        Ok([self.i32(what)?, self.i32(what)?, self.i32(what)?])
    }

    /// A u32-length-prefixed byte string (OpenVDB's `readString`).
    pub fn string(&mut self, what: &str) -> PResult<String> {
        let at = self.offset();
        let n = self.u32(what)? as usize;
        if n > MAX_STRING || n > self.remaining() {
            return Err(ParseError::corrupt(
                at,
                format!(
                    "{what}: string length {n} is absurd ({} bytes remain)",
                    self.remaining()
                ),
            ));
        }
        let s = self.take(n, what)?;
        Ok(String::from_utf8_lossy(s).into_owned())
    }

    /// A bit mask of `words` u64 words, as OpenVDB's `NodeMask::load` stores it.
    pub fn mask_into(&mut self, out: &mut [u64], what: &str) -> PResult<()> {
        let s = self.take(out.len() * 8, what)?;
        for (w, b) in out.iter_mut().zip(s.chunks_exact(8)) {
            *w = u64::from_le_bytes(b.try_into().expect("chunk of 8"));
        }
        Ok(())
    }

    /// Checks that `count` items of at least `min_size` bytes each can still follow.
    pub fn check_count(&self, count: u64, min_size: u64, what: &str) -> PResult<()> {
        if count.saturating_mul(min_size) > self.remaining() as u64 {
            return Err(ParseError::corrupt(
                self.offset(),
                format!(
                    "{what}: count {count} cannot fit in the {} bytes that remain",
                    self.remaining()
                ),
            ));
        }
        Ok(())
    }
}
