//! Where the detector searches, shared by every stage from the trials to the verification:
//! the scene's points at three densities with their grids, the depth noise that sets the inlier
//! bands, the support plane, and the measures every stage takes of a placed shape in them
//! (its inliers, its consensus, whether two placements are the same hypothesis).

use crate::cloud::grid::Grid;
use crate::cloud::plane::{Plane, RangeScale};
use crate::geometry::{NearBatch, PlacedKernel, PlacedSuperquadric, Superquadric};
use crate::numeric::lanes::widened;
use nalgebra::{Point3, Vector3};

/// A trial needs at least this many points around its seed to say anything about the pose.
pub const MIN_SAMPLE: usize = 8;

/// Every k-th point so that at most `n` remain (the points come in grid order, so a stride
/// keeps them spread over the surface).
pub fn thin(points: Vec<Point3<f64>>, n: usize) -> Vec<Point3<f64>> {
    if points.len() <= n {
        return points;
    }
    let step = points.len().div_ceil(n);
    points.into_iter().step_by(step).collect()
}

/// Where the detector searches: the full-resolution points and two subsampled copies, with grids.
pub struct SearchSpace<'a> {
    pub points: &'a [Point3<f64>],
    pub grid: &'a Grid,
    pub sub: &'a [Point3<f64>],
    pub sub_grid: &'a Grid,
    /// Indices into `sub` in Morton order ([`morton_order`]): where the search's regions come
    /// from.
    pub sub_morton: &'a [u32],
    /// A coarser subsample, where the trials count their consensus.
    pub coarse: &'a [Point3<f64>],
    pub coarse_grid: &'a Grid,
    /// A denser subsample, where the refinement's final rounds gather their points.
    pub mid: &'a [Point3<f64>],
    pub mid_grid: &'a Grid,
    pub viewpoint: Option<Point3<f64>>,
    /// Depth noise (one sigma) at each place: sets the inlier bands.
    pub noise: RangeNoise,
    /// The support plane (normal towards the objects), when one was found: nothing the sensor
    /// saw on it can reach through it.
    pub plane: Option<Plane>,
}

/// Search settings of one part.
#[derive(Debug, Clone, Copy)]
pub struct SearchSettings {
    pub trials: usize,
    pub sample_points: usize,
    pub fit_iterations: usize,
}

/// One refined hypothesis.
#[derive(Debug, Clone, Copy)]
pub struct Hypothesis {
    pub placed: PlacedSuperquadric,
    /// The paper's M after refinement.
    pub m: f64,
}

/// The depth noise (m, one sigma) of a triangulating sensor (a laser profiler, a structured-light
/// camera), as the support plane showed it: it grows with the square of the range, so the noise
/// at a point is the plane's at the median range scaled as the plane's distances were
/// ([`RangeScale`]). Without a viewpoint, or without a plane, it is one figure for the whole
/// scene.
#[derive(Debug, Clone, Copy)]
pub struct RangeNoise {
    pub(super) at_reference: f64,
    pub(super) scale: RangeScale,
}

impl RangeNoise {
    pub fn uniform(sigma: f64) -> RangeNoise {
        RangeNoise {
            at_reference: sigma,
            scale: RangeScale::uniform(),
        }
    }

    /// The noise at `p`.
    pub fn at(&self, p: &Point3<f64>) -> f64 {
        (self.at_reference * self.scale.at(p)).max(MIN_NOISE)
    }

    /// The noise at the median range.
    pub fn reference(&self) -> f64 {
        self.at_reference
    }
}

/// The least noise assumed (m): below it, the sensor's quantisation and the models'
/// approximation dominate.
pub(super) const MIN_NOISE: f64 = 0.0005;

/// The inlier band for refinement: three noise sigmas, at least a tenth of the smallest size
/// (so a rough RANSAC pose still gathers its object's points), at most half of it.
pub fn refine_band(shape: &Superquadric, noise: f64) -> f64 {
    (3.0 * noise)
        .max(0.1 * shape.min_size())
        .min(0.5 * shape.min_size())
        .max(0.002)
}

/// Points of `space.points` near the surface of `placed` (within the inlier band) and within the
/// part's reach.
pub fn local_inliers(space: &SearchSpace<'_>, placed: &PlacedSuperquadric, band: f64) -> Vec<Point3<f64>> {
    inliers_in(space.points, space.grid, placed, band)
}

