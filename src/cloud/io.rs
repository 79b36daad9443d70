//! Point-cloud file IO: PLY, PCD and plain text.
//!
//! # Formats
//! - **PLY** ([`read_ply`](super::read_ply), [`write_ply`](super::write_ply)): `ascii`, `binary_little_endian` and (read only)
//!   `binary_big_endian`. The `vertex` element gives the points: its `x y z` properties (any scalar
//!   type; `double` is rounded to `f32`) are the coordinates and every other scalar property becomes
//!   a [`Field`](super::Field) of the same name and type (`red`, `nx`, `intensity`, `label`, ...). List properties
//!   of the vertex element and all other elements (faces, edges, ...) are parsed past and dropped.
//!   Type names `char uchar short ushort int uint float double` and `int8 ... float64` are read;
//!   the former are written. Writing emits one `vertex` element: `x y z` as `float`, then each field
//!   with its type; a field with `count = k > 1` becomes `k` properties `name_0 .. name_{k-1}` (they
//!   read back as `k` separate fields). PLY has no notion of an organized cloud, so the writer records
//!   `width x height` in an `obj_info sqscan width W height H` line, which the reader honours.
//! - **PCD** ([`read_pcd`](super::read_pcd), [`write_pcd`](super::write_pcd)) as PCL writes it: v0.7 headers and older ones without
//!   `VERSION`/`VIEWPOINT`/`COUNT` (`COLUMNS` is accepted for `FIELDS`, missing `SIZE`/`TYPE` mean
//!   4-byte floats), `DATA ascii`, `binary` (point-major records) and `binary_compressed` (LZF, see
//!   [`super::lzf`], over field-major data). `x y z` may be anywhere in the field list and of any
//!   numeric type (converted to `f32`); every other field is kept with its `TYPE`/`SIZE`/`COUNT`,
//!   except padding fields named `_`, which are skipped. Packed colours (`rgb`/`rgba`, `F 4` or
//!   `U 4`) are kept bit-exact as the file has them; in ASCII, `F 4` `rgb`/`rgba` values are written
//!   (and, if they look like integers, read) as the `u32` of their bits, as PCL does, because many
//!   packed colours are NaN as floats. The viewpoint is checked but not kept (written as identity).
//!   Writing puts `x y z` (`F 4`) first, then the fields in order.
//! - **MCAP** (the `mcap` feature, read only): the first `sensor_msgs/msg/PointCloud2` in CDR,
//!   that of `/sqscan/points` where there is one (see `cloud/mcap.rs`).
//! - **Plain text** ([`read_text`](super::read_text), [`write_text`](super::write_text)): one point per line, `x y z [more columns]`,
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
//! A file holding or declaring more points than [`max_points`](super::max_points) (4 Mi, or
//! `SQSCAN_MAX_POINTS`) is refused before its data is read.
//! Errors ([`CloudError`]) say what is wrong and where: the file (when read through [`read_cloud`]),
//! the header line, or the point/vertex index (with the line for text data), and the field.

use std::fs;
use std::io::{self, Write};
use std::path::Path;

use super::codec::{MCAP_MAGIC, lines};
use super::{CloudError, PcdData, PlyFormat, PointCloud};

/// The file formats [`read_cloud`] tells apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Ply,
    Pcd,
    Mcap,
    Text,
}

fn format_of(path: &Path, content: Option<&[u8]>) -> Format {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match (ext.as_deref(), content) {
        (Some("ply"), _) => Format::Ply,
        (Some("pcd"), _) => Format::Pcd,
        (Some("mcap"), _) => Format::Mcap,
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
    if bytes.starts_with(MCAP_MAGIC) {
        return Format::Mcap;
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

/// Reads a cloud from `path`: `.ply`, `.pcd` and `.mcap` (the `mcap` feature: the first ROS 2
/// `PointCloud2` in it) by extension, anything else (including files without extension) by
/// content: PLY or MCAP magic, PCD header, else plain text.
pub fn read_cloud(path: &Path) -> Result<PointCloud, CloudError> {
    let bytes = read_regular(path).map_err(|e| CloudError::Io(e).in_file(path))?;
    let result = match format_of(path, Some(&bytes)) {
        Format::Ply => super::ply::parse_ply(&bytes),
        Format::Pcd => super::pcd::parse_pcd(&bytes),
        #[cfg(feature = "mcap")]
        Format::Mcap => super::mcap::parse_mcap(&bytes),
        #[cfg(not(feature = "mcap"))]
        Format::Mcap => Err(CloudError::Format(
            "an MCAP file: this build reads MCAP only with the `mcap` feature".into(),
        )),
        Format::Text => super::text::parse_text(&bytes),
    };
    result.map_err(|e| e.in_file(path))
}

/// The sweep id and time (Unix s) that sqscand's own MCAP recording at `path` holds in its
/// `sqscan.sweep` metadata; `None` for an MCAP file without them.
#[cfg(feature = "mcap")]
pub fn mcap_recorded_sweep(path: &Path) -> Result<Option<(u64, f64)>, CloudError> {
    let bytes = read_regular(path).map_err(|e| CloudError::Io(e).in_file(path))?;
    super::mcap::recorded_sweep(&bytes).map_err(|e| e.in_file(path))
}

/// The bytes of a regular file, opened without blocking (a FIFO would wait for a writer in
/// open(2)); anything else (a FIFO, a device, a directory) is refused as not a regular file.
fn read_regular(path: &Path) -> io::Result<Vec<u8>> {
    use std::io::Read;
    let mut file = crate::spec::open_regular(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, "not a regular file"));
    }
    let mut bytes = Vec::with_capacity(meta.len().min(1 << 30) as usize);
    file.read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// Writes `cloud` to `path`: `.ply` as binary little-endian PLY, `.pcd` as `binary_compressed`
/// PCD, anything else as plain text.
pub fn write_cloud(path: &Path, cloud: &PointCloud) -> Result<(), CloudError> {
    let write = || -> Result<(), CloudError> {
        let mut file = io::BufWriter::new(fs::File::create(path)?);
        match format_of(path, None) {
            Format::Ply => super::ply::write_ply(&mut file, cloud, PlyFormat::BinaryLittleEndian)?,
            Format::Pcd => super::pcd::write_pcd(&mut file, cloud, PcdData::BinaryCompressed)?,
            Format::Mcap => {
                return Err(CloudError::Format(
                    "MCAP is written by the daemon's recordings, not as a cloud file".into(),
                ));
            }
            Format::Text => super::text::write_text(&mut file, cloud)?,
        }
        file.flush()?;
        Ok(())
    };
    write().map_err(|e| e.in_file(path))
}

#[cfg(test)]
mod tests {
    use super::*;

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
