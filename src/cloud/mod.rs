//! Point clouds: an organized or unorganized set of points with optional named per-point fields,
//! and their file formats.
//!
//! Coordinates are stored as `f32` because every sensor and every file format here delivers them
//! that way; keeping them in `f32` makes every read-write round trip bit-exact. Algorithms convert
//! to `f64` where they compute.
//!
//! File IO (PLY, PCD, plain text) is described in the [`io`] module docs; its API is re-exported
//! here.

mod codec;
mod error;
pub mod grid;
pub mod io;
pub mod lzf;
#[cfg(feature = "mcap")]
mod mcap;
mod median;
mod pcd;
pub mod plane;
mod ply;
mod pointcloud2;
mod text;

pub use codec::{PcdData, PlyFormat};
pub use error::CloudError;
pub use io::{read_cloud, write_cloud};
pub use pcd::{read_pcd, write_pcd};
pub use ply::{read_ply, write_ply};
pub use pointcloud2::{point_cloud2, point_cloud2_data, read_point_cloud2};
pub use text::{read_text, write_text};

/// The most points a cloud file may hold unless `SQSCAN_MAX_POINTS` says otherwise: 4 Mi, more
/// than any scanner's single frame we read (a Kinect's 307,200, a Ranger3 sweep of 2,560 columns
/// by 1,000 profiles) and the count at which the detector's working set reaches about 200 MB.
/// A compressed file's declared count is checked against it before anything is expanded.
pub const DEFAULT_MAX_POINTS: usize = 4 << 20;

/// The points cap of [`DEFAULT_MAX_POINTS`], or `SQSCAN_MAX_POINTS` when that is a count of at
/// least one (for a user whose scanner gives larger frames; an unreadable value is ignored).
pub fn max_points() -> usize {
    static CAP: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *CAP.get_or_init(|| {
        std::env::var("SQSCAN_MAX_POINTS")
            .ok()
            .and_then(|v| v.trim().parse::<usize>().ok())
            .filter(|&n| n > 0)
            .unwrap_or(DEFAULT_MAX_POINTS)
    })
}

/// The error for a file declaring (or holding) `count` points, more than [`max_points`].
pub(crate) fn check_point_count(count: usize) -> Result<(), String> {
    let cap = max_points();
    if count > cap {
        return Err(format!(
            "{count} points, more than the {cap} a cloud may have (SQSCAN_MAX_POINTS sets the cap)"
        ));
    }
    Ok(())
}

