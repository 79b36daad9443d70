//! The first stage: the cloud as the detector works on it. Non-finite points and points out of
//! range are dropped, the dominant (support) plane is removed and gives the noise estimate, and
//! the rest is subsampled and put into grids for the search and the checks.

use super::Params;
use super::search::{PlaneCheck, SearchSettings, SearchSpace};
use super::verify::{SurfaceSamples, median_spacing};
use crate::cloud::grid::{Grid, voxel_subsample};
use crate::cloud::plane::{Plane, RangeScale, remove_dominant_plane};
use crate::model::Model;
use nalgebra::Point3;
use std::fmt;

/// Depth noise (m, one sigma) assumed when no plane gives an estimate.
const DEFAULT_NOISE: f64 = 0.002;

/// The cloud after filtering and plane removal.
pub struct Scene {
    /// Finite input points (before the range cut).
    pub input_points: usize,
    /// Every finite point within range, the plane's included: the lines of sight of the
    /// free-space check end on them.
    pub points: Vec<Point3<f64>>,
    /// Grid over `points` for the lines of sight.
    pub all_grid: Grid,
    /// The points off the plane: where the objects are searched.
    pub objects: Vec<Point3<f64>>,
    /// The support plane, its normal towards the objects.
    pub plane: Option<Plane>,
    /// Depth noise (one sigma) from the plane's inlier band.
    pub noise: RangeNoise,
}

/// The depth noise (m, one sigma) of a triangulating sensor (a laser profiler, a structured-light
/// camera), as the support plane showed it: it grows with the square of the range, so the noise
/// at a point is the plane's at the median range scaled as the plane's distances were
/// ([`RangeScale`]). Without a viewpoint, or without a plane, it is one figure for the whole
/// scene.
#[derive(Debug, Clone, Copy)]
pub struct RangeNoise {
    at_reference: f64,
    scale: RangeScale,
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
const MIN_NOISE: f64 = 0.0005;

/// What plane removal found, for the log.
pub struct RemovalSummary {
    pub plane: Option<Plane>,
    pub band: f64,
    pub inliers: usize,
    pub kept: usize,
}

/// `plane <coefficients> band .. inliers .. kept ..`.
impl fmt::Display for RemovalSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "plane {:?} band {:.4} inliers {} kept {}",
            self.plane.map(|p| p.coefficients()),
            self.band,
            self.inliers,
            self.kept
        )
    }
}

/// Filter the cloud (non-finite points are skipped) and remove the support plane.
pub fn scene(cloud: &[[f32; 3]], params: &Params) -> Scene {
    let origin = params.viewpoint.unwrap_or(Point3::origin());
    let mut points: Vec<Point3<f64>> = Vec::with_capacity(cloud.len());
    points.extend(
        cloud
            .iter()
            .filter(|p| p.iter().all(|v| v.is_finite()))
            .map(|p| Point3::new(p[0] as f64, p[1] as f64, p[2] as f64)),
    );
    let input_points = points.len();
    let points: Vec<Point3<f64>> = match params.max_range {
        Some(r) => points.into_iter().filter(|p| (p - origin).norm() <= r).collect(),
        None => points,
    };
    let points = without_wild_points(points);
    if !params.remove_plane {
        return Scene {
            input_points,
            objects: points.clone(),
            all_grid: sight_grid(&points),
            points,
            plane: None,
            noise: RangeNoise::uniform(DEFAULT_NOISE),
        };
    }
    // The grid of the lines of sight needs every point and nothing of the plane: it is built on
    // the second core while the plane is found.
    let (removal, all_grid) = rayon::join(
        || remove_dominant_plane(&points, false, params.viewpoint),
        || sight_grid(&points),
    );
    let noise = if removal.plane.is_some() {
        RangeNoise {
            at_reference: (removal.band / 3.0).max(MIN_NOISE),
            scale: removal.range_scale,
        }
    } else {
        RangeNoise::uniform(DEFAULT_NOISE)
    };
    let summary = RemovalSummary {
        plane: removal.plane,
        band: removal.band,
        inliers: removal.inliers,
        kept: removal.kept.len(),
    };
    tracing::debug!("{summary}");
    Scene {
        input_points,
        objects: removal.kept.iter().map(|&i| points[i]).collect(),
        points,
        all_grid,
        plane: removal.plane,
        noise,
    }
}

/// How far beyond the box of the middle 98 % of the points (per axis), in multiples of that
/// box's size, a point is taken for a wild return and dropped.
const WILD_REACH: f64 = 2.0;

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
    let inside = |p: &Point3<f64>| (0..3).all(|k| p[k] >= bounds[k].0 && p[k] <= bounds[k].1);
    if points.iter().all(inside) {
        return points;
    }
    points.into_iter().filter(|p| inside(p)).collect()
}

/// The grid the free-space check looks along the lines of sight in.
fn sight_grid(points: &[Point3<f64>]) -> Grid {
    Grid::new(points, 0.01)
}

