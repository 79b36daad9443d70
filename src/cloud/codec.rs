//! What the PLY, PCD and text codecs share: the encodings, scalar tokens, column assembly into a
//! [`PointCloud`], and line and token scanning.

use std::fmt;
use std::io::Read;

use super::error::CloudError;
use super::{FieldData, PointCloud, with_field_data};

/// The first bytes of every MCAP file (how `read_cloud` tells one from a PLY or PCD file).
pub(super) const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// The `DATA` encoding of a PCD file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PcdData {
    Ascii,
    Binary,
    /// LZF-compressed field-major data (PCL's `binary_compressed`).
    BinaryCompressed,
}

/// The `format` of a PLY file to write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlyFormat {
    Ascii,
    BinaryLittleEndian,
}

/// Reads all of `r`. The readers parse from memory: files are a few MB, and a slice makes every
/// bounds check explicit.
pub(crate) fn read_all(mut r: impl Read) -> Result<Vec<u8>, CloudError> {
    let mut buf = Vec::new();
    r.read_to_end(&mut buf)?;
    Ok(buf)
}

/// A fixed-size value that can appear in a file.
pub(crate) trait Scalar: Copy + 'static {
    const SIZE: usize;
    /// Decodes `b[..SIZE]`; callers pass slices of exactly `SIZE` bytes (from `chunks_exact`).
    fn from_le(b: &[u8]) -> Self;
    fn from_be(b: &[u8]) -> Self;
    fn put_le(self, out: &mut Vec<u8>);
    /// Parses a text token; integers also accept integral floats (`3.0`, `1e3`) in range.
    fn parse_token(s: &str) -> Option<Self>;
    /// Appends the shortest text that parses back to the same value (`nan` for NaN).
    fn write_token(self, out: &mut String);
}

macro_rules! impl_scalar_int {
    ($($t:ty),*) => {$(
        impl Scalar for $t {
            const SIZE: usize = std::mem::size_of::<$t>();
            fn from_le(b: &[u8]) -> Self {
                let mut a = [0u8; std::mem::size_of::<$t>()];
                a.copy_from_slice(&b[..Self::SIZE]);
                <$t>::from_le_bytes(a)
            }
            fn from_be(b: &[u8]) -> Self {
                let mut a = [0u8; std::mem::size_of::<$t>()];
                a.copy_from_slice(&b[..Self::SIZE]);
                <$t>::from_be_bytes(a)
            }
            fn put_le(self, out: &mut Vec<u8>) {
                out.extend_from_slice(&self.to_le_bytes());
            }
            fn parse_token(s: &str) -> Option<Self> {
                s.parse::<$t>().ok().or_else(|| {
                    // Some writers print integers as floats ("3.0", "1e+03").
                    let f: f64 = s.parse().ok()?;
                    let in_range = f.fract() == 0.0 && f >= <$t>::MIN as f64 && f <= <$t>::MAX as f64;
                    in_range.then_some(f as $t)
                })
            }
            fn write_token(self, out: &mut String) {
                use std::fmt::Write as _;
                let _ = write!(out, "{self}");
            }
        }
    )*};
}
impl_scalar_int!(i8, u8, i16, u16, i32, u32);

macro_rules! impl_scalar_float {
    ($($t:ty),*) => {$(
        impl Scalar for $t {
            const SIZE: usize = std::mem::size_of::<$t>();
            fn from_le(b: &[u8]) -> Self {
                let mut a = [0u8; std::mem::size_of::<$t>()];
                a.copy_from_slice(&b[..Self::SIZE]);
                <$t>::from_le_bytes(a)
            }
            fn from_be(b: &[u8]) -> Self {
                let mut a = [0u8; std::mem::size_of::<$t>()];
                a.copy_from_slice(&b[..Self::SIZE]);
                <$t>::from_be_bytes(a)
            }
            fn put_le(self, out: &mut Vec<u8>) {
                out.extend_from_slice(&self.to_le_bytes());
            }
            fn parse_token(s: &str) -> Option<Self> {
                // Rust accepts nan/inf/infinity in any case, with a sign: what C's printf writes.
                s.parse().ok()
            }
            fn write_token(self, out: &mut String) {
                use std::fmt::Write as _;
                let a = self.abs();
                // `{}` and `{:e}` both print the shortest exact representation; plain notation
                // reads better but gets very long for tiny and huge magnitudes.
                let _ = if self.is_nan() {
                    write!(out, "nan")
                } else if a == 0.0 || a.is_infinite() || (1e-5..1e16).contains(&a) {
                    write!(out, "{self}")
                } else {
                    write!(out, "{self:e}")
                };
            }
        }
    )*};
}
impl_scalar_float!(f32, f64);

