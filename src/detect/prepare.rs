//! The first stage: the cloud as the detector works on it. Non-finite points and points out of
//! range are dropped, the dominant (support) plane is removed and gives the noise estimate, and
//! the rest is subsampled and put into grids for the search and the checks.

use super::Params;
use super::search::{PlaneCheck, SearchSettings, SearchSpace, morton_order};
use super::verify::{SurfaceSamples, median_spacing};
use crate::cloud::grid::{Grid, voxel_subsample};
use crate::cloud::plane::{
    Plane, RangeScale, find_dominant_plane, remove_dominant_plane, sample_stride, split_at_plane,
};
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
    // x - x is 0 for a finite x and NaN otherwise: a count without branches.
    #[allow(clippy::eq_op)]
    let input_points = cloud
        .iter()
        .filter(|p| (p[0] - p[0]) + (p[1] - p[1]) + (p[2] - p[2]) == 0.0)
        .count();
    let stride = thinning_stride(cloud, origin);
    if !params.remove_plane {
        let points = without_wild_points(filtered(cloud, stride, input_points, params, origin));
        let all_grid = sight_grid(&points);
        return Scene {
            input_points,
            objects: points.clone(),
            all_grid,
            points,
            plane: None,
            noise: RangeNoise::uniform(DEFAULT_NOISE),
        };
    }
    // The plane is found on an even sample of the points: taken from the cloud on this core
    // while the other converts every point and builds the grid of the lines of sight, which
    // needs nothing of the plane.
    let finite = |p: &&[f32; 3]| p.iter().all(|v| v.is_finite());
    let in_range = |p: &Point3<f64>| params.max_range.is_none_or(|r| (p - origin).norm() <= r);
    let kept = || cloud.iter().step_by(stride).filter(finite).map(to_f64).filter(in_range);
    let n = if stride == 1 && params.max_range.is_none() {
        input_points
    } else {
        kept().count()
    };
    let (found, (points, all_grid)) = rayon::join(
        || {
            sample_stride(n).and_then(|s| {
                let sample: Vec<Point3<f64>> = kept().step_by(s).collect();
                find_dominant_plane(&sample, params.viewpoint)
            })
        },
        || {
            let points = without_wild_points(filtered(cloud, stride, input_points, params, origin));
            let all_grid = sight_grid(&points);
            (points, all_grid)
        },
    );
    // Wild points dropped: the plane is found again on the sample of the points that stay.
    let removal = if points.len() == n {
        split_at_plane(&points, found, false, params.viewpoint)
    } else {
        remove_dominant_plane(&points, false, params.viewpoint)
    };
    if stride > 1 {
        tracing::debug!(
            "rows thinned to one point in {stride}: {} of {input_points} kept",
            points.len()
        );
    }
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

fn to_f64(p: &[f32; 3]) -> Point3<f64> {
    Point3::new(p[0] as f64, p[1] as f64, p[2] as f64)
}

/// Every `stride`-th point of the cloud that is finite and within range, in double precision.
fn filtered(
    cloud: &[[f32; 3]],
    stride: usize,
    input_points: usize,
    params: &Params,
    origin: Point3<f64>,
) -> Vec<Point3<f64>> {
    let finite = |p: &&[f32; 3]| p.iter().all(|v| v.is_finite());
    let mut points: Vec<Point3<f64>> = Vec::with_capacity(cloud.len() / stride + 1);
    if input_points == cloud.len() {
        // Every point finite: a plain conversion, without the test that keeps the loop from
        // being vectorized.
        points.extend(cloud.iter().step_by(stride).map(to_f64));
    } else {
        points.extend(cloud.iter().step_by(stride).filter(finite).map(to_f64));
    }
    match params.max_range {
        Some(r) => points.into_iter().filter(|p| (p - origin).norm() <= r).collect(),
        None => points,
    }
}

/// The spacing (m) along a sensor's rows below which points are thinned: finer than any model's
/// subsamples (at least 2 mm for the search, a twelfth of the smallest part for the refinement)
/// and than the depth noise of a triangulating sensor at a metre.
const THIN_SPACING: f64 = 0.002;

