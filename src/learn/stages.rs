//! The stages of the single-part fit (from the starts of `starts.rs`): A (visible points), A2 and B (free space), C (the
//! mirrored twins, along the rays), D (the smallest equally good shape), E (along the rays again).

use super::family::{FamilyResult, canonicalise, choose_family, is_open, volume};
use super::params::{Cost, LearnError, LearnParams, MIN_POINTS, Recovered, ShapeFamily};
use super::residual::{Problem, Rays, score, turn_half};
use super::robust::robust_fit;
use super::seen::{Seen, drop_rays_through_top, free_space_within, open_top_of_points, unseen_top};
use super::segment::{MERGE_GAP, clusters, remove_stray_points, subsample, with_nearby_clusters};
use super::starts::{moments, starts};
use super::state::State;
use super::{prism, profile};
use crate::cloud::plane::Plane;
use crate::numeric::{huber, median};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// The inlier threshold of the statistics of a shape from the outer wall's profile (m).
const PROFILE_DELTA: f64 = 0.003;

/// The Huber threshold never falls below this (m): the noise floor of the sensors learned from.
const MIN_DELTA: f64 = 0.001;

/// A start after a stage: its name, where it converged, and its score on the stage's problem.
#[derive(Debug, Clone)]
pub(super) struct Scored {
    pub(super) name: String,
    pub(super) state: State,
    pub(super) score: f64,
}

/// Recover one superquadric from the points of a single view. `plane`: the surface the object
/// stands on (normal towards the object), `up`: the up direction when there is no plane.
pub fn fit_superquadric(
    all_points: &[Point3<f64>],
    free_points: &[Point3<f64>],
    plane: Option<&Plane>,
    params: &LearnParams,
) -> Result<Recovered, LearnError> {
    let points = object_points(all_points, plane, params)?;
    let up = plane
        .map(|p| p.normal)
        .or(params.up.and_then(|u| u.try_normalize(1e-12)));
    let support = if params.support {
        plane.map(|p| (*p, (points.len() as f64 / 4.0).sqrt()))
    } else {
        None
    };
    let (centroid, axes) = moments(&points);
    let starts = starts(&points, &centroid, &axes, up.as_ref(), params);
    // Stage A: the visible points (and the support plane) decide the centre: the mirrored points
    // cannot, since their union with the visible ones is symmetric about whatever centre they
    // were mirrored through.
    let problem_visible = Problem {
        points: &points,
        free: &[],
        support,
        cost: params.cost,
        volume: None,
        seen: None,
        rays: None,
        fix_taper: false,
    };
    // Stage A1: every start on the visible points (and the support plane), each scored once on
    // them: for the open top's judgement and for the distinct ones stage A2 refits.
    let results = refit_scored(starts, Some(&problem_visible), (4, 25), MIN_DELTA, &problem_visible);
    let upright = best_upright(&results, up.as_ref(), params);
    let open_top = judge_open_top(&points, plane, up.as_ref(), upright.as_ref(), params);
    if let Some(r) = measured(&points, plane, open_top, up.as_ref(), params) {
        return Ok(r);
    }
    // The free space, for the stages from here on (the measurements above need none).
    let free = free_space(&points, free_points, &centroid, plane, params);
    let free: Vec<Point3<f64>> = match (open_top, upright) {
        (true, Some(s)) => drop_rays_through_top(&free, &s.placed()),
        _ => free,
    };
    // What faced the sensor must have been seen (from stage A2 on: the starts are rough); an
    // open top is not surface.
    let seen = params.viewpoint.map(|v| Seen::new(v, &points, plane, open_top));
    let problem_free = Problem {
        points: &points,
        free: &free,
        support,
        cost: params.cost,
        volume: None,
        seen: seen.as_ref(),
        rays: None,
        fix_taper: false,
    };
    // Most starts converge to the same fit (they differ in exponents and tapers that the
    // visible points settle): the best of each is refitted.
    let results = distinct(results, usize::MAX);
    tracing::debug!("{} distinct starts after stage A1", results.len());
    let results = refit_with_thinned_free_space(results, &problem_free);
    let ctx = Context {
        points: &points,
        up,
        open_top,
        params,
        problem_free: &problem_free,
        problem_visible: &problem_visible,
    };
    // Stages B and C for each family (general, revolution), then the choice between them.
    let finals: Vec<FamilyResult> = [false, true]
        .into_par_iter()
        .filter_map(|family| fit_family(&ctx, &results, family))
        .collect();
    let FamilyResult {
        name,
        state: best,
        delta,
        fitted,
        mirror_at,
        ..
    } = choose_family(finals);
    let best = smallest_along_rays(&ctx, &fitted, best, mirror_at);
    Ok(recovered(&points, best, delta, name, open_top, up.as_ref(), params))
}

