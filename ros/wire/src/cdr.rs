//! A CDR writer: XCDR1, little endian, as DDS and rmw_zenoh carry ROS 2 messages. The
//! buffer starts with the 4-byte encapsulation header (`00 01 00 00`: CDR_LE); primitives
//! are aligned to their size, counted from the end of that header; strings are a `u32`
//! length including the terminating NUL, the bytes, and the NUL; sequences a `u32` count
//! and the elements.

/// The encapsulation header of little-endian plain CDR.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Writes one message's CDR bytes.
#[derive(Debug, Clone)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::with_capacity(64)
    }
}

impl CdrWriter {
    /// An empty message of room for `capacity` bytes, header written.
    pub fn with_capacity(capacity: usize) -> Self {
        let mut buf = Vec::with_capacity(capacity.max(4));
        buf.extend_from_slice(&CDR_LE_HEADER);
        Self { buf }
    }

    /// The bytes, header included.
    pub fn into_bytes(self) -> Vec<u8> {
        self.buf
    }

    fn align(&mut self, n: usize) {
        let offset = self.buf.len() - CDR_LE_HEADER.len();
        let pad = (n - offset % n) % n;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    /// A `uint8`, `byte` or `char`.
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// A `bool` (one byte, 0 or 1).
    pub fn bool(&mut self, v: bool) {
        self.buf.push(u8::from(v));
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A sequence's element count (saturating at `u32::MAX`, far beyond any message here).
    pub fn len(&mut self, n: usize) {
        self.u32(u32::try_from(n).unwrap_or(u32::MAX));
    }

    /// A `string`: length with the NUL, bytes, NUL.
    pub fn string(&mut self, s: &str) {
        self.len(s.len() + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// A `uint8[]` (or `byte[]`): count, then the bytes as they are.
    pub fn bytes(&mut self, data: &[u8]) {
        self.len(data.len());
        self.buf.extend_from_slice(data);
    }

    /// A `float32` sequence written as `uint8[]` (the `data` of a `32FC1` image): the count
    /// of bytes, then each value little endian.
    pub fn f32_as_bytes(&mut self, values: &[f32]) {
        self.len(values.len() * 4);
        self.buf.reserve(values.len() * 4);
        for v in values {
            self.buf.extend_from_slice(&v.to_le_bytes());
        }
    }

    /// A `float64[]`.
    pub fn f64_seq(&mut self, values: &[f64]) {
        self.len(values.len());
        if !values.is_empty() {
            self.align(8);
        }
        for v in values {
            self.buf.extend_from_slice(&v.to_le_bytes());
        }
    }

    /// A `string[]`.
    pub fn string_seq<S: AsRef<str>>(&mut self, values: &[S]) {
        self.len(values.len());
        for s in values {
            self.string(s.as_ref());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_counts_from_after_the_header() {
        let mut w = CdrWriter::default();
        w.u8(7);
        w.f64(1.0);
        w.string("ab");
        w.u32(5);
        let b = w.into_bytes();
        // header, u8, 7 pad to offset 8, f64, len 3 "ab\0", pad 1, u32
        assert_eq!(&b[..4], &CDR_LE_HEADER);
        assert_eq!(b[4], 7);
        assert!(b[5..12].iter().all(|&x| x == 0));
        assert_eq!(&b[12..20], &1.0f64.to_le_bytes());
        assert_eq!(&b[20..24], &3u32.to_le_bytes());
        assert_eq!(&b[24..27], b"ab\0");
        assert_eq!(b[27], 0);
        assert_eq!(&b[28..32], &5u32.to_le_bytes());
        assert_eq!(b.len(), 32);
    }

    #[test]
    fn an_empty_f64_sequence_is_just_its_count() {
        let mut w = CdrWriter::default();
        w.u8(1);
        w.f64_seq(&[]);
        assert_eq!(w.into_bytes().len(), 4 + 4 + 4);
    }
}