impl FieldData {
    /// Appends the little-endian values in `bytes` (a whole number of values).
    pub(crate) fn extend_le(&mut self, bytes: &[u8]) {
        with_field_data!(self, v => extend_from(v, bytes, Scalar::from_le))
    }

    /// Appends the big-endian values in `bytes` (a whole number of values).
    pub(crate) fn extend_be(&mut self, bytes: &[u8]) {
        with_field_data!(self, v => extend_from(v, bytes, Scalar::from_be))
    }

    /// Appends, for each of the `records` (each `stride` bytes, back to back in `data`), the
    /// values in bytes `first..first + len` of the record, little- or big-endian. The caller
    /// guarantees `first + len <= stride`, `len` a multiple of the value size and
    /// `records * stride <= data.len()`.
    pub(crate) fn extend_strided(
        &mut self,
        data: &[u8],
        (stride, records): (usize, usize),
        (first, len): (usize, usize),
        big_endian: bool,
    ) {
        fn go<T: Scalar>(
            v: &mut Vec<T>,
            data: &[u8],
            (stride, records): (usize, usize),
            (first, len): (usize, usize),
            big_endian: bool,
        ) {
            v.reserve(records * (len / T::SIZE));
            for rec in data.chunks_exact(stride).take(records) {
                if big_endian {
                    extend_from(v, &rec[first..first + len], T::from_be);
                } else {
                    extend_from(v, &rec[first..first + len], T::from_le);
                }
            }
        }
        if stride == 0 {
            return;
        }
        with_field_data!(self, v => go(v, data, (stride, records), (first, len), big_endian))
    }

    /// Parses one text token and appends it; `false` (and nothing appended) if it does not parse.
    pub(crate) fn push_token(&mut self, token: &str) -> bool {
        with_field_data!(self, v => match Scalar::parse_token(token) {
            Some(x) => {
                v.push(x);
                true
            }
            None => false,
        })
    }

    /// Appends values `range` in little-endian order. Panics if the range is out of bounds (the
    /// writers check the cloud with [`PointCloud::validate`] first).
    pub(crate) fn put_le(&self, range: std::ops::Range<usize>, out: &mut Vec<u8>) {
        with_field_data!(self, v => v[range].iter().for_each(|x| x.put_le(out)))
    }

    /// Appends value `i` as text (see [`Scalar::write_token`]).
    pub(crate) fn write_token(&self, i: usize, out: &mut String) {
        with_field_data!(self, v => v[i].write_token(out))
    }

    /// The values as `f32` (coordinates); moves `F32` data, converts the rest.
    pub(crate) fn into_f32(self) -> Vec<f32> {
        match self {
            FieldData::F32(v) => v,
            FieldData::F64(v) => v.into_iter().map(|x| x as f32).collect(),
            other => {
                let n = other.len();
                (0..n).filter_map(|i| other.get_f64(i)).map(|x| x as f32).collect()
            }
        }
    }
}

/// (Generic over the decoder, not a function pointer: a call through a pointer per value cost
/// more than the decoding.)
#[inline(always)]
fn extend_from<T: Scalar>(v: &mut Vec<T>, bytes: &[u8], decode: impl Fn(&[u8]) -> T) {
    v.extend(bytes.chunks_exact(T::SIZE).map(decode));
}

/// One decoded column of a file: a coordinate or a field.
pub(crate) struct Column {
    pub name: String,
    pub count: usize,
    pub data: FieldData,
}

/// Builds the cloud from decoded columns: `x`, `y`, `z` (count 1; the readers check that they
/// exist with the right length) become the points, the rest the fields, in file order.
pub(crate) fn assemble(columns: Vec<Column>, width: usize, height: usize) -> Result<PointCloud, CloudError> {
    let mut xyz: [Option<Vec<f32>>; 3] = [None, None, None];
    let mut fields = Vec::new();
    for col in columns {
        let axis = match col.name.as_str() {
            "x" => Some(0),
            "y" => Some(1),
            "z" => Some(2),
            _ => None,
        };
        match axis {
            Some(k) if col.count == 1 && xyz[k].is_none() => xyz[k] = Some(col.data.into_f32()),
            _ => fields.push(super::Field {
                name: col.name,
                count: col.count,
                data: col.data,
            }),
        }
    }
    let [Some(x), Some(y), Some(z)] = xyz else {
        return Err(CloudError::Format("missing x, y or z".into()));
    };
    let points: Vec<[f32; 3]> = x.into_iter().zip(y).zip(z).map(|((x, y), z)| [x, y, z]).collect();
    let (width, height) = if height > 1 { (width, height) } else { (points.len(), 1) };
    let cloud = PointCloud {
        points,
        width,
        height,
        fields,
        viewpoint: None,
    };
    // Catches field names a file can carry but a cloud cannot (control characters, `x` twice);
    // the readers build columns of matching lengths.
    cloud.validate()?;
    Ok(cloud)
}

