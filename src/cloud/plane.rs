//! Dominant plane removal (paper III-A).
//!
//! 100 seed points spread evenly over the data each get a plane patch fitted to their
//! neighbourhood (normal: the eigenvector of the covariance's smallest eigenvalue). Every patch
//! plane is verified against the other seeds: a seed supports a plane when its normal distance is
//! below the median of all seed-to-plane distances of all hypotheses (the paper's median rule,
//! read as one global threshold: a per-hypothesis median would give every hypothesis half the
//! seeds). The best-supported plane is refined on all the points near it, and removed only when
//! it holds more points than the rest of the scene.

use super::grid::Grid;
use crate::numeric::lanes::widened;
use crate::numeric::median;
use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};

/// Seeds spread over the data, as in the paper.
const SEEDS: usize = 100;
/// Least share of the points the dominant plane must hold to be removed.
const MIN_PLANE_SHARE: f64 = 0.3;
/// Neighbours a seed's patch is fitted to.
const PATCH_POINTS: usize = 30;

/// A plane `n . p + d = 0` with unit normal `n`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    pub normal: Vector3<f64>,
    pub d: f64,
}

impl Plane {
    #[inline]
    pub fn signed_distance(&self, p: &Point3<f64>) -> f64 {
        self.normal.dot(&p.coords) + self.d
    }

    /// `[nx, ny, nz, d]`.
    pub fn coefficients(&self) -> [f64; 4] {
        [self.normal.x, self.normal.y, self.normal.z, self.d]
    }

    fn flipped(&self) -> Plane {
        Plane {
            normal: -self.normal,
            d: -self.d,
        }
    }
}

/// The result of plane removal.
#[derive(Debug, Clone)]
pub struct PlaneRemoval {
    /// The dominant plane, its normal pointing to the side where the rest of the scene (the
    /// objects on it) lies; `None` when no plane held more points than the rest.
    pub plane: Option<Plane>,
    /// Points on the plane within `band` (m) of it.
    pub inliers: usize,
    /// The half-width of the band removed (m) at the median range (it grows with the square of
    /// the range when a viewpoint is known): three robust standard deviations of the inliers'
    /// distances.
    pub band: f64,
    /// Indices of the points kept (off the plane, and above it when `keep_below` is false).
    pub kept: Vec<usize>,
    /// How the noise, and so `band`, scales with the range: `band` holds at its reference range.
    pub range_scale: RangeScale,
}

/// Plane through a point set: centroid and the smallest-eigenvalue eigenvector.
fn fit_plane(points: &[Point3<f64>], idx: impl Iterator<Item = usize> + Clone) -> Option<(Plane, f64)> {
    let mut n = 0usize;
    let mut c = Vector3::zeros();
    for i in idx.clone() {
        c += points[i].coords;
        n += 1;
    }
    if n < 3 {
        return None;
    }
    c /= n as f64;
    // The six distinct sums of the symmetric covariance, each the same products in the same
    // order as the full outer products would add.
    let mut s = [0.0f64; 6];
    for i in idx {
        let d = points[i].coords - c;
        s[0] += d.x * d.x;
        s[1] += d.x * d.y;
        s[2] += d.x * d.z;
        s[3] += d.y * d.y;
        s[4] += d.y * d.z;
        s[5] += d.z * d.z;
    }
    let mut cov = Matrix3::new(s[0], s[1], s[2], s[1], s[3], s[4], s[2], s[4], s[5]);
    cov /= n as f64;
    let eig = SymmetricEigen::new(cov);
    let k = eig.eigenvalues.imin();
    let normal = eig.eigenvectors.column(k).into_owned().try_normalize(1e-12)?;
    // The smallest eigenvalue is the mean squared distance to the plane.
    Some((
        Plane {
            normal,
            d: -normal.dot(&c),
        },
        eig.eigenvalues[k].max(0.0),
    ))
}

/// Find and remove the dominant plane. `keep_below`: keep points on the far side of the plane
/// (under a table) too; by default they are dropped, since nothing there stands on it.
pub fn remove_dominant_plane(points: &[Point3<f64>], keep_below: bool, viewpoint: Option<Point3<f64>>) -> PlaneRemoval {
    let found = sample_stride(points.len()).and_then(|stride| {
        let sample: Vec<Point3<f64>> = points.iter().step_by(stride).copied().collect();
        find_dominant_plane(&sample, viewpoint)
    });
    split_at_plane(points, found, keep_below)
}

/// A plane found on an even sample of the points ([`find_dominant_plane`]), before the points
/// are split at it ([`split_at_plane`]).
#[derive(Debug, Clone, Copy)]
pub struct FoundPlane {
    plane: Plane,
    band: f64,
    range_scale: RangeScale,
}

