//! Plain text clouds: one point per line, `x y z [more columns]`.

use std::io::{Read, Write};

use super::codec::{Column, Scalar, assemble, lines, quote, read_all};
use super::{CloudError, FieldData, PointCloud, ScalarKind};

/// The comment that names and types the columns (written by [`write_text`]).
const COLUMNS_TAG: &str = "sqscan-columns:";

/// One extra column group declared by a `# sqscan-columns:` line.
#[derive(Debug)]
struct Spec {
    name: String,
    kind: ScalarKind,
    count: usize,
}

/// Parses the part of a `# sqscan-columns: x y z name:kind[*count] ...` line after the tag.
fn parse_spec(line: usize, rest: &str) -> Result<Vec<Spec>, CloudError> {
    let mut words = rest.split_ascii_whitespace();
    if words.by_ref().take(3).collect::<Vec<_>>() != ["x", "y", "z"] {
        return Err(CloudError::header(line, format!("{COLUMNS_TAG} must start with x y z")));
    }
    words
        .map(|w| {
            let parsed = w.split_once(':').and_then(|(name, ty)| {
                let (kind, count) = match ty.split_once('*') {
                    Some((k, c)) => (k, c.parse().ok().filter(|&c| c > 0)?),
                    None => (ty, 1),
                };
                let kind = ScalarKind::from_name(kind)?;
                Some(Spec {
                    name: name.to_string(),
                    kind,
                    count,
                })
            });
            parsed.filter(|s| !s.name.is_empty()).ok_or_else(|| {
                let msg = format!("{COLUMNS_TAG} entry {} is not name:kind[*count]", quote(w));
                CloudError::header(line, msg)
            })
        })
        .collect::<Result<Vec<Spec>, CloudError>>()
        .and_then(|specs| {
            let mut seen = std::collections::HashSet::with_capacity(specs.len());
            for s in &specs {
                if matches!(s.name.as_str(), "x" | "y" | "z") || !seen.insert(s.name.as_str()) {
                    let msg = format!("{COLUMNS_TAG} column `{}` appears twice", s.name);
                    return Err(CloudError::header(line, msg));
                }
            }
            Ok(specs)
        })
}

/// Reads a plain text cloud (see the [`io`](super::io) module docs).
pub fn read_text(r: impl Read) -> Result<PointCloud, CloudError> {
    parse_text(&read_all(r)?)
}

/// Where the extra columns go: typed by a `sqscan-columns` line, or `f64` until the end decides.
enum Extra {
    Typed(Vec<(Spec, FieldData)>),
    Untyped(Vec<Vec<f64>>),
}

pub(crate) fn parse_text(buf: &[u8]) -> Result<PointCloud, CloudError> {
    let mut spec: Option<(usize, Vec<Spec>)> = None;
    // Number of columns and the line that set it.
    let mut layout: Option<(usize, usize)> = None;
    let mut coords: [Vec<f32>; 3] = Default::default();
    let mut extra = Extra::Untyped(Vec::new());
    let mut tokens: Vec<&str> = Vec::new();

    for (line_no, (raw, _)) in (1..).zip(lines(buf)) {
        let point = coords[0].len();
        let err = |field: Option<&str>, msg: String| CloudError::record("point", point, Some(line_no), field, msg);
        let text = std::str::from_utf8(raw).map_err(|_| err(None, "not UTF-8 text".into()))?;
        let (data, comment) = text.split_once('#').unwrap_or((text, ""));
        if let Some(rest) = comment.trim_start().strip_prefix(COLUMNS_TAG)
            && layout.is_none()
        {
            spec = Some((line_no, parse_spec(line_no, rest)?));
        }
        let data = data.trim();
        if data.starts_with("//") {
            continue; // CloudCompare-style column header
        }
        tokens.clear();
        tokens.extend(
            data.split(|c: char| c.is_ascii_whitespace() || c == ',')
                .filter(|t| !t.is_empty()),
        );
        if tokens.is_empty() {
            continue;
        }
        super::check_point_count(point + 1).map_err(|msg| err(None, msg))?;
        match layout {
            None => {
                if tokens.len() < 3 {
                    return Err(err(None, format!("{} columns, need at least x y z", tokens.len())));
                }
                extra = Extra::for_columns(tokens.len(), spec.take()).map_err(|msg| err(None, msg))?;
                layout = Some((tokens.len(), line_no));
            }
            Some((n, first)) if n != tokens.len() => {
                let msg = format!("{} columns, expected {n} (as on line {first})", tokens.len());
                return Err(err(None, msg));
            }
            Some(_) => {}
        }
        for (k, (axis, tok)) in ["x", "y", "z"].iter().zip(&tokens).enumerate() {
            let Some(v) = f32::parse_token(tok) else {
                return Err(err(Some(axis), format!("cannot parse {} as f32", quote(tok))));
            };
            coords[k].push(v);
        }
        extra
            .push(&tokens[3..])
            .map_err(|(field, msg)| err(Some(&field), msg))?;
    }
    let n = coords[0].len();
    assemble(columns(coords, extra), n, 1)
}

impl Extra {
    /// The extra columns of a cloud whose first point has `n` columns: as the `sqscan-columns`
    /// line (and its line number) declares them, which must add up to `n`, or untyped.
    fn for_columns(n: usize, spec: Option<(usize, Vec<Spec>)>) -> Result<Extra, String> {
        let Some((spec_line, specs)) = spec else {
            return Ok(Extra::Untyped(vec![Vec::new(); n - 3]));
        };
        let declared = specs.iter().try_fold(3usize, |k, s| k.checked_add(s.count));
        if declared != Some(n) {
            let declared = declared.map_or("too many".into(), |k| k.to_string());
            return Err(format!(
                "{n} columns, but the {COLUMNS_TAG} line {spec_line} declares {declared}"
            ));
        }
        let typed = specs
            .into_iter()
            .map(|s| {
                let data = FieldData::with_capacity(s.kind, 0);
                (s, data)
            })
            .collect();
        Ok(Extra::Typed(typed))
    }

