//! The SQPF profile frame: one laser profile per frame, little-endian throughout.
//!
//! ```text
//!  offset   size  field          meaning
//!  0        4     magic          "SQPF" (53 51 50 46)
//!  4        1     version        1
//!  5        1     flags          bit 0: intensity present; bits 1..7 reserved, must be 0
//!  6        2     header_len     u16, 24: bytes from the magic to the first range value
//!  8        4     seq            u32, +1 per profile, wraps at 2^32
//!  12       8     timestamp_ns   u64, exposure time on the sensor clock, ns
//!  20       2     columns        u16, N, 1..=8192
//!  22       1     fraction_bits  u8, 0..=15: row_px = raw / 2^fraction_bits (4 = 1/16 px)
//!  23       1     value_bits     u8, 16: width of one range value (only 16 is defined)
//!  24       2N    rows           N x u16: sub-pixel row of the laser line per column, 0 = no return
//!  24+2N    N     intensity      N x u8, only if flags bit 0
//!  end-4    4     crc32          CRC-32/IEEE over bytes [4, end-4): everything after the magic
//! ```
//! Frame length = 24 + 2N (+ N) + 4, at most 24 + 3 * 8192 + 4 = 24604 bytes.
//!
//! The header is checked before the payload arrives, so an absurd column count is rejected at
//! once instead of making the decoder wait for megabytes; the CRC then catches the rest.

use super::crc::{Crc32, crc32};

/// Frame start marker.
pub const MAGIC: [u8; 4] = *b"SQPF";
/// The only version this codec speaks.
pub const VERSION: u8 = 1;
/// Header bytes, magic included.
pub const HEADER_LEN: usize = 24;
/// flags bit 0: an intensity byte per column follows the range values.
pub const FLAG_INTENSITY: u8 = 0x01;
/// Most columns a frame may carry (high-resolution sensors have 3072; leave room).
pub const MAX_COLUMNS: u16 = 8192;
/// Most fraction bits that leave at least one integer bit in a 16-bit value.
pub const MAX_FRACTION_BITS: u8 = 15;
/// The only range value width defined.
pub const VALUE_BITS: u8 = 16;
const CRC_LEN: usize = 4;
/// The longest frame: every column with intensity.
pub const MAX_FRAME_LEN: usize = HEADER_LEN + 3 * MAX_COLUMNS as usize + CRC_LEN;

/// What is wrong with a profile frame (or with a profile to be encoded).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ProfileError {
    #[error("unsupported profile frame version {0}")]
    BadVersion(u8),
    #[error("reserved flag bits set: {0:#04x}")]
    BadFlags(u8),
    #[error("header length {0}, expected 24")]
    BadHeaderLen(u16),
    #[error("column count {0} outside 1..=8192")]
    BadColumnCount(usize),
    #[error("{0} fraction bits, at most 15")]
    BadFractionBits(u8),
    #[error("range value width {0} bits, only 16 is supported")]
    BadValueWidth(u8),
    #[error("bad CRC: received {received:#010x}, computed {computed:#010x}")]
    BadCrc { received: u32, computed: u32 },
    #[error("{intensity} intensity values for {columns} columns")]
    IntensityLength { columns: usize, intensity: usize },
}

/// One laser profile: the sub-pixel row of the laser line in each sensor column.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Profile {
    /// Sequence number, +1 per profile, wrapping.
    pub seq: u32,
    /// Exposure time on the sensor clock, ns.
    pub timestamp_ns: u64,
    /// Fixed-point fraction bits of `rows`.
    pub fraction_bits: u8,
    /// Raw fixed-point sub-pixel rows, one per column, counted from the ROI edge; 0 = no return.
    pub rows: Vec<u16>,
    /// Optional 8-bit intensity per column.
    pub intensity: Option<Vec<u8>>,
}

impl Profile {
    /// Number of columns.
    pub fn columns(&self) -> usize {
        self.rows.len()
    }

    /// Sub-pixel row of column `col` in pixels, `None` for no return (raw 0) or no such column.
    pub fn row_px(&self, col: usize) -> Option<f64> {
        let raw = *self.rows.get(col)?;
        if raw == 0 {
            return None;
        }
        // fraction_bits <= 15 for any decoded profile; clamp so a hand-built one cannot overflow.
        let scale = f64::from(1u32 << self.fraction_bits.min(31));
        Some(f64::from(raw) / scale)
    }