/// Every how many of `n` points the plane is found on: a table holds far more points than a
/// plane needs (a Kinect frame 300 000), and every step of the search passes over them several
/// times; only the split into plane and objects runs on every point. `None`: too few points to
/// look for a plane in.
pub fn sample_stride(n: usize) -> Option<usize> {
    (n >= SEEDS).then(|| n.div_ceil(FIT_POINTS).max(1))
}

/// The dominant plane of `sample`, every [`sample_stride`]-th of the points, and the band its
/// points lie in.
pub fn find_dominant_plane(sample: &[Point3<f64>], viewpoint: Option<Point3<f64>>) -> Option<FoundPlane> {
    let range_scale = RangeScale::new(sample, viewpoint);
    let (plane, band) = find_plane(sample, &range_scale)?;
    Some(FoundPlane {
        plane,
        band,
        range_scale,
    })
}

/// Split `points` at the plane found on their sample, or keep them all when none was found or it
/// holds too few of them. `keep_below` as for [`remove_dominant_plane`].
pub fn split_at_plane(points: &[Point3<f64>], found: Option<FoundPlane>, keep_below: bool) -> PlaneRemoval {
    // Nothing removed: every point kept.
    let no_plane = |inliers: usize, band: f64, range_scale: RangeScale| PlaneRemoval {
        plane: None,
        inliers,
        band,
        kept: (0..points.len()).collect(),
        range_scale,
    };
    let Some(FoundPlane {
        mut plane,
        band,
        range_scale,
    }) = found
    else {
        return no_plane(0, 0.0, RangeScale::uniform());
    };
    // Each point's distance once: the split below and the count here both need it.
    let dist = normalized_distances(points, &plane, &range_scale);
    let inliers = dist.iter().filter(|d| d.abs() < band).count();
    // The paper removes the plane only when it holds more points than the rest. A cluttered
    // table seen with the room behind it holds less than half (mOSD test64: 48 %), and leaving it
    // in makes every cylinder hypothesis lie in it; a plane with a third of the points is still
    // by far the largest structure in view.
    if (inliers as f64) < MIN_PLANE_SHARE * points.len() as f64 {
        return no_plane(inliers, band, range_scale);
    }
    // Orient the normal towards the objects: towards the sensor, which sees the plane's top
    // (a wall or floor behind the table must not decide it); without a viewpoint, towards the
    // side with more off-plane points.
    let flip = match range_scale.viewpoint {
        Some(v) => plane.signed_distance(&v) < 0.0,
        None => {
            let above = dist.iter().filter(|&&d| d >= band).count();
            let below = dist.iter().filter(|&&d| d <= -band).count();
            below > above
        }
    };
    let side = if flip {
        plane = plane.flipped();
        -1.0
    } else {
        1.0
    };
    let kept = (0..points.len())
        .filter(|&i| {
            let d = side * dist[i];
            d >= band || (keep_below && d <= -band)
        })
        .collect();
    PlaneRemoval {
        plane: Some(plane),
        inliers,
        band,
        kept,
        range_scale,
    }
}

/// Points the seeds are chosen from at most: a few dozen a cell.
const SEED_CANDIDATES: usize = 3_000;

/// Points each candidate plane is counted against.
const CONSENSUS_POINTS: usize = 10_000;

/// Points every candidate plane is first counted against.
const SCREEN_POINTS: usize = 2_000;

/// Candidates with the most points on the coarse count that are counted on the full set.
const LEADERS: usize = 8;

/// Points the plane and its band are refined on at most.
const REFINE_POINTS: usize = 10_000;

/// Points the plane is found on at most: as many as a candidate is counted on, the consensus
/// set (a table's plane is as well found from them as from thirty times more, a Kinect frame's,
/// and each step of the search passes over them).
const FIT_POINTS: usize = CONSENSUS_POINTS;

/// Triangulating sensors (laser profilers, structured light) get noisier with the square of
/// the range, so distances to the plane are measured in units of the noise at each point's
/// range: `scale = (r / r_ref)^2` (at least 0.05), `r_ref` the median range. Without a viewpoint
/// every scale is 1.
#[derive(Debug, Clone, Copy)]
pub struct RangeScale {
    viewpoint: Option<Point3<f64>>,
    r_ref: f64,
}

