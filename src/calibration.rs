//! Calibration of the scanning rig: from a sensor column and its raw row value to a point in the
//! base frame.
//!
//! The chain, each link in its own frame:
//!
//! ```text
//!  (col, raw row)  --fraction bits-->  (u = col + 0.5, v = row px)      image
//!                  --homography H-->   (x, y) in the laser plane         laser plane frame
//!                  --laser_plane-->    point in the sensor frame         sensor frame
//!                  --sensor_mount-->   tilt link   --tilt about y-->  pan link --pan about z-->
//!                  --ptu-->            base frame
//! ```
//!
//! `H` is the general plane-to-image homography a real calibration fits (PROTOCOLS.md): in
//! homogeneous coordinates `[x, y, w] = H [u, v, 1]`, the point is `(x/w, y/w)`. For the
//! simulated sensor depth is `x = f b / (v + row_offset)` and lateral offset `y = x (cx - u) / f`,
//! which is `H = [[0, 0, f b], [-b, 0, b cx], [0, 1, row_offset]]` (the simulator builds its exact
//! calibration with [`Calibration::from_homography`]: `sim::Rig::calibration`).
//!
//! The joint angles given to [`Calibration::point_in_base`] are *joint* angles, as a
//! [`sqscan_drivers::PanTilt`] driver reports them; the calibration's axis signs and offsets are
//! what that driver must be configured with ([`Calibration::pan_axis`], [`Calibration::tilt_axis`]),
//! so they are applied once, in the driver.
//!
//! Files are read as a serde struct ([`CalibrationFile`]) and validated into [`Calibration`];
//! every inconsistency is a [`SpecError`] naming the file and the field.

use std::path::Path;

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use serde::{Deserialize, Serialize};
use sqscan_drivers::AxisConfig;

use crate::pose::PoseSpec;
use crate::spec::{SpecError, parse_toml, read_toml};

/// An axis mapping as written in the file: `joint = sign * device + offset_rad`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AxisFile {
    pub sign: f64,
    #[serde(default)]
    pub offset_rad: f64,
}

/// The calibration file as written (see `calibration/README.md`).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationFile {
    #[serde(default)]
    pub description: String,
    /// Sensor columns a profile.
    pub columns: usize,
    /// Sub-pixel bits of a raw row value: row px = raw / 2^fraction_bits.
    pub fraction_bits: u8,
    /// Rows of the 3x3 homography from `(col + 0.5, row px, 1)` to the laser plane `(x, y, w)`.
    pub homography: [[f64; 3]; 3],
    /// The laser plane's frame in the sensor frame (the plane is its x-y plane).
    #[serde(default)]
    pub laser_plane: PoseSpec,
    /// The sensor frame in the tilt link's frame.
    pub sensor_mount: PoseSpec,
    /// The PTU frame (pan and tilt axes' intersection) in the base frame.
    pub ptu: PoseSpec,
    pub pan: AxisFile,
    pub tilt: AxisFile,
    /// Optional measured table that replaces the homography (e.g. for a lens it does not fit).
    pub lookup: Option<LookupFile>,
}

/// A per-column lookup table: for each column, the laser-plane point at each sample row;
/// rows between samples are interpolated linearly, rows outside them map to no point.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LookupFile {
    /// Sample rows (px), strictly increasing, at least two.
    pub rows_px: Vec<f64>,
    /// `x[col][k]`: laser-plane x (m) of column `col` at `rows_px[k]`.
    pub x: Vec<Vec<f64>>,
    /// `y[col][k]`: laser-plane y (m) likewise.
    pub y: Vec<Vec<f64>>,
}

/// A validated lookup table (see [`LookupFile`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Lookup {
    rows_px: Vec<f64>,
    x: Vec<Vec<f64>>,
    y: Vec<Vec<f64>>,
}

impl Lookup {
    fn validate(raw: LookupFile, columns: usize, path: &Path) -> Result<Lookup, SpecError> {
        let invalid = |field: &str, msg: String| SpecError::invalid(path, format!("lookup.{field}"), msg);
        let r = &raw.rows_px;
        if r.len() < 2 || r.iter().any(|v| !v.is_finite()) || r.windows(2).any(|w| w[1] <= w[0]) {
            return Err(invalid(
                "rows_px",
                "give at least two finite rows, strictly increasing".into(),
            ));
        }
        for (name, table) in [("x", &raw.x), ("y", &raw.y)] {
            if table.len() != columns {
                return Err(invalid(
                    name,
                    format!("{} columns, the sensor has {columns}", table.len()),
                ));
            }
            if let Some(col) = table
                .iter()
                .position(|c| c.len() != r.len() || c.iter().any(|v| !v.is_finite()))
            {
                return Err(invalid(
                    name,
                    format!("column {col}: give {} finite values, one a sample row", r.len()),
                ));
            }
        }
        Ok(Lookup {
            rows_px: raw.rows_px,
            x: raw.x,
            y: raw.y,
        })
    }