/// The scalar type of an extra per-point field, as PCD (`TYPE`/`SIZE`) and PLY name them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScalarKind {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl ScalarKind {
    /// All kinds, smallest first.
    pub const ALL: [ScalarKind; 8] = [
        ScalarKind::I8,
        ScalarKind::U8,
        ScalarKind::I16,
        ScalarKind::U16,
        ScalarKind::I32,
        ScalarKind::U32,
        ScalarKind::F32,
        ScalarKind::F64,
    ];

    /// Size of one value in bytes.
    pub fn size(self) -> usize {
        match self {
            ScalarKind::I8 | ScalarKind::U8 => 1,
            ScalarKind::I16 | ScalarKind::U16 => 2,
            ScalarKind::I32 | ScalarKind::U32 | ScalarKind::F32 => 4,
            ScalarKind::F64 => 8,
        }
    }

    /// Short lowercase name (`i8`, `u8`, ..., `f64`), as used in text headers and messages.
    pub fn name(self) -> &'static str {
        match self {
            ScalarKind::I8 => "i8",
            ScalarKind::U8 => "u8",
            ScalarKind::I16 => "i16",
            ScalarKind::U16 => "u16",
            ScalarKind::I32 => "i32",
            ScalarKind::U32 => "u32",
            ScalarKind::F32 => "f32",
            ScalarKind::F64 => "f64",
        }
    }

    /// Inverse of [`ScalarKind::name`].
    pub fn from_name(name: &str) -> Option<ScalarKind> {
        ScalarKind::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// Values of one extra field for every point, `count` values per point, point-major.
#[derive(Debug, Clone, PartialEq)]
pub enum FieldData {
    I8(Vec<i8>),
    U8(Vec<u8>),
    I16(Vec<i16>),
    U16(Vec<u16>),
    I32(Vec<i32>),
    U32(Vec<u32>),
    F32(Vec<f32>),
    F64(Vec<f64>),
}

/// Applies `$body` to the vector inside any [`FieldData`] variant, bound as `$v`.
macro_rules! with_field_data {
    ($data:expr, $v:ident => $body:expr) => {
        match $data {
            $crate::cloud::FieldData::I8($v) => $body,
            $crate::cloud::FieldData::U8($v) => $body,
            $crate::cloud::FieldData::I16($v) => $body,
            $crate::cloud::FieldData::U16($v) => $body,
            $crate::cloud::FieldData::I32($v) => $body,
            $crate::cloud::FieldData::U32($v) => $body,
            $crate::cloud::FieldData::F32($v) => $body,
            $crate::cloud::FieldData::F64($v) => $body,
        }
    };
}
pub(crate) use with_field_data;

impl FieldData {
    /// An empty vector of `kind` with room for `capacity` values.
    pub fn with_capacity(kind: ScalarKind, capacity: usize) -> FieldData {
        match kind {
            ScalarKind::I8 => FieldData::I8(Vec::with_capacity(capacity)),
            ScalarKind::U8 => FieldData::U8(Vec::with_capacity(capacity)),
            ScalarKind::I16 => FieldData::I16(Vec::with_capacity(capacity)),
            ScalarKind::U16 => FieldData::U16(Vec::with_capacity(capacity)),
            ScalarKind::I32 => FieldData::I32(Vec::with_capacity(capacity)),
            ScalarKind::U32 => FieldData::U32(Vec::with_capacity(capacity)),
            ScalarKind::F32 => FieldData::F32(Vec::with_capacity(capacity)),
            ScalarKind::F64 => FieldData::F64(Vec::with_capacity(capacity)),
        }
    }

    pub fn kind(&self) -> ScalarKind {
        match self {
            FieldData::I8(_) => ScalarKind::I8,
            FieldData::U8(_) => ScalarKind::U8,
            FieldData::I16(_) => ScalarKind::I16,
            FieldData::U16(_) => ScalarKind::U16,
            FieldData::I32(_) => ScalarKind::I32,
            FieldData::U32(_) => ScalarKind::U32,
            FieldData::F32(_) => ScalarKind::F32,
            FieldData::F64(_) => ScalarKind::F64,
        }
    }

    /// Number of values (points x count).
    pub fn len(&self) -> usize {
        with_field_data!(self, v => v.len())
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Value `i` as `f64` (exact for every kind); `None` when out of range.
    // The macro expands to every variant, the `f64` one included.
    #[allow(clippy::useless_conversion)]
    pub fn get_f64(&self, i: usize) -> Option<f64> {
        with_field_data!(self, v => v.get(i).map(|&x| f64::from(x)))
    }

    /// The values of the points `indices`, `count` values per point.
    ///
    /// # Panics
    /// If an index is out of range.
    pub fn select(&self, count: usize, indices: &[usize]) -> FieldData {
        fn pick<T: Copy>(v: &[T], count: usize, indices: &[usize]) -> Vec<T> {
            let mut out = Vec::with_capacity(indices.len() * count);
            for &i in indices {
                out.extend_from_slice(&v[i * count..(i + 1) * count]);
            }
            out
        }
        match self {
            FieldData::I8(v) => FieldData::I8(pick(v, count, indices)),
            FieldData::U8(v) => FieldData::U8(pick(v, count, indices)),
            FieldData::I16(v) => FieldData::I16(pick(v, count, indices)),
            FieldData::U16(v) => FieldData::U16(pick(v, count, indices)),
            FieldData::I32(v) => FieldData::I32(pick(v, count, indices)),
            FieldData::U32(v) => FieldData::U32(pick(v, count, indices)),
            FieldData::F32(v) => FieldData::F32(pick(v, count, indices)),
            FieldData::F64(v) => FieldData::F64(pick(v, count, indices)),
        }
    }
}

/// A named per-point field beyond x, y, z (for example `rgba`, `label`, `intensity`, `normal_x`).
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    pub name: String,
    /// Values per point (PCD `COUNT`); 1 for plain scalars.
    pub count: usize,
    pub data: FieldData,
}

impl Field {
    /// A field with one value per point.
    pub fn scalar(name: impl Into<String>, data: FieldData) -> Field {
        Field {
            name: name.into(),
            count: 1,
            data,
        }
    }
}

/// A point cloud. Organized clouds (`height > 1`) are row-major `width x height` images whose
/// missing returns are NaN points; unorganized clouds have `height == 1`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PointCloud {
    pub points: Vec<[f32; 3]>,
    pub width: usize,
    pub height: usize,
    pub fields: Vec<Field>,
    /// Where the sensor was, as PCD's `VIEWPOINT` gives it: `[tx, ty, tz, qw, qx, qy, qz]` in the
    /// cloud's frame. Camera-frame clouds have the sensor at the origin; the detector uses the
    /// position to tell the front of a surface from its back. `None` when the file said nothing.
    pub viewpoint: Option<[f64; 7]>,
}

fn is_finite_point(p: &[f32; 3]) -> bool {
    p.iter().all(|c| c.is_finite())
}

