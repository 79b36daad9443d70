//! The detector: find a known object (one to three tapered superquadrics) in a point cloud and
//! give its 6-DoF pose, as Biegelbauer & Vincze (ICRA 2007) do, then further:
//!
//! 1. dominant plane removal ([`plane`]);
//! 2. hierarchical search ([`search`]): RANSAC trials on subsampled points with LM pose fits,
//!    the best of each hypothesis refined on full resolution;
//! 3. verification ([`verify`]): ranked voting over M, S and I;
//! 4. compound objects: the largest part is searched over the whole scene, every other part only
//!    where its connection to an already-found part puts it, and the combinations are ranked by
//!    the connection errors A and D together with the parts' M, S and I;
//! 5. acceptance: coverage of the visible surface, interior points and fit decide whether the
//!    winner is the object at all ("not here"), with a confidence in [0, 1];
//! 6. with `all`, every accepted hypothesis that does not overlap a better one.
//!
//! Every random choice comes from `Params::seed`; hypotheses run in parallel but each draws from
//! its own stream, so the answer does not depend on the number of threads.

pub mod fit;

pub mod output;

pub mod rigid;
pub mod search;
pub mod verify;

use crate::cloud::grid::{Grid, voxel_subsample};
use crate::cloud::plane::{Plane, remove_dominant_plane};
use crate::geometry::{PlacedSuperquadric, Superquadric};
use crate::model::{Model, axis_angle};
use crate::sim::stream_seed;
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use search::{Hypothesis, SearchSettings, SearchSpace};
use std::time::Instant;
use verify::{Scores, SurfaceSamples, median_spacing, rank_sums, score};

/// Detector settings. `Default` gives the paper's settings (n = 10 trials of 30 points, 20 LM
/// iterations, gamma = 0.2) and the calibrated acceptance thresholds.
#[derive(Debug, Clone)]
pub struct Params {
    pub seed: u64,
    /// RANSAC trials per hypothesis (paper: n = 10).
    pub trials: usize,
    /// Points per trial (paper: 30).
    pub sample_points: usize,
    /// LM iterations per fit (paper: 20).
    pub fit_iterations: usize,
    /// Surface tolerance of the S and I criteria (paper: 0.2).
    pub gamma: f64,
    /// Hypotheses for the (first) part; `None`: the model's m, else derived from the scene.
    pub hypotheses: Option<usize>,
    /// Hypotheses searched for each further part of a compound around each candidate.
    pub local_hypotheses: usize,
    /// Candidates of the first part a compound search continues from.
    pub compound_candidates: usize,
    pub remove_plane: bool,
    /// Drop points farther than this from the viewpoint (or the origin) (m).
    pub max_range: Option<f64>,
    /// Where the sensor was: orients surface normals. Camera-frame clouds have it at the origin.
    pub viewpoint: Option<Point3<f64>>,
    /// Return every accepted, non-overlapping instance instead of the best one.
    pub all: bool,
    pub acceptance: Acceptance,
}

/// Thresholds of the "is it there" test, calibrated on simulated scenes with and without the
/// objects (see BENCHMARKS.md).
#[derive(Debug, Clone, Copy)]
pub struct Acceptance {
    /// Least share of the visible surface that must hold points.
    pub min_coverage: f64,
    /// Most inside points per surface point.
    pub max_interior_ratio: f64,
    /// Most points just outside the surface per surface point.
    pub max_shell_ratio: f64,
    /// Least share of each part's visible side that, where the sensor could have seen it, it
    /// did (see [`verify::Visibility::seen_ratio`]).
    pub min_seen: f64,
    /// Largest RMS surface distance, in noise sigmas.
    pub max_rms_sigmas: f64,
    /// Largest connection angle error of a compound (rad).
    pub max_angle_error: f64,
    /// Largest connection distance error of a compound, as a share of the nominal distance.
    pub max_distance_error: f64,
}

impl Default for Acceptance {
    fn default() -> Self {
        Acceptance {
            min_coverage: 0.45,
            max_interior_ratio: 0.15,
            max_shell_ratio: 0.08,
            min_seen: 0.5,
            max_rms_sigmas: 1.6,
            max_angle_error: 25f64.to_radians(),
            max_distance_error: 0.25,
        }
    }
}

impl Default for Params {
    fn default() -> Self {
        Params {
            seed: 0,
            trials: 10,
            sample_points: 30,
            fit_iterations: 20,
            gamma: 0.2,
            hypotheses: None,
            local_hypotheses: 8,
            compound_candidates: 6,
            remove_plane: true,
            max_range: None,
            viewpoint: None,
            all: false,
            acceptance: Acceptance::default(),
        }
    }
}