    /// The interpolated laser-plane point; `None` outside the sampled rows.
    fn point(&self, col: usize, row_px: f64) -> Option<(f64, f64)> {
        let (first, last) = (*self.rows_px.first()?, *self.rows_px.last()?);
        if !(first..=last).contains(&row_px) {
            return None;
        }
        // The last sample row not above `row_px`, and the next one.
        let k = self
            .rows_px
            .partition_point(|&r| r <= row_px)
            .saturating_sub(1)
            .min(self.rows_px.len() - 2);
        let (r0, r1) = (self.rows_px[k], self.rows_px[k + 1]);
        let f = (row_px - r0) / (r1 - r0);
        let lerp = |t: &[Vec<f64>]| -> Option<f64> {
            let c = t.get(col)?;
            Some(c[k] + f * (c[k + 1] - c[k]))
        };
        Some((lerp(&self.x)?, lerp(&self.y)?))
    }
}

/// A validated calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    pub columns: usize,
    pub fraction_bits: u8,
    pub homography: Matrix3<f64>,
    pub laser_plane_in_sensor: Isometry3<f64>,
    pub sensor_in_tilt: Isometry3<f64>,
    pub ptu_in_base: Isometry3<f64>,
    pan: AxisConfig,
    tilt: AxisConfig,
    /// When given, used instead of the homography.
    pub lookup: Option<Lookup>,
}

/// `|det H|` relative to the cube of its largest entry below this is a singular homography.
const SINGULAR: f64 = 1e-12;

/// The pan link in the PTU frame: turned by the pan angle (rad) about the PTU's z axis.
pub fn pan_link(pan_rad: f64) -> Isometry3<f64> {
    Isometry3::rotation(Vector3::z() * pan_rad)
}

/// The tilt link in the pan link: turned by the tilt angle (rad) about its y axis.
pub fn tilt_link(tilt_rad: f64) -> Isometry3<f64> {
    Isometry3::rotation(Vector3::y() * tilt_rad)
}

impl Calibration {
    /// Reads and validates a calibration file.
    pub fn from_file(path: &Path) -> Result<Calibration, SpecError> {
        let raw: CalibrationFile = read_toml(path)?;
        Self::validate(raw, path)
    }

    /// Parses and validates calibration text that came from `path` (used for messages only).
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Calibration, SpecError> {
        let raw: CalibrationFile = parse_toml(text, path)?;
        Self::validate(raw, path)
    }

    /// Checks a file's values for consistency.
    pub fn validate(raw: CalibrationFile, path: &Path) -> Result<Calibration, SpecError> {
        let invalid = |field: &str, msg: String| SpecError::invalid(path, field, msg);
        if !(1..=8192).contains(&raw.columns) {
            return Err(invalid("columns", format!("{}: give 1 to 8192", raw.columns)));
        }
        if raw.fraction_bits > 15 {
            return Err(invalid("fraction_bits", format!("{}: give 0 to 15", raw.fraction_bits)));
        }
        let h = Matrix3::from_fn(|r, c| raw.homography[r][c]);
        if h.iter().any(|v| !v.is_finite()) {
            return Err(invalid("homography", "entries must be finite".into()));
        }
        let scale = h.amax();
        if scale <= 0.0 || (h.determinant() / scale.powi(3)).abs() < SINGULAR {
            return Err(invalid(
                "homography",
                format!("singular (determinant {:e})", h.determinant()),
            ));
        }
        let pose = |field: &str, spec: &PoseSpec| spec.to_isometry().map_err(|m| invalid(field, m));
        let axis = |field: &str, a: AxisFile| {
            AxisConfig::new(a.sign, a.offset_rad).map_err(|e| invalid(field, format!("{e} (sign is +1 or -1)")))
        };
        Ok(Calibration {
            columns: raw.columns,
            fraction_bits: raw.fraction_bits,
            homography: h,
            laser_plane_in_sensor: pose("laser_plane", &raw.laser_plane)?,
            sensor_in_tilt: pose("sensor_mount", &raw.sensor_mount)?,
            ptu_in_base: pose("ptu", &raw.ptu)?,
            pan: axis("pan", raw.pan)?,
            tilt: axis("tilt", raw.tilt)?,
            lookup: raw.lookup.map(|l| Lookup::validate(l, raw.columns, path)).transpose()?,
        })
    }

