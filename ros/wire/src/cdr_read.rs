//! A CDR reader for what arrives from the network (service and action requests): XCDR1,
//! little endian, after the 4-byte encapsulation header, primitives aligned to their size
//! counted from the end of that header (as [`crate::cdr::CdrWriter`] writes them). Every
//! read is bounds-checked: a truncated or malformed request is a [`CdrError`], never a
//! panic.

use thiserror::Error;

/// Why a request's bytes could not be read.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CdrError {
    /// Fewer than the 4 bytes of the encapsulation header.
    #[error("{len} bytes: shorter than the 4-byte CDR encapsulation header")]
    NoHeader {
        /// The bytes received.
        len: usize,
    },
    /// An encapsulation other than little-endian plain CDR (`00 01`).
    #[error("CDR encapsulation {0:02x} {1:02x}: only little-endian plain CDR (00 01) is accepted")]
    Encapsulation(u8, u8),
    /// The bytes end before the field does.
    #[error("truncated: `{field}` needs {need} bytes at offset {offset}, {len} bytes in all")]
    Truncated {
        /// The field being read.
        field: &'static str,
        /// Its offset after the header.
        offset: usize,
        /// The bytes it needs.
        need: usize,
        /// The payload's length after the header.
        len: usize,
    },
    /// A `bool` that is neither 0 nor 1.
    #[error("`{field}` = {value}: a bool is 0 or 1")]
    Bool {
        /// The field.
        field: &'static str,
        /// The byte found.
        value: u8,
    },
}

/// Reads one message's fields in order.
#[derive(Debug, Clone)]
pub struct CdrReader<'a> {
    body: &'a [u8],
    pos: usize,
}

impl<'a> CdrReader<'a> {
    /// A reader over `bytes` (header included), the header checked.
    pub fn new(bytes: &'a [u8]) -> Result<Self, CdrError> {
        let (header, body) = bytes
            .split_at_checked(4)
            .ok_or(CdrError::NoHeader { len: bytes.len() })?;
        if header[0] != 0x00 || header[1] != 0x01 {
            return Err(CdrError::Encapsulation(header[0], header[1]));
        }
        Ok(Self { body, pos: 0 })
    }

    fn take(&mut self, field: &'static str, n: usize, align: usize) -> Result<&'a [u8], CdrError> {
        let start = self.pos.next_multiple_of(align);
        let end = start.checked_add(n).filter(|&e| e <= self.body.len());
        let Some(end) = end else {
            return Err(CdrError::Truncated {
                field,
                offset: start,
                need: n,
                len: self.body.len(),
            });
        };
        self.pos = end;
        Ok(&self.body[start..end])
    }

    /// A `uint8`.
    pub fn u8(&mut self, field: &'static str) -> Result<u8, CdrError> {
        Ok(self.take(field, 1, 1)?[0])
    }

    /// A `bool` (0 or 1).
    pub fn bool(&mut self, field: &'static str) -> Result<bool, CdrError> {
        match self.u8(field)? {
            0 => Ok(false),
            1 => Ok(true),
            value => Err(CdrError::Bool { field, value }),
        }
    }

    /// An `int32`.
    pub fn i32(&mut self, field: &'static str) -> Result<i32, CdrError> {
        let b = self.take(field, 4, 4)?;
        Ok(i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// A `uint32`.
    pub fn u32(&mut self, field: &'static str) -> Result<u32, CdrError> {
        let b = self.take(field, 4, 4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// A `float64`.
    pub fn f64(&mut self, field: &'static str) -> Result<f64, CdrError> {
        let b = self.take(field, 8, 8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(f64::from_le_bytes(a))
    }

    /// A `uint8[16]` (a UUID or a GID): 16 bytes, no count.
    pub fn bytes16(&mut self, field: &'static str) -> Result<[u8; 16], CdrError> {
        let b = self.take(field, 16, 1)?;
        let mut a = [0u8; 16];
        a.copy_from_slice(b);
        Ok(a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cdr::CdrWriter;

    #[test]
    fn reads_what_the_writer_wrote() {
        let mut w = CdrWriter::default();
        w.u8(7);
        w.f64(1.5);
        w.bool(true);
        w.i32(-3);
        w.u32(9);
        let b = w.into_bytes();
        let mut r = CdrReader::new(&b).expect("header");
        assert_eq!(r.u8("a"), Ok(7));
        assert_eq!(r.f64("b"), Ok(1.5));
        assert_eq!(r.bool("c"), Ok(true));
        assert_eq!(r.i32("d"), Ok(-3));
        assert_eq!(r.u32("e"), Ok(9));
        assert!(matches!(
            r.u8("f"),
            Err(CdrError::Truncated { field: "f", .. })
        ));
    }

    #[test]
    fn bad_headers_and_bools_are_errors() {
        assert_eq!(
            CdrReader::new(&[0, 1]).err(),
            Some(CdrError::NoHeader { len: 2 })
        );
        assert_eq!(
            CdrReader::new(&[0, 0, 0, 0]).err(),
            Some(CdrError::Encapsulation(0, 0))
        );
        let mut r = CdrReader::new(&[0, 1, 0, 0, 2]).expect("header");
        assert_eq!(
            r.bool("x"),
            Err(CdrError::Bool {
                field: "x",
                value: 2
            })
        );
        let mut r = CdrReader::new(&[0, 1, 0, 0, 1, 2, 3]).expect("header");
        assert!(r.bytes16("uuid").is_err());
        let mut r = CdrReader::new(&[0, 1, 0, 0, 1, 0, 0, 0, 1, 2]).expect("header");
        assert!(r.f64("late").is_err());
    }
}