/// The best of the stage A1 fits standing upright (z along `up`), of the general family unless
/// a body of revolution was asked for: an open container's top is judged on it. The visible
/// points alone (a bowl's inner and outer wall) may be fitted better by a shape lying on its
/// side, whose top says nothing of the object's; and a body of revolution about a wrong axis
/// fitted to them can be a disc as wide as the view, which would take the free space with it.
fn best_upright(results: &[Scored], up: Option<&Vector3<f64>>, params: &LearnParams) -> Option<State> {
    results
        .iter()
        .filter(|r| !r.state.rev || params.shape == ShapeFamily::Revolution)
        .filter(|r| up.is_some_and(|u| (r.state.rot * Vector3::z()).dot(u).abs() > 0.9))
        .min_by(|a, b| a.score.total_cmp(&b.score))
        .map(|r| r.state)
}

/// Whether the object is an open container: the sensor is above its top but sees nothing on
/// it, so it is seen into, and rays through its opening are not free space.
fn judge_open_top(
    points: &[Point3<f64>],
    plane: Option<&Plane>,
    up: Option<&Vector3<f64>>,
    upright: Option<&State>,
    params: &LearnParams,
) -> bool {
    let open_top = match (params.viewpoint, up, upright, plane) {
        (Some(v), _, _, Some(pl)) => open_top_of_points(points, pl, &v).unwrap_or(false),
        (Some(v), Some(u), Some(s), None) => unseen_top(&s.placed(), points, &v, u),
        _ => false,
    };
    if let Some(s) = upright {
        let c = s.placed().pose.translation.vector;
        tracing::debug!(
            "open top: {open_top} (judged on the upright fit {} at ({:.3}, {:.3}, {:.3}))",
            s.shape(),
            c.x,
            c.y,
            c.z
        );
    } else {
        tracing::debug!("open top: {open_top} (no upright fit)");
    }
    open_top
}

/// The shape measured instead of fitted, where the view allows: an open container standing
/// upright from its outer wall's profile (a vessel, a body of revolution; the closed shape
/// fitted to both of its walls comes out too small, see `profile.rs`), a closed object
/// standing on the plane with its top in view from its top's outline (the fit fills the hidden
/// back coarsely, see `prism.rs`).
fn measured(
    points: &[Point3<f64>],
    plane: Option<&Plane>,
    open_top: bool,
    up: Option<&Vector3<f64>>,
    params: &LearnParams,
) -> Option<Recovered> {
    let (Some(pl), Some(v)) = (plane, params.viewpoint) else {
        return None;
    };
    let round_allowed = params.shape != ShapeFamily::General;
    if open_top
        && round_allowed
        && let Some(measured) = profile::measure(points, pl, &v)
        && let Some((shape, rms)) = profile::fit(&measured)
    {
        tracing::debug!("outer wall profile fit: rms {:.2} mm, {shape}", rms * 1e3);
        let s = profile::state(&measured, &shape, pl);
        let name = "outer wall profile".to_string();
        return Some(recovered(points, s, PROFILE_DELTA, name, true, up, params));
    }
    if open_top || !params.measure_top {
        return None;
    }
    match prism::measure(points, pl, &v) {
        Ok(p) if p.round || params.shape != ShapeFamily::Revolution => {
            tracing::debug!("measured from the top: {p}");
            let s = prism::state(&p, pl);
            let name = "top outline".to_string();
            // Closed by what the top showed: the walls' points seen at a grazing angle past
            // the outline's edge face away from the sensor, which would read as an inside.
            let mut r = recovered(points, s, PROFILE_DELTA, name, false, up, params);
            r.open = false;
            Some(r)
        }
        Ok(p) => {
            tracing::debug!("the top is not round, a body of revolution was asked for: fitted ({p})");
            None
        }
        Err(why) => {
            tracing::debug!("not measured from the top: {why}");
            None
        }
    }
}

