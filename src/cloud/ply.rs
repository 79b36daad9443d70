//! PLY (Stanford polygon format): the vertex element as a point cloud.

use std::io::{Read, Write};

use super::codec::{Column, Scalar, Tokens, assemble, dims, lines, quote, read_all};
use super::{CloudError, FieldData, PlyFormat, PointCloud, ScalarKind};

#[derive(Debug, Clone, Copy, PartialEq)]
enum Encoding {
    Ascii,
    LittleEndian,
    BigEndian,
}

#[derive(Debug, Clone, Copy)]
enum PropType {
    Scalar(ScalarKind),
    /// A list: its length (an integer type), then that many items.
    List {
        len: ScalarKind,
        item: ScalarKind,
    },
}

#[derive(Debug)]
struct Prop {
    name: String,
    ty: PropType,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Prop>,
    /// The properties' names, for a linear-time duplicate check.
    prop_names: std::collections::HashSet<String>,
}

impl Element {
    /// Bytes per instance when the element has no list properties.
    fn fixed_size(&self) -> Option<usize> {
        self.props.iter().try_fold(0usize, |acc, p| match p.ty {
            PropType::Scalar(k) => acc.checked_add(k.size()),
            PropType::List { .. } => None,
        })
    }

    /// The fewest bytes a binary instance takes: its scalars, and each list's length word (an
    /// empty list).
    fn min_binary_size(&self) -> usize {
        self.props
            .iter()
            .map(|p| match p.ty {
                PropType::Scalar(k) | PropType::List { len: k, .. } => k.size(),
            })
            .sum()
    }
}

#[derive(Debug)]
struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// `(width, height)` from our `obj_info sqscan width W height H` line.
    organized: Option<(usize, usize)>,
    /// From our `obj_info sqscan viewpoint tx ty tz qw qx qy qz` line.
    viewpoint: Option<[f64; 7]>,
    data_start: usize,
    /// Line number of `end_header`.
    end_line: usize,
}

/// PLY type names: the classic ones and the sized aliases.
fn ply_kind(name: &str) -> Option<ScalarKind> {
    Some(match name {
        "char" | "int8" => ScalarKind::I8,
        "uchar" | "uint8" => ScalarKind::U8,
        "short" | "int16" => ScalarKind::I16,
        "ushort" | "uint16" => ScalarKind::U16,
        "int" | "int32" => ScalarKind::I32,
        "uint" | "uint32" => ScalarKind::U32,
        "float" | "float32" => ScalarKind::F32,
        "double" | "float64" => ScalarKind::F64,
        _ => return None,
    })
}

fn ply_name(kind: ScalarKind) -> &'static str {
    match kind {
        ScalarKind::I8 => "char",
        ScalarKind::U8 => "uchar",
        ScalarKind::I16 => "short",
        ScalarKind::U16 => "ushort",
        ScalarKind::I32 => "int",
        ScalarKind::U32 => "uint",
        ScalarKind::F32 => "float",
        ScalarKind::F64 => "double",
    }
}