    /// Checks what the frame format can carry.
    pub fn validate(&self) -> Result<(), ProfileError> {
        let n = self.rows.len();
        if n == 0 || n > usize::from(MAX_COLUMNS) {
            return Err(ProfileError::BadColumnCount(n));
        }
        if self.fraction_bits > MAX_FRACTION_BITS {
            return Err(ProfileError::BadFractionBits(self.fraction_bits));
        }
        if let Some(i) = &self.intensity
            && i.len() != n
        {
            return Err(ProfileError::IntensityLength {
                columns: n,
                intensity: i.len(),
            });
        }
        Ok(())
    }
}

/// Encodes a profile as one SQPF frame. Fails if the profile does not fit the format.
pub fn encode_profile(p: &Profile) -> Result<Vec<u8>, ProfileError> {
    p.validate()?;
    let n = p.rows.len();
    // validate() bounds n by 8192, so it fits u16.
    let columns = u16::try_from(n).map_err(|_| ProfileError::BadColumnCount(n))?;
    let flags = if p.intensity.is_some() { FLAG_INTENSITY } else { 0 };
    let mut out = Vec::with_capacity(frame_len(n, p.intensity.is_some()));
    out.extend_from_slice(&MAGIC);
    out.push(VERSION);
    out.push(flags);
    out.extend_from_slice(&(HEADER_LEN as u16).to_le_bytes());
    out.extend_from_slice(&p.seq.to_le_bytes());
    out.extend_from_slice(&p.timestamp_ns.to_le_bytes());
    out.extend_from_slice(&columns.to_le_bytes());
    out.push(p.fraction_bits);
    out.push(VALUE_BITS);
    for r in &p.rows {
        out.extend_from_slice(&r.to_le_bytes());
    }
    if let Some(i) = &p.intensity {
        out.extend_from_slice(i);
    }
    let mut crc = Crc32::new();
    crc.update(out.get(MAGIC.len()..).unwrap_or(&[]));
    out.extend_from_slice(&crc.finish().to_le_bytes());
    Ok(out)
}

const fn frame_len(columns: usize, intensity: bool) -> usize {
    HEADER_LEN + columns * if intensity { 3 } else { 2 } + CRC_LEN
}

/// The validated fixed header.
#[derive(Clone, Copy, Debug)]
struct Header {
    intensity: bool,
    seq: u32,
    timestamp_ns: u64,
    columns: usize,
    fraction_bits: u8,
}

impl Header {
    fn frame_len(&self) -> usize {
        frame_len(self.columns, self.intensity)
    }
}

/// Fixed-size little-endian read at `off`; `None` past the end.
fn le<const N: usize>(b: &[u8], off: usize) -> Option<[u8; N]> {
    b.get(off..off.checked_add(N)?)?.try_into().ok()
}

/// Parses and checks the header at the start of `b` (which starts with the magic).
/// `Ok(None)`: not enough bytes yet.
fn parse_header(b: &[u8]) -> Result<Option<Header>, ProfileError> {
    let Some(h) = b.get(..HEADER_LEN) else {
        return Ok(None);
    };
    let field = |off: usize| h.get(off).copied().unwrap_or(0);
    let version = field(4);
    if version != VERSION {
        return Err(ProfileError::BadVersion(version));
    }
    let flags = field(5);
    if flags & !FLAG_INTENSITY != 0 {
        return Err(ProfileError::BadFlags(flags));
    }
    let header_len = u16::from_le_bytes(le(h, 6).unwrap_or_default());
    if usize::from(header_len) != HEADER_LEN {
        return Err(ProfileError::BadHeaderLen(header_len));
    }
    let columns = u16::from_le_bytes(le(h, 20).unwrap_or_default());
    if columns == 0 || columns > MAX_COLUMNS {
        return Err(ProfileError::BadColumnCount(usize::from(columns)));
    }
    let fraction_bits = field(22);
    if fraction_bits > MAX_FRACTION_BITS {
        return Err(ProfileError::BadFractionBits(fraction_bits));
    }
    let value_bits = field(23);
    if value_bits != VALUE_BITS {
        return Err(ProfileError::BadValueWidth(value_bits));
    }
    Ok(Some(Header {
        intensity: flags & FLAG_INTENSITY != 0,
        seq: u32::from_le_bytes(le(h, 8).unwrap_or_default()),
        timestamp_ns: u64::from_le_bytes(le(h, 12).unwrap_or_default()),
        columns: usize::from(columns),
        fraction_bits,
    }))
}