impl PointCloud {
    /// An unorganized cloud without extra fields.
    pub fn from_points(points: Vec<[f32; 3]>) -> PointCloud {
        PointCloud {
            width: points.len(),
            height: 1,
            points,
            fields: Vec::new(),
            viewpoint: None,
        }
    }

    /// An organized `width x height` cloud (row-major; NaN points mark missing returns).
    ///
    /// # Panics
    /// If `points.len() != width * height`.
    pub fn organized(width: usize, height: usize, points: Vec<[f32; 3]>) -> PointCloud {
        assert_eq!(
            Some(points.len()),
            width.checked_mul(height),
            "organized cloud: {} points for {width}x{height}",
            points.len()
        );
        PointCloud {
            points,
            width,
            height,
            fields: Vec::new(),
            viewpoint: None,
        }
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// True for image-like clouds (`height > 1`).
    pub fn is_organized(&self) -> bool {
        self.height > 1
    }

    /// Number of points whose three coordinates are finite.
    pub fn finite_count(&self) -> usize {
        self.points.iter().filter(|p| is_finite_point(p)).count()
    }

    /// The finite points, in f64 (what the detector and the learner work on).
    pub fn finite_points(&self) -> Vec<nalgebra::Point3<f64>> {
        self.points
            .iter()
            .filter(|p| is_finite_point(p))
            .map(|p| nalgebra::Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
            .collect()
    }

    /// Where the sensor was (the viewpoint's position), if the cloud says.
    pub fn viewpoint_position(&self) -> Option<nalgebra::Point3<f64>> {
        self.viewpoint.map(|v| nalgebra::Point3::new(v[0], v[1], v[2]))
    }

    /// Axis-aligned bounds `(min, max)` of the finite points; `None` when there are none.
    pub fn bbox(&self) -> Option<([f32; 3], [f32; 3])> {
        let mut finite = self.points.iter().filter(|p| is_finite_point(p));
        let first = *finite.next()?;
        Some(finite.fold((first, first), |(mut lo, mut hi), p| {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
            (lo, hi)
        }))
    }

    /// The extra field called `name`.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// The colour of every point, where it has one: a PCL packed `rgb` or `rgba` field
    /// (as `F 4` bits or `U 4`), or PLY's `red`, `green` and `blue`. None where every point has
    /// the same colour: a writer's placeholder (zeros from a sensor without colour), not a
    /// measurement.
    pub fn colours(&self) -> Option<Vec<[u8; 3]>> {
        let colours = self.colour_field()?;
        let first = *colours.first()?;
        colours.iter().any(|c| *c != first).then_some(colours)
    }

    fn colour_field(&self) -> Option<Vec<[u8; 3]>> {
        let n = self.points.len();
        let packed = ["rgba", "rgb"].iter().find_map(|name| self.field(name));
        if let Some(f) = packed {
            let unpack = |c: u32| [(c >> 16) as u8, (c >> 8) as u8, c as u8];
            let colours: Vec<[u8; 3]> = match &f.data {
                FieldData::F32(v) => v.iter().map(|x| unpack(x.to_bits())).collect(),
                FieldData::U32(v) => v.iter().map(|&x| unpack(x)).collect(),
                FieldData::I32(v) => v.iter().map(|&x| unpack(x as u32)).collect(),
                _ => return None,
            };
            return (colours.len() == n).then_some(colours);
        }
        let channel = |name: &str| match self.field(name).map(|f| &f.data) {
            Some(FieldData::U8(v)) if v.len() == n => Some(v),
            _ => None,
        };
        let (r, g, b) = (channel("red")?, channel("green")?, channel("blue")?);
        Some((0..n).map(|i| [r[i], g[i], b[i]]).collect())
    }

    /// A new unorganized cloud of the finite points, fields kept in step.
    pub fn retain_finite(&self) -> PointCloud {
        let keep: Vec<usize> = (0..self.points.len())
            .filter(|&i| is_finite_point(&self.points[i]))
            .collect();
        self.select(&keep)
    }

    /// A new unorganized cloud of the points `indices` (in that order), fields kept in step.
    ///
    /// # Panics
    /// If an index is out of range or a field's length does not match the points.
    pub fn select(&self, indices: &[usize]) -> PointCloud {
        PointCloud {
            points: indices.iter().map(|&i| self.points[i]).collect(),
            width: indices.len(),
            height: 1,
            fields: self
                .fields
                .iter()
                .map(|f| Field {
                    name: f.name.clone(),
                    count: f.count,
                    data: f.data.select(f.count, indices),
                })
                .collect(),
            viewpoint: self.viewpoint,
        }
    }

    /// Checks the invariants the writers rely on: `width * height` (or `width` for unorganized
    /// clouds) equals the number of points, every field has `count >= 1` and `count` values per
    /// point, and field names are unique, non-empty, free of whitespace and not `x`, `y`, `z`.
    pub fn validate(&self) -> Result<(), CloudError> {
        let n = self.points.len();
        let bad = |msg: String| Err(CloudError::InvalidCloud(msg));
        if self.height > 1 {
            if self.width.checked_mul(self.height) != Some(n) {
                return bad(format!(
                    "{} points but width x height = {} x {}",
                    n, self.width, self.height
                ));
            }
        } else if self.width != n && !(n == 0 && self.width == 0) {
            return bad(format!("{n} points but width = {} (unorganized)", self.width));
        }
        // Names seen so far: a set, so a header of 100 000 fields is checked in linear time.
        let mut names: std::collections::HashSet<&str> = std::collections::HashSet::with_capacity(self.fields.len());
        for (i, f) in self.fields.iter().enumerate() {
            if f.name.is_empty() || f.name.chars().any(|c| c.is_whitespace() || c.is_control()) {
                return bad(format!("field {i}: invalid name {:?}", f.name));
            }
            if matches!(f.name.as_str(), "x" | "y" | "z") {
                return bad(format!("field `{}`: coordinates are not fields", f.name));
            }
            if !names.insert(f.name.as_str()) {
                return bad(format!("field `{}` appears twice", f.name));
            }
            if f.count == 0 {
                return bad(format!("field `{}`: count is 0", f.name));
            }
            if n.checked_mul(f.count) != Some(f.data.len()) {
                return bad(format!(
                    "field `{}`: {} values for {} points x count {}",
                    f.name,
                    f.data.len(),
                    n,
                    f.count
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// PCL's packed colour (as float bits or as uint) and PLY's channels give the same colours;
    /// a field of another length or kind, or one colour for every point, gives none.
    #[test]
    fn colours_are_read_from_packed_and_separate_fields() {
        let mut cloud = PointCloud::from_points(vec![[0.0; 3]; 2]);
        let packed = [0x00ff_8000u32, 0x0001_0203];
        let field = |name: &str, data: FieldData| Field {
            name: name.into(),
            count: 1,
            data,
        };
        cloud.fields = vec![field(
            "rgb",
            FieldData::F32(packed.iter().map(|&b| f32::from_bits(b)).collect()),
        )];
        let want = vec![[255, 128, 0], [1, 2, 3]];
        assert_eq!(cloud.colours().as_ref(), Some(&want));
        cloud.fields = vec![field("rgba", FieldData::U32(packed.to_vec()))];
        assert_eq!(cloud.colours().as_ref(), Some(&want));
        cloud.fields = vec![
            field("red", FieldData::U8(vec![255, 1])),
            field("green", FieldData::U8(vec![128, 2])),
            field("blue", FieldData::U8(vec![0, 3])),
        ];
        assert_eq!(cloud.colours().as_ref(), Some(&want));
        cloud.fields.truncate(2);
        assert_eq!(cloud.colours(), None);
        cloud.fields = vec![field("rgb", FieldData::U32(vec![1]))];
        assert_eq!(cloud.colours(), None, "one value for two points");
        cloud.fields = vec![field("rgb", FieldData::U8(vec![1, 2]))];
        assert_eq!(cloud.colours(), None);
        cloud.fields = vec![field("rgb", FieldData::F32(vec![0.0, 0.0]))];
        assert_eq!(cloud.colours(), None, "all one colour: a placeholder");
    }

    #[test]
    fn helpers() {
        let nan = f32::NAN;
        let mut c = PointCloud::organized(
            2,
            2,
            vec![[0.0, 1.0, 2.0], [nan, nan, nan], [-1.0, 5.0, 0.5], [3.0, nan, 1.0]],
        );
        c.fields.push(Field {
            name: "n".into(),
            count: 2,
            data: FieldData::U16(vec![1, 2, 3, 4, 5, 6, 7, 8]),
        });
        assert!(c.is_organized());
        assert_eq!(c.len(), 4);
        assert_eq!(c.finite_count(), 2);
        assert_eq!(c.bbox(), Some(([-1.0, 1.0, 0.5], [0.0, 5.0, 2.0])));
        c.validate().unwrap();
        let f = c.retain_finite();
        assert!(!f.is_organized());
        assert_eq!((f.width, f.height), (2, 1));
        assert_eq!(f.points, vec![[0.0, 1.0, 2.0], [-1.0, 5.0, 0.5]]);
        assert_eq!(f.field("n").unwrap().data, FieldData::U16(vec![1, 2, 5, 6]));
        f.validate().unwrap();
        assert_eq!(PointCloud::from_points(vec![]).bbox(), None);
        c.fields[0].data = FieldData::U16(vec![1]);
        assert!(c.validate().is_err());
    }
}