fn parse_header(buf: &[u8]) -> Result<Header, CloudError> {
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut organized = None;
    let mut viewpoint = None;
    let mut vertex_line = 0;
    for (line_no, (raw, next)) in (1..).zip(lines(buf)) {
        let err = |msg: String| CloudError::header(line_no, msg);
        let text = std::str::from_utf8(raw).map_err(|_| err("not text".into()))?;
        let words: Vec<&str> = text.split_ascii_whitespace().collect();
        if line_no == 1 {
            if words != ["ply"] {
                return Err(err("not a PLY file (first line is not `ply`)".into()));
            }
            continue;
        }
        match words.as_slice() {
            [] | ["comment", ..] => {}
            ["obj_info", "sqscan", "width", w, "height", h] => {
                organized = w.parse().ok().zip(h.parse().ok());
            }
            ["obj_info", "sqscan", "viewpoint", rest @ ..] => {
                let v: Vec<f64> = rest.iter().filter_map(|t| t.parse().ok()).collect();
                viewpoint = <[f64; 7]>::try_from(v.as_slice())
                    .ok()
                    .filter(|v| v.iter().all(|x| x.is_finite()));
            }
            ["obj_info", ..] => {}
            ["format", f, _version] => {
                encoding = Some(match *f {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::LittleEndian,
                    "binary_big_endian" => Encoding::BigEndian,
                    _ => return Err(err(format!("unknown format {}", quote(f)))),
                });
            }
            ["element", name, count] => {
                let count = count
                    .parse()
                    .map_err(|_| err(format!("element count {} is not a count", quote(count))))?;
                if *name == "vertex" && vertex_line == 0 {
                    vertex_line = line_no;
                    super::check_point_count(count).map_err(err)?;
                }
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                    prop_names: std::collections::HashSet::new(),
                });
            }
            ["property", rest @ ..] => {
                let Some(element) = elements.last_mut() else {
                    return Err(err("property before any element".into()));
                };
                add_property(element, rest).map_err(err)?;
            }
            ["end_header"] => {
                let Some(encoding) = encoding else {
                    return Err(err("no format line before end_header".into()));
                };
                check_vertex(&elements, vertex_line).map_err(|e| match e {
                    None => err("no vertex element".into()),
                    Some(e) => e,
                })?;
                return Ok(Header {
                    encoding,
                    elements,
                    organized,
                    viewpoint,
                    data_start: next,
                    end_line: line_no,
                });
            }
            [keyword, ..] => return Err(err(format!("unknown keyword {}", quote(keyword)))),
        }
    }
    Err(CloudError::Format(
        "PLY header: no end_header line before the end of the file".into(),
    ))
}

/// Adds a `property` line's property (`rest`: its words after `property`) to `element`.
fn add_property(element: &mut Element, rest: &[&str]) -> Result<(), String> {
    let kind = |t: &str| ply_kind(t).ok_or_else(|| format!("unknown type {}", quote(t)));
    let (ty, name) = match rest {
        ["list", len, item, name] => {
            let len = kind(len)?;
            if matches!(len, ScalarKind::F32 | ScalarKind::F64) {
                return Err(format!("list `{name}`: length type must be an integer"));
            }
            (PropType::List { len, item: kind(item)? }, name)
        }
        [ty, name] => (PropType::Scalar(kind(ty)?), name),
        _ => return Err("property needs a type and a name".into()),
    };
    if !element.prop_names.insert(name.to_string()) {
        return Err(format!("property `{name}` appears twice"));
    }
    element.props.push(Prop {
        name: name.to_string(),
        ty,
    });
    Ok(())
}

/// That there is a vertex element (`Err(None)` where there is none) with scalar x, y and z
/// (an error naming the vertex element's line otherwise).
fn check_vertex(elements: &[Element], vertex_line: usize) -> Result<(), Option<CloudError>> {
    let vertex = elements.iter().find(|e| e.name == "vertex").ok_or(None)?;
    for axis in ["x", "y", "z"] {
        let found = vertex.props.iter().find(|p| p.name == axis);
        if !matches!(
            found,
            Some(Prop {
                ty: PropType::Scalar(_),
                ..
            })
        ) {
            return Err(Some(CloudError::header(
                vertex_line,
                format!("vertex element has no scalar `{axis}` property"),
            )));
        }
    }
    Ok(())
}

/// Reads a PLY file (see the [`io`](super::io) module docs).
pub fn read_ply(r: impl Read) -> Result<PointCloud, CloudError> {
    parse_ply(&read_all(r)?)
}

pub(crate) fn parse_ply(buf: &[u8]) -> Result<PointCloud, CloudError> {
    let header = parse_header(buf)?;
    let body = buf.get(header.data_start..).unwrap_or_default();
    let (columns, n) = match header.encoding {
        Encoding::Ascii => read_ascii(&header, body)?,
        Encoding::LittleEndian => read_binary(&header, body, false)?,
        Encoding::BigEndian => read_binary(&header, body, true)?,
    };
    let (width, height) = match header.organized {
        Some((w, h)) if h > 1 && w.checked_mul(h) == Some(n) => (w, h),
        _ => (n, 1),
    };
    let mut cloud = assemble(columns, width, height)?;
    cloud.viewpoint = header.viewpoint;
    Ok(cloud)
}