/// One part of a detection.
#[derive(Debug, Clone)]
pub struct PartResult {
    pub name: String,
    /// The part's pose in the cloud's frame; `None` when a compound's part was not found.
    pub placed: Option<PlacedSuperquadric>,
    pub scores: Scores,
}

/// One detected instance.
#[derive(Debug, Clone)]
pub struct Detection {
    /// Whether the acceptance test says this is the object.
    pub found: bool,
    pub confidence: f64,
    /// The object's pose (its model frame) in the cloud's frame.
    pub pose: Isometry3<f64>,
    pub parts: Vec<PartResult>,
    /// For compounds: angle (rad) and distance (m) errors of each connection.
    pub connection_errors: Vec<(f64, f64)>,
}

/// Milliseconds spent in each stage.
#[derive(Debug, Clone, Copy, Default)]
pub struct Timing {
    pub plane_ms: f64,
    pub search_ms: f64,
    pub verify_ms: f64,
    pub total_ms: f64,
}

/// What a detection run found.
#[derive(Debug, Clone)]
pub struct Report {
    pub object: String,
    /// The best candidate first; with `Params::all` every accepted instance. Empty when the scene
    /// held nothing to fit.
    pub detections: Vec<Detection>,
    pub plane: Option<Plane>,
    /// Finite input points.
    pub points: usize,
    /// Points left after plane removal and the range cut.
    pub scene_points: usize,
    pub timing: Timing,
}

impl Report {
    /// The best candidate if the acceptance test passed it.
    pub fn best_found(&self) -> Option<&Detection> {
        self.detections.first().filter(|d| d.found)
    }
}

/// Rounds of search at most (see `detect`).
const SEARCH_ROUNDS: u64 = 2;
/// Anchor candidates of a compound below this coverage are not continued.
const MIN_ANCHOR_COVERAGE: f64 = 0.35;

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Hypotheses for the first part: the model's m if given, else one per object-sized patch of
/// the scene, bounded 10..=100 as in the paper.
fn auto_hypotheses(shape: &Superquadric, points: &[Point3<f64>]) -> usize {
    if points.is_empty() {
        return 10;
    }
    let mut lo = points[0];
    let mut hi = points[0];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let mut ext = [hi.x - lo.x, hi.y - lo.y, hi.z - lo.z];
    ext.sort_by(|a, b| b.total_cmp(a));
    let cell = 2.0 * shape.max_size();
    ((ext[0] * ext[1]) / (cell * cell)).ceil().clamp(10.0, 100.0) as usize
}