impl RangeScale {
    /// The median range of `points` from `viewpoint` as the reference.
    pub fn new(points: &[Point3<f64>], viewpoint: Option<Point3<f64>>) -> RangeScale {
        let r_ref = viewpoint.map_or(1.0, |v| {
            // The median of an even share of 2 000 points: a reference range, not a statistic
            // of the cloud that needs to be exact.
            let stride = points.len().div_ceil(2_000).max(1);
            let mut r: Vec<f64> = points.iter().step_by(stride).map(|p| (p - v).norm()).collect();
            median(&mut r).unwrap_or(0.0).max(1e-3)
        });
        RangeScale { viewpoint, r_ref }
    }

    /// Scale 1 at every range relative to `viewpoint` of `r_ref` (m).
    pub fn at_range(viewpoint: Point3<f64>, r_ref: f64) -> RangeScale {
        RangeScale {
            viewpoint: Some(viewpoint),
            r_ref: r_ref.max(1e-3),
        }
    }

    /// One scale everywhere.
    pub fn uniform() -> RangeScale {
        RangeScale {
            viewpoint: None,
            r_ref: 1.0,
        }
    }

    #[inline]
    pub fn at(&self, p: &Point3<f64>) -> f64 {
        match self.viewpoint {
            // (r / r_ref)^2 without the square root; a select rather than `f64::max`, whose NaN
            // handling costs more in the split's pass over every point.
            Some(v) => scale_from(&v, self.r_ref * self.r_ref, p),
            None => 1.0,
        }
    }
}

/// `RangeScale::at` for a viewpoint `v` and `rr = r_ref^2`: the one formula, also for the
/// split's loop, which takes the viewpoint's match out of its body.
#[inline(always)]
fn scale_from(v: &Point3<f64>, rr: f64, p: &Point3<f64>) -> f64 {
    let s = (p - v).norm_squared() / rr;
    if s > 0.05 { s } else { 0.05 }
}

/// The dominant plane of `points` and the half-width of its band at the reference range.
fn find_plane(points: &[Point3<f64>], range_scale: &RangeScale) -> Option<(Plane, f64)> {
    let (seeds, area) = seed_points(points)?;
    // Patch radius: enough for PATCH_POINTS neighbours at the cloud's mean density.
    let radius = (PATCH_POINTS as f64 * area / points.len() as f64 / std::f64::consts::PI).sqrt() * 1.5;
    let grid = Grid::new(points, radius);
    // Each seed's patch plane, with the patch's RMS distance to it (its noise).
    let hypotheses: Vec<(usize, Plane, f64)> = seeds
        .iter()
        .filter_map(|&s| {
            let near = grid.within(points, &points[s], radius);
            fit_plane(points, near.iter().copied()).map(|(p, ms)| (s, p, ms.sqrt()))
        })
        .collect();
    if hypotheses.is_empty() {
        return None;
    }
    let mut all_d: Vec<f64> = Vec::with_capacity(hypotheses.len() * seeds.len());
    for (_, h, _) in &hypotheses {
        all_d.extend(seeds.iter().map(|&s| h.signed_distance(&points[s]).abs()));
    }
    let threshold = median(&mut all_d).unwrap_or(0.0);
    // The paper's vote over the seeds ranks the hypotheses; on a cluttered table most seeds lie
    // on objects and the vote alone can crown a box top, so the hypotheses are compared by how
    // many of the points (an even share of them) lie within a centimetre of them.
    let mut voted: Vec<(usize, Plane, f64)> = hypotheses
        .iter()
        .map(|(s, h, rms)| {
            let support = seeds
                .iter()
                .filter(|&&t| t != *s && h.signed_distance(&points[t]).abs() < threshold)
                .count();
            (support, *h, *rms)
        })
        .collect();
    voted.sort_by_key(|v| std::cmp::Reverse(v.0));
    // Counting every hypothesis against thousands of points is most of the plane's cost, and
    // most hypotheses are near copies of a few planes: each is counted on a coarse share first,
    // and only the leaders on the full consensus set.
    let every = |n: usize| Columns::every(points, points.len() / n);
    let (screen, consensus) = (every(SCREEN_POINTS), every(CONSENSUS_POINTS));
    let count_within = |h: &Plane, on: &Columns| count_near(on, h, 0.01);
    let mut screened: Vec<(usize, Plane, f64)> = voted
        .iter()
        .map(|(_, h, rms)| (count_within(h, &screen), *h, *rms))
        .collect();
    // Stable: among equal counts the better-voted hypothesis stays first.
    screened.sort_by_key(|s| std::cmp::Reverse(s.0));
    let (best, patch_rms) = screened
        .iter()
        .take(LEADERS)
        .map(|(_, h, rms)| (count_within(h, &consensus), *h, *rms))
        .max_by_key(|(c, _, _)| *c)
        .map(|(_, h, rms)| (h, rms))
        .expect("hypotheses is not empty");
    // The band never grows past a few patch noises: on a cluttered table the objects' bottoms
    // next to the plane would otherwise keep widening it and tilt the fit.
    let cap = (6.0 * patch_rms).clamp(0.006, 0.02);
    // Refine on the points near the plane: least squares, with a band from their
    // robust spread, until both the band and the plane settle. A wide first band can hold a
    // second, parallel surface (the far end of a table a step lower); each round sheds part of
    // it. A start tilted by its patch's noise comes back only a part of the way each round (the
    // band cuts the far points off on one side), so a band that has settled does not say that the
    // plane has: stopping there left a table 0.15 degrees off, 3 mm at its far end.
    // The refinement runs on an even share of the points: a plane's four parameters and a
    // band's spread are settled long before ten thousand points.
    let refine_points: Vec<Point3<f64>> = points
        .iter()
        .step_by(points.len().div_ceil(REFINE_POINTS).max(1))
        .copied()
        .collect();
    // Start narrow: a least-squares fit over a wide band mixes in the bottoms of the objects
    // standing on the plane and tilts it (a cluttered table: a 1 degree tilt, a band of 8 cm).
    refine_plane(&refine_points, range_scale, best, threshold.clamp(0.003, cap), cap)
}