/// A cursor over whitespace-separated tokens of text data, counting lines (1-based).
pub(crate) struct Tokens<'a> {
    buf: &'a [u8],
    pos: usize,
    /// Line of the byte at `pos`.
    pub line: usize,
}

impl<'a> Tokens<'a> {
    pub fn new(buf: &'a [u8], first_line: usize) -> Tokens<'a> {
        Tokens {
            buf,
            pos: 0,
            line: first_line,
        }
    }

    /// Skips whitespace and returns the next token with its line, `None` at the end. A token that
    /// is not UTF-8 is returned as `"\u{FFFD}"` so that it fails to parse with a readable message.
    pub fn next_token(&mut self) -> Option<(&'a str, usize)> {
        while let Some(&b) = self.buf.get(self.pos) {
            if !b.is_ascii_whitespace() {
                break;
            }
            if b == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
        let start = self.pos;
        while self.buf.get(self.pos).is_some_and(|b| !b.is_ascii_whitespace()) {
            self.pos += 1;
        }
        let tok = self.buf.get(start..self.pos).filter(|t| !t.is_empty())?;
        Some((std::str::from_utf8(tok).unwrap_or("\u{FFFD}"), self.line))
    }
}

/// Iterates over the lines of `buf` (without `\n` / `\r\n`), with their byte ranges.
pub(crate) fn lines(buf: &[u8]) -> impl Iterator<Item = (&[u8], usize)> {
    let mut pos = 0;
    std::iter::from_fn(move || {
        if pos >= buf.len() {
            return None;
        }
        let rest = buf.get(pos..)?;
        let (line, next) = match rest.iter().position(|&b| b == b'\n') {
            Some(i) => (&rest[..i], pos + i + 1),
            None => (rest, buf.len()),
        };
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        pos = next;
        Some((line, next))
    })
}

/// Shortens a token for an error message.
pub(crate) fn quote(token: &str) -> impl fmt::Display + '_ {
    struct Q<'a>(&'a str);
    impl fmt::Display for Q<'_> {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            match self.0.char_indices().nth(24) {
                Some((i, _)) => write!(f, "`{}...`", &self.0[..i]),
                None => write!(f, "`{}`", self.0),
            }
        }
    }
    Q(token)
}

/// `(width, height)` to write: unorganized clouds are `len x 1`.
pub(crate) fn dims(cloud: &PointCloud) -> (usize, usize) {
    if cloud.is_organized() {
        (cloud.width, cloud.height)
    } else {
        (cloud.points.len(), 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn float_tokens_round_trip() {
        let vals = [
            0.1f32,
            -0.0,
            1e-7,
            3.4028235e38,
            f32::MIN_POSITIVE,
            1e-45,
            123456.79,
            f32::INFINITY,
        ];
        for v in vals {
            let mut s = String::new();
            v.write_token(&mut s);
            assert_eq!(f32::parse_token(&s).map(f32::to_bits), Some(v.to_bits()), "{s}");
        }
        let mut s = String::new();
        f32::NAN.write_token(&mut s);
        assert_eq!(s, "nan");
    }

    #[test]
    fn int_tokens() {
        assert_eq!(u8::parse_token("255"), Some(255));
        assert_eq!(u8::parse_token("256"), None);
        assert_eq!(i16::parse_token("-3.0"), Some(-3));
        assert_eq!(i16::parse_token("1.5"), None);
        assert_eq!(u32::parse_token("nan"), None);
    }

    #[test]
    fn tokens_and_lines() {
        let mut t = Tokens::new(b" a b\n\n c\r\nd", 5);
        let got: Vec<_> = std::iter::from_fn(|| t.next_token()).collect();
        assert_eq!(got, vec![("a", 5), ("b", 5), ("c", 7), ("d", 8)]);
        let l: Vec<_> = lines(b"x\r\ny\n\nz").map(|(l, _)| l).collect();
        assert_eq!(l, vec![&b"x"[..], b"y", b"", b"z"]);
    }
}
