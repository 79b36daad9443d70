//! PCD (PCL's Point Cloud Data format), v0.7 and the older headers PCL still reads.
//!
//! Over 600 lines on purpose: the header parser and the three encodings (ascii, binary,
//! binary_compressed) read and written, with their byte-level tests, are one format best read in
//! one place.

use std::io::{Read, Write};

use super::codec::{Column, Scalar, assemble, dims, lines, quote, read_all};
use super::{CloudError, FieldData, PcdData, PointCloud, ScalarKind, lzf};

/// One entry of `FIELDS`, with its `SIZE`/`TYPE`/`COUNT`.
#[derive(Debug)]
struct PcdField {
    name: String,
    kind: ScalarKind,
    count: usize,
}

impl PcdField {
    /// Bytes per point.
    fn bytes(&self) -> usize {
        self.kind.size() * self.count
    }

    /// Padding (`_`) fields are skipped.
    fn is_padding(&self) -> bool {
        self.name == "_"
    }

    /// PCL stores packed colours as `F 4` `rgb`/`rgba` and prints them in ASCII as the `u32` of
    /// their bits, because many colours are NaN as floats.
    fn is_packed_color(&self) -> bool {
        self.kind == ScalarKind::F32 && matches!(self.name.as_str(), "rgb" | "rgba")
    }
}

#[derive(Debug)]
struct Header {
    fields: Vec<PcdField>,
    width: usize,
    height: usize,
    points: usize,
    data: PcdData,
    /// Byte offset of the data section.
    data_start: usize,
    /// Line number of the `DATA` line.
    data_line: usize,
    viewpoint: Option<[f64; 7]>,
}

fn pcd_kind(ty: char, size: usize) -> Option<ScalarKind> {
    Some(match (ty, size) {
        ('I', 1) => ScalarKind::I8,
        ('U', 1) => ScalarKind::U8,
        ('I', 2) => ScalarKind::I16,
        ('U', 2) => ScalarKind::U16,
        ('I', 4) => ScalarKind::I32,
        ('U', 4) => ScalarKind::U32,
        ('F', 4) => ScalarKind::F32,
        ('F', 8) => ScalarKind::F64,
        _ => return None,
    })
}

fn pcd_type(kind: ScalarKind) -> char {
    match kind {
        ScalarKind::I8 | ScalarKind::I16 | ScalarKind::I32 => 'I',
        ScalarKind::U8 | ScalarKind::U16 | ScalarKind::U32 => 'U',
        ScalarKind::F32 | ScalarKind::F64 => 'F',
    }
}

/// A header keyword's values and the line they were on.
type Entry<T> = Option<(usize, T)>;

/// Header entries as read, before they are checked against each other.
#[derive(Default)]
struct RawHeader {
    fields: Entry<Vec<String>>,
    sizes: Entry<Vec<usize>>,
    types: Entry<Vec<char>>,
    counts: Entry<Vec<usize>>,
    width: Entry<usize>,
    height: Entry<usize>,
    points: Entry<usize>,
}

