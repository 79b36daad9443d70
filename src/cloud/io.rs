//! Point-cloud file IO: PLY, PCD and plain text.
//!
//! # Formats
//! - **PLY** ([`read_ply`], [`write_ply`]): `ascii`, `binary_little_endian` and (read only)
//!   `binary_big_endian`. The `vertex` element gives the points: its `x y z` properties (any scalar
//!   type; `double` is rounded to `f32`) are the coordinates and every other scalar property becomes
//!   a [`Field`] of the same name and type (`red`, `nx`, `intensity`, `label`, ...). List properties
//!   of the vertex element and all other elements (faces, edges, ...) are parsed past and dropped.
//!   Type names `char uchar short ushort int uint float double` and `int8 ... float64` are read;
//!   the former are written. Writing emits one `vertex` element: `x y z` as `float`, then each field
//!   with its type; a field with `count = k > 1` becomes `k` properties `name_0 .. name_{k-1}` (they
//!   read back as `k` separate fields). PLY has no notion of an organized cloud, so the writer records
//!   `width x height` in an `obj_info sqscan width W height H` line, which the reader honours.
//! - **PCD** ([`read_pcd`], [`write_pcd`]) as PCL writes it: v0.7 headers and older ones without
//!   `VERSION`/`VIEWPOINT`/`COUNT` (`COLUMNS` is accepted for `FIELDS`, missing `SIZE`/`TYPE` mean
//!   4-byte floats), `DATA ascii`, `binary` (point-major records) and `binary_compressed` (LZF, see
//!   [`super::lzf`], over field-major data). `x y z` may be anywhere in the field list and of any
//!   numeric type (converted to `f32`); every other field is kept with its `TYPE`/`SIZE`/`COUNT`,
//!   except padding fields named `_`, which are skipped. Packed colours (`rgb`/`rgba`, `F 4` or
//!   `U 4`) are kept bit-exact as the file has them; in ASCII, `F 4` `rgb`/`rgba` values are written
//!   (and, if they look like integers, read) as the `u32` of their bits, as PCL does, because many
//!   packed colours are NaN as floats. The viewpoint is checked but not kept (written as identity).
//!   Writing puts `x y z` (`F 4`) first, then the fields in order.
//! - **Plain text** ([`read_text`], [`write_text`]): one point per line, `x y z [more columns]`,
//!   separated by whitespace and/or commas; `#` starts a comment, lines starting with `//` (e.g.
//!   CloudCompare's column header) are ignored. Every line must have the same number of columns.
//!   Extra columns become `F64` fields `c3`, `c4`, ... (0-based column index), except that exactly
//!   six columns whose last three are all integers in 0..=255 become `U8` fields `red green blue`
//!   (the iCub `x y z r g b` files). The writer emits a comment line
//!   `# sqscan-columns: x y z name:kind[*count] ...` before the data; when the reader finds it, the
//!   columns get those names and types, so text round trips are exact too.
//!
//! # NaN and organized clouds
//! Coordinates are `f32`, copied bit-exact from and to binary files, so NaN points of organized
//! clouds (missing returns) survive every binary round trip. ASCII output writes each float in the
//! shortest form that parses back to the same value (NaN as `nan`, as PCL does; NaN payloads are
//! lost in ASCII). PCD keeps `WIDTH`/`HEIGHT`; PLY uses the `obj_info` line above; plain text has no
//! organization, so a text round trip yields an unorganized cloud with the same points.
//!
//! # Robustness
//! Readers take the whole input into memory and parse it from a byte slice. No input makes them
//! panic, and no allocation is sized by a header count alone: sizes are checked against the bytes
//! actually present (for LZF, against the largest expansion the format allows) before allocating.
//! Errors ([`CloudError`]) say what is wrong and where: the file (when read through [`read_cloud`]),
//! the header line, or the point/vertex index (with the line for text data), and the field.

use std::fmt;
use std::fs;
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

use thiserror::Error;

use super::{FieldData, PointCloud, with_field_data};

