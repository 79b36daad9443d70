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
pub mod grid;
pub mod io;
pub mod lzf;
mod pcd;
pub mod plane;
mod ply;
mod text;

pub use codec::{CloudError, PcdData, PlyFormat};
pub use io::{read_cloud, write_cloud};
pub use pcd::{read_pcd, write_pcd};
pub use ply::{read_ply, write_ply};
pub use text::{read_text, write_text};

use crate::numeric::median;

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

    /// The per-pixel median of several sweeps of one view: organized clouds of the same size
    /// whose pixel `i` is the same sensor ray in each (a static scene, the pan-tilt unit driven
    /// through the same sweep). A triangulation sensor's noise runs along the ray, so the points
    /// of one pixel lie on a line and the coordinate-wise median is their median point; the
    /// noise of `n` sweeps drops by about `sqrt(n)`. A pixel with fewer than half the sweeps
    /// returning is left out (NaN): shadow and grazing edges that come and go are not surface
    /// to trust. The viewpoint and extra fields (labels) are those of the first sweep.
    pub fn median_of_sweeps(sweeps: &[PointCloud]) -> Result<PointCloud, String> {
        let Some(first) = sweeps.first() else {
            return Err("no sweeps given".into());
        };
        for (k, c) in sweeps.iter().enumerate() {
            if !c.is_organized() {
                return Err(format!(
                    "sweep {}: an unorganized cloud ({} points in one row); sweeps are combined pixel by pixel, so give organized clouds",
                    k + 1,
                    c.len()
                ));
            }
            if (c.width, c.height) != (first.width, first.height) {
                return Err(format!(
                    "sweep {} is {}x{}, sweep 1 is {}x{}: the sweeps of one view are clouds of the same size",
                    k + 1,
                    c.width,
                    c.height,
                    first.width,
                    first.height
                ));
            }
            if let (Some(a), Some(b)) = (first.viewpoint_position(), c.viewpoint_position()) {
                // 1 cm: the sensor did not move between the sweeps (beyond encoder jitter).
                if (a - b).norm() > 0.01 {
                    return Err(format!(
                        "sweep {}: viewpoint {:.3},{:.3},{:.3} is {:.3} m from sweep 1's: not the same view",
                        k + 1,
                        b.x,
                        b.y,
                        b.z,
                        (a - b).norm()
                    ));
                }
            }
        }
        // Pixel i must be the same ray in every sweep. A pan-tilt unit sweeping back and forth
        // stores every other sweep's rows in the opposite order (rows are in exposure order);
        // such a sweep is turned round. One whose rays still differ by more than a row and a
        // half (a sweep that started late, another tilt range) is refused.
        let v = first.viewpoint_position().unwrap_or_else(nalgebra::Point3::origin);
        let dir = |p: &[f32; 3]| -> Option<nalgebra::Vector3<f64>> {
            if !is_finite_point(p) {
                return None;
            }
            (nalgebra::Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])) - v.coords).try_normalize(1e-9)
        };
        let (w, h) = (first.width, first.height);
        let spacing = {
            let mut a: Vec<f64> = Vec::new();
            for r in 0..h.saturating_sub(1) {
                for c in (0..w.saturating_sub(1)).step_by(3) {
                    for (i, j) in [(r * w + c, (r + 1) * w + c), (r * w + c, r * w + c + 1)] {
                        if let (Some(d1), Some(d2)) = (dir(&first.points[i]), dir(&first.points[j])) {
                            a.push(d1.angle(&d2));
                        }
                    }
                }
            }
            median(&mut a).unwrap_or(f64::NAN)
        };
        let offset = |c: &PointCloud, flip: bool| -> Option<f64> {
            let mut a: Vec<f64> = Vec::new();
            for r in 0..h {
                let rc = if flip { h - 1 - r } else { r };
                for col in (0..w).step_by(3) {
                    if let (Some(d1), Some(d2)) = (dir(&first.points[r * w + col]), dir(&c.points[rc * w + col])) {
                        a.push(d1.angle(&d2));
                    }
                }
            }
            median(&mut a)
        };
        // Whether each sweep is read turned round (its rows from the last).
        let mut turned = vec![false; sweeps.len()];
        for (k, c) in sweeps.iter().enumerate().skip(1) {
            let (Some(straight), Some(round)) = (offset(c, false), offset(c, true)) else {
                // No pixel returned in both: nothing to tell the order by, nothing to mix up.
                continue;
            };
            let best = straight.min(round);
            if spacing.is_finite() && best > 1.5 * spacing {
                return Err(format!(
                    "sweep {}: its pixels are not sweep 1's rays (a median {:.2} mrad apart, the rows {:.2} mrad): another sweep range, or a sweep that started late",
                    k + 1,
                    best * 1e3,
                    spacing * 1e3
                ));
            }
            turned[k] = round < straight;
        }
        let pixel = |k: usize, i: usize| -> [f32; 3] {
            if turned[k] {
                sweeps[k].points[(h - 1 - i / w) * w + i % w]
            } else {
                sweeps[k].points[i]
            }
        };
        let need = sweeps.len().div_ceil(2);
        let mut column: Vec<[f32; 3]> = Vec::with_capacity(sweeps.len());
        let mut axis: Vec<f32> = Vec::with_capacity(sweeps.len());
        let points = (0..first.len())
            .map(|i| {
                column.clear();
                column.extend((0..sweeps.len()).map(|k| pixel(k, i)).filter(is_finite_point));
                if column.len() < need.max(1) {
                    return [f32::NAN; 3];
                }
                [0, 1, 2].map(|k| {
                    axis.clear();
                    axis.extend(column.iter().map(|p| p[k]));
                    axis.sort_by(f32::total_cmp);
                    let m = axis.len() / 2;
                    if axis.len() % 2 == 1 {
                        axis[m]
                    } else {
                        0.5 * (axis[m - 1] + axis[m])
                    }
                })
            })
            .collect();
        Ok(PointCloud {
            points,
            width: first.width,
            height: first.height,
            fields: first.fields.clone(),
            viewpoint: first.viewpoint,
        })
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
        for (i, f) in self.fields.iter().enumerate() {
            if f.name.is_empty() || f.name.chars().any(|c| c.is_whitespace() || c.is_control()) {
                return bad(format!("field {i}: invalid name {:?}", f.name));
            }
            if matches!(f.name.as_str(), "x" | "y" | "z") {
                return bad(format!("field `{}`: coordinates are not fields", f.name));
            }
            if self.fields[..i].iter().any(|g| g.name == f.name) {
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

    #[test]
    fn median_of_sweeps_is_the_per_pixel_median() {
        let nan = [f32::NAN; 3];
        let sweep = |p: [[f32; 3]; 4]| PointCloud::organized(2, 2, p.to_vec());
        let sweeps = [
            sweep([[1.0, 0.0, 0.0], nan, nan, [0.0, 0.0, 4.0]]),
            sweep([[3.0, 0.0, 0.0], [0.0, 2.0, 0.0], nan, [0.0, 0.0, 5.0]]),
            sweep([[2.0, 0.0, 0.0], nan, nan, [0.0, 0.0, 9.0]]),
        ];
        let m = PointCloud::median_of_sweeps(&sweeps).unwrap();
        assert_eq!((m.width, m.height), (2, 2));
        assert_eq!(m.points[0], [2.0, 0.0, 0.0]);
        // One return out of three is too few; none is none.
        assert!(m.points[1][0].is_nan() && m.points[2][0].is_nan());
        assert_eq!(m.points[3], [0.0, 0.0, 5.0]);
        // Two of four: the mean of the middle two.
        let two = [
            sweep([[1.0, 0.0, 0.0], nan, nan, nan]),
            sweep([[2.0, 0.0, 0.0], nan, nan, nan]),
            sweep([nan, nan, nan, nan]),
            sweep([nan, nan, nan, nan]),
        ];
        assert_eq!(PointCloud::median_of_sweeps(&two).unwrap().points[0], [1.5, 0.0, 0.0]);
    }

    /// A sweep of a plane z = 1 seen from the origin, rows 10 mrad apart, rows `shift` on.
    fn plane_sweep(shift: usize, dz: f32, reversed: bool) -> PointCloud {
        let (w, h) = (8, 6);
        let mut p = Vec::new();
        for r in 0..h {
            let r = if reversed { h - 1 - r } else { r };
            for c in 0..w {
                p.push([0.01 * c as f32, 0.01 * (r + shift) as f32, 1.0 + dz]);
            }
        }
        PointCloud::organized(w, h, p)
    }

    #[test]
    fn median_of_sweeps_turns_a_sweep_run_backwards_round_and_refuses_a_shifted_one() {
        let forth = plane_sweep(0, 0.0, false);
        let back = plane_sweep(0, 0.002, true);
        let m = PointCloud::median_of_sweeps(&[forth.clone(), back]).unwrap();
        for r in 0..6 {
            for c in 0..8 {
                let p = m.points[r * 8 + c];
                assert!(
                    (p[1] - 0.01 * r as f32).abs() < 1e-6 && (p[2] - 1.001).abs() < 1e-6,
                    "{r} {c}: {p:?}"
                );
            }
        }
        let late = plane_sweep(3, 0.0, false);
        let e = PointCloud::median_of_sweeps(&[forth, late]).unwrap_err();
        assert!(e.contains("sweep 2: its pixels are not sweep 1's rays"), "{e}");
    }

    #[test]
    fn median_of_sweeps_refuses_what_is_not_one_view() {
        let a = PointCloud::organized(2, 2, vec![[0.0; 3]; 4]);
        let b = PointCloud::organized(4, 2, vec![[0.0; 3]; 8]);
        let e = PointCloud::median_of_sweeps(&[a.clone(), b]).unwrap_err();
        assert!(e.contains("sweep 2 is 4x2, sweep 1 is 2x2"), "{e}");
        let flat = PointCloud::from_points(vec![[0.0; 3]; 4]);
        let e = PointCloud::median_of_sweeps(&[a.clone(), flat]).unwrap_err();
        assert!(e.contains("sweep 2: an unorganized cloud"), "{e}");
        let mut moved = a.clone();
        moved.viewpoint = Some([0.0, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0]);
        let mut here = a;
        here.viewpoint = Some([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]);
        let e = PointCloud::median_of_sweeps(&[here, moved]).unwrap_err();
        assert!(e.contains("not the same view"), "{e}");
        assert!(PointCloud::median_of_sweeps(&[]).is_err());
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