/// Empty columns for the scalar properties of the vertex element (`None` for lists).
fn vertex_columns(vertex: &Element, capacity: usize) -> Vec<Option<Column>> {
    vertex
        .props
        .iter()
        .map(|p| match p.ty {
            PropType::Scalar(kind) => Some(Column {
                name: p.name.clone(),
                count: 1,
                data: FieldData::with_capacity(kind, capacity),
            }),
            PropType::List { .. } => None,
        })
        .collect()
}

/// Decodes the vertex element and returns its columns and vertex count; elements before it are
/// skipped, elements after it are not read at all.
fn read_binary(h: &Header, body: &[u8], big_endian: bool) -> Result<(Vec<Column>, usize), CloudError> {
    let mut pos = 0usize;
    for el in &h.elements {
        if el.name != "vertex" {
            pos = skip_binary(el, body, pos, big_endian)?;
            continue;
        }
        let data = body.get(pos..).unwrap_or_default();
        let mut cols;
        if let Some(stride) = el.fixed_size() {
            let needed = el.count.checked_mul(stride);
            if needed.is_none_or(|n| n > data.len()) {
                return Err(eof(el, data.len() / stride.max(1), None));
            }
            cols = vertex_columns(el, el.count);
            let mut offset = 0;
            for (p, col) in el.props.iter().zip(cols.iter_mut()) {
                if let (Some(col), PropType::Scalar(kind)) = (col, p.ty) {
                    let range = (offset, kind.size());
                    col.data.extend_strided(data, (stride, el.count), range, big_endian);
                    offset += kind.size();
                }
            }
        } else {
            // Lists in the vertex element: walk vertex by vertex. Reserve for the vertices the
            // data can hold, not for the header's count.
            cols = vertex_columns(el, el.count.min(data.len() / el.min_binary_size().max(1)));
            let mut at = 0usize;
            for i in 0..el.count {
                for (p, col) in el.props.iter().zip(cols.iter_mut()) {
                    match p.ty {
                        PropType::Scalar(kind) => {
                            let bytes = data
                                .get(at..at + kind.size())
                                .ok_or_else(|| eof(el, i, Some(&p.name)))?;
                            if let Some(col) = col {
                                if big_endian {
                                    col.data.extend_be(bytes);
                                } else {
                                    col.data.extend_le(bytes);
                                }
                            }
                            at += kind.size();
                        }
                        PropType::List { len, item } => {
                            at = skip_list(data, at, (len, item), big_endian)
                                .ok_or_else(|| eof(el, i, Some(&p.name)))?;
                        }
                    }
                }
            }
        }
        return Ok((cols.into_iter().flatten().collect(), el.count));
    }
    // parse_header made sure there is a vertex element.
    Err(CloudError::Format("no vertex element".into()))
}

fn eof(el: &Element, index: usize, field: Option<&str>) -> CloudError {
    CloudError::record(&el.name, index, None, field, "unexpected end of file")
}

/// Skips a binary element starting at `pos`; returns the position after it.
fn skip_binary(el: &Element, body: &[u8], pos: usize, big_endian: bool) -> Result<usize, CloudError> {
    let remaining = body.len().saturating_sub(pos);
    if let Some(size) = el.fixed_size() {
        return match el.count.checked_mul(size) {
            Some(total) if total <= remaining => Ok(pos + total),
            _ => Err(eof(el, remaining / size.max(1), None)),
        };
    }
    // Every instance has a list, hence takes at least one byte: the loop ends at the end of the
    // data whatever the declared count.
    let mut at = pos;
    for i in 0..el.count {
        for p in &el.props {
            at = match p.ty {
                PropType::Scalar(kind) => Some(at + kind.size()).filter(|&e| e <= body.len()),
                PropType::List { len, item } => skip_list(body, at, (len, item), big_endian),
            }
            .ok_or_else(|| eof(el, i, Some(&p.name)))?;
        }
    }
    Ok(at)
}