    /// A homography calibration with the laser plane as the sensor's x-y plane, joint angles
    /// as the driver reports them (no axis sign or offset) and no lookup table: what an exact
    /// model of a rig (the simulator's) gives.
    pub fn from_homography(
        columns: usize,
        fraction_bits: u8,
        homography: Matrix3<f64>,
        sensor_in_tilt: Isometry3<f64>,
        ptu_in_base: Isometry3<f64>,
    ) -> Calibration {
        Calibration {
            columns,
            fraction_bits,
            homography,
            laser_plane_in_sensor: Isometry3::identity(),
            sensor_in_tilt,
            ptu_in_base,
            pan: AxisConfig::default(),
            tilt: AxisConfig::default(),
            lookup: None,
        }
    }

    /// How the PTU driver maps the pan device angle to the joint angle.
    pub fn pan_axis(&self) -> AxisConfig {
        self.pan
    }

    /// How the PTU driver maps the tilt device angle to the joint angle.
    pub fn tilt_axis(&self) -> AxisConfig {
        self.tilt
    }

    /// The point in the laser plane frame `(x, y)` that column `col` at sub-pixel row `row_px`
    /// sees; `None` for a column beyond the sensor, a point on or behind the homography's
    /// horizon (`w <= 0`: no physical return maps there), or a row outside the lookup table.
    pub fn point_in_plane(&self, col: usize, row_px: f64) -> Option<(f64, f64)> {
        if col >= self.columns || !row_px.is_finite() {
            return None;
        }
        if let Some(lookup) = &self.lookup {
            return lookup.point(col, row_px);
        }
        let p = self.homography * Vector3::new(col as f64 + 0.5, row_px, 1.0);
        if p.z.is_nan() || p.z <= 0.0 {
            return None;
        }
        let (x, y) = (p.x / p.z, p.y / p.z);
        (x.is_finite() && y.is_finite()).then_some((x, y))
    }

    /// The sub-pixel row of a raw value, `None` for 0 (no return).
    pub fn row_px(&self, raw: u16) -> Option<f64> {
        (raw != 0).then(|| f64::from(raw) / f64::from(1u32 << self.fraction_bits))
    }

    /// The point, in the sensor frame, that column `col` measured with raw row value `raw`;
    /// `None` for no return (0) or a value that maps to no point.
    pub fn point_in_sensor(&self, col: usize, raw: u16) -> Option<Vector3<f64>> {
        let (x, y) = self.point_in_plane(col, self.row_px(raw)?)?;
        Some(
            self.laser_plane_in_sensor
                .transform_point(&Point3::new(x, y, 0.0))
                .coords,
        )
    }

    /// The sensor frame in the base frame at the given joint angles (rad).
    pub fn sensor_in_base(&self, pan_rad: f64, tilt_rad: f64) -> Isometry3<f64> {
        self.ptu_in_base * pan_link(pan_rad) * tilt_link(tilt_rad) * self.sensor_in_tilt
    }

    /// The point in the base frame that column `col` measured with raw value `raw` at the
    /// given joint angles.
    pub fn point_in_base(&self, col: usize, raw: u16, pan_rad: f64, tilt_rad: f64) -> Option<Point3<f64>> {
        let p = self.point_in_sensor(col, raw)?;
        Some(self.sensor_in_base(pan_rad, tilt_rad).transform_point(&Point3::from(p)))
    }