/// Stage D: the smallest shape as good as the chosen one, on the points of stage C (`fitted`,
/// with their mirrored twins: the hidden half of a can is the twin of its front, not free to
/// shrink). Stage E: that shape refitted along the rays again, its taper held. Stage D's
/// distance to the nearest surface rounds the edges again (a lying shaft's e1 0.21 for 0.1);
/// D's size term along the rays would shrink an open bowl's rim away from the points on its
/// inside, whose rays cannot read it. The taper and the size of a bowl's hidden lower half
/// trade against each other freely along the rays (a = 51 mm, k 0.65 for 60 mm, 0.3 from one
/// sweep, seed 7): D chose between them, E keeps that.
fn smallest_along_rays(
    ctx: &Context,
    fitted: &[Point3<f64>],
    best: State,
    mirror_at: Option<(Vector3<f64>, Vector3<f64>)>,
) -> State {
    let problem_fitted = Problem {
        points: fitted,
        ..*ctx.problem_free
    };
    let best = smallest_equally_good(&problem_fitted, best, MIN_DELTA);
    match ctx.rays(mirror_at) {
        Some(r) => {
            let problem = Problem {
                rays: Some(r),
                fix_taper: true,
                ..problem_fitted
            };
            let (s, _) = robust_fit(&problem, best, 3, 30, MIN_DELTA);
            tracing::debug!("stage E along the rays: {}", s.shape());
            s
        }
        None => best,
    }
}

/// The points to fit: strays removed, the largest cluster with what lies next to it seen from
/// above, subsampled.
fn object_points(
    all_points: &[Point3<f64>],
    plane: Option<&Plane>,
    params: &LearnParams,
) -> Result<Vec<Point3<f64>>, LearnError> {
    if all_points.len() < MIN_POINTS {
        return Err(LearnError::TooFewPoints(all_points.len()));
    }
    // Strays: isolated points, then everything not connected to the largest cluster or next to
    // it seen from above (a few stereo outliers 25 cm behind a can are a cluster of their own).
    let kept = remove_stray_points(all_points, 0.01, 4);
    let idx: Vec<usize> = (0..kept.len()).collect();
    let found = clusters(&kept, &idx, 0.01);
    let kept: Vec<Point3<f64>> = if found.is_empty() {
        Vec::new()
    } else {
        // With the clusters next to it seen from above (an open container's inside).
        with_nearby_clusters(&kept, &found, 0, MERGE_GAP, plane)
            .into_iter()
            .map(|i| kept[i])
            .collect()
    };
    tracing::debug!(
        "object points: {} given, {} after strays, {} in the cluster",
        all_points.len(),
        idx.len(),
        kept.len()
    );
    if kept.len() < MIN_POINTS {
        return Err(LearnError::TooFewPoints(kept.len()));
    }
    Ok(subsample(&kept, params.max_points))
}