/// Seed points spread evenly over the cloud (indices into `points`): the point nearest the
/// centre of each cell of a grid over the two principal directions of the whole cloud; and the
/// area (m²) the grid spans.
fn seed_points(points: &[Point3<f64>]) -> Option<(Vec<usize>, f64)> {
    // The seeds' grid and the cloud's extent come from an even share of the points: a few
    // dozen a cell choose a seed near its centre as well as all of them do.
    let every = points.len().div_ceil(SEED_CANDIDATES).max(1);
    let (whole, _) = fit_plane(points, (0..points.len()).step_by(every))?;
    let (u, v) = orthonormal_basis(&whole.normal);
    let (us, vs): (Vec<f64>, Vec<f64>) = points
        .iter()
        .step_by(every)
        .map(|p| (u.dot(&p.coords), v.dot(&p.coords)))
        .unzip();
    let bounds = |c: &[f64]| {
        c.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &a| {
            (lo.min(a), hi.max(a))
        })
    };
    let ((umin, umax), (vmin, vmax)) = (bounds(&us), bounds(&vs));
    let side = (SEEDS as f64).sqrt().ceil() as usize;
    let (du, dv) = (
        (umax - umin).max(1e-9) / side as f64,
        (vmax - vmin).max(1e-9) / side as f64,
    );
    // The point nearest each cell's centre represents the cell.
    let mut nearest = vec![(f64::INFINITY, usize::MAX); side * side];
    for (k, (&a, &b)) in us.iter().zip(&vs).enumerate() {
        let (cu, cv) = (((a - umin) / du) as usize, ((b - vmin) / dv) as usize);
        let (cu, cv) = (cu.min(side - 1), cv.min(side - 1));
        let (ca, cb) = (umin + (cu as f64 + 0.5) * du, vmin + (cv as f64 + 0.5) * dv);
        let d = (a - ca).powi(2) + (b - cb).powi(2);
        let slot = &mut nearest[cv * side + cu];
        if d < slot.0 {
            *slot = (d, k * every);
        }
    }
    let seeds: Vec<usize> = nearest.into_iter().filter(|s| s.1 != usize::MAX).map(|s| s.1).collect();
    Some((seeds, ((umax - umin) * (vmax - vmin)).max(1e-9)))
}

/// Least squares on the points within `band` of the plane (distances in units of the noise at
/// each point's range), the band from their robust spread (at most `cap`), round after round
/// from `start` until both settle. Returns the plane and its band.
fn refine_plane(
    points: &[Point3<f64>],
    range_scale: &RangeScale,
    start: Plane,
    band: f64,
    cap: f64,
) -> Option<(Plane, f64)> {
    let scale: Vec<f64> = points.iter().map(|p| range_scale.at(p)).collect();
    let norm_dist = |plane: &Plane, i: usize| plane.signed_distance(&points[i]) / scale[i];
    let mut plane = start;
    let mut band = band;
    // Each point's distance to the current plane, once a round: the band's points for the next
    // fit and the spread that sets its band both come from it.
    let distances = |plane: &Plane| -> Vec<f64> { (0..points.len()).map(|i| norm_dist(plane, i).abs()).collect() };
    let mut dist_all = distances(&plane);
    let mut near: Vec<usize> = Vec::with_capacity(points.len());
    for _ in 0..12 {
        let previous = band;
        near.clear();
        near.extend((0..points.len()).filter(|&i| dist_all[i] < band));
        let (p, _) = fit_plane(points, near.iter().copied())?;
        let p = if p.normal.dot(&plane.normal) < 0.0 {
            p.flipped()
        } else {
            p
        };
        let moved = plane_motion(&plane, &p, points, &near);
        plane = p;
        dist_all = distances(&plane);
        let mut dist: Vec<f64> = dist_all.iter().copied().filter(|&d| d < band).collect();
        // 1.4826 MAD estimates sigma; three sigma hold 99.7 % of the plane's noise.
        band = (3.0 * 1.4826 * median(&mut dist).unwrap_or(0.0)).clamp(0.002, cap);
        if (band - previous).abs() < 0.05 * previous && moved < 0.05 * previous {
            break;
        }
    }
    Some((plane, band))
}