/// Detect `model` in `cloud` (finite and non-finite points; non-finite are skipped).
pub fn detect(cloud: &[[f32; 3]], model: &Model, params: &Params) -> Report {
    let start = Instant::now();
    let origin = params.viewpoint.unwrap_or(Point3::origin());
    let points: Vec<Point3<f64>> = cloud
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .map(|p| Point3::new(p[0] as f64, p[1] as f64, p[2] as f64))
        .collect();
    let n_input = points.len();
    let points: Vec<Point3<f64>> = match params.max_range {
        Some(r) => points.into_iter().filter(|p| (p - origin).norm() <= r).collect(),
        None => points,
    };
    let t_plane = Instant::now();
    let (plane, noise, scene) = if params.remove_plane {
        let removal = remove_dominant_plane(&points, false, params.viewpoint);
        let noise = if removal.plane.is_some() {
            (removal.band / 3.0).max(0.0005)
        } else {
            0.002
        };
        if tracing::enabled!(tracing::Level::DEBUG) {
            tracing::debug!(
                "plane {:?} band {:.4} inliers {} kept {}",
                removal.plane.map(|p| p.coefficients()),
                removal.band,
                removal.inliers,
                removal.kept.len()
            );
        }
        let scene: Vec<Point3<f64>> = removal.kept.iter().map(|&i| points[i]).collect();
        (removal.plane, noise, scene)
    } else {
        (None, 0.002, points.clone())
    };
    let plane_ms = ms(t_plane);
    let mut report = Report {
        object: model.name.clone(),
        detections: Vec::new(),
        plane,
        points: n_input,
        scene_points: scene.len(),
        timing: Timing {
            plane_ms,
            ..Default::default()
        },
    };
    if scene.len() < 10 {
        report.timing.total_ms = ms(start);
        return report;
    }
    let t_search = Instant::now();
    let min_size = model
        .parts
        .iter()
        .map(|p| p.shape.min_size())
        .fold(f64::INFINITY, f64::min);
    let max_size = model.parts.iter().map(|p| p.shape.max_size()).fold(0.0, f64::max);
    // Subsample to a quarter of the smallest size: a 30-point sample within min(a) of its seed
    // then still spans the patch, and the trials touch a fraction of the points.
    let voxel = (min_size / 4.0).clamp(0.002, 0.01);
    let sub: Vec<Point3<f64>> = voxel_subsample(&scene, voxel).into_iter().map(|i| scene[i]).collect();
    let grid = Grid::new(&scene, 1.2 * max_size);
    let sub_grid = Grid::new(&sub, min_size);
    let space = SearchSpace {
        points: &scene,
        grid: &grid,
        sub: &sub,
        sub_grid: &sub_grid,
        viewpoint: params.viewpoint,
        noise,
        plane,
    };
    let spacing = median_spacing(&scene, &Grid::new(&scene, 0.02));
    let samples: Vec<SurfaceSamples> = model
        .parts
        .iter()
        .map(|p| SurfaceSamples::new(&p.shape, spacing, p.open))
        .collect();
    let checks: Vec<search::PlaneCheck> = model
        .parts
        .iter()
        .map(|p| search::PlaneCheck::new(&p.shape, noise))
        .collect();
    let settings = SearchSettings {
        trials: params.trials,
        sample_points: params.sample_points,
        fit_iterations: params.fit_iterations,
    };

    // The first (anchor) part: the largest, searched over the whole scene.
    let anchor = (0..model.parts.len())
        .max_by(|&a, &b| volume(&model.parts[a].shape).total_cmp(&volume(&model.parts[b].shape)))
        .expect("a model has parts");
    let anchor_shape = model.parts[anchor].shape;
    let m = params
        .hypotheses
        .or(model.parts[anchor].hypotheses.map(|m| m as usize))
        .unwrap_or_else(|| auto_hypotheses(&anchor_shape, &scene))
        .max(1);
    let all_seeds: Vec<usize> = (0..sub.len()).collect();
    let all_grid = Grid::new(&points, 0.01);
    let (mut search_ms, mut verify_ms) = (0.0, 0.0);
    let mut t_search = t_search;
    let mut candidates: Vec<Detection> = Vec::new();
    // A second round with fresh seeds when the first finds nothing acceptable: "not here" costs
    // twice the time, but a found object costs no more, and a search that missed the object in
    // one round rarely misses it in two.
    for round in 0..SEARCH_ROUNDS {
        if round > 0 {
            t_search = Instant::now();
        }
        let anchors = search_part(
            &space,
            &anchor_shape,
            &all_seeds,
            m,
            &settings,
            model.parts[anchor].open,
            &checks[anchor],
            stream_seed(params.seed, anchor as u64 + 1000 * round),
        );
        search_ms += ms(t_search);
        let t_verify = Instant::now();
        let anchor_scores: Vec<Scores> = anchors
            .par_iter()
            .map(|h| score(&space, &h.placed, h.m, params.gamma, &samples[anchor]))
            .collect();
        let anchor_rank = rank_sums(&paper_criteria(&anchor_scores));
        verify_ms += ms(t_verify);

        let mut order: Vec<usize> = (0..anchors.len()).collect();
        order.sort_by_key(|&k| (anchor_rank[k], ordered(anchors[k].m)));
        if tracing::enabled!(tracing::Level::DEBUG) {
            for &k in &order {
                let t = anchors[k].placed.pose.translation.vector;
                let z = anchors[k].placed.pose.rotation * Vector3::z();
                let s = &anchor_scores[k];
                tracing::debug!(
                    "rank {:3} pos ({:.3} {:.3} {:.3}) z ({:.2} {:.2} {:.2}) M {:.4} S {} I {} cov {:.2} rms {:.4} surf {} inside {} shell {}",
                    anchor_rank[k],
                    t.x,
                    t.y,
                    t.z,
                    z.x,
                    z.y,
                    z.z,
                    s.m,
                    s.s,
                    s.i,
                    s.coverage,
                    s.rms,
                    s.surface_points,
                    s.inside_points,
                    s.shell_points
                );
            }
        }
        let first_new = candidates.len();
        if !model.is_compound() {
            for &k in &order {
                let parts = vec![PartResult {
                    name: model.parts[0].name.clone(),
                    placed: Some(anchors[k].placed),
                    scores: anchor_scores[k],
                }];
                candidates.push(finish(model, parts, Vec::new(), noise, &params.acceptance));
            }
        } else {
            // Continue from the best distinct anchor candidates that could be the part at all (a
            // part seen on less than a third of its visible side is too uncertain to build on).
            let mut picked: Vec<usize> = Vec::new();
            for &k in &order {
                let c = anchors[k].placed.pose.translation.vector;
                let distinct = picked
                    .iter()
                    .all(|&j| (anchors[j].placed.pose.translation.vector - c).norm() > anchor_shape.max_size());
                if distinct && anchor_scores[k].coverage >= MIN_ANCHOR_COVERAGE {
                    picked.push(k);
                }
                if picked.len() >= params.compound_candidates.max(1) {
                    break;
                }
            }
            let t = Instant::now();
            let combos = compound_combinations(
                &space,
                model,
                anchor,
                &picked,
                &anchors,
                &anchor_scores,
                params,
                round,
                &samples,
                &checks,
            );
            search_ms += ms(t);
            // Rank the combinations over the connection errors and every part's M, S, I.
            let t = Instant::now();
            let mut criteria: Vec<(Vec<f64>, bool)> = Vec::new();
            for c in 0..model.connections.len() {
                criteria.push((combos.iter().map(|x| x.2[c].0).collect(), true));
                criteria.push((combos.iter().map(|x| x.2[c].1).collect(), true));
            }
            for p in 0..model.parts.len() {
                let sc: Vec<Scores> = combos.iter().map(|x| x.1[p].scores).collect();
                criteria.extend(paper_criteria(&sc));
            }
            let sums = rank_sums(&criteria);
            let mut idx: Vec<usize> = (0..combos.len()).collect();
            idx.sort_by_key(|&k| sums[k]);
            if tracing::enabled!(tracing::Level::DEBUG) {
                for &k in idx.iter().take(12) {
                    let (_, parts, errs) = &combos[k];
                    let desc: Vec<String> = parts
                        .iter()
                        .map(|p| match p.placed {
                            Some(q) => {
                                let t = q.pose.translation.vector;
                                format!(
                                    "{} ({:.3} {:.3} {:.3}) M {:.3} S {} cov {:.2} in {} surf {}",
                                    p.name,
                                    t.x,
                                    t.y,
                                    t.z,
                                    p.scores.m,
                                    p.scores.s,
                                    p.scores.coverage,
                                    p.scores.inside_points,
                                    p.scores.surface_points
                                )
                            }
                            None => format!("{} -", p.name),
                        })
                        .collect();
                    tracing::debug!(
                        "combo sum {} A {:.1} deg D {:.3} | {}",
                        sums[k],
                        errs[0].0.to_degrees(),
                        errs[0].1,
                        desc.join(" | ")
                    );
                }
            }
            // The best-ranked combination of every anchor candidate is refined as one rigid object
            // and scored again.
            let mut best_of_anchor: Vec<usize> = Vec::new();
            for &k in &idx {
                if best_of_anchor.iter().all(|&j| combos[j].0 != combos[k].0) {
                    best_of_anchor.push(k);
                }
            }
            let refined: Vec<Detection> = best_of_anchor
                .par_iter()
                .map(|&k| {
                    let (_, parts, errors) = &combos[k];
                    let start = object_pose(model, parts);
                    let smallest = model
                        .parts
                        .iter()
                        .map(|p| p.shape)
                        .min_by(|a, b| volume(a).total_cmp(&volume(b)))
                        .expect("parts");
                    let coarse = 0.3 * search::sample_radius(&smallest);
                    let fine = search::refine_band(&smallest, noise);
                    let (pose, _) = rigid::refine_object(&space, model, &start, coarse, fine, params.fit_iterations);
                    let placed = model.placed_parts(&pose);
                    let parts: Vec<PartResult> = model
                        .parts
                        .iter()
                        .zip(placed)
                        .zip(&samples)
                        .map(|((p, q), samples)| {
                            let inliers = search::local_inliers(&space, &q, search::refine_band(&p.shape, noise));
                            let m = fit::measure_of_fit(&q, &inliers);
                            PartResult {
                                name: p.name.clone(),
                                placed: Some(q),
                                scores: score(&space, &q, m, params.gamma, samples),
                            }
                        })
                        .collect();
                    let mut d = finish(model, parts, Vec::new(), noise, &params.acceptance);
                    // The rigid fit moves parts that were not searched (a part never found is placed
                    // by the model): none may go through the support plane.
                    let possible = d
                        .parts
                        .iter()
                        .zip(&checks)
                        .all(|(r, check)| r.placed.is_none_or(|q| check.allows(&space, &q)));
                    if !possible {
                        d.found = false;
                        d.confidence = d.confidence.min(0.1);
                    }
                    d.pose = pose;
                    d.connection_errors = errors.clone();
                    d
                })
                .collect();
            let n_refined = refined.len();
            if tracing::enabled!(tracing::Level::DEBUG) {
                for d in &refined {
                    let t = d.pose.translation.vector;
                    tracing::debug!(
                        "refined found {} conf {:.3} pos ({:.3} {:.3} {:.3}) {}",
                        d.found,
                        d.confidence,
                        t.x,
                        t.y,
                        t.z,
                        d.parts
                            .iter()
                            .map(|p| format!(
                                "{} cov {:.2} surf {} in {} rms {:.4}",
                                p.name,
                                p.scores.coverage,
                                p.scores.surface_points,
                                p.scores.inside_points,
                                p.scores.rms
                            ))
                            .collect::<Vec<_>>()
                            .join(" | ")
                    );
                }
            }
            candidates.extend(refined);
            let _ = n_refined;
            let mut combos: Vec<Option<Combination>> = combos.into_iter().map(Some).collect();
            for k in idx.into_iter().filter(|k| !best_of_anchor.contains(k)) {
                if let Some((_, parts, errors)) = combos[k].take() {
                    candidates.push(finish(model, parts, errors, noise, &params.acceptance));
                }
            }
            verify_ms += ms(t);
        }
        // Free-space check of the candidates the acceptance test passed: a part where the sensor saw
        // through it is not there. Only the candidates that may be reported are checked (it is the
        // most expensive test per candidate, and most candidates fail cheaper ones first).
        let limit = if params.all { usize::MAX } else { 1 };
        let mut accepted = candidates[..first_new].iter().filter(|d| d.found).count();
        for d in candidates[first_new..].iter_mut() {
            if accepted >= limit {
                break;
            }
            if !d.found {
                continue;
            }
            for (k, part) in d.parts.iter().enumerate() {
                let Some(placed) = part.placed else { continue };
                let vis = verify::visibility(
                    &points,
                    &all_grid,
                    &placed,
                    params.viewpoint,
                    report.plane.as_ref(),
                    &samples[k],
                );
                if tracing::enabled!(tracing::Level::DEBUG) {
                    tracing::debug!("visibility {} {vis:?} seen {:.2}", part.name, vis.seen_ratio());
                }
                let margin = (vis.seen_ratio() - params.acceptance.min_seen) / 0.1;
                if margin < 0.0 {
                    d.found = false;
                }
                d.confidence = d.confidence.min(1.0 / (1.0 + (-4.0 * margin).exp()));
            }
            if d.found {
                accepted += 1;
            }
        }
        if accepted > 0 {
            break;
        }
    }
    report.detections = if params.all {
        // Every accepted instance that does not overlap a better one.
        let mut kept: Vec<Detection> = Vec::new();
        for d in candidates {
            if !d.found {
                continue;
            }
            let c = d.pose.translation.vector;
            if kept.iter().all(|k| (k.pose.translation.vector - c).norm() > max_size) {
                kept.push(d);
            }
        }
        kept
    } else {
        // The voting winner, unless a lower-ranked candidate passes the acceptance test and the
        // winner does not (voting is relative; acceptance is absolute).
        match candidates.iter().position(|d| d.found) {
            Some(k) => vec![candidates.swap_remove(k)],
            None => candidates.into_iter().take(1).collect(),
        }
    };
    if let Some(plane) = &report.plane {
        // Report the equivalent pose that stands on the plane (see `Symmetry::canonical_up`).
        // The symmetry search samples the model, so it is done only for a pose that leans
        // away from the plane's normal.
        let up = plane.normal;
        let mut symmetry = None;
        for d in &mut report.detections {
            if (d.pose.rotation * Vector3::z()).dot(&up) < 0.0 {
                let s = symmetry.get_or_insert_with(|| crate::symmetry::Symmetry::of(model));
                d.pose.rotation = s.canonical_up(&d.pose.rotation, &up);
            }
        }
    }
    report.timing.search_ms = search_ms;
    report.timing.verify_ms = verify_ms;
    report.timing.total_ms = ms(start);
    report
}

