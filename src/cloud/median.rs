//! The per-pixel median of several sweeps of one view.

use super::{PointCloud, is_finite_point};
use crate::numeric::median;

impl PointCloud {
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
        same_view(sweeps)?;
        let turned = turned_round(sweeps)?;
        let (w, h) = (first.width, first.height);
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
}

/// That the sweeps are organized clouds of one size taken from one place (1 cm).
fn same_view(sweeps: &[PointCloud]) -> Result<(), String> {
    let first = &sweeps[0];
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
    Ok(())
}

/// Whether each sweep is read turned round (its rows from the last) to have pixel `i` on the
/// same ray as sweep 1's; an error where its rays differ from sweep 1's whichever way it is read.
fn turned_round(sweeps: &[PointCloud]) -> Result<Vec<bool>, String> {
    let first = &sweeps[0];
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
    Ok(turned)
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
}