/// Checks the CRC of a complete frame `b` (exactly `hdr.frame_len()` bytes) and builds the profile.
fn parse_frame(hdr: &Header, b: &[u8]) -> Result<Profile, ProfileError> {
    let crc_at = hdr.frame_len() - CRC_LEN;
    let covered = b.get(MAGIC.len()..crc_at).unwrap_or(&[]);
    let received = u32::from_le_bytes(le(b, crc_at).unwrap_or_default());
    let computed = crc32(covered);
    if received != computed {
        return Err(ProfileError::BadCrc { received, computed });
    }
    let rows_end = HEADER_LEN + 2 * hdr.columns;
    let rows = b
        .get(HEADER_LEN..rows_end)
        .unwrap_or(&[])
        .chunks_exact(2)
        .map(|c| u16::from_le_bytes([c.first().copied().unwrap_or(0), c.get(1).copied().unwrap_or(0)]))
        .collect();
    let intensity = hdr
        .intensity
        .then(|| b.get(rows_end..rows_end + hdr.columns).unwrap_or(&[]).to_vec());
    Ok(Profile {
        seq: hdr.seq,
        timestamp_ns: hdr.timestamp_ns,
        fraction_bits: hdr.fraction_bits,
        rows,
        intensity,
    })
}

/// Decoder counters for diagnostics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ProfileDecoderStats {
    pub profiles: u64,
    pub errors: u64,
    /// Bytes dropped while scanning for the magic.
    pub skipped_bytes: u64,
}

/// Incremental SQPF decoder: push bytes as they arrive, pop profiles.
///
/// Resynchronisation: the decoder scans for the magic. A frame whose header or CRC is bad is
/// reported and the scan resumes one byte after that magic, never a whole claimed length
/// later (the length may be the corrupt part). Guarantee: a valid frame preceded by bytes that
/// contain no magic is decoded as soon as it is complete. If the preceding garbage does contain
/// a magic with a plausible header, that candidate claims up to [`MAX_FRAME_LEN`] bytes and the
/// valid frame is decoded once the candidate's CRC has been seen to fail, i.e. after at most
/// [`MAX_FRAME_LEN`] further bytes; a caller whose stream goes idle mid-candidate may call
/// [`ProfileDecoder::resync`] to drop the candidate at once.
#[derive(Debug, Default)]
pub struct ProfileDecoder {
    buf: Vec<u8>,
    stats: ProfileDecoderStats,
}

impl ProfileDecoder {
    pub fn new() -> Self {
        Self::default()
    }

    /// Queues received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// Decodes the next profile or error from queued bytes; `None` when more bytes are needed.
    pub fn next_profile(&mut self) -> Option<Result<Profile, ProfileError>> {
        // Find the magic; keep a possible partial magic at the end for the next push.
        let start = match find(&self.buf, &MAGIC) {
            Some(p) => p,
            None => {
                let keep = (MAGIC.len() - 1).min(self.buf.len());
                self.skip(self.buf.len() - keep);
                return None;
            }
        };
        self.skip(start);
        let hdr = match parse_header(&self.buf) {
            Ok(Some(h)) => h,
            Ok(None) => return None,
            Err(e) => return Some(self.reject(e)),
        };
        let len = hdr.frame_len();
        let frame = self.buf.get(..len)?;
        match parse_frame(&hdr, frame) {
            Ok(p) => {
                self.buf.drain(..len);
                self.stats.profiles += 1;
                Some(Ok(p))
            }
            Err(e) => Some(self.reject(e)),
        }
    }