fn volume(s: &Superquadric) -> f64 {
    s.a[0] * s.a[1] * s.a[2]
}

/// Totally ordered key of a finite-or-infinite float for sorting.
fn ordered(v: f64) -> i64 {
    let b = v.to_bits() as i64;
    if b < 0 { b ^ i64::MAX } else { b }
}

/// The paper's three criteria: M ascending, S descending, I ascending.
fn paper_criteria(scores: &[Scores]) -> Vec<(Vec<f64>, bool)> {
    vec![
        (scores.iter().map(|s| s.m).collect(), true),
        (scores.iter().map(|s| s.s as f64).collect(), false),
        (scores.iter().map(|s| s.i as f64).collect(), true),
    ]
}

/// `m` hypotheses of one part from the given seed points, in parallel, each from its own stream.
#[allow(clippy::too_many_arguments)]
fn search_part(
    space: &SearchSpace<'_>,
    shape: &Superquadric,
    seeds: &[usize],
    m: usize,
    settings: &SearchSettings,
    open: bool,
    check: &search::PlaneCheck,
    seed: u64,
) -> Vec<Hypothesis> {
    let regions = spatial_regions(space.sub, seeds, m);
    let fits: Vec<(usize, fit::Fit)> = (0..m)
        .into_par_iter()
        .filter_map(|h| {
            let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(seed, h as u64));
            search::ransac(space, shape, &regions[h % regions.len()], settings, check, &mut rng)
        })
        .collect();
    search::distinct(fits)
        .par_iter()
        .filter_map(|f| {
            let mut h = search::refine(space, f, settings.fit_iterations);
            if open && !open_side_up(&mut h.placed, space.plane.as_ref()) {
                return None;
            }
            check.allows(space, &h.placed).then_some(h)
        })
        .collect()
}