/// Skips the list at `at`; `None` if it runs past the end (or has a negative length).
fn skip_list(data: &[u8], at: usize, (len, item): (ScalarKind, ScalarKind), big_endian: bool) -> Option<usize> {
    let bytes = data.get(at..at + len.size())?;
    let mut value = FieldData::with_capacity(len, 1);
    if big_endian {
        value.extend_be(bytes);
    } else {
        value.extend_le(bytes);
    }
    let n = value.get_f64(0).filter(|&n| n >= 0.0)? as usize;
    let end = (at + len.size()).checked_add(n.checked_mul(item.size())?)?;
    (end <= data.len()).then_some(end)
}

fn read_ascii(h: &Header, body: &[u8]) -> Result<(Vec<Column>, usize), CloudError> {
    let mut tokens = Tokens::new(body, h.end_line + 1);
    for el in &h.elements {
        let is_vertex = el.name == "vertex";
        if el.props.is_empty() {
            continue;
        }
        let mut cols = if is_vertex {
            // Each value takes at least two bytes: reserve by the data present, not the count.
            let capacity = el.count.min(body.len() / (2 * el.props.len()) + 1);
            vertex_columns(el, capacity)
        } else {
            Vec::new()
        };
        for i in 0..el.count {
            for (j, p) in el.props.iter().enumerate() {
                let Some((tok, line)) = tokens.next_token() else {
                    let line = Some(tokens.line);
                    let msg = "unexpected end of file";
                    return Err(CloudError::record(&el.name, i, line, Some(&p.name), msg));
                };
                let bad = |msg: String| CloudError::record(&el.name, i, Some(line), Some(&p.name), msg);
                match p.ty {
                    PropType::Scalar(kind) => {
                        if let Some(Some(col)) = cols.get_mut(j)
                            && !col.data.push_token(tok)
                        {
                            return Err(bad(format!("cannot parse {} as {}", quote(tok), ply_name(kind))));
                        }
                    }
                    PropType::List { .. } => {
                        let Ok(n) = tok.parse::<u64>() else {
                            return Err(bad(format!("list length {} is not a count", quote(tok))));
                        };
                        for _ in 0..n {
                            if tokens.next_token().is_none() {
                                let line = Some(tokens.line);
                                let msg = "unexpected end of file in a list";
                                return Err(CloudError::record(&el.name, i, line, Some(&p.name), msg));
                            }
                        }
                    }
                }
            }
        }
        if is_vertex {
            return Ok((cols.into_iter().flatten().collect(), el.count));
        }
    }
    Err(CloudError::Format("no vertex element".into()))
}