    /// Drops the frame candidate in progress (if any) and rescans from the next byte: for a
    /// stream that went idle in the middle of what turned out not to be a frame.
    pub fn resync(&mut self) {
        if find(&self.buf, &MAGIC) == Some(0) {
            self.skip(1);
        }
    }

    /// Bytes queued but not yet consumed.
    pub fn pending(&self) -> usize {
        self.buf.len()
    }

    pub fn stats(&self) -> ProfileDecoderStats {
        self.stats
    }

    fn skip(&mut self, n: usize) {
        let n = n.min(self.buf.len());
        self.buf.drain(..n);
        self.stats.skipped_bytes += n as u64;
    }

    /// Reports `e` for the candidate at the buffer start and steps past its first magic byte.
    fn reject(&mut self, e: ProfileError) -> Result<Profile, ProfileError> {
        self.buf.drain(..1.min(self.buf.len()));
        self.stats.errors += 1;
        Err(e)
    }
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(intensity: bool) -> Profile {
        let rows: Vec<u16> = (0..1536u16).map(|c| if c % 7 == 0 { 0 } else { c * 3 + 5 }).collect();
        let intensity = intensity.then(|| (0..1536usize).map(|c| (c % 251) as u8).collect());
        Profile {
            seq: 41,
            timestamp_ns: 1_700_000_000_123_456_789,
            fraction_bits: 4,
            rows,
            intensity,
        }
    }

    fn decode_all(bytes: &[u8]) -> Vec<Result<Profile, ProfileError>> {
        let mut d = ProfileDecoder::new();
        d.push(bytes);
        std::iter::from_fn(|| d.next_profile()).collect()
    }

    #[test]
    fn byte_layout_of_a_small_frame() {
        let p = Profile {
            seq: 0x0403_0201,
            timestamp_ns: 0x0C0B_0A09_0807_0605,
            fraction_bits: 4,
            rows: vec![0x0010, 0x0000],
            intensity: Some(vec![0xAA, 0xBB]),
        };
        let b = encode_profile(&p).unwrap();
        let expected_head: [u8; 24] = [
            b'S', b'Q', b'P', b'F', 1, 0x01, 24, 0, // magic, version, flags, header_len
            0x01, 0x02, 0x03, 0x04, // seq
            0x05, 0x06, 0x07, 0x08, 0x09, 0x0A, 0x0B, 0x0C, // timestamp_ns
            2, 0, 4, 16, // columns, fraction_bits, value_bits
        ];
        assert_eq!(b[..24], expected_head);
        assert_eq!(b[24..30], [0x10, 0x00, 0x00, 0x00, 0xAA, 0xBB]);
        assert_eq!(b.len(), 24 + 6 + 4);
        assert_eq!(b[30..], crc32(&b[4..30]).to_le_bytes());
        assert_eq!(decode_all(&b), [Ok(p.clone())]);
        assert_eq!(p.row_px(0), Some(1.0));
        assert_eq!(p.row_px(1), None);
        assert_eq!(p.row_px(2), None);
    }

    #[test]
    fn round_trip_with_and_without_intensity() {
        for with in [false, true] {
            let p = sample(with);
            let b = encode_profile(&p).unwrap();
            assert_eq!(b.len(), 24 + 1536 * if with { 3 } else { 2 } + 4);
            assert_eq!(decode_all(&b), [Ok(p)]);
        }
    }

    #[test]
    fn row_px_is_fixed_point() {
        let p = Profile {
            seq: 0,
            timestamp_ns: 0,
            fraction_bits: 4,
            rows: vec![0, 1, 16, 0xFFFF, 24],
            intensity: None,
        };
        assert_eq!(p.row_px(0), None);
        assert_eq!(p.row_px(1), Some(1.0 / 16.0));
        assert_eq!(p.row_px(2), Some(1.0));
        assert_eq!(p.row_px(3), Some(65535.0 / 16.0));
        assert_eq!(p.row_px(4), Some(1.5));
        assert_eq!(p.row_px(5), None);
    }