/// An open container stands on its base: its opening (+z) must face away from the support
/// plane. An untapered part fits the same either way up, so it is turned over; a tapered one
/// the wrong way up is no container standing on the table. (A container upside down looks like
/// a closed one, a mug like a canister, and is not reported as the container.)
fn open_side_up(placed: &mut PlacedSuperquadric, plane: Option<&Plane>) -> bool {
    let Some(plane) = plane else { return true };
    let z = placed.pose.rotation * Vector3::z();
    if z.dot(&plane.normal) >= 0.0 {
        return true;
    }
    if placed.shape.is_tapered() {
        return false;
    }
    placed.pose.rotation *= UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    true
}

/// Split the seed points into `m` spatially compact regions of equal size (consecutive runs in
/// Morton order of 1 cm voxels), one for each hypothesis.
///
/// The paper draws every hypothesis' trials from the whole scene and keeps each one's best fit,
/// so the hypotheses crowd onto the few objects that fit best and a lookalike can hide the
/// object from all m of them. Its m is chosen "to cover the whole scene": giving each hypothesis
/// its own part of the scene does exactly that.
fn spatial_regions(points: &[Point3<f64>], seeds: &[usize], m: usize) -> Vec<Vec<usize>> {
    if seeds.is_empty() || m <= 1 {
        return vec![seeds.to_vec()];
    }
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
        let c = [0, 1, 2].map(|k| ((p[k] / voxel).floor() as i64 + (1 << 20)).clamp(0, (1 << 21) - 1) as u64);
        spread(c[0]) | spread(c[1]) << 1 | spread(c[2]) << 2
    };
    let mut order: Vec<(u64, usize)> = seeds.iter().map(|&i| (key(&points[i]), i)).collect();
    order.sort_unstable();
    let m = m.min(order.len());
    (0..m)
        .map(|h| {
            order[h * order.len() / m..(h + 1) * order.len() / m]
                .iter()
                .map(|&(_, i)| i)
                .collect()
        })
        .collect()
}