/// The scene indexed for the search and the checks of one model.
pub struct Prepared {
    /// Shared: one sweep's scene serves the detections of every object asked for on it.
    pub scene: std::sync::Arc<Scene>,
    /// The objects' points subsampled to a quarter of the model's smallest size.
    pub sub: Vec<Point3<f64>>,
    /// Grid over `sub`, cells the size of the model's smallest part.
    pub sub_grid: Grid,
    /// `sub` subsampled again to twice its voxel, where the trials count their consensus.
    pub coarse: Vec<Point3<f64>>,
    /// Grid over `coarse`, cells the size of the model's smallest part.
    pub coarse_grid: Grid,
    /// The objects' points subsampled to a twelfth of the smallest size, where the refinement
    /// gathers its inliers.
    pub mid: Vec<Point3<f64>>,
    /// Grid over `mid`, cells the size of the model's largest part.
    pub mid_grid: Grid,
    pub viewpoint: Option<Point3<f64>>,
    /// Each part's surface samples at the data's spacing.
    pub samples: Vec<SurfaceSamples>,
    /// Each part's placement check against the support plane.
    pub checks: Vec<PlaneCheck>,
    /// The search settings of a part searched over the whole scene.
    pub settings: SearchSettings,
    /// The largest size of any part: instances closer than this are the same one.
    pub max_size: f64,
}

impl Prepared {
    /// Where the search and the scores look.
    pub fn space(&self) -> SearchSpace<'_> {
        SearchSpace {
            points: &self.mid,
            grid: &self.mid_grid,
            sub: &self.sub,
            sub_grid: &self.sub_grid,
            coarse: &self.coarse,
            coarse_grid: &self.coarse_grid,
            mid: &self.mid,
            mid_grid: &self.mid_grid,
            viewpoint: self.viewpoint,
            noise: self.scene.noise,
            plane: self.scene.plane,
        }
    }

    pub fn noise(&self) -> RangeNoise {
        self.scene.noise
    }
}

/// Subsample the scene and build the grids, surface samples and plane checks for `model`.
pub fn index(scene: std::sync::Arc<Scene>, model: &Model, params: &Params) -> Prepared {
    let min_size = model
        .parts
        .iter()
        .map(|p| p.shape.min_size())
        .fold(f64::INFINITY, f64::min);
    let max_size = model.parts.iter().map(|p| p.shape.max_size()).fold(0.0, f64::max);
    // Subsample to a quarter of the smallest size: a 30-point sample within min(a) of its seed
    // then still spans the patch, and the trials touch a fraction of the points.
    let objects = &scene.objects;
    let voxel = (min_size / 4.0).clamp(0.002, 0.01);
    let sub: Vec<Point3<f64>> = voxel_subsample(objects, voxel)
        .into_iter()
        .map(|i| objects[i])
        .collect();
    // The refinement fits at most a few hundred points of a part: a twelfth of the smallest
    // size still leaves a part's visible side well over that, at a fraction of the points to
    // test against its surface.
    let mid: Vec<Point3<f64>> = voxel_subsample(objects, min_size / 12.0)
        .into_iter()
        .map(|i| objects[i])
        .collect();
    let mid_grid = Grid::new(&mid, 1.2 * max_size);
    let sub_grid = Grid::new(&sub, min_size);
    // A trial's consensus only has to rank the trials of one hypothesis: a quarter of the points
    // on a surface rank them as well, and counting is a third of a trial's work.
    let coarse: Vec<Point3<f64>> = voxel_subsample(&sub, 2.0 * voxel).into_iter().map(|i| sub[i]).collect();
    let coarse_grid = Grid::new(&coarse, min_size);
    let spacing = median_spacing(&mid);
    tracing::debug!(
        "{} object points: {} subsampled, {} coarse, {} mid; spacing {:.4} m",
        objects.len(),
        sub.len(),
        coarse.len(),
        mid.len(),
        spacing
    );
    let samples = model
        .parts
        .iter()
        .map(|p| SurfaceSamples::new(&p.shape, spacing, p.open))
        .collect();
    let checks = model
        .parts
        .iter()
        .map(|p| PlaneCheck::new(&p.shape, scene.noise.reference(), p.open))
        .collect();
    Prepared {
        sub,
        sub_grid,
        coarse,
        coarse_grid,
        mid,
        mid_grid,
        viewpoint: params.viewpoint,
        samples,
        checks,
        settings: SearchSettings {
            trials: params.trials,
            sample_points: params.sample_points,
            fit_iterations: params.fit_iterations,
        },
        max_size,
        scene,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Twice the range, four times the noise; never under the floor; one figure without a
    /// viewpoint.
    #[test]
    fn noise_grows_with_the_square_of_the_range() {
        let n = RangeNoise {
            at_reference: 0.002,
            scale: RangeScale::at_range(Point3::origin(), 0.8),
        };
        assert!((n.at(&Point3::new(0.0, 0.0, 0.8)) - 0.002).abs() < 1e-12);
        assert!((n.at(&Point3::new(0.0, 1.6, 0.0)) - 0.008).abs() < 1e-12);
        assert_eq!(n.at(&Point3::new(0.0, 0.0, 0.01)), MIN_NOISE);
        assert_eq!(RangeNoise::uniform(0.003).at(&Point3::new(5.0, 0.0, 0.0)), 0.003);
    }
}