fn parse_header(buf: &[u8]) -> Result<Header, CloudError> {
    let mut raw = RawHeader::default();
    let mut seen_version = false;
    let mut viewpoint: Option<[f64; 7]> = None;

    for (line_no, (bytes, next)) in (1..).zip(lines(buf)) {
        let err = |msg: String| CloudError::header(line_no, msg);
        let text =
            std::str::from_utf8(bytes).map_err(|_| err("not text (binary data before the DATA line?)".into()))?;
        let text = text.trim();
        if text.is_empty() || text.starts_with('#') {
            continue;
        }
        let mut words = text.split_ascii_whitespace();
        let keyword = words.next().unwrap_or_default();
        let values: Vec<&str> = words.collect();
        let dup = |seen: bool| {
            if seen {
                Err(err(format!("second {keyword} line")))
            } else {
                Ok(())
            }
        };
        let number = |s: &str| {
            s.parse::<usize>()
                .map_err(|_| err(format!("{keyword}: {} is not a count", quote(s))))
        };
        let single = || match values.as_slice() {
            [v] => number(v),
            _ => Err(err(format!("{keyword} needs one value, found {}", values.len()))),
        };
        match keyword {
            "VERSION" => {
                dup(seen_version)?;
                seen_version = true;
            }
            "FIELDS" | "COLUMNS" => {
                dup(raw.fields.is_some())?;
                if values.is_empty() {
                    return Err(err(format!("{keyword} lists no fields")));
                }
                raw.fields = Some((line_no, values.iter().map(|s| s.to_string()).collect()));
            }
            "SIZE" => {
                dup(raw.sizes.is_some())?;
                let v = values.iter().map(|s| number(s)).collect::<Result<_, _>>()?;
                raw.sizes = Some((line_no, v));
            }
            "TYPE" => {
                dup(raw.types.is_some())?;
                raw.types = Some((line_no, field_types(&values).map_err(err)?));
            }
            "COUNT" => {
                dup(raw.counts.is_some())?;
                let v: Vec<usize> = values.iter().map(|s| number(s)).collect::<Result<_, _>>()?;
                if v.contains(&0) {
                    return Err(err("COUNT 0 is not allowed".into()));
                }
                raw.counts = Some((line_no, v));
            }
            "WIDTH" => {
                dup(raw.width.is_some())?;
                raw.width = Some((line_no, single()?));
            }
            "HEIGHT" => {
                dup(raw.height.is_some())?;
                raw.height = Some((line_no, single()?));
            }
            "POINTS" => {
                dup(raw.points.is_some())?;
                raw.points = Some((line_no, single()?));
            }
            "VIEWPOINT" => {
                dup(viewpoint.is_some())?;
                viewpoint = Some(viewpoint_values(&values).map_err(err)?);
            }
            "DATA" => {
                let data = data_kind(&values).map_err(err)?;
                let mut header = finish_header(raw, data, next, line_no)?;
                header.viewpoint = viewpoint;
                return Ok(header);
            }
            _ => return Err(err(format!("unknown keyword {}", quote(keyword)))),
        }
    }
    Err(CloudError::Format(
        "PCD header: no DATA line before the end of the file".into(),
    ))
}

/// The TYPE line's letters: F (float), I (signed) or U (unsigned) each.
fn field_types(values: &[&str]) -> Result<Vec<char>, String> {
    values
        .iter()
        .map(|s| match s.as_bytes() {
            [t @ (b'F' | b'I' | b'U')] => Ok(char::from(*t)),
            _ => Err(format!("TYPE {} is not F, I or U", quote(s))),
        })
        .collect()
}

/// The VIEWPOINT line: 7 finite numbers, the translation and the rotation (w first).
fn viewpoint_values(values: &[&str]) -> Result<[f64; 7], String> {
    let nums: Vec<f64> = values.iter().filter_map(|v| v.parse::<f64>().ok()).collect();
    match <[f64; 7]>::try_from(nums.as_slice()) {
        Ok(v) if values.len() == 7 && v.iter().all(|x| x.is_finite()) => Ok(v),
        _ => Err("VIEWPOINT needs 7 finite numbers (tx ty tz qw qx qy qz)".into()),
    }
}

/// The DATA line's encoding.
fn data_kind(values: &[&str]) -> Result<PcdData, String> {
    match values {
        [v] if v.eq_ignore_ascii_case("ascii") => Ok(PcdData::Ascii),
        [v] if v.eq_ignore_ascii_case("binary") => Ok(PcdData::Binary),
        [v] if v.eq_ignore_ascii_case("binary_compressed") => Ok(PcdData::BinaryCompressed),
        _ => Err(format!(
            "DATA {} is not ascii, binary or binary_compressed",
            values.join(" ")
        )),
    }
}