widened! {
pub fn inliers_in(
    points: &[Point3<f64>],
    grid: &Grid,
    placed: &PlacedSuperquadric,
    band: f64,
) -> Vec<Point3<f64>> {
    let centre = Point3::from(placed.pose.translation.vector);
    let kernel = PlacedKernel::new(placed);
    let mut out = Vec::new();
    let mut batch = NearBatch::new(&kernel, band, |i, _, rg| {
        if PlacedSuperquadric::distance_from(rg).abs() < band {
            out.push(points[i]);
        }
    });
    let reach = kernel.frame_reach(band);
    grid.for_each_within_box(points, &centre, placed.shape.bounding_radius() + band, &reach, |i| {
        batch.push(i, &points[i])
    });
    batch.finish();
    out
}
}

/// Radius of the neighbourhood a trial samples around its seed. The paper takes min(a1, a2, a3);
/// for flat shapes (a bowl's a3 is a third of its width) that patch is too small to constrain six
/// pose parameters, so the geometric mean of the sizes is used: the radius of the sphere of the
/// same volume class, the same as min(a) for a round shape.
pub fn sample_radius(shape: &Superquadric) -> f64 {
    (shape.a[0] * shape.a[1] * shape.a[2]).cbrt()
}

widened! {
/// Points of the coarse subsample within `band` of the placed surface.
pub fn consensus(space: &SearchSpace<'_>, placed: &PlacedSuperquadric, band: f64) -> usize {
    let centre = Point3::from(placed.pose.translation.vector);
    let kernel = PlacedKernel::new(placed);
    let mut n = 0;
    let mut batch = NearBatch::new(&kernel, band, |_, _, rg| {
        if PlacedSuperquadric::distance_from(rg).abs() < band {
            n += 1;
        }
    });
    let reach = kernel.frame_reach(band);
    space.coarse_grid.for_each_within_box(
        space.coarse,
        &centre,
        placed.shape.bounding_radius() + band,
        &reach,
        |i| batch.push(i, &space.coarse[i]),
    );
    batch.finish();
    n
}
}

/// The indices of `points` sorted by the Morton code of their 1 cm voxels (ties by index): runs
/// of it are compact regions of space.
pub fn morton_order(points: &[Point3<f64>]) -> Vec<u32> {
    let voxel = 0.01;
    let spread = |v: u64| {
        // Interleave the low 21 bits with two zero bits between each.
        let mut x = v & 0x1f_ffff;
        x = (x | x << 32) & 0x1f_0000_0000_ffff;
        x = (x | x << 16) & 0x1f_0000_ff00_00ff;
        x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
        x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
        x = (x | x << 2) & 0x1249_2492_4924_9249;
        x
    };
    let key = |p: &Point3<f64>| {
        // The float-to-integer cast saturates; the add must too (a wild point 3e38 m away).
        let c = [0, 1, 2].map(|k| {
            ((p[k] / voxel).floor() as i64)
                .saturating_add(1 << 20)
                .clamp(0, (1 << 21) - 1) as u64
        });
        spread(c[0]) | spread(c[1]) << 1 | spread(c[2]) << 2
    };
    let mut order: Vec<(u64, u32)> = points.iter().enumerate().map(|(i, p)| (key(p), i as u32)).collect();
    order.sort_unstable();
    order.into_iter().map(|(_, i)| i).collect()
}

/// Whether two placements of one shape are the same hypothesis: the same place within half the
/// sample radius and the same axis within 30 degrees.
pub fn same_pose(a: &PlacedSuperquadric, b: &PlacedSuperquadric) -> bool {
    let shape = &b.shape;
    let za = a.pose.rotation * Vector3::z();
    let zb = b.pose.rotation * Vector3::z();
    (a.pose.translation.vector - b.pose.translation.vector).norm() < 0.5 * sample_radius(shape)
        && axis_angle_deg(&za, &zb, shape.is_tapered()) < 30.0
}

fn axis_angle_deg(a: &Vector3<f64>, b: &Vector3<f64>, signed: bool) -> f64 {
    crate::model::axis_angle(a, b, signed).to_degrees()
}
