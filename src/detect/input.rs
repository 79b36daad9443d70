//! The points the detector takes from a cloud: every k-th of a sensor's rows where they are much
//! denser than any model can use, without non-finite points, points out of range and wild
//! returns, in double precision.

use super::Params;
use nalgebra::Point3;

/// The spacing (m) along a sensor's rows below which points are thinned: finer than any model's
/// subsamples (at least 2 mm for the search, a twelfth of the smallest part for the refinement)
/// and than the depth noise of a triangulating sensor at a metre.
const THIN_SPACING: f64 = 0.002;

/// How far beyond the box of the middle 98 % of the points (per axis), in multiples of that
/// box's size, a point is taken for a wild return and dropped.
const WILD_REACH: f64 = 2.0;

fn to_f64(p: &[f32; 3]) -> Point3<f64> {
    Point3::new(p[0] as f64, p[1] as f64, p[2] as f64)
}

/// Every `stride`-th point of the cloud that is finite and within `params.max_range` of the
/// viewpoint (the origin without one), in double precision; wild returns are still in.
pub(super) fn kept<'a>(
    cloud: &'a [[f32; 3]],
    stride: usize,
    params: &Params,
) -> impl Iterator<Item = Point3<f64>> + 'a {
    let origin = params.viewpoint.unwrap_or(Point3::origin());
    let max_range = params.max_range;
    cloud
        .iter()
        .step_by(stride)
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .map(to_f64)
        .filter(move |p| max_range.is_none_or(|r| (p - origin).norm() <= r))
}

/// The points the detector works on: [`kept`] without wild returns. `finite` is how many of the
/// cloud's points are finite.
pub(super) fn points(cloud: &[[f32; 3]], stride: usize, finite: usize, params: &Params) -> Vec<Point3<f64>> {
    let points = if finite == cloud.len() && params.max_range.is_none() {
        // Every point kept: a plain conversion, without the tests that keep the loop from being
        // vectorized.
        let mut points = Vec::with_capacity(cloud.len().div_ceil(stride));
        points.extend(cloud.iter().step_by(stride).map(to_f64));
        points
    } else {
        kept(cloud, stride, params).collect()
    };
    without_wild_points(points)
}

/// Every how many points of the cloud the detector keeps: 1, unless the cloud's rows are much
/// denser than [`THIN_SPACING`]. A profile sensor with 4096 columns, or a depth camera close to
/// its target, gives points a fraction of a millimetre apart along a row, many times what any
/// model's fit can use, and every stage would pay for them. The rows are seen in the file's own
/// order: the median distance between consecutive finite points, over up to 2,000 pairs spread
/// over the cloud, across the line of sight from `origin` (along it, a triangulating sensor's
/// depth noise would hide how close the rows are). In an organized cloud consecutive points are
/// neighbours along a row, and keeping every k-th thins the rows evenly; in an unorganized cloud
/// consecutive points are far apart and nothing is thinned.
pub(super) fn thinning_stride(cloud: &[[f32; 3]], origin: Point3<f64>) -> usize {
    const PAIRS: usize = 2_000;
    if cloud.len() < 4 * PAIRS {
        return 1;
    }
    let step = (cloud.len() - 1) / PAIRS;
    let mut gaps: Vec<f64> = (0..PAIRS)
        .map(|i| (&cloud[i * step], &cloud[i * step + 1]))
        .filter(|(a, b)| a.iter().chain(b.iter()).all(|v| v.is_finite()))
        .filter_map(|(a, b)| {
            let (a, b) = (to_f64(a), to_f64(b));
            let sight = (a - origin).try_normalize(1e-9)?;
            Some((b - a).cross(&sight).norm())
        })
        .collect();
    if gaps.len() < PAIRS / 4 {
        return 1;
    }
    let n = gaps.len();
    let median = *gaps.select_nth_unstable_by(n / 2, f64::total_cmp).1;
    tracing::debug!("median gap between consecutive points {median:.5} m over {n} pairs");
    if median <= 0.0 {
        // Repeated points: nothing says how dense the rows are.
        return 1;
    }
    ((THIN_SPACING / median).floor() as usize).clamp(1, 64)
}

/// The points without wild returns (a reflection, a window, a corrupt value 30 m or 3e38 m
/// away): a few such points are nothing a detector can use, and stretch every grid and bounding
/// box over empty space. The box is the 1st to 99th percentile of each coordinate, widened by
/// twice its size (at least 1 cm) on each side; the room behind a table stays.
fn without_wild_points(points: Vec<Point3<f64>>) -> Vec<Point3<f64>> {
    if points.len() < 100 {
        return points;
    }
    // The percentiles of an even share of 2 000 points: a bound widened by twice the box does
    // not need them closer than that.
    let stride = points.len().div_ceil(2_000).max(1);
    let bounds: [(f64, f64); 3] = std::array::from_fn(|k| {
        let mut v: Vec<f64> = points.iter().step_by(stride).map(|p| p[k]).collect();
        let n = v.len();
        let lo = *v.select_nth_unstable_by(n / 100, f64::total_cmp).1;
        let hi = *v.select_nth_unstable_by(n - 1 - n / 100, f64::total_cmp).1;
        let reach = WILD_REACH * (hi - lo).max(0.01);
        (lo - reach, hi + reach)
    });
    // 1 for a point outside the box, 0 inside, without branches: the count over every point,
    // which nearly always finds none, vectorizes. The points are finite: outside is below the
    // low bound or above the high one.
    let outside = |p: &Point3<f64>| {
        let out = |k: usize| usize::from(p[k] < bounds[k].0) | usize::from(p[k] > bounds[k].1);
        out(0) | out(1) | out(2)
    };
    if points.iter().map(outside).sum::<usize>() == 0 {
        return points;
    }
    points.into_iter().filter(|p| outside(p) == 0).collect()
}

/// Rows of a plane 1 m away, `gap` apart along the row, with depth noise along the line of
/// sight, in the sensor's order.
#[cfg(test)]
pub(super) fn rows(gap: f64, columns: usize, rows: usize, noise: f64) -> Vec<[f32; 3]> {
    use nalgebra::Vector3;
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let mut out = Vec::new();
    for r in 0..rows {
        for c in 0..columns {
            let x = (c as f64 - columns as f64 / 2.0) * gap;
            let y = r as f64 * 0.003;
            let p = Vector3::new(x, y, 1.0);
            let p = p * (1.0 + rng.random_range(-noise..noise) / p.norm());
            out.push([p.x as f32, p.y as f32, p.z as f32]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows 0.2 mm apart are thinned to about THIN_SPACING, however noisy their depth; rows at a
    /// depth camera's 1.5 mm are not; the same points in no order are not either.
    #[test]
    fn dense_rows_are_thinned_along_the_row() {
        let dense = rows(0.0002, 4096, 10, 0.002);
        assert_eq!(thinning_stride(&dense, Point3::origin()), 10);
        let sparse = rows(0.0015, 640, 20, 0.002);
        assert_eq!(thinning_stride(&sparse, Point3::origin()), 1);
        let mut shuffled = dense.clone();
        use rand::{SeedableRng, seq::SliceRandom};
        shuffled.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(2));
        assert_eq!(thinning_stride(&shuffled, Point3::origin()), 1);
        // Mostly holes (no return): nothing to judge by.
        let holes: Vec<[f32; 3]> = dense
            .iter()
            .enumerate()
            .map(|(i, p)| if i % 8 == 0 { *p } else { [f32::NAN; 3] })
            .collect();
        assert_eq!(thinning_stride(&holes, Point3::origin()), 1);
    }
}