/// Free space: the sensor saw the scene beyond the object along rays that pass by it, so the
/// surface must not cross them. Without this nothing stops the hidden back of a flat top (a
/// cylinder's disc, a book's cover) from growing: the points on a face say where its plane
/// is, not where it ends. Samples around the points' bounding sphere, the same for every start.
fn free_space(
    points: &[Point3<f64>],
    free_points: &[Point3<f64>],
    centroid: &Vector3<f64>,
    plane: Option<&Plane>,
    params: &LearnParams,
) -> Vec<Point3<f64>> {
    let extent = points.iter().map(|p| (p.coords - centroid).norm()).fold(0.0, f64::max);
    free_space_within(points, free_points, centroid, 1.5 * extent, plane, params)
}

/// The best of each group of results that converged to the same fit ([`same_fit`], within a
/// family), best first, at most `limit`.
fn distinct(mut scored: Vec<Scored>, limit: usize) -> Vec<Scored> {
    scored.sort_by(|a, b| a.score.total_cmp(&b.score));
    let mut kept: Vec<Scored> = Vec::new();
    for r in scored {
        if kept.len() < limit
            && !kept
                .iter()
                .any(|k| k.state.rev == r.state.rev && same_fit(&k.state, &r.state))
        {
            kept.push(r);
        }
    }
    kept
}

/// Stage A2: every start again with a thinned free space (at most 1500 samples), which is
/// what keeps a start from keeping a skirt or a back where the sensor saw through. Scored on
/// all of the free space.
fn refit_with_thinned_free_space(results: Vec<Scored>, problem_free: &Problem) -> Vec<Scored> {
    let free = problem_free.free;
    let coarse: Vec<Point3<f64>> = free.iter().step_by(free.len().div_ceil(1500).max(1)).copied().collect();
    let problem_coarse = Problem {
        free: &coarse,
        ..*problem_free
    };
    let results = refit_scored(
        results.into_iter().map(|r| (r.name, r.state)).collect(),
        (!coarse.is_empty()).then_some(&problem_coarse),
        (2, 20),
        MIN_DELTA,
        problem_free,
    );
    for r in &results {
        tracing::debug!(
            "start {}: score {:.6} {} t {:?}",
            r.name,
            r.score,
            r.state.shape(),
            r.state.t.as_slice()
        );
    }
    results
}

/// What stages B to E share.
struct Context<'a> {
    /// The visible points.
    points: &'a [Point3<f64>],
    up: Option<Vector3<f64>>,
    open_top: bool,
    params: &'a LearnParams,
    /// The visible points with the free space, the support and the seen surface.
    problem_free: &'a Problem<'a>,
    /// The visible points with the support only.
    problem_visible: &'a Problem<'a>,
}

impl Context<'_> {
    /// From stage C on the visible points take the distance along their rays, and their twins
    /// (mirrored through the vertical axis at `mirror`) the distance along the mirrored rays:
    /// the view a sensor at the mirrored viewpoint would have had. Only with the twins: the
    /// distance along a ray reads where the ray enters the surface and nothing behind it, so
    /// without them (no up direction) nothing holds the hidden back half.
    fn rays(&self, mirror: Option<(Vector3<f64>, Vector3<f64>)>) -> Option<Rays> {
        let v = self.params.viewpoint.filter(|_| self.params.along_rays)?;
        let (c, u) = mirror?;
        Some(Rays {
            viewpoint: v,
            seen: self.points.len(),
            twin_viewpoint: turn_half(&v, &c, &u),
            open: self.open_top,
        })
    }
}

