//! The first stage: the cloud as the detector works on it. The points the detector takes
//! ([`input`]) lose the dominant (support) plane, which gives the noise estimate, and the rest is
//! subsampled and put into grids for the search and the checks.

use super::Params;
use super::input;
use super::plane_check::PlaneCheck;
use super::space::{MIN_NOISE, RangeNoise, SearchSettings, SearchSpace, morton_order};
use super::verify::{SurfaceSamples, median_spacing};
use crate::cloud::grid::{Grid, voxel_subsample};
use crate::cloud::plane::{Plane, find_dominant_plane, remove_dominant_plane, sample_stride, split_at_plane};
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
    let stride = input::thinning_stride(cloud, origin);
    if !params.remove_plane {
        let points = input::points(cloud, stride, input_points, params);
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
    let kept = || input::kept(cloud, stride, params);
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
            let points = input::points(cloud, stride, input_points, params);
            let all_grid = sight_grid(&points);
            (points, all_grid)
        },
    );
    // Wild points dropped: the plane is found again on the sample of the points that stay.
    let removal = if points.len() == n {
        split_at_plane(&points, found, false)
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
    /// Indices into `sub` in Morton order (`space::morton_order`).
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
    let max_size = super::select::overlap_distance(model);
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
    let models = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    simulated_model(scene, sim_seed, Model::load(name, &models).unwrap())
}

/// [`simulated`] for a model given whole.
#[cfg(test)]
pub(super) fn simulated_model(scene: &str, sim_seed: u64, model: Model) -> (Model, Params, Prepared) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let models = root.join("models");
    let scene = crate::sim::Scene::from_file(&root.join(format!("scenes/{scene}.toml")), &models).unwrap();
    let sweep = crate::sim::simulate(&scene, sim_seed);
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
    use crate::cloud::plane::RangeScale;

    /// The scene reports every finite input point, thinned or not, and keeps about one in the
    /// stride.
    #[test]
    fn a_thinned_scene_counts_every_input_point() {
        let mut dense = input::rows(0.0002, 4096, 10, 0.001);
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
        let dense: Vec<[f32; 3]> = input::rows(0.0002, 4096, 30, 0.0005);
        let cases = [
            ("sweep", &plain[..], None),
            ("wild return", &wild[..], None),
            ("range cut", &plain[..], Some(1.0)),
            ("every point finite", &finite[..], None),
            ("thinned rows", &dense[..], None),
        ];
        for (name, cloud, max_range) in cases {
            let params = Params {
                viewpoint: if name == "thinned rows" { None } else { viewpoint },
                max_range,
                ..Params::default()
            };
            let s = scene(cloud, &params);
            let origin = params.viewpoint.unwrap_or(Point3::origin());
            let stride = input::thinning_stride(cloud, origin);
            let finite = cloud.iter().filter(|p| p.iter().all(|v| v.is_finite())).count();
            let points = input::points(cloud, stride, finite, &params);
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