    /// One point's extra tokens; the field and the message where one does not parse.
    fn push(&mut self, tokens: &[&str]) -> Result<(), (String, String)> {
        let mut rest = tokens.iter();
        match self {
            Extra::Typed(cols) => {
                for (s, data) in cols.iter_mut() {
                    for tok in rest.by_ref().take(s.count) {
                        if !data.push_token(tok) {
                            let msg = format!("cannot parse {} as {}", quote(tok), s.kind.name());
                            return Err((s.name.clone(), msg));
                        }
                    }
                }
            }
            Extra::Untyped(cols) => {
                for (c, (col, tok)) in cols.iter_mut().zip(rest).enumerate() {
                    let Some(v) = f64::parse_token(tok) else {
                        return Err((format!("c{}", c + 3), format!("cannot parse {} as f64", quote(tok))));
                    };
                    col.push(v);
                }
            }
        }
        Ok(())
    }
}

/// The cloud's columns: x, y and z, then the extra ones (three untyped columns of integers in
/// 0..=255 as red, green and blue).
fn columns(coords: [Vec<f32>; 3], extra: Extra) -> Vec<Column> {
    let [x, y, z] = coords;
    let mut columns = vec![
        Column {
            name: "x".into(),
            count: 1,
            data: FieldData::F32(x),
        },
        Column {
            name: "y".into(),
            count: 1,
            data: FieldData::F32(y),
        },
        Column {
            name: "z".into(),
            count: 1,
            data: FieldData::F32(z),
        },
    ];
    match extra {
        Extra::Typed(cols) => columns.extend(cols.into_iter().map(|(s, data)| Column {
            name: s.name,
            count: s.count,
            data,
        })),
        Extra::Untyped(cols) if looks_like_rgb(&cols) => {
            for (name, col) in ["red", "green", "blue"].into_iter().zip(cols) {
                let data = FieldData::U8(col.into_iter().map(|v| v as u8).collect());
                columns.push(Column {
                    name: name.into(),
                    count: 1,
                    data,
                });
            }
        }
        Extra::Untyped(cols) => {
            for (c, col) in cols.into_iter().enumerate() {
                let data = FieldData::F64(col);
                columns.push(Column {
                    name: format!("c{}", c + 3),
                    count: 1,
                    data,
                });
            }
        }
    }
    columns
}

/// Three extra columns of integers in 0..=255: `x y z r g b` colour.
fn looks_like_rgb(cols: &[Vec<f64>]) -> bool {
    cols.len() == 3
        && !cols[0].is_empty()
        && cols
            .iter()
            .flatten()
            .all(|&v| v.fract() == 0.0 && (0.0..=255.0).contains(&v))
}

/// Writes one point per line: `x y z` and then every field's values, preceded by a
/// `# sqscan-columns:` comment that lets [`read_text`] restore names and types.
pub fn write_text(mut w: impl Write, cloud: &PointCloud) -> Result<(), CloudError> {
    cloud.validate()?;
    let mut out = format!("# {COLUMNS_TAG} x y z");
    for f in &cloud.fields {
        out += &format!(" {}:{}", f.name, f.data.kind().name());
        if f.count > 1 {
            out += &format!("*{}", f.count);
        }
    }
    out.push('\n');
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
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rgb_and_generic_columns() {
        let c = parse_text(b"# comment\n1 2 3 10 20 255\n4,5,6,0,0,0 # trailing\n\n").unwrap();
        assert_eq!(c.points, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!(c.field("green").unwrap().data, FieldData::U8(vec![20, 0]));
        let c = parse_text(b"//X,Y,Z,I,J\n1 2 3 0.5 7\n4 5 6 1 2\n").unwrap();
        assert_eq!(c.field("c3").unwrap().data, FieldData::F64(vec![0.5, 1.0]));
        assert_eq!(c.field("c4").unwrap().data, FieldData::F64(vec![7.0, 2.0]));
        let c = parse_text(b"1 2 3 1 2 256\n").unwrap();
        assert!(c.field("c5").is_some());
        let c = parse_text(b"").unwrap();
        assert!(c.is_empty());
    }

    #[test]
    fn errors() {
        let e = |b: &[u8]| parse_text(b).unwrap_err().to_string();
        assert_eq!(
            e(b"1 2 3\n4 5\n"),
            "point 1 (line 2): 2 columns, expected 3 (as on line 1)"
        );
        assert_eq!(
            e(b"1 2 3\n4 5 z\n"),
            "point 1 (line 2), field `z`: cannot parse `z` as f32"
        );
        assert_eq!(e(b"1 2\n"), "point 0 (line 1): 2 columns, need at least x y z");
        assert_eq!(
            e(b"# sqscan-columns: x y z i:u8\n1 2 3 300\n"),
            "point 0 (line 2), field `i`: cannot parse `300` as u8"
        );
        assert_eq!(
            e(b"# sqscan-columns: x y z i:u9\n"),
            "header line 1: sqscan-columns: entry `i:u9` is not name:kind[*count]"
        );
        assert_eq!(
            e(b"# sqscan-columns: x y z a:u8*18446744073709551615 b:u8\n1 2 3 4\n"),
            "point 0 (line 2): 4 columns, but the sqscan-columns: line 1 declares too many"
        );
        assert_eq!(
            e(b"# sqscan-columns: x y z x:f32\n1 2 3 4\n"),
            "header line 1: sqscan-columns: column `x` appears twice"
        );
    }
}
