//! ROS 2's wire encoding: OMG CDR (XCDR1, "plain CDR"), little-endian, as rmw implementations and
//! rosbag2 write it.
//!
//! A serialized message is a 4-byte encapsulation header (`00 01 00 00`: plain CDR,
//! little-endian; `00 00 00 00` is the big-endian variant, which [`CdrReader`] also reads) and
//! the fields in declaration order. Each primitive is aligned to its own size (8 at most),
//! counted from the end of the encapsulation header; a string is its byte length including a
//! terminating NUL (`u32`), the bytes and the NUL; a sequence is its element count (`u32`) and
//! the elements; a fixed-size array is its elements only.
//!
//! The reader checks every length against the bytes that remain, so a malformed message is a
//! [`CdrError`], never a panic or an allocation larger than the input.

use thiserror::Error;

/// The encapsulation header of a little-endian plain-CDR message.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];
/// The encapsulation header of a big-endian plain-CDR message.
pub const CDR_BE_HEADER: [u8; 4] = [0x00, 0x00, 0x00, 0x00];

/// What was wrong with a CDR message.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CdrError {
    /// Fewer than 4 bytes: no encapsulation header.
    #[error("CDR message of {0} bytes: shorter than its 4-byte encapsulation header")]
    NoHeader(usize),
    /// An encapsulation other than plain CDR (XCDR2, parameter lists, ...).
    #[error("unsupported CDR encapsulation {0:02x} {1:02x} (only plain CDR, 00 00 / 00 01)")]
    Encapsulation(u8, u8),
    /// The message ends inside a field.
    #[error("CDR message truncated: {field} needs {needed} bytes at offset {offset}, {left} left")]
    Truncated {
        /// The field being read.
        field: &'static str,
        /// Bytes the field needs.
        needed: usize,
        /// Offset in the payload (after the header).
        offset: usize,
        /// Bytes left.
        left: usize,
    },
    /// A string without its terminating NUL, or with a length of 0.
    #[error("CDR string `{0}` is not NUL-terminated (or has length 0)")]
    Unterminated(&'static str),
    /// A string that is not UTF-8.
    #[error("CDR string `{0}` is not valid UTF-8")]
    Utf8(&'static str),
    /// A `bool` byte other than 0 or 1.
    #[error("CDR bool `{0}` holds {1}, not 0 or 1")]
    Bool(&'static str, u8),
    /// A sequence longer than the bytes left could hold.
    #[error("CDR sequence `{field}` claims {count} elements, more than the {left} bytes left")]
    SequenceTooLong {
        /// The field.
        field: &'static str,
        /// The count it claims.
        count: u32,
        /// Bytes left.
        left: usize,
    },
    /// Bytes left over after the last field (beyond the 3 bytes of padding CDR allows).
    #[error("{0} bytes left over after the message's last field")]
    Trailing(usize),
    /// A value the message type constrains (e.g. a beam count that changed) is out of range.
    #[error("invalid message: {0}")]
    Invalid(String),
}

/// Writes a CDR message (little-endian, plain CDR), header included.
#[derive(Debug, Clone)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    /// An empty message with its encapsulation header.
    pub fn new() -> Self {
        Self::with_capacity(64)
    }

    /// As [`CdrWriter::new`], reserving `n` bytes.
    pub fn with_capacity(n: usize) -> Self {
        let mut buf = Vec::with_capacity(n + 4);
        buf.extend_from_slice(&CDR_LE_HEADER);
        Self { buf }
    }

    fn align(&mut self, n: usize) {
        let pos = self.buf.len() - 4;
        let pad = (n - pos % n) % n;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    /// Writes a `u8` (also `byte`, `char`, `int8` by cast).
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }
    /// Writes a `bool`.
    pub fn bool(&mut self, v: bool) {
        self.buf.push(u8::from(v));
    }
    /// Writes an `int8`.
    pub fn i8(&mut self, v: i8) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Writes a `uint16`.
    pub fn u16(&mut self, v: u16) {
        self.align(2);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Writes an `int16`.
    pub fn i16(&mut self, v: i16) {
        self.align(2);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Writes a `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Writes an `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Writes a `uint64`.
    pub fn u64(&mut self, v: u64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Writes an `int64`.
    pub fn i64(&mut self, v: i64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Writes a `float32`.
    pub fn f32(&mut self, v: f32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Writes a `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// Writes a `string` (length with the NUL, bytes, NUL).
    ///
    /// # Panics
    /// If the string is longer than `u32::MAX - 1` bytes.
    pub fn string(&mut self, s: &str) {
        self.seq_len(s.len() + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }
    /// Writes a sequence's element count.
    ///
    /// # Panics
    /// If `n` exceeds `u32::MAX` (a CDR sequence cannot hold more).
    pub fn seq_len(&mut self, n: usize) {
        let n = u32::try_from(n).unwrap_or_else(|_| panic!("CDR sequence of {n} > u32::MAX"));
        self.u32(n);
    }
    /// Writes raw bytes (the elements of a `uint8[]` after its count).
    pub fn bytes(&mut self, b: &[u8]) {
        self.buf.extend_from_slice(b);
    }
    /// Writes `float32` elements (after their count, if a sequence).
    pub fn f32_slice(&mut self, v: &[f32]) {
        if v.is_empty() {
            return;
        }
        self.align(4);
        self.buf.reserve(4 * v.len());
        for x in v {
            self.buf.extend_from_slice(&x.to_le_bytes());
        }
    }
    /// The message so far, header included.
    pub fn as_bytes(&self) -> &[u8] {
        &self.buf
    }
    /// The finished message, header included.
    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

/// Reads a CDR message (plain CDR, either byte order).
#[derive(Debug, Clone)]
pub struct CdrReader<'a> {
    data: &'a [u8],
    pos: usize,
    big_endian: bool,
}

macro_rules! read_num {
    ($(#[$m:meta])* $name:ident, $t:ty, $n:expr) => {
        $(#[$m])*
        pub fn $name(&mut self, field: &'static str) -> Result<$t, CdrError> {
            self.align($n, field)?;
            let b = self.take($n, field)?;
            let mut a = [0u8; $n];
            a.copy_from_slice(b);
            Ok(if self.big_endian { <$t>::from_be_bytes(a) } else { <$t>::from_le_bytes(a) })
        }
    };
}

impl<'a> CdrReader<'a> {
    /// A reader over a whole message, header included.
    ///
    /// # Errors
    /// [`CdrError::NoHeader`] or [`CdrError::Encapsulation`].
    pub fn new(message: &'a [u8]) -> Result<Self, CdrError> {
        if message.len() < 4 {
            return Err(CdrError::NoHeader(message.len()));
        }
        let big_endian = match (message[0], message[1]) {
            (0x00, 0x01) => false,
            (0x00, 0x00) => true,
            (a, b) => return Err(CdrError::Encapsulation(a, b)),
        };
        Ok(Self {
            data: &message[4..],
            pos: 0,
            big_endian,
        })
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    fn align(&mut self, n: usize, field: &'static str) -> Result<(), CdrError> {
        let pad = (n - self.pos % n) % n;
        self.take(pad, field).map(|_| ())
    }

    fn take(&mut self, n: usize, field: &'static str) -> Result<&'a [u8], CdrError> {
        if self.remaining() < n {
            return Err(CdrError::Truncated {
                field,
                needed: n,
                offset: self.pos,
                left: self.remaining(),
            });
        }
        let s = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    /// Reads a `uint8`.
    pub fn u8(&mut self, field: &'static str) -> Result<u8, CdrError> {
        Ok(self.take(1, field)?[0])
    }
    /// Reads an `int8`.
    pub fn i8(&mut self, field: &'static str) -> Result<i8, CdrError> {
        Ok(self.take(1, field)?[0] as i8)
    }
    /// Reads a `bool` (0 or 1; anything else is an error).
    pub fn bool(&mut self, field: &'static str) -> Result<bool, CdrError> {
        match self.u8(field)? {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(CdrError::Bool(field, v)),
        }
    }
    read_num!(
        /// Reads a `uint16`.
        u16, u16, 2);
    read_num!(
        /// Reads an `int16`.
        i16, i16, 2);
    read_num!(
        /// Reads a `uint32`.
        u32, u32, 4);
    read_num!(
        /// Reads an `int32`.
        i32, i32, 4);
    read_num!(
        /// Reads a `uint64`.
        u64, u64, 8);
    read_num!(
        /// Reads an `int64`.
        i64, i64, 8);
    read_num!(
        /// Reads a `float32`.
        f32, f32, 4);
    read_num!(
        /// Reads a `float64`.
        f64, f64, 8);

    /// Reads a `string`.
    pub fn string(&mut self, field: &'static str) -> Result<String, CdrError> {
        let n = self.u32(field)? as usize;
        if n == 0 {
            return Err(CdrError::Unterminated(field));
        }
        let b = self.take(n, field)?;
        let (nul, text) = b.split_last().ok_or(CdrError::Unterminated(field))?;
        if *nul != 0 {
            return Err(CdrError::Unterminated(field));
        }
        String::from_utf8(text.to_vec()).map_err(|_| CdrError::Utf8(field))
    }

    /// Reads a sequence's count and checks that `min_elem_bytes` per element fit in what is
    /// left (so the caller may reserve `count` elements).
    pub fn seq_len(
        &mut self,
        field: &'static str,
        min_elem_bytes: usize,
    ) -> Result<usize, CdrError> {
        let count = self.u32(field)?;
        let left = self.remaining();
        if (count as usize).saturating_mul(min_elem_bytes.max(1)) > left
            && !(min_elem_bytes == 0 && count == 0)
        {
            return Err(CdrError::SequenceTooLong { field, count, left });
        }
        Ok(count as usize)
    }

    /// Reads `n` raw bytes.
    pub fn bytes(&mut self, n: usize, field: &'static str) -> Result<Vec<u8>, CdrError> {
        Ok(self.take(n, field)?.to_vec())
    }

    /// Checks that nothing but alignment padding (at most 7 bytes) is left.
    pub fn finish(self) -> Result<(), CdrError> {
        match self.remaining() {
            n if n < 8 => Ok(()),
            n => Err(CdrError::Trailing(n)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_counts_from_the_end_of_the_header() {
        let mut w = CdrWriter::new();
        w.u8(7);
        w.f64(1.5);
        w.string("ab");
        let b = w.finish();
        // header, u8, 7 bytes of padding, f64, u32 len 3, "ab\0"
        assert_eq!(b.len(), 4 + 1 + 7 + 8 + 4 + 3);
        let mut r = CdrReader::new(&b).unwrap();
        assert_eq!(r.u8("a").unwrap(), 7);
        assert_eq!(r.f64("b").unwrap(), 1.5);
        assert_eq!(r.string("c").unwrap(), "ab");
        r.finish().unwrap();
    }

    #[test]
    fn malformed_input_is_an_error() {
        assert_eq!(CdrReader::new(&[0, 1]).unwrap_err(), CdrError::NoHeader(2));
        assert!(matches!(
            CdrReader::new(&[0, 7, 0, 0]),
            Err(CdrError::Encapsulation(0, 7))
        ));
        let mut r = CdrReader::new(&[0, 1, 0, 0, 0xff, 0xff, 0xff, 0xff]).unwrap();
        assert!(matches!(
            r.seq_len("s", 1),
            Err(CdrError::SequenceTooLong { .. })
        ));
        let mut r = CdrReader::new(&[0, 1, 0, 0, 2, 0, 0, 0, b'a', b'b']).unwrap();
        assert_eq!(r.string("t").unwrap_err(), CdrError::Unterminated("t"));
        let mut r = CdrReader::new(&[0, 1, 0, 0, 2]).unwrap();
        assert_eq!(r.bool("flag").unwrap_err(), CdrError::Bool("flag", 2));
    }

    #[test]
    fn big_endian_messages_are_read() {
        let b = [0, 0, 0, 0, 0, 0, 0, 5];
        let mut r = CdrReader::new(&b).unwrap();
        assert_eq!(r.u32("n").unwrap(), 5);
    }
}
