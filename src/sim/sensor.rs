//! The triangulation sensor's measurement model: which direction each column sees, how depth
//! maps to the sub-pixel row where the laser line appears, and back.
//!
//! The camera sits `baseline` above the laser plane and looks parallel to it. A point of the
//! laser plane at depth `X` (along the sensor x axis) and lateral offset `Y` images at column
//! `u = cx - f Y / X` and at disparity `f b / X` rows below the horizon. So column `u` sees the
//! fan direction `tan(psi) = (cx - u) / f`, and the row gives depth: `X = f b / disparity`. This
//! is the plane-to-image homography that real calibrations fit (see `../shared/PROTOCOLS.md`).
//! Rows are counted from the region of interest's far edge so that row 1.0 is `range_max`, and
//! they are reported with `fraction_bits` of sub-pixel resolution, 0 meaning "no return", as
//! IVP/SICK Ranger units deliver them.

use nalgebra::{Matrix3, Vector3};

/// The measurement model of a laser triangulation profile sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorModel {
    pub columns: usize,
    /// Focal length in pixels.
    pub focal_px: f64,
    /// Principal point column.
    pub cx: f64,
    /// Camera offset from the laser plane (m).
    pub baseline: f64,
    /// Depth limits of the region of interest (m, along the sensor x axis).
    pub range_min: f64,
    pub range_max: f64,
    /// Range noise (1 sigma) at 1 m depth; it grows with depth squared, as triangulation does.
    pub noise_sigma_at_1m: f64,
    /// Probability that a return is lost for no geometric reason.
    pub dropout: f64,
    /// Returns whose laser incidence or camera view is more oblique than this are lost (rad).
    pub max_incidence: f64,
    /// Sub-pixel bits of the reported row.
    pub fraction_bits: u8,
    /// Disparity (px) at row 0.
    pub row_offset: f64,
    /// Rows in the region of interest.
    pub rows: usize,
}

impl SensorModel {
    /// The plane-to-image homography `H` of this model (see `crate::calibration`): `[x, y, w] =
    /// H [col + 0.5, row px, 1]`, the laser-plane point is `(x/w, y/w)`.
    pub fn homography(&self) -> Matrix3<f64> {
        let b = self.baseline;
        Matrix3::new(
            0.0,
            0.0,
            self.focal_px * b,
            -b,
            0.0,
            b * self.cx,
            0.0,
            1.0,
            self.row_offset,
        )
    }

    /// A validated model; on error, the offending field and what is wrong.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        columns: usize,
        fov: f64,
        baseline: f64,
        range_min: f64,
        range_max: f64,
        noise_sigma_at_1m: f64,
        dropout: f64,
        max_incidence: f64,
        fraction_bits: u8,
    ) -> Result<Self, (&'static str, String)> {
        if !(1..=8192).contains(&columns) {
            return Err(("columns", format!("{columns}: give 1 to 8192")));
        }
        if !(fov > 0.0 && fov < 170f64.to_radians()) {
            return Err((
                "fov_deg",
                format!("{} deg: give a field of view in (0, 170)", fov.to_degrees()),
            ));
        }
        if !(baseline.is_finite() && baseline > 0.0 && baseline < 2.0) {
            return Err(("baseline", format!("{baseline} m: give a camera offset in (0, 2) m")));
        }
        if !(range_min > 0.0 && range_max > range_min && range_max.is_finite()) {
            return Err((
                "range_min",
                format!("[{range_min}, {range_max}] m is not a depth range"),
            ));
        }
        if !(noise_sigma_at_1m.is_finite() && (0.0..0.1).contains(&noise_sigma_at_1m)) {
            return Err(("noise_sigma_at_1m", format!("{noise_sigma_at_1m} m: give 0 to 0.1")));
        }
        if !(0.0..=1.0).contains(&dropout) {
            return Err(("dropout", format!("{dropout}: a probability in [0, 1]")));
        }
        if !(max_incidence > 0.0 && max_incidence <= std::f64::consts::FRAC_PI_2) {
            return Err((
                "max_incidence_deg",
                format!("{} deg: give (0, 90]", max_incidence.to_degrees()),
            ));
        }
        if fraction_bits > 8 {
            return Err(("fraction_bits", format!("{fraction_bits}: give 0 to 8")));
        }
        let focal_px = 0.5 * columns as f64 / (0.5 * fov).tan();
        let fb = focal_px * baseline;
        let row_offset = fb / range_max - 1.0;
        let rows = (fb / range_min - row_offset).ceil() as usize + 1;
        if ((rows as f64) * f64::from(1u32 << fraction_bits)) >= 65535.0 {
            return Err((
                "range_min",
                format!("{rows} sensor rows at {fraction_bits} fraction bits overflow 16-bit row values"),
            ));
        }
        Ok(SensorModel {
            columns,
            focal_px,
            cx: 0.5 * columns as f64,
            baseline,
            range_min,
            range_max,
            noise_sigma_at_1m,
            dropout,
            max_incidence,
            fraction_bits,
            row_offset,
            rows,
        })
    }

    /// `tan(psi)` of the fan direction column `col` sees (psi from x towards +y).
    #[inline]
    pub fn column_tan(&self, col: usize) -> f64 {
        (self.cx - (col as f64 + 0.5)) / self.focal_px
    }

    /// The unit direction, in the sensor frame, of the laser ray that column `col` sees.
    pub fn column_direction(&self, col: usize) -> Vector3<f64> {
        Vector3::new(1.0, self.column_tan(col), 0.0).normalize()
    }

    /// Sub-pixel row at which a point at depth `x` appears.
    #[inline]
    pub fn row_of_depth(&self, x: f64) -> f64 {
        self.focal_px * self.baseline / x - self.row_offset
    }

    /// Depth of a point seen at sub-pixel row `row`.
    #[inline]
    pub fn depth_of_row(&self, row: f64) -> f64 {
        self.focal_px * self.baseline / (row + self.row_offset)
    }

    /// Row noise (px, 1 sigma) that gives `noise_sigma_at_1m` of depth noise at 1 m: depth noise
    /// is `x^2 / (f b)` times row noise.
    pub fn row_sigma_px(&self) -> f64 {
        self.noise_sigma_at_1m * self.focal_px * self.baseline
    }

    /// The fixed-point row value the sensor reports (0 = no return).
    pub fn encode_row(&self, row: f64) -> u16 {
        let v = (row * f64::from(1u32 << self.fraction_bits)).round();
        if v >= 1.0 && v <= f64::from(u16::MAX) {
            v as u16
        } else {
            0
        }
    }

    /// The sub-pixel row of a reported value, `None` for 0 (no return).
    pub fn decode_row(&self, value: u16) -> Option<f64> {
        (value != 0).then(|| f64::from(value) / f64::from(1u32 << self.fraction_bits))
    }

    /// The point in the sensor frame that column `col` at sub-pixel row `row` measures.
    pub fn point_in_sensor(&self, col: usize, row: f64) -> Vector3<f64> {
        let x = self.depth_of_row(row);
        Vector3::new(x, x * self.column_tan(col), 0.0)
    }
}