/// Which anchor candidate a combination grew from, its parts, and its connection errors.
type Combination = (usize, Vec<PartResult>, Vec<(f64, f64)>);

/// For each anchor candidate, search the other parts where their connections put them and list
/// every combination with its connection errors `(A, D)`.
#[allow(clippy::too_many_arguments)]
fn compound_combinations(
    space: &SearchSpace<'_>,
    model: &Model,
    anchor: usize,
    picked: &[usize],
    anchors: &[Hypothesis],
    anchor_scores: &[Scores],
    params: &Params,
    round: u64,
    samples: &[SurfaceSamples],
    checks: &[search::PlaneCheck],
) -> Vec<Combination> {
    // Visit parts breadth-first from the anchor along the connections.
    let mut visit: Vec<(usize, usize, usize)> = Vec::new(); // (part, parent part, connection)
    let mut seen = vec![false; model.parts.len()];
    seen[anchor] = true;
    let mut frontier = vec![anchor];
    while let Some(p) = frontier.pop() {
        for (ci, c) in model.connections.iter().enumerate() {
            let other = if c.parts[0] == p {
                c.parts[1]
            } else if c.parts[1] == p {
                c.parts[0]
            } else {
                continue;
            };
            if !seen[other] {
                seen[other] = true;
                visit.push((other, p, ci));
                frontier.push(other);
            }
        }
    }
    // The shell around a candidate is small: half the trials find the part there as surely as
    // all of them find it in the whole scene.
    let settings = SearchSettings {
        trials: params.trials.div_ceil(2).max(3),
        sample_points: params.sample_points,
        fit_iterations: params.fit_iterations,
    };
    let empty = |name: &str| PartResult {
        name: name.to_owned(),
        placed: None,
        scores: Scores {
            m: f64::INFINITY,
            ..Default::default()
        },
    };
    // Partial combinations: a placement (or none) per part.
    let mut partial: Vec<(usize, Vec<PartResult>)> = picked
        .iter()
        .map(|&k| {
            let mut v: Vec<PartResult> = model.parts.iter().map(|p| empty(&p.name)).collect();
            v[anchor] = PartResult {
                name: model.parts[anchor].name.clone(),
                placed: Some(anchors[k].placed),
                scores: anchor_scores[k],
            };
            (k, v)
        })
        .collect();
    for (step, &(part, parent, ci)) in visit.iter().enumerate() {
        let conn = &model.connections[ci];
        let shape = model.parts[part].shape;
        let mut next = Vec::new();
        for (pi, (origin, combo)) in partial.iter().enumerate() {
            let Some(parent_placed) = combo[parent].placed else {
                next.push((*origin, combo.clone()));
                continue;
            };
            // Seeds: subsampled points in the shell where this part's surface can be, that are
            // not on the parent part's own surface.
            let pc = Point3::from(parent_placed.pose.translation.vector);
            let reach = shape.bounding_radius();
            let band = search::refine_band(&parent_placed.shape, space.noise);
            let mut seeds = Vec::new();
            space
                .sub_grid
                .for_each_within(space.sub, &pc, conn.distance + reach, |i| {
                    let p = &space.sub[i];
                    if (p - pc).norm() >= conn.distance - reach && parent_placed.surface_distance(p).abs() > band {
                        seeds.push(i);
                    }
                });
            let m = params.local_hypotheses.max(1);
            let stream = stream_seed(params.seed, 1_000_000 * (round + 1) + (step * 100 + pi) as u64);
            let hyps = search_part(
                space,
                &shape,
                &seeds,
                m,
                &settings,
                model.parts[part].open,
                &checks[part],
                stream,
            );
            if hyps.is_empty() {
                next.push((*origin, combo.clone()));
                continue;
            }
            let scores: Vec<Scores> = hyps
                .par_iter()
                .map(|h| score(space, &h.placed, h.m, params.gamma, &samples[part]))
                .collect();
            for (h, s) in hyps.iter().zip(scores) {
                let mut c = combo.clone();
                c[part] = PartResult {
                    name: model.parts[part].name.clone(),
                    placed: Some(h.placed),
                    scores: s,
                };
                next.push((*origin, c));
            }
        }
        partial = next;
    }
    partial
        .into_iter()
        .map(|(origin, parts)| {
            let errors = model
                .connections
                .iter()
                .map(|c| connection_error(model, c, &parts))
                .collect();
            (origin, parts, errors)
        })
        .collect()
}