fn finish_header(raw: RawHeader, data: PcdData, data_start: usize, data_line: usize) -> Result<Header, CloudError> {
    let RawHeader {
        fields,
        sizes,
        types,
        counts,
        width,
        height,
        points,
    } = raw;
    let Some((fields_line, names)) = fields else {
        return Err(CloudError::header(data_line, "no FIELDS line before DATA"));
    };
    let n = names.len();
    let check_len = |entry: &Option<(usize, usize)>, what: &str| match entry {
        Some((line, len)) if *len != n => Err(CloudError::header(
            *line,
            format!("{what} has {len} entries but FIELDS has {n}"),
        )),
        _ => Ok(()),
    };
    check_len(&sizes.as_ref().map(|(l, v)| (*l, v.len())), "SIZE")?;
    check_len(&types.as_ref().map(|(l, v)| (*l, v.len())), "TYPE")?;
    check_len(&counts.as_ref().map(|(l, v)| (*l, v.len())), "COUNT")?;

    // Old (v.5) headers may lack SIZE, TYPE or COUNT: PCL then assumes 4-byte floats, one each.
    let mut out = Vec::with_capacity(n);
    // Names seen so far, for a linear-time duplicate check.
    let mut seen: std::collections::HashSet<String> = std::collections::HashSet::with_capacity(n);
    for (i, name) in names.into_iter().enumerate() {
        let size = sizes.as_ref().and_then(|(_, v)| v.get(i)).copied().unwrap_or(4);
        let ty = types.as_ref().and_then(|(_, v)| v.get(i)).copied().unwrap_or('F');
        let count = counts.as_ref().and_then(|(_, v)| v.get(i)).copied().unwrap_or(1);
        let Some(kind) = pcd_kind(ty, size) else {
            let line = (types.as_ref().map(|e| e.0))
                .or(sizes.as_ref().map(|e| e.0))
                .unwrap_or(fields_line);
            return Err(CloudError::header(
                line,
                format!("field `{name}`: TYPE {ty} with SIZE {size} is not supported"),
            ));
        };
        if name != "_" && !seen.insert(name.clone()) {
            return Err(CloudError::header(fields_line, format!("field `{name}` appears twice")));
        }
        out.push(PcdField { name, kind, count });
    }
    for axis in ["x", "y", "z"] {
        match out.iter().find(|f| f.name == axis) {
            None => {
                return Err(CloudError::header(fields_line, format!("FIELDS has no `{axis}` field")));
            }
            Some(f) if f.count != 1 => {
                let line = counts.as_ref().map_or(fields_line, |e| e.0);
                return Err(CloudError::header(
                    line,
                    format!("field `{axis}` has COUNT {}, expected 1", f.count),
                ));
            }
            Some(_) => {}
        }
    }

    let (width, height, points) = match (width, height, points) {
        (Some((wl, w)), h, p) => {
            let h = h.map_or(1, |e| e.1);
            let Some(wh) = w.checked_mul(h) else {
                return Err(CloudError::header(wl, "WIDTH*HEIGHT overflows"));
            };
            if let Some((pl, p)) = p
                && p != wh
            {
                return Err(CloudError::header(pl, format!("POINTS {p} but WIDTH*HEIGHT = {wh}")));
            }
            (w, h, wh)
        }
        (None, None, Some((_, p))) => (p, 1, p),
        (None, Some((hl, _)), _) => return Err(CloudError::header(hl, "HEIGHT without WIDTH")),
        (None, None, None) => {
            return Err(CloudError::header(data_line, "no WIDTH or POINTS before DATA"));
        }
    };
    super::check_point_count(points).map_err(|msg| CloudError::header(data_line, msg))?;
    Ok(Header {
        fields: out,
        width,
        height,
        points,
        data,
        data_start,
        data_line,
        viewpoint: None,
    })
}

/// Reads a PCD file (see the [`io`](super::io) module docs).
pub fn read_pcd(r: impl Read) -> Result<PointCloud, CloudError> {
    parse_pcd(&read_all(r)?)
}