/// How far (m) plane `b` lies from plane `a` where the points `near` (indices into `points`)
/// are: the largest change of the distance to the plane at the corners of their box (of an even
/// share of them).
fn plane_motion(a: &Plane, b: &Plane, points: &[Point3<f64>], near: &[usize]) -> f64 {
    let (mut lo, mut hi) = (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY));
    for &i in near.iter().step_by(16) {
        lo = lo.inf(&points[i].coords);
        hi = hi.sup(&points[i].coords);
    }
    (0..8)
        .map(|k| {
            let c = Point3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            (a.signed_distance(&c) - b.signed_distance(&c)).abs()
        })
        .fold(0.0, f64::max)
}

/// Points as three columns of coordinates: a pass over them that only adds and compares is
/// vectorized by the compiler.
struct Columns {
    x: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
}

impl Columns {
    /// Every `stride`-th point.
    fn every(points: &[Point3<f64>], stride: usize) -> Columns {
        let pick = || points.iter().step_by(stride.max(1));
        Columns {
            x: pick().map(|p| p.x).collect(),
            y: pick().map(|p| p.y).collect(),
            z: pick().map(|p| p.z).collect(),
        }
    }
}

widened! {
/// Each point's signed distance to the plane in units of the noise at its range
/// (`RangeScale::at`).
fn normalized_distances(points: &[Point3<f64>], plane: &Plane, scale: &RangeScale) -> Vec<f64> {
    // `RangeScale::at` with its match taken out of the loop, which then vectorizes.
    match scale.viewpoint {
        Some(v) => {
            let rr = scale.r_ref * scale.r_ref;
            points
                .iter()
                .map(|p| plane.signed_distance(p) / scale_from(&v, rr, p))
                .collect()
        }
        None => points.iter().map(|p| plane.signed_distance(p)).collect(),
    }
}
}

widened! {
/// How many of the points lie within `tol` of the plane.
fn count_near(points: &Columns, plane: &Plane, tol: f64) -> usize {
    let n = &plane.normal;
    let mut count = 0usize;
    for ((x, y), z) in points.x.iter().zip(&points.y).zip(&points.z) {
        count += usize::from((n.x * x + n.y * y + n.z * z + plane.d).abs() < tol);
    }
    count
}
}

/// Two unit vectors completing `n` to an orthonormal basis.
pub fn orthonormal_basis(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let u = n.cross(&helper).normalize();
    (u, n.cross(&u))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    /// A table of 1 m by 1 m at z = 0 with 1.3 mm of normal depth noise.
    fn noisy_table() -> Vec<Point3<f64>> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        (0..10_000)
            .map(|_| {
                // Box-Muller.
                let (u, v): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random_range(0.0..1.0));
                let z = 0.0013 * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos();
                Point3::new(rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5), z)
            })
            .collect()
    }

    /// A start tilted by 0.6 degrees (a small patch's noise) settles on the table, though the
    /// band has settled after the first round: the refinement stopped there once, millimetres off
    /// at the table's edges.
    #[test]
    fn a_tilted_start_settles_on_the_table() {
        let points = noisy_table();
        let tilt = 0.6f64.to_radians();
        let start = Plane {
            normal: Vector3::new(0.0, tilt.sin(), tilt.cos()),
            d: 0.0,
        };
        let (plane, band) = refine_plane(&points, &RangeScale::uniform(), start, 0.0042, 0.02).unwrap();
        let table = Plane {
            normal: Vector3::z(),
            d: 0.0,
        };
        let all: Vec<usize> = (0..points.len()).collect();
        let off_at_edge = plane_motion(&plane, &table, &points, &all);
        assert!(off_at_edge < 0.0003, "{:.2} mm off at the edge", off_at_edge * 1e3);
        assert!((band - 3.0 * 0.0013).abs() < 0.0003, "band {band}");
    }
}