    /// The calibration as a file (the golden file's generator), through the same
    /// [`CalibrationFile`] it is read as: floats as the shortest text that reads back as the
    /// same number, so a lookup table round-trips exactly.
    pub fn to_toml(&self, description: &str) -> Result<String, toml::ser::Error> {
        let pose = |iso: &Isometry3<f64>| {
            let t = iso.translation.vector;
            let q = iso.rotation.quaternion();
            let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
            PoseSpec {
                position: [t.x, t.y, t.z],
                orientation: Some([sign * q.i, sign * q.j, sign * q.k, sign * q.w]),
                ..PoseSpec::default()
            }
        };
        let axis = |a: AxisConfig| AxisFile {
            sign: a.sign,
            offset_rad: a.offset_rad,
        };
        let h = &self.homography;
        let file = CalibrationFile {
            description: description.to_owned(),
            columns: self.columns,
            fraction_bits: self.fraction_bits,
            homography: [0, 1, 2].map(|r| [h[(r, 0)], h[(r, 1)], h[(r, 2)]]),
            laser_plane: pose(&self.laser_plane_in_sensor),
            sensor_mount: pose(&self.sensor_in_tilt),
            ptu: pose(&self.ptu_in_base),
            pan: axis(self.pan),
            tilt: axis(self.tilt),
            lookup: self.lookup.as_ref().map(|l| LookupFile {
                rows_px: l.rows_px.clone(),
                x: l.x.clone(),
                y: l.y.clone(),
            }),
        };
        Ok(format!(
            "# homography: [x, y, w] = H [col + 0.5, row_px, 1]; the point is (x/w, y/w) in the laser plane (m)\n{}",
            toml::to_string(&file)?
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn root() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
    }

    #[test]
    fn inconsistent_files_are_refused_naming_the_field() {
        let path = root().join("calibration/sim_rig.toml");
        let good: CalibrationFile = read_toml(&path).unwrap();
        let field = |edit: &dyn Fn(&mut CalibrationFile)| {
            let mut raw = good.clone();
            edit(&mut raw);
            match Calibration::validate(raw, &path) {
                Err(SpecError::Invalid { field, .. }) => field,
                other => panic!("not a validation error: {other:?}"),
            }
        };
        assert_eq!(field(&|r| r.columns = 0), "columns");
        assert_eq!(field(&|r| r.fraction_bits = 16), "fraction_bits");
        assert_eq!(
            field(&|r| r.homography = [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]]),
            "homography"
        );
        assert_eq!(field(&|r| r.homography[0][0] = f64::NAN), "homography");
        assert_eq!(field(&|r| r.ptu.orientation = Some([0.0, 0.0, 0.0, 2.0])), "ptu");
        assert_eq!(field(&|r| r.sensor_mount.position[0] = f64::INFINITY), "sensor_mount");
        assert_eq!(field(&|r| r.pan.sign = 2.0), "pan");
        let text = std::fs::read_to_string(&path)
            .unwrap()
            .replacen("fraction_bits", "fraction_bitz", 1);
        assert!(matches!(
            Calibration::from_toml_str(&text, &path),
            Err(SpecError::Syntax { .. })
        ));
    }

    #[test]
    fn a_lookup_table_sampled_from_the_homography_reproduces_it() {
        let path = root().join("calibration/sim_rig.toml");
        let mut raw: CalibrationFile = read_toml(&path).unwrap();
        let exact = Calibration::validate(raw.clone(), &path).unwrap();
        let rows_px: Vec<f64> = (0..=64).map(|k| 4.0 + 2.0 * f64::from(k)).collect();
        let sample = |i: usize| -> Vec<Vec<f64>> {
            (0..raw.columns)
                .map(|c| {
                    rows_px
                        .iter()
                        .map(|&r| {
                            let p = exact.point_in_plane(c, r).unwrap();
                            [p.0, p.1][i]
                        })
                        .collect()
                })
                .collect()
        };
        raw.lookup = Some(LookupFile {
            rows_px: rows_px.clone(),
            x: sample(0),
            y: sample(1),
        });
        let cal = Calibration::validate(raw.clone(), &path).unwrap();
        // On a sample row: the table's value; between: within the interpolation error (< 1 mm).
        assert_eq!(cal.point_in_plane(17, 20.0), exact.point_in_plane(17, 20.0));
        let (a, b) = (
            cal.point_in_plane(200, 31.3).unwrap(),
            exact.point_in_plane(200, 31.3).unwrap(),
        );
        assert!((a.0 - b.0).abs() < 1e-3 && (a.1 - b.1).abs() < 1e-3, "{a:?} vs {b:?}");
        assert_eq!(cal.point_in_plane(3, 2.0), None);
        assert_eq!(cal.point_in_plane(3, 200.0), None);
        assert!(cal.point_in_plane(3, 132.0).is_some());

        let field = |edit: &dyn Fn(&mut LookupFile)| {
            let mut bad = raw.clone();
            if let Some(l) = bad.lookup.as_mut() {
                edit(l);
            }
            match Calibration::validate(bad, &path) {
                Err(SpecError::Invalid { field, .. }) => field,
                other => panic!("not a validation error: {other:?}"),
            }
        };
        // Written back, the table reads back the same, whatever the description holds.
        let text = cal
            .to_toml("with a lookup table, \"quotes\", a tab\t, an escape \u{1b} and a backslash \\")
            .unwrap();
        assert!(text.contains("[lookup]"));
        assert_eq!(Calibration::from_toml_str(&text, &path).unwrap(), cal);

        assert_eq!(field(&|l| l.rows_px.swap(0, 1)), "lookup.rows_px");
        assert_eq!(
            field(&|l| {
                l.x.pop();
            }),
            "lookup.x"
        );
        assert_eq!(field(&|l| l.y[5][2] = f64::NAN), "lookup.y");
    }

    #[test]
    fn no_return_and_points_behind_the_horizon_give_none() {
        let cal = Calibration::from_file(&root().join("calibration/sim_rig.toml")).unwrap();
        assert_eq!(cal.point_in_sensor(10, 0), None);
        assert_eq!(cal.point_in_sensor(cal.columns, 100), None);
        let mut bad = cal.clone();
        bad.homography[(2, 2)] = -1e6;
        assert_eq!(bad.point_in_sensor(10, 100), None);
    }
}