pub(crate) fn parse_pcd(buf: &[u8]) -> Result<PointCloud, CloudError> {
    let header = parse_header(buf)?;
    let body = buf.get(header.data_start..).unwrap_or_default();
    let columns = match header.data {
        PcdData::Ascii => read_ascii(&header, body)?,
        PcdData::Binary => read_binary(&header, body)?,
        PcdData::BinaryCompressed => read_compressed(&header, body)?,
    };
    let mut cloud = assemble(columns, header.width, header.height)?;
    cloud.viewpoint = header.viewpoint;
    Ok(cloud)
}

/// Bytes per point, or an error for absurd `SIZE`/`COUNT` products.
fn point_size(h: &Header) -> Result<usize, CloudError> {
    h.fields
        .iter()
        .try_fold(0usize, |acc, f| f.kind.size().checked_mul(f.count)?.checked_add(acc))
        .ok_or_else(|| CloudError::Format("PCD header: point size overflows".into()))
}

/// Empty columns for the non-padding fields, with room for `capacity` points.
fn empty_columns(h: &Header, capacity: usize) -> Vec<Option<Column>> {
    h.fields
        .iter()
        .map(|f| {
            (!f.is_padding()).then(|| Column {
                name: f.name.clone(),
                count: f.count,
                data: FieldData::with_capacity(f.kind, capacity.saturating_mul(f.count)),
            })
        })
        .collect()
}

fn read_ascii(h: &Header, body: &[u8]) -> Result<Vec<Column>, CloudError> {
    let per_point = h
        .fields
        .iter()
        .try_fold(0usize, |acc, f| acc.checked_add(f.count))
        .ok_or_else(|| CloudError::Format("PCD header: values per point overflow".into()))?;
    // Every value takes at least two bytes (a digit and a separator): bound the reservation by
    // the data present, not by POINTS or COUNT.
    let capacity = h.points.min(body.len() / per_point.saturating_mul(2));
    let mut cols = empty_columns(h, capacity);
    let mut tokens: Vec<&[u8]> = Vec::new();
    let mut point = 0usize;
    let mut line_no = h.data_line;
    for (line, _) in lines(body) {
        line_no += 1;
        if point == h.points {
            break;
        }
        tokens.clear();
        tokens.extend(line.split(|b| b.is_ascii_whitespace()).filter(|t| !t.is_empty()));
        if tokens.is_empty() {
            continue;
        }
        if tokens.len() != per_point {
            return Err(CloudError::record(
                "point",
                point,
                Some(line_no),
                None,
                format!("{} values, expected {per_point}", tokens.len()),
            ));
        }
        let mut values = tokens.iter();
        for (f, col) in h.fields.iter().zip(cols.iter_mut()) {
            for _ in 0..f.count {
                let tok = values.next().copied().unwrap_or_default();
                let Some(col) = col.as_mut() else { continue };
                let tok = std::str::from_utf8(tok).unwrap_or("\u{FFFD}");
                if !push_ascii_value(f, &mut col.data, tok) {
                    return Err(CloudError::record(
                        "point",
                        point,
                        Some(line_no),
                        Some(&f.name),
                        format!("cannot parse {} as {}", quote(tok), f.kind.name()),
                    ));
                }
            }
        }
        point += 1;
    }
    if point < h.points {
        return Err(CloudError::record(
            "point",
            point,
            Some(line_no + 1),
            None,
            format!("unexpected end of file (POINTS {})", h.points),
        ));
    }
    Ok(cols.into_iter().flatten().collect())
}

fn push_ascii_value(f: &PcdField, data: &mut FieldData, tok: &str) -> bool {
    if f.is_packed_color()
        && tok.bytes().all(|b| b.is_ascii_digit())
        && let (Ok(bits), FieldData::F32(v)) = (tok.parse::<u32>(), &mut *data)
    {
        v.push(f32::from_bits(bits));
        return true;
    }
    data.push_token(tok)
}