/// Everything that can go wrong reading or writing a cloud.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum CloudError {
    /// An error while reading or writing the file `path`.
    #[error("{}: {error}", path.display())]
    File { path: PathBuf, error: Box<CloudError> },
    #[error("I/O error: {0}")]
    Io(#[from] io::Error),
    /// A malformed header; `line` is 1-based.
    #[error("header line {line}: {msg}")]
    Header { line: usize, msg: String },
    /// A malformed record of the data section: `element` `index` (0-based; `point` for PCD and
    /// text, the element name for PLY), the 1-based text line when the data is text, the field.
    #[error("{}", fmt_record(element, *index, *line, field.as_deref(), msg))]
    Record {
        element: String,
        index: usize,
        line: Option<usize>,
        field: Option<String>,
        msg: String,
    },
    /// Corrupt LZF data; `offset` is the byte of the offending instruction (in the file when read
    /// from a PCD file, else in the compressed block).
    #[error("LZF data corrupt at byte {offset}: {msg}")]
    Lzf { offset: usize, msg: &'static str },
    /// A file-level inconsistency (e.g. `POINTS 100 but WIDTH*HEIGHT = 120`).
    #[error("{0}")]
    Format(String),
    /// The cloud handed to a writer breaks the [`PointCloud`] invariants.
    #[error("invalid cloud: {0}")]
    InvalidCloud(String),
}

fn fmt_record(element: &str, index: usize, line: Option<usize>, field: Option<&str>, msg: &str) -> String {
    let mut s = format!("{element} {index}");
    if let Some(line) = line {
        s += &format!(" (line {line})");
    }
    if let Some(field) = field {
        s += &format!(", field `{field}`");
    }
    s + ": " + msg
}

impl CloudError {
    pub(crate) fn header(line: usize, msg: impl Into<String>) -> CloudError {
        CloudError::Header { line, msg: msg.into() }
    }

    pub(crate) fn record(
        element: &str,
        index: usize,
        line: Option<usize>,
        field: Option<&str>,
        msg: impl Into<String>,
    ) -> CloudError {
        CloudError::Record {
            element: element.to_string(),
            index,
            line,
            field: field.map(str::to_string),
            msg: msg.into(),
        }
    }

    fn in_file(self, path: &Path) -> CloudError {
        CloudError::File {
            path: path.to_path_buf(),
            error: Box::new(self),
        }
    }
}

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

/// The file formats [`read_cloud`] tells apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Ply,
    Pcd,
    Text,
}

fn format_of(path: &Path, content: Option<&[u8]>) -> Format {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match (ext.as_deref(), content) {
        (Some("ply"), _) => Format::Ply,
        (Some("pcd"), _) => Format::Pcd,
        (_, Some(bytes)) => sniff(bytes),
        (_, None) => Format::Text,
    }
}

/// Guesses the format from the first bytes: the PLY magic, a PCD header keyword, else text.
fn sniff(bytes: &[u8]) -> Format {
    if bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n") {
        return Format::Ply;
    }
    if bytes.starts_with(b"# .PCD") {
        return Format::Pcd;
    }
    // PCD headers may open with other comments: look at the first line that is not one.
    let first = lines(bytes)
        .take(100)
        .map(|(line, _)| line.trim_ascii_start())
        .find(|line| !line.is_empty() && !line.starts_with(b"#"));
    let keywords: [&[u8]; 3] = [b"VERSION", b"FIELDS", b"COLUMNS"];
    match first {
        Some(line) if keywords.iter().any(|k| line.starts_with(k)) => Format::Pcd,
        _ => Format::Text,
    }
}

/// Reads a cloud from `path`: `.ply` and `.pcd` by extension, anything else (including files
/// without extension) by content: PLY magic, PCD header, else plain text.
pub fn read_cloud(path: &Path) -> Result<PointCloud, CloudError> {
    let bytes = fs::read(path).map_err(|e| CloudError::Io(e).in_file(path))?;
    let result = match format_of(path, Some(&bytes)) {
        Format::Ply => super::ply::parse_ply(&bytes),
        Format::Pcd => super::pcd::parse_pcd(&bytes),
        Format::Text => super::text::parse_text(&bytes),
    };
    result.map_err(|e| e.in_file(path))
}

/// Writes `cloud` to `path`: `.ply` as binary little-endian PLY, `.pcd` as `binary_compressed`
/// PCD, anything else as plain text.
pub fn write_cloud(path: &Path, cloud: &PointCloud) -> Result<(), CloudError> {
    let write = || -> Result<(), CloudError> {
        let mut file = io::BufWriter::new(fs::File::create(path)?);
        match format_of(path, None) {
            Format::Ply => super::ply::write_ply(&mut file, cloud, PlyFormat::BinaryLittleEndian)?,
            Format::Pcd => super::pcd::write_pcd(&mut file, cloud, PcdData::BinaryCompressed)?,
            Format::Text => super::text::write_text(&mut file, cloud)?,
        }
        file.flush()?;
        Ok(())
    };
    write().map_err(|e| e.in_file(path))
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
            let decode = if big_endian { T::from_be } else { T::from_le };
            v.reserve(records * (len / T::SIZE));
            for rec in data.chunks_exact(stride).take(records) {
                extend_from(v, &rec[first..first + len], decode);
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

fn extend_from<T: Scalar>(v: &mut Vec<T>, bytes: &[u8], decode: fn(&[u8]) -> T) {
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

    #[test]
    fn sniffing() {
        assert_eq!(sniff(b"ply\nformat"), Format::Ply);
        assert_eq!(sniff(b"# .PCD v0.7"), Format::Pcd);
        assert_eq!(sniff(b"FIELDS x y z"), Format::Pcd);
        assert_eq!(sniff(b"# made by hand\n\nVERSION .5\nFIELDS x y z"), Format::Pcd);
        assert_eq!(sniff(b"# x y z\n1 2 3\n"), Format::Text);
        assert_eq!(sniff(b"1 2 3\n"), Format::Text);
        assert_eq!(format_of(Path::new("a/b.PLY"), None), Format::Ply);
        assert_eq!(format_of(Path::new("a/cylinder"), Some(b"1 2 3")), Format::Text);
    }
}