/// Stages B and C for one family (`rev`: bodies of revolution, else general shapes); `None`
/// when no start of the family is left.
fn fit_family(ctx: &Context, results: &[Scored], rev: bool) -> Option<FamilyResult> {
    let (points, params, problem_free) = (ctx.points, ctx.params, ctx.problem_free);
    // Stage B: the best three starts again with all of the free space.
    // Three distinct ones: starts that converged to the same shape count once.
    let three = distinct(results.iter().filter(|r| r.state.rev == rev).cloned().collect(), 3);
    let free = problem_free.free;
    let results = refit_scored(
        three.into_iter().map(|r| (r.name, r.state)).collect(),
        (!free.is_empty()).then_some(problem_free),
        (3, 40),
        MIN_DELTA,
        problem_free,
    );
    for r in &results {
        tracing::debug!(
            "stage B {} ({} free samples): score {:.6} {} t {:?}",
            r.name,
            free.len(),
            r.score,
            r.state.shape(),
            r.state.t.as_slice()
        );
    }
    // Of the results as good as the best (within SMALLEST_TOLERANCE), the smallest: one view
    // cannot tell a ball from an egg pointing at the sensor, and the mirror of stage C
    // would fix the egg's centre, pushed back, for good.
    let top = results.iter().map(|r| r.score).min_by(f64::total_cmp)?;
    let Scored { name, state: best, .. } = results
        .into_iter()
        .filter(|r| r.score <= top * (1.0 + SMALLEST_TOLERANCE))
        .min_by(|a, b| volume(&a.state.shape()).total_cmp(&volume(&b.state.shape())))
        .expect("the best is within its own tolerance");
    // Stage C: the visible points plus their twins turned 180 degrees about the vertical
    // axis through the stage-B centre (fixed), which fixes the hidden back half.
    let mirror_at = match (params.mirror, ctx.up) {
        (true, Some(u)) => Some((best.t, u)),
        _ => None,
    };
    let (best, delta, fitted) = match mirror_at {
        Some((c, u)) => {
            let mut both = points.to_vec();
            both.extend(points.iter().map(|p| turn_half(p, &c, &u)));
            let problem = Problem {
                points: &both,
                rays: ctx.rays(mirror_at),
                ..*problem_free
            };
            let (s, d) = robust_fit(&problem, best, 3, 40, MIN_DELTA);
            (s, d, both)
        }
        None => {
            let (s, d) = robust_fit(ctx.problem_visible, best, 2, 40, MIN_DELTA);
            (s, d, points.to_vec())
        }
    };
    // The families are compared on the points of stage C (with their twins) by the
    // first-order distance along the normal (the better approximation of the true distance,
    // so of the likelihood), whatever the fit minimised: the radial distance's bias on flat
    // parts is what the general family's extra freedom otherwise wins on. With the rays, the
    // distance along them.
    let sc = score(
        &Problem {
            cost: Cost::Normal,
            rays: ctx.rays(mirror_at),
            points: &fitted,
            ..*problem_free
        },
        &best,
    );
    if tracing::enabled!(tracing::Level::DEBUG) {
        let mut r = Vec::new();
        problem_free.residuals(&best, &mut r);
        let np = points.len();
        let part = |a: usize, b: usize| r[a..b].iter().map(|v| huber(*v, 0.003)).sum::<f64>();
        tracing::debug!(
            "stage C {name}: score {sc:.6} (points {:.6}, free {:.6}, rest {:.6}) {}",
            part(0, np),
            part(np, np + free.len()),
            part(np + free.len(), r.len()),
            best.shape()
        );
    }
    Some(FamilyResult {
        name,
        state: best,
        delta,
        score: sc,
        fitted,
        mirror_at,
    })
}