fn read_binary(h: &Header, body: &[u8]) -> Result<Vec<Column>, CloudError> {
    let size = point_size(h)?;
    let needed = h.points.checked_mul(size);
    if needed.is_none_or(|n| n > body.len()) {
        return Err(CloudError::record(
            "point",
            body.len() / size.max(1),
            None,
            None,
            format!(
                "unexpected end of file (POINTS {} x {size} bytes from byte {}, file has {})",
                h.points,
                h.data_start,
                h.data_start + body.len()
            ),
        ));
    }
    let mut cols = empty_columns(h, h.points);
    let mut offset = 0;
    for (f, col) in h.fields.iter().zip(cols.iter_mut()) {
        if let Some(col) = col {
            col.data
                .extend_strided(body, (size, h.points), (offset, f.bytes()), false);
        }
        offset += f.bytes();
    }
    Ok(cols.into_iter().flatten().collect())
}

fn read_compressed(h: &Header, body: &[u8]) -> Result<Vec<Column>, CloudError> {
    let size = point_size(h)?;
    let fmt_err = |msg: String| Err(CloudError::Format(format!("binary_compressed data: {msg}")));
    let (Some(comp), Some(raw)) = (body.get(0..4), body.get(4..8)) else {
        if h.points == 0 {
            return Ok(empty_columns(h, 0).into_iter().flatten().collect());
        }
        return fmt_err(format!(
            "file ends at byte {} inside the size header",
            h.data_start + body.len()
        ));
    };
    let comp = <u32 as Scalar>::from_le(comp) as usize;
    let raw = <u32 as Scalar>::from_le(raw) as usize;
    let expected = h.points.checked_mul(size);
    if expected != Some(raw) {
        return fmt_err(format!(
            "uncompressed size {raw} but POINTS {} x {size} bytes per point = {}",
            h.points,
            expected.map_or("overflow".into(), |e| e.to_string())
        ));
    }
    let Some(packed) = body.get(8..8 + comp) else {
        return fmt_err(format!(
            "compressed size {comp} but only {} bytes follow the size header",
            body.len() - 8
        ));
    };
    let data = lzf::decompress(packed, raw).map_err(|e| match e {
        CloudError::Lzf { offset, msg } => CloudError::Lzf {
            offset: offset + h.data_start + 8,
            msg,
        },
        other => other,
    })?;
    // Field-major: all values of the first field, then of the second, ...
    let mut cols = empty_columns(h, 0);
    let mut offset = 0;
    for (f, col) in h.fields.iter().zip(cols.iter_mut()) {
        let len = f.bytes() * h.points;
        if let (Some(col), Some(chunk)) = (col, data.get(offset..offset + len)) {
            col.data.extend_le(chunk);
        }
        offset += len;
    }
    Ok(cols.into_iter().flatten().collect())
}