    #[test]
    fn garbage_bad_crc_and_bad_headers_are_reported_and_skipped() {
        let good = encode_profile(&sample(true)).unwrap();
        let mut corrupt = good.clone();
        corrupt[100] ^= 0x40;
        let mut bad_version = good.clone();
        bad_version[4] = 2;
        let mut absurd = good.clone();
        absurd[20..22].copy_from_slice(&60000u16.to_le_bytes());

        let mut stream = b"noise SQP".to_vec();
        stream.extend_from_slice(&corrupt);
        stream.extend_from_slice(&bad_version);
        stream.extend_from_slice(&absurd);
        stream.extend_from_slice(&good);
        let items = decode_all(&stream);
        assert!(matches!(items[0], Err(ProfileError::BadCrc { .. })), "{:?}", items[0]);
        assert_eq!(items[1], Err(ProfileError::BadVersion(2)));
        assert_eq!(items[2], Err(ProfileError::BadColumnCount(60000)));
        assert_eq!(items[3], Ok(sample(true)));
        assert_eq!(items.len(), 4);
    }

    #[test]
    fn other_header_faults() {
        let good = encode_profile(&sample(false)).unwrap();
        let cases: [(usize, u8, ProfileError); 4] = [
            (5, 0x02, ProfileError::BadFlags(0x02)),
            (6, 25, ProfileError::BadHeaderLen(25)),
            (22, 16, ProfileError::BadFractionBits(16)),
            (23, 12, ProfileError::BadValueWidth(12)),
        ];
        for (off, v, err) in cases {
            let mut b = good.clone();
            b[off] = v;
            assert_eq!(decode_all(&b), [Err(err)]);
        }
        let mut zero = good;
        zero[20..22].copy_from_slice(&[0, 0]);
        assert_eq!(decode_all(&zero), [Err(ProfileError::BadColumnCount(0))]);
    }

    #[test]
    fn byte_at_a_time() {
        let mut stream = encode_profile(&sample(false)).unwrap();
        stream.extend(
            encode_profile(&Profile {
                seq: 42,
                ..sample(true)
            })
            .unwrap(),
        );
        let mut d = ProfileDecoder::new();
        let mut got = Vec::new();
        for b in &stream {
            d.push(std::slice::from_ref(b));
            while let Some(item) = d.next_profile() {
                got.push(item);
            }
        }
        assert_eq!(
            got,
            [
                Ok(sample(false)),
                Ok(Profile {
                    seq: 42,
                    ..sample(true)
                })
            ]
        );
        assert_eq!(d.pending(), 0);
    }

    #[test]
    fn resync_drops_a_stalled_candidate() {
        // A fake header claiming 8192 columns, then a real frame, then silence.
        let mut fake = encode_profile(&Profile {
            rows: vec![1; 8192],
            ..sample(false)
        })
        .unwrap();
        fake.truncate(HEADER_LEN);
        let good = encode_profile(&sample(false)).unwrap();
        let mut d = ProfileDecoder::new();
        d.push(&fake);
        d.push(&good);
        assert_eq!(d.next_profile(), None, "waiting for the candidate to complete");
        d.resync();
        assert_eq!(d.next_profile(), Some(Ok(sample(false))));
    }

    #[test]
    fn encode_rejects_what_the_format_cannot_carry() {
        let mut p = sample(true);
        p.intensity = Some(vec![0; 3]);
        assert_eq!(
            encode_profile(&p),
            Err(ProfileError::IntensityLength {
                columns: 1536,
                intensity: 3
            })
        );
        p = Profile {
            rows: vec![],
            ..sample(false)
        };
        assert_eq!(encode_profile(&p), Err(ProfileError::BadColumnCount(0)));
        p = Profile {
            rows: vec![1; 8193],
            ..sample(false)
        };
        assert_eq!(encode_profile(&p), Err(ProfileError::BadColumnCount(8193)));
        p = Profile {
            fraction_bits: 16,
            ..sample(false)
        };
        assert_eq!(encode_profile(&p), Err(ProfileError::BadFractionBits(16)));
        // The largest frame is accepted.
        p = Profile {
            rows: vec![7; 8192],
            intensity: Some(vec![1; 8192]),
            ..sample(false)
        };
        assert_eq!(encode_profile(&p).map(|b| b.len()), Ok(MAX_FRAME_LEN));
    }
}