/// Writes `cloud` as a PLY vertex element: `x y z` as `float`, then each field with its type
/// (a field with `count > 1` as properties `name_0`, `name_1`, ...).
pub fn write_ply(mut w: impl Write, cloud: &PointCloud, format: PlyFormat) -> Result<(), CloudError> {
    cloud.validate()?;
    let n = cloud.points.len();
    let mut header = String::from("ply\n");
    header += match format {
        PlyFormat::Ascii => "format ascii 1.0\n",
        PlyFormat::BinaryLittleEndian => "format binary_little_endian 1.0\n",
    };
    header += "comment written by sqscan\n";
    if cloud.is_organized() {
        let (width, height) = dims(cloud);
        header += &format!("obj_info sqscan width {width} height {height}\n");
    }
    if let Some(v) = cloud.viewpoint {
        let v: Vec<String> = v.iter().map(|x| x.to_string()).collect();
        header += &format!("obj_info sqscan viewpoint {}\n", v.join(" "));
    }
    header += &format!("element vertex {n}\nproperty float x\nproperty float y\nproperty float z\n");
    for f in &cloud.fields {
        let ty = ply_name(f.data.kind());
        if f.count == 1 {
            header += &format!("property {ty} {}\n", f.name);
        } else {
            for k in 0..f.count {
                header += &format!("property {ty} {}_{k}\n", f.name);
            }
        }
    }
    header += "end_header\n";
    w.write_all(header.as_bytes())?;
    match format {
        PlyFormat::Ascii => {
            let mut out = String::new();
            for (i, p) in cloud.points.iter().enumerate() {
                for (k, c) in p.iter().enumerate() {
                    if k > 0 {
                        out.push(' ');
                    }
                    c.write_token(&mut out);
                }
                for f in &cloud.fields {
                    for j in i * f.count..(i + 1) * f.count {
                        out.push(' ');
                        f.data.write_token(j, &mut out);
                    }
                }
                out.push('\n');
            }
            w.write_all(out.as_bytes())?;
        }
        PlyFormat::BinaryLittleEndian => {
            let mut out = Vec::new();
            for (i, p) in cloud.points.iter().enumerate() {
                p.iter().for_each(|c| c.put_le(&mut out));
                for f in &cloud.fields {
                    f.data.put_le(i * f.count..(i + 1) * f.count, &mut out);
                }
            }
            w.write_all(&out)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(bytes: &[u8]) -> String {
        parse_ply(bytes).unwrap_err().to_string()
    }

    #[test]
    fn skips_faces_and_reads_big_endian() {
        let mut file = b"ply\nformat binary_big_endian 1.0\ncomment x\nobj_info y\n\
            element face 2\nproperty list uchar int vertex_indices\n\
            element vertex 2\nproperty double x\nproperty float y\nproperty float z\n\
            property uchar red\nend_header\n"
            .to_vec();
        for face in [[0i32, 1, 1], [1, 0, 0]] {
            file.push(3);
            face.iter().for_each(|v| file.extend_from_slice(&v.to_be_bytes()));
        }
        for (x, y, z, r) in [(1.0f64, 2.0f32, 3.0f32, 7u8), (4.0, 5.0, -6.0, 255)] {
            file.extend_from_slice(&x.to_be_bytes());
            file.extend_from_slice(&y.to_be_bytes());
            file.extend_from_slice(&z.to_be_bytes());
            file.push(r);
        }
        let c = parse_ply(&file).unwrap();
        assert_eq!(c.points, vec![[1.0, 2.0, 3.0], [4.0, 5.0, -6.0]]);
        assert_eq!(c.field("red").unwrap().data, FieldData::U8(vec![7, 255]));
        let e = err(&file[..file.len() - 1]);
        assert_eq!(e, "vertex 1: unexpected end of file");
        let e = err(&file[..file.len() - 40]);
        assert_eq!(e, "face 1, field `vertex_indices`: unexpected end of file");
    }

    #[test]
    fn ascii_with_lists_and_sized_type_names() {
        let text = b"ply\r\nformat ascii 1.0\r\nelement vertex 2\r\nproperty float32 x\r\n\
            property float32 y\r\nproperty float32 z\r\nproperty list uint8 int32 idx\r\n\
            property int16 t\r\nelement face 1\r\nproperty list uchar int v\r\nend_header\r\n\
            1 2 3 2 9 9 -4\r\n4 5 6 0 7\r\n3 0 1 1\r\n";
        let c = parse_ply(text).unwrap();
        assert_eq!(c.points, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!(c.field("t").unwrap().data, FieldData::I16(vec![-4, 7]));
    }

    #[test]
    fn errors_name_line_and_field() {
        let e = err(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n");
        assert_eq!(e, "header line 3: vertex element has no scalar `z` property");
        let e = err(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty floot x\n");
        assert_eq!(e, "header line 4: unknown type `floot`");
        let e = err(
            b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
            property float z\nend_header\n1 2 3\n4 x 6\n",
        );
        assert_eq!(e, "vertex 1 (line 9), field `y`: cannot parse `x` as float");
        let e = err(
            b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
            property float z\nend_header\n1 2 3\n4 5",
        );
        assert_eq!(e, "vertex 1 (line 9), field `z`: unexpected end of file");
        let e = err(b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000\n\
            property float x\nproperty float y\nproperty float z\nend_header\n");
        assert_eq!(e, "vertex 0: unexpected end of file");
        let e = err(b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\n\
            property float x\nproperty float y\nproperty float z\nend_header\n");
        assert!(e.contains("1000000000000 points, more than the 4194304"), "{e}");
    }
}