/// Writes `cloud` as PCD v0.7 with `data` encoding: `x y z` as `F 4`, then every field.
pub fn write_pcd(mut w: impl Write, cloud: &PointCloud, data: PcdData) -> Result<(), CloudError> {
    cloud.validate()?;
    let (width, height) = dims(cloud);
    let n = cloud.points.len();
    let mut names = String::from("x y z");
    let mut sizes = String::from("4 4 4");
    let mut types = String::from("F F F");
    let mut counts = String::from("1 1 1");
    for f in &cloud.fields {
        let kind = f.data.kind();
        names += &format!(" {}", f.name);
        sizes += &format!(" {}", kind.size());
        types += &format!(" {}", pcd_type(kind));
        counts += &format!(" {}", f.count);
    }
    let viewpoint = cloud
        .viewpoint
        .unwrap_or([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
        .map(|v| v.to_string())
        .join(" ");
    let encoding = match data {
        PcdData::Ascii => "ascii",
        PcdData::Binary => "binary",
        PcdData::BinaryCompressed => "binary_compressed",
    };
    let header = format!(
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {names}\nSIZE {sizes}\n\
         TYPE {types}\nCOUNT {counts}\nWIDTH {width}\nHEIGHT {height}\n\
         VIEWPOINT {viewpoint}\nPOINTS {n}\nDATA {encoding}\n"
    );
    w.write_all(header.as_bytes())?;
    match data {
        PcdData::Ascii => w.write_all(ascii_body(cloud).as_bytes())?,
        PcdData::Binary => {
            let mut out = Vec::new();
            for (i, p) in cloud.points.iter().enumerate() {
                p.iter().for_each(|c| c.put_le(&mut out));
                for f in &cloud.fields {
                    f.data.put_le(i * f.count..(i + 1) * f.count, &mut out);
                }
            }
            w.write_all(&out)?;
        }
        PcdData::BinaryCompressed => {
            let mut raw = Vec::new();
            for k in 0..3 {
                cloud.points.iter().for_each(|p| p[k].put_le(&mut raw));
            }
            for f in &cloud.fields {
                f.data.put_le(0..f.data.len(), &mut raw);
            }
            let packed = lzf::compress(&raw);
            let too_big = || CloudError::InvalidCloud("too large for binary_compressed PCD".into());
            let comp = u32::try_from(packed.len()).map_err(|_| too_big())?;
            let raw_len = u32::try_from(raw.len()).map_err(|_| too_big())?;
            w.write_all(&comp.to_le_bytes())?;
            w.write_all(&raw_len.to_le_bytes())?;
            w.write_all(&packed)?;
        }
    }
    Ok(())
}

fn ascii_body(cloud: &PointCloud) -> String {
    let mut out = String::new();
    for (i, p) in cloud.points.iter().enumerate() {
        for (k, c) in p.iter().enumerate() {
            if k > 0 {
                out.push(' ');
            }
            c.write_token(&mut out);
        }
        for f in &cloud.fields {
            let packed = matches!(f.name.as_str(), "rgb" | "rgba");
            for j in i * f.count..(i + 1) * f.count {
                out.push(' ');
                match &f.data {
                    FieldData::F32(v) if packed => out += &v[j].to_bits().to_string(),
                    data => data.write_token(j, &mut out),
                }
            }
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        parse_pcd(text.as_bytes()).unwrap_err().to_string()
    }

    const HEAD: &str = "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n";

    #[test]
    fn header_errors_name_the_line() {
        let e = err("VERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4\nTYPE F F F F\nPOINTS 1\nDATA ascii\n");
        assert_eq!(e, "header line 3: SIZE has 3 entries but FIELDS has 4");
        let e = err(&format!("{HEAD}WIDTH 10\nHEIGHT 12\nPOINTS 100\nDATA ascii\n"));
        assert_eq!(e, "header line 9: POINTS 100 but WIDTH*HEIGHT = 120");
        let e = err("FIELDS x y\nPOINTS 1\nDATA ascii\n1 2\n");
        assert_eq!(e, "header line 1: FIELDS has no `z` field");
        let e = err("FIELDS x y z\nSIZE 4 4 3\nPOINTS 1\nDATA ascii\n");
        assert!(e.starts_with("header line 2: field `z`: TYPE F with SIZE 3"), "{e}");
        let e = err(&format!("{HEAD}WIDTH 2\nDATA zip\n"));
        assert!(e.starts_with("header line 8: DATA zip"), "{e}");
        let e = err(&format!("{HEAD}WIDTH 2\n"));
        assert!(e.contains("no DATA line"), "{e}");
    }

    #[test]
    fn data_errors_name_point_and_field() {
        let e = err(&format!("{HEAD}WIDTH 2\nDATA ascii\n1 2 3\n4 five 6\n"));
        assert_eq!(e, "point 1 (line 10), field `y`: cannot parse `five` as f32");
        let e = err(&format!("{HEAD}WIDTH 3\nDATA ascii\n1 2 3\n4 5 6\n"));
        assert!(e.starts_with("point 2 (line 11): unexpected end of file"), "{e}");
        let e = err(&format!("{HEAD}WIDTH 2\nDATA binary\n0123456789abcdef"));
        assert!(e.starts_with("point 1: unexpected end of file"), "{e}");
    }

    #[test]
    fn huge_counts_do_not_allocate() {
        let e = err(&format!("{HEAD}WIDTH 4000000\nDATA binary\n0123"));
        assert!(e.starts_with("point 0: unexpected end of file"), "{e}");
        let e = err(&format!("{HEAD}WIDTH 1000000000000\nDATA binary\n0123"));
        assert!(e.contains("1000000000000 points, more than the 4194304"), "{e}");
        let mut file = format!("{HEAD}WIDTH 1000000\nDATA binary_compressed\n").into_bytes();
        file.extend_from_slice(&16u32.to_le_bytes());
        file.extend_from_slice(&12_000_000u32.to_le_bytes());
        let e = parse_pcd(&file).unwrap_err().to_string();
        assert!(e.contains("compressed size 16 but only 0 bytes"), "{e}");
        file.truncate(file.len() - 8);
        file.extend_from_slice(&4u32.to_le_bytes());
        file.extend_from_slice(&12_000_000u32.to_le_bytes());
        file.extend_from_slice(&[0xff; 4]);
        let e = parse_pcd(&file).unwrap_err().to_string();
        assert!(e.contains("LZF data corrupt at byte"), "{e}");
        let e = err(&format!("{HEAD}WIDTH 1000000000000\nHEIGHT 1000000000\nDATA binary\n"));
        assert!(e.contains("overflows"), "{e}");
        let e = err(&format!("{HEAD}WIDTH 4000000\nDATA ascii\n1 2 3\n"));
        assert!(e.contains("point 1"), "{e}");
        let huge_count = "FIELDS x y z n\nCOUNT 1 1 1 1000000000000000000\nWIDTH 9\nDATA";
        let e = err(&format!("{huge_count} ascii\n1 2 3 4\n"));
        assert!(e.contains("4 values, expected 1000000000000000003"), "{e}");
        let e = err(&format!("{huge_count} binary\n1 2 3 4\n"));
        assert!(e.starts_with("point 0: unexpected end of file"), "{e}");
        let e = err(&format!("{huge_count} binary_compressed\n1 2 3 4 5 6 7 8\n"));
        assert!(e.contains("overflow"), "{e}");
        let e = err("FIELDS x y z n m\nCOUNT 1 1 1 18446744073709551615 9\nWIDTH 9\nDATA ascii\n");
        assert!(e.contains("values per point overflow"), "{e}");
    }

    #[test]
    fn old_header_and_padding() {
        // v.5 style: no VERSION, SIZE/TYPE/COUNT defaults; `_` padding skipped; x after others.
        let c = parse_pcd(b"COLUMNS i x _ y z\nPOINTS 2\nDATA ascii\n7 1 0 2 3\n8 4 0 5 nan\n").unwrap();
        assert_eq!(c.points[0], [1.0, 2.0, 3.0]);
        assert!(c.points[1][2].is_nan());
        assert_eq!(c.fields.len(), 1);
        assert_eq!(c.fields[0].data, FieldData::F32(vec![7.0, 8.0]));
    }

    #[test]
    fn packed_rgb_ascii_keeps_bits() {
        let mut c = PointCloud::from_points(vec![[1.0, 2.0, 3.0]]);
        let bits = 0xff_12_34_56u32; // a NaN as f32
        c.fields.push(super::super::Field::scalar(
            "rgb",
            FieldData::F32(vec![f32::from_bits(bits)]),
        ));
        let mut out = Vec::new();
        write_pcd(&mut out, &c, PcdData::Ascii).unwrap();
        assert!(String::from_utf8_lossy(&out).ends_with(&format!("1 2 3 {bits}\n")));
        let back = parse_pcd(&out).unwrap();
        let FieldData::F32(v) = &back.fields[0].data else {
            panic!()
        };
        assert_eq!(v[0].to_bits(), bits);
    }
}