/// The result: the fit's residual statistics over the visible points, open or closed, in
/// canonical axes.
fn recovered(
    points: &[Point3<f64>],
    best: State,
    delta: f64,
    start: String,
    open_top: bool,
    up: Option<&Vector3<f64>>,
    params: &LearnParams,
) -> Recovered {
    let mut r = Vec::new();
    let vis = Problem {
        points,
        free: &[],
        support: None,
        cost: params.cost,
        volume: None,
        seen: None,
        rays: None,
        fix_taper: false,
    };
    vis.residuals(&best, &mut r);
    let inliers: Vec<f64> = r.iter().copied().filter(|v| v.abs() <= delta).collect();
    let rms = (inliers.iter().map(|v| v * v).sum::<f64>() / inliers.len().max(1) as f64).sqrt();
    let mut abs: Vec<f64> = r.iter().map(|v| v.abs()).collect();
    let median_abs = median(&mut abs).unwrap_or(0.0);
    let mut placed = best.placed();
    let open = open_top || is_open(&placed, points, params.viewpoint.as_ref());
    canonicalise(&mut placed, up);
    Recovered {
        placed,
        rms,
        median_abs,
        inlier_share: inliers.len() as f64 / r.len().max(1) as f64,
        fitted_points: points.len(),
        open,
        start,
    }
}

/// The smallest shape (by volume) whose score stays within this share of the best fit's.
pub(super) const SMALLEST_TOLERANCE: f64 = 0.03;

/// What one view leaves hidden (a bowl's foot under its rim, the far side of a wall) any shape
/// that explains the view may fill in; of those, the smallest is the one a detector can rely on
/// (its seen parts are where the data put them) and the likeliest (an object has no more
/// material than it must). LM with a growing size term, keeping the last result whose score
/// (points, free space, support, seen surface; no size term) is within [`SMALLEST_TOLERANCE`] of
/// the start's.
pub(super) fn smallest_equally_good(problem: &Problem, best: State, min_delta: f64) -> State {
    let base = score(problem, &best);
    let v0 = volume(&best.shape());
    let n = problem.points.len() as f64;
    let mut kept = best;
    for w in [0.5, 1.0, 2.0, 4.0, 8.0, 16.0] {
        let shrinking = Problem {
            volume: Some((w * n.sqrt() * 1e-3, v0)),
            ..*problem
        };
        let s = robust_fit(&shrinking, kept, 2, 30, min_delta).0;
        let sc = score(problem, &s);
        if tracing::enabled!(tracing::Level::DEBUG) {
            let mut r = Vec::new();
            problem.residuals(&s, &mut r);
            let (np, nf) = (problem.points.len(), problem.free.len());
            let part = |a: usize, b: usize| r[a..b].iter().map(|v| huber(*v, 0.003)).sum::<f64>();
            tracing::debug!(
                "smallest w {w}: score {sc:.6} (base {base:.6}; points {:.6}, free {:.6}, rest {:.6}) {} t {:?}",
                part(0, np),
                part(np, np + nf),
                part(np + nf, r.len()),
                s.shape(),
                s.t.as_slice()
            );
        }
        if sc > base * (1.0 + SMALLEST_TOLERANCE) {
            break;
        }
        kept = s;
    }
    kept
}

/// Every start refitted on `fit` (when there is one to refit on: without free space a stage
/// adds nothing) with `(rounds, iterations)` of [`robust_fit`], in parallel, and scored on
/// `scored`.
pub(super) fn refit_scored(
    starts: Vec<(String, State)>,
    fit: Option<&Problem>,
    (rounds, iterations): (usize, usize),
    min_delta: f64,
    scored: &Problem,
) -> Vec<Scored> {
    starts
        .into_par_iter()
        .map(|(name, s0)| {
            let state = match fit {
                Some(p) => robust_fit(p, s0, rounds, iterations, min_delta).0,
                None => s0,
            };
            let score = score(scored, &state);
            Scored { name, state, score }
        })
        .collect()
}

/// Two fits that are the same shape in the same place (2 mm, 5 %, 8 degrees between the z axes).
pub(super) fn same_fit(a: &State, b: &State) -> bool {
    let (za, zb) = (a.rot * Vector3::z(), b.rot * Vector3::z());
    (a.t - b.t).norm() < 0.002 && (0..3).all(|k| (a.ln_a[k] - b.ln_a[k]).abs() < 0.05) && za.dot(&zb).abs() > 0.99
}