/// A and D of one connection (paper eq. 6, 7); infinite when a part is missing. An untapered
/// part's z axis has no sign, so its angle is compared folded.
fn connection_error(model: &Model, c: &crate::model::Connection, parts: &[PartResult]) -> (f64, f64) {
    let (Some(a), Some(b)) = (parts[c.parts[0]].placed, parts[c.parts[1]].placed) else {
        return (f64::INFINITY, f64::INFINITY);
    };
    let signed = model.parts[c.parts[0]].shape.is_tapered() && model.parts[c.parts[1]].shape.is_tapered();
    let za = a.pose.rotation * Vector3::z();
    let zb = b.pose.rotation * Vector3::z();
    let nominal = if signed {
        c.angle
    } else {
        c.angle.min(std::f64::consts::PI - c.angle)
    };
    let angle = axis_angle(&za, &zb, signed);
    let dist = (a.pose.translation.vector - b.pose.translation.vector).norm();
    ((nominal - angle).abs(), (c.distance - dist).abs())
}

/// Turn part placements into a detection: the object pose, the acceptance test, the confidence.
fn finish(
    model: &Model,
    parts: Vec<PartResult>,
    connection_errors: Vec<(f64, f64)>,
    noise: f64,
    acc: &Acceptance,
) -> Detection {
    let pose = object_pose(model, &parts);
    // Pool the measures over the parts found (a hidden part lowers coverage by its share).
    let (mut covered, mut expected_weight, mut surface, mut inside, mut ss) = (0.0, 0.0, 0usize, 0usize, 0.0);
    let mut shell = 0usize;
    for (p, r) in model.parts.iter().zip(&parts) {
        // Weight a part's coverage by its surface size.
        let w = p.shape.a[0] * p.shape.a[1] + p.shape.a[1] * p.shape.a[2] + p.shape.a[0] * p.shape.a[2];
        expected_weight += w;
        if r.placed.is_some() {
            covered += w * r.scores.coverage;
            surface += r.scores.surface_points;
            inside += r.scores.inside_points;
            shell += r.scores.shell_points;
            if r.scores.rms.is_finite() {
                ss += r.scores.rms * r.scores.rms * r.scores.surface_points as f64;
            }
        }
    }
    let coverage = covered / expected_weight.max(1e-12);
    let interior = inside as f64 / (surface as f64).max(1.0);
    let rms = if surface > 0 {
        (ss / surface as f64).sqrt()
    } else {
        f64::INFINITY
    };
    let max_rms = acc.max_rms_sigmas * noise.max(0.001);
    let mut margins = vec![
        (coverage - acc.min_coverage) / 0.15,
        (acc.max_interior_ratio - interior) / 0.1,
        (acc.max_shell_ratio - shell as f64 / (surface as f64).max(1.0)) / 0.04,
        (max_rms - rms) / (0.5 * max_rms),
    ];
    for (c, (a, d)) in model.connections.iter().zip(&connection_errors) {
        if a.is_finite() {
            margins.push((acc.max_angle_error - a) / acc.max_angle_error);
            let dmax = acc.max_distance_error * c.distance.max(0.02);
            margins.push((dmax - d) / dmax);
        }
    }
    tracing::trace!(
        "acceptance margins [coverage, interior, shell, rms, connections..] {:?}",
        margins.iter().map(|m| (m * 100.0).round() / 100.0).collect::<Vec<_>>()
    );
    let worst = margins.iter().copied().fold(f64::INFINITY, f64::min);
    let worst = if worst.is_nan() { f64::NEG_INFINITY } else { worst };
    let confidence = 1.0 / (1.0 + (-4.0 * worst).exp());
    Detection {
        found: worst >= 0.0,
        confidence,
        pose,
        parts,
        connection_errors,
    }
}