/// Every how many points of the cloud the detector keeps: 1, unless the cloud's rows are much
/// denser than [`THIN_SPACING`]. A profile sensor with 4096 columns, or a depth camera close to
/// its target, gives points a fraction of a millimetre apart along a row, many times what any
/// model's fit can use, and every stage would pay for them. The rows are seen in the file's own
/// order: the median distance between consecutive finite points, over up to 2,000 pairs spread
/// over the cloud, across the line of sight from `origin` (along it, a triangulating sensor's
/// depth noise would hide how close the rows are). In an organized cloud consecutive points are
/// neighbours along a row, and keeping every k-th thins the rows evenly; in an unorganized cloud
/// consecutive points are far apart and nothing is thinned.
fn thinning_stride(cloud: &[[f32; 3]], origin: Point3<f64>) -> usize {
    const PAIRS: usize = 2_000;
    if cloud.len() < 4 * PAIRS {
        return 1;
    }
    let step = (cloud.len() - 1) / PAIRS;
    let point = |p: &[f32; 3]| Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
    let mut gaps: Vec<f64> = (0..PAIRS)
        .map(|i| (&cloud[i * step], &cloud[i * step + 1]))
        .filter(|(a, b)| a.iter().chain(b.iter()).all(|v| v.is_finite()))
        .filter_map(|(a, b)| {
            let (a, b) = (point(a), point(b));
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

/// How far beyond the box of the middle 98 % of the points (per axis), in multiples of that
/// box's size, a point is taken for a wild return and dropped.
const WILD_REACH: f64 = 2.0;

/// Where wild returns lie (a reflection, a window, a corrupt value 30 m or 3e38 m away): a few
/// such points are nothing a detector can use, and stretch every grid and bounding box over
/// empty space. Outside the box of the 1st to 99th percentile of each coordinate, widened by
/// twice its size (at least 1 cm) on each side; the room behind a table stays.
struct WildBounds([(f64, f64); 3]);

impl WildBounds {
    /// The bounds of `n` finite points (`None` below 100, too few to tell). The percentiles are
    /// those of an even share of 2 000 of them: a bound widened by twice the box does not need
    /// them closer than that.
    fn of(points: impl Iterator<Item = Point3<f64>>, n: usize) -> Option<WildBounds> {
        if n < 100 {
            return None;
        }
        let stride = n.div_ceil(2_000).max(1);
        let mut v: [Vec<f64>; 3] = std::array::from_fn(|_| Vec::with_capacity(2_000));
        for p in points.step_by(stride) {
            for (k, c) in v.iter_mut().enumerate() {
                c.push(p[k]);
            }
        }
        Some(WildBounds(v.map(|mut v| {
            let n = v.len();
            let lo = *v.select_nth_unstable_by(n / 100, f64::total_cmp).1;
            let hi = *v.select_nth_unstable_by(n - 1 - n / 100, f64::total_cmp).1;
            let reach = WILD_REACH * (hi - lo).max(0.01);
            (lo - reach, hi + reach)
        })))
    }

    /// 1 for a point outside the box, 0 inside, without branches: the count over every point,
    /// which nearly always finds none, vectorizes. The points are finite: outside is below the
    /// low bound or above the high one.
    #[inline]
    fn outside(&self, p: &Point3<f64>) -> usize {
        let b = &self.0;
        let out = |k: usize| usize::from(p[k] < b[k].0) | usize::from(p[k] > b[k].1);
        out(0) | out(1) | out(2)
    }
}

/// The points without wild returns ([`WildBounds`]).
fn without_wild_points(points: Vec<Point3<f64>>) -> Vec<Point3<f64>> {
    let Some(wild) = WildBounds::of(points.iter().copied(), points.len()) else {
        return points;
    };
    if points.iter().map(|p| wild.outside(p)).sum::<usize>() == 0 {
        return points;
    }
    points.into_iter().filter(|p| wild.outside(p) == 0).collect()
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
    /// Indices into `sub` in Morton order (`search::morton_order`).
    pub sub_morton: Vec<u32>,
    /// `sub` subsampled again to three times its voxel, where the trials count their consensus.
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
            sub_morton: &self.sub_morton,
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

/// About how many points the refinement's subsample (`mid`) holds at most. The scores, the
/// refinement's inliers and the coverage test each hypothesis against the `mid` points near it,
/// so their cost grows with its density; a twelfth of the smallest part's size gives a few
/// hundred points on a part's visible side from a sparse sweep or a depth camera, but several
/// times that from a dense profile sensor, which adds nothing to a pose's accuracy that the
/// fit's noise model has not already. A table scene from a depth camera at a metre or a sweep of
/// 256 columns stays under this count.
const MID_POINTS: usize = 8_000;

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
    // Two chains of subsamples and grids that need nothing of each other: one on each core.
    let ((sub, sub_grid, sub_morton, coarse, coarse_grid), (mid, mid_grid, spacing, samples)) = rayon::join(
        || {
            let sub: Vec<Point3<f64>> = voxel_subsample(objects, voxel)
                .into_iter()
                .map(|i| objects[i])
                .collect();
            let sub_grid = Grid::new(&sub, min_size);
            let sub_morton = morton_order(&sub);
            // A trial's consensus only has to rank the trials of one hypothesis: a ninth of the
            // points on a surface (three times the voxel) rank them as well, and counting is a third of a trial's work.
            let coarse: Vec<Point3<f64>> = voxel_subsample(&sub, 3.0 * voxel).into_iter().map(|i| sub[i]).collect();
            let coarse_grid = Grid::new(&coarse, min_size);
            (sub, sub_grid, sub_morton, coarse, coarse_grid)
        },
        || {
            // The refinement fits at most a few hundred points of a part: a twelfth of the
            // smallest size still leaves a part's visible side well over that, at a fraction of
            // the points to test against its surface.
            let mut mid: Vec<Point3<f64>> = voxel_subsample(objects, min_size / 12.0)
                .into_iter()
                .map(|i| objects[i])
                .collect();
            if mid.len() > MID_POINTS {
                // Denser data than the refinement can use: a coarser voxel, up to twice as
                // coarse. The count falls with the square of the voxel on a surface sampled
                // finely both ways, but only in proportion to it across a sweep's rows when they
                // are further apart than the voxel, which is where there are too many points.
                let voxel = min_size / 12.0 * (mid.len() as f64 / MID_POINTS as f64).min(2.0);
                mid = voxel_subsample(&mid, voxel).into_iter().map(|i| mid[i]).collect();
            }
            // The spacing and the surface samples on this core, the grid free for the other to
            // take once its chain is done: the spacing's search is this chain's longest step.
            let ((spacing, samples), mid_grid) = rayon::join(
                || {
                    let spacing = median_spacing(&mid);
                    let samples: Vec<SurfaceSamples> = model
                        .parts
                        .iter()
                        .map(|p| SurfaceSamples::new(&p.shape, spacing, p.open))
                        .collect();
                    (spacing, samples)
                },
                || Grid::new(&mid, 1.2 * max_size),
            );
            (mid, mid_grid, spacing, samples)
        },
    );
    tracing::debug!(
        "{} object points: {} subsampled, {} coarse, {} mid; spacing {:.4} m",
        objects.len(),
        sub.len(),
        coarse.len(),
        mid.len(),
        spacing
    );
    let checks = model
        .parts
        .iter()
        .map(|p| PlaneCheck::new(&p.shape, scene.noise.reference(), p.open))
        .collect();
    Prepared {
        sub,
        sub_grid,
        sub_morton,
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

/// For the detector's tests: `scenes/{scene}.toml` simulated with noise seed `sim_seed`, indexed
/// for model `name` with the default parameters seen from the sweep's viewpoint.
#[cfg(test)]
pub(super) fn simulated(scene: &str, sim_seed: u64, name: &str) -> (Model, Params, Prepared) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let models = root.join("models");
    let scene = crate::sim::Scene::from_file(&root.join(format!("scenes/{scene}.toml")), &models).unwrap();
    let sweep = crate::sim::simulate(&scene, sim_seed);
    let model = Model::load(name, &models).unwrap();
    let params = Params {
        viewpoint: sweep.cloud.viewpoint_position(),
        ..Params::default()
    };
    let prep = index(
        std::sync::Arc::new(super::scene(&sweep.cloud.points, &params)),
        &model,
        &params,
    );
    (model, params, prep)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// Rows of a plane 1 m away, `gap` apart along the row, with depth noise along the line of
    /// sight, in the sensor's order.
    fn rows(gap: f64, columns: usize, rows: usize, noise: f64) -> Vec<[f32; 3]> {
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

    /// The scene reports every finite input point, thinned or not, and keeps about one in the
    /// stride.
    #[test]
    fn a_thinned_scene_counts_every_input_point() {
        let mut dense = rows(0.0002, 4096, 10, 0.001);
        dense[5] = [f32::NAN, 0.0, 0.0];
        dense[6] = [0.0, f32::INFINITY, 0.0];
        let params = Params {
            remove_plane: false,
            ..Params::default()
        };
        let s = scene(&dense, &params);
        assert_eq!(s.input_points, dense.len() - 2);
        assert!(s.points.len() <= dense.len() / 10 + 1, "{} kept", s.points.len());
    }

    /// The plane found on a sample taken from the cloud, beside the conversion, is the one found
    /// on the converted points, and splits them the same: with holes, thinned rows, a range cut
    /// and wild returns (whose removal changes the sample).
    #[test]
    fn the_plane_found_beside_the_conversion_is_the_one_of_the_points() {
        let sweep = crate::sim::simulate(
            &crate::sim::Scene::from_file(
                &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/fig3_table.toml"),
                &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models"),
            )
            .unwrap(),
            1,
        );
        let viewpoint = sweep.cloud.viewpoint_position();
        let plain = sweep.cloud.points.clone();
        assert!(plain.iter().any(|p| p[0].is_nan()), "a sweep has holes");
        let mut wild = plain.clone();
        let k = wild.iter().position(|p| p[0].is_finite()).unwrap();
        wild[k] = [3e4, -2e4, 5e4];
        let finite: Vec<[f32; 3]> = plain.iter().copied().filter(|p| p[0].is_finite()).collect();
        let dense: Vec<[f32; 3]> = rows(0.0002, 4096, 30, 0.0005);
        let cases: [(&str, &[[f32; 3]], Option<f64>); 5] = [
            ("sweep", &plain, None),
            ("wild return", &wild, None),
            ("range cut", &plain, Some(1.0)),
            ("every point finite", &finite, None),
            ("thinned rows", &dense, None),
        ];
        for (name, cloud, max_range) in cases {
            let params = Params {
                viewpoint: if name == "thinned rows" { None } else { viewpoint },
                max_range,
                ..Params::default()
            };
            let s = scene(cloud, &params);
            let origin = params.viewpoint.unwrap_or(Point3::origin());
            let stride = thinning_stride(cloud, origin);
            let input = cloud.iter().filter(|p| p.iter().all(|v| v.is_finite())).count();
            let points = without_wild_points(filtered(cloud, stride, input, &params, origin));
            let removal = remove_dominant_plane(&points, false, params.viewpoint);
            assert!(removal.plane.is_some(), "{name}: no plane");
            assert_eq!(s.points, points, "{name}");
            assert_eq!(s.plane, removal.plane, "{name}");
            let objects: Vec<Point3<f64>> = removal.kept.iter().map(|&i| points[i]).collect();
            assert_eq!(s.objects, objects, "{name}");
        }
        let count = |cloud: &[[f32; 3]], max_range| {
            let params = Params {
                viewpoint,
                max_range,
                ..Params::default()
            };
            scene(cloud, &params).points.len()
        };
        let all = count(&plain, None);
        assert!(count(&wild, None) == all - 1 && count(&plain, Some(1.0)) < all);
    }

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
