//! The CDR encoding ROS 2 puts on the wire and in bags: little-endian XCDR1 (OMG DDS-XTypes
//! "PLAIN_CDR"), behind the 4-byte encapsulation header `00 01 00 00`. Every primitive is
//! aligned to its own size (at most 8) from the first byte after that header; a string is its
//! byte count with the terminating NUL, its bytes and the NUL; a sequence is its element count,
//! then the elements; a fixed-size array is its elements alone.

/// A CDR message being written.
pub struct CdrWriter {
    buf: Vec<u8>,
}

/// Representation identifier of little-endian plain CDR (`CDR_LE`).
const CDR_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    pub fn new() -> CdrWriter {
        CdrWriter::with_capacity(64)
    }

    pub fn with_capacity(bytes: usize) -> CdrWriter {
        let mut buf = Vec::with_capacity(bytes + CDR_LE.len());
        buf.extend_from_slice(&CDR_LE);
        CdrWriter { buf }
    }

    /// The encoded message, header included.
    pub fn finish(self) -> Vec<u8> {
        self.buf
    }

    fn align(&mut self, n: usize) {
        let at = self.buf.len() - CDR_LE.len();
        let pad = (n - at % n) % n;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    pub fn bool(&mut self, v: bool) {
        self.buf.push(v as u8);
    }

    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f32(&mut self, v: f32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A sequence's or a string's length. CDR counts in 32 bits; nothing sqscan writes comes
    /// near that (a sweep's points are at most 2^24).
    pub fn count(&mut self, n: usize) {
        self.u32(u32::try_from(n).unwrap_or(u32::MAX));
    }

    pub fn string(&mut self, s: &str) {
        self.count(s.len() + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// `uint8[]`.
    pub fn bytes(&mut self, b: &[u8]) {
        self.count(b.len());
        self.buf.extend_from_slice(b);
    }

    /// `float64[]`.
    pub fn f64_seq(&mut self, v: &[f64]) {
        self.count(v.len());
        for &x in v {
            self.f64(x);
        }
    }

    /// `string[]`.
    pub fn string_seq<S: AsRef<str>>(&mut self, v: &[S]) {
        self.count(v.len());
        for s in v {
            self.string(s.as_ref());
        }
    }
}

/// A CDR message being read: every read checks the bytes are there, and says what it was
/// reading where they are not.
#[derive(Debug)]
pub struct CdrReader<'a> {
    buf: &'a [u8],
    at: usize,
}

impl<'a> CdrReader<'a> {
    /// After its encapsulation header, which must say little-endian plain CDR.
    pub fn new(buf: &'a [u8]) -> Result<CdrReader<'a>, String> {
        match buf.get(..4) {
            Some(h) if h[..2] == CDR_LE[..2] => Ok(CdrReader { buf, at: 4 }),
            Some(h) if h[..2] == [0, 0] => Err("big-endian CDR is not read".into()),
            Some(h) => Err(format!("encapsulation {:02x} {:02x} is not plain CDR", h[0], h[1])),
            None => Err(format!("{} bytes: no CDR encapsulation header", buf.len())),
        }
    }

    fn take(&mut self, n: usize, align: usize, what: &str) -> Result<&'a [u8], String> {
        let pad = (align - (self.at - 4) % align) % align;
        let start = self.at + pad;
        match start.checked_add(n).filter(|&end| end <= self.buf.len()) {
            Some(end) => {
                self.at = end;
                Ok(&self.buf[start..end])
            }
            None => Err(format!(
                "{what}: {n} bytes at byte {start}, past the message's end ({} bytes)",
                self.buf.len()
            )),
        }
    }

    pub fn u8(&mut self, what: &str) -> Result<u8, String> {
        Ok(self.take(1, 1, what)?[0])
    }

    pub fn bool(&mut self, what: &str) -> Result<bool, String> {
        Ok(self.u8(what)? != 0)
    }

    pub fn u32(&mut self, what: &str) -> Result<u32, String> {
        let b = self.take(4, 4, what)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    pub fn i32(&mut self, what: &str) -> Result<i32, String> {
        Ok(self.u32(what)? as i32)
    }

    pub fn f64(&mut self, what: &str) -> Result<f64, String> {
        let b = self.take(8, 8, what)?;
        Ok(f64::from_le_bytes(b.try_into().unwrap_or([0; 8])))
    }

    /// A string: UTF-8, its NUL dropped.
    pub fn string(&mut self, what: &str) -> Result<&'a str, String> {
        let n = self.u32(what)? as usize;
        let b = self.take(n, 1, what)?;
        let b = b.strip_suffix(&[0]).unwrap_or(b);
        std::str::from_utf8(b).map_err(|_| format!("{what}: not UTF-8"))
    }

    /// `uint8[]`.
    pub fn bytes(&mut self, what: &str) -> Result<&'a [u8], String> {
        let n = self.u32(what)? as usize;
        self.take(n, 1, what)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The layout of a `std_msgs/Header` followed by a float64, worked out by hand from the
    /// rules: the float is aligned to 8 from the end of the encapsulation header.
    #[test]
    fn primitives_are_aligned_from_after_the_encapsulation_header() {
        let mut w = CdrWriter::new();
        w.i32(7);
        w.u32(500);
        w.string("ab");
        w.f64(1.5);
        let b = w.finish();
        let mut want = vec![0, 1, 0, 0];
        want.extend_from_slice(&7i32.to_le_bytes());
        want.extend_from_slice(&500u32.to_le_bytes());
        want.extend_from_slice(&3u32.to_le_bytes());
        want.extend_from_slice(b"ab\0");
        // 15 bytes so far after the header: one byte of padding to 16.
        want.push(0);
        want.extend_from_slice(&1.5f64.to_le_bytes());
        assert_eq!(b, want);
    }

    #[test]
    fn sequences_carry_their_count() {
        let mut w = CdrWriter::new();
        w.bool(true);
        w.bytes(&[9, 8]);
        w.string_seq(&["x"]);
        let b = w.finish();
        assert_eq!(
            b,
            [
                0, 1, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 9, 8, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, b'x', 0
            ]
        );
    }

    /// What the writer wrote, the reader reads; a message cut short is an error that names the
    /// field, never a panic.
    #[test]
    fn the_reader_reads_what_the_writer_wrote_and_no_further() {
        let mut w = CdrWriter::new();
        w.u8(3);
        w.f64(-2.5);
        w.string("frame");
        w.bytes(&[1, 2, 3]);
        w.i32(-7);
        let b = w.finish();
        let mut r = CdrReader::new(&b).unwrap();
        assert_eq!(r.u8("a").unwrap(), 3);
        assert_eq!(r.f64("b").unwrap(), -2.5);
        assert_eq!(r.string("c").unwrap(), "frame");
        assert_eq!(r.bytes("d").unwrap(), &[1, 2, 3]);
        assert_eq!(r.i32("e").unwrap(), -7);
        assert!(r.u32("past").unwrap_err().contains("past"));
        for cut in 0..b.len() {
            let Ok(mut r) = CdrReader::new(&b[..cut]) else { continue };
            let all = (|| -> Result<(), String> {
                r.u8("a")?;
                r.f64("b")?;
                r.string("c")?;
                r.bytes("d")?;
                r.i32("e")?;
                Ok(())
            })();
            assert!(all.is_err(), "{cut} bytes read as whole");
        }
        let mut huge = vec![0, 1, 0, 0];
        huge.extend_from_slice(&u32::MAX.to_le_bytes());
        assert!(
            CdrReader::new(&huge)
                .unwrap()
                .bytes("data")
                .unwrap_err()
                .contains("data")
        );
        assert!(CdrReader::new(&[0, 0, 0, 0]).unwrap_err().contains("big-endian"));
    }
}