/// The object's pose from its parts' placements. The anchor part (the largest found) fixes the
/// pose up to that part's own symmetries; the other parts choose among those symmetries and, for
/// a body of revolution, fix the spin.
fn object_pose(model: &Model, parts: &[PartResult]) -> Isometry3<f64> {
    let Some(a) = (0..parts.len())
        .filter(|&k| parts[k].placed.is_some())
        .max_by(|&x, &y| volume(&model.parts[x].shape).total_cmp(&volume(&model.parts[y].shape)))
    else {
        return Isometry3::identity();
    };
    let placed = parts[a].placed.expect("filtered");
    let shape = &model.parts[a].shape;
    let anchor_in_object = model.parts[a].pose_in_object;
    let others: Vec<(Point3<f64>, Vector3<f64>)> = parts
        .iter()
        .enumerate()
        .filter(|(k, _)| *k != a)
        .filter_map(|(k, r)| {
            r.placed.map(|p| {
                // The model's centre of part k in the anchor part's frame.
                let rel = anchor_in_object.inverse() * model.parts[k].pose_in_object;
                (Point3::from(rel.translation.vector), p.pose.translation.vector)
            })
        })
        .collect();
    if others.is_empty() {
        return placed.pose * anchor_in_object.inverse();
    }
    let mut symmetries = vec![
        UnitQuaternion::identity(),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI),
    ];
    if !shape.is_tapered() {
        symmetries.push(UnitQuaternion::from_axis_angle(
            &Vector3::x_axis(),
            std::f64::consts::PI,
        ));
        symmetries.push(UnitQuaternion::from_axis_angle(
            &Vector3::y_axis(),
            std::f64::consts::PI,
        ));
    }
    let mut best = (f64::INFINITY, placed.pose);
    for g in symmetries {
        let mut part_pose = placed.pose * Isometry3::from_parts(Default::default(), g);
        if shape.is_revolution() {
            // Spin about z so the first other part's centre lands at the detected azimuth.
            let (model_c, world_c) = &others[0];
            let local = part_pose.inverse_transform_point(&Point3::from(*world_c));
            let spin = local.y.atan2(local.x) - model_c.y.atan2(model_c.x);
            if model_c.x.hypot(model_c.y) > 1e-9 && local.x.hypot(local.y) > 1e-9 {
                part_pose *= Isometry3::rotation(Vector3::z() * spin);
            }
        }
        let err: f64 = others
            .iter()
            .map(|(mc, wc)| (part_pose.transform_point(mc).coords - wc).norm_squared())
            .sum();
        if err < best.0 {
            best = (err, part_pose);
        }
    }
    best.1 * anchor_in_object.inverse()
}
