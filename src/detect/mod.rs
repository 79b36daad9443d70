//! The detector: find a known object (one to three tapered superquadrics) in a point cloud and
//! give its 6-DoF pose, as Biegelbauer & Vincze (ICRA 2007) do, then further. [`detect`] runs
//! these stages in order, each in its own module, each handing a struct to the next:
//!
//! 1. `prepare`: drop non-finite, out-of-range and wild points (`input`), remove the dominant
//!    plane ([`plane`](crate::cloud::plane)), which also gives the noise estimate, and subsample
//!    and grid the rest ([`grid`](crate::cloud::grid)) -> `Prepared`;
//! 2. `anchor`: the largest part searched over the whole scene by the hierarchical search
//!    ([`search`]: RANSAC trials on subsampled points with LM pose fits ([`fit`]), with poses
//!    resting on the support plane that its seen walls place ([`rest`]), the best of each
//!    hypothesis refined on a denser subsample), its hypotheses scored and ranked by the
//!    paper's voting over M, S and I ([`verify`]) -> `Anchors`;
//! 3. `compound`: every other part placed where the model puts it against an already-found part
//!    (at every spin about that part's axis) and searched by a few RANSAC trials in the shell its
//!    connection leaves, the combinations ranked by the connection errors A and D together with
//!    the parts' M, S and I, the best of each anchor candidate refined as one rigid object
//!    ([`rigid`]);
//! 4. `accept`: coverage of the visible surface, interior points and fit decide whether a
//!    candidate is the object at all ("not here"), with a confidence in [0, 1]; the candidates
//!    that may be reported are checked against the free space the sensor saw through;
//! 5. `select`: the best candidate, or with `all` every accepted one that does not overlap a
//!    better one, in the pose that stands on the plane.
//!
//! A caller that has the cloud's colours and a model that keeps its object's then runs
//! [`check_colour`]: what the geometry found must also look like the object.
//!
//! When a round of search finds nothing acceptable, stages 2 to 4 run once more with fresh seeds.
//! Every random choice comes from `Params::seed`; hypotheses run in parallel but each draws from
//! its own stream, so the answer does not depend on the number of threads. With `SQSCAN_LOG=debug`
//! every stage logs what it found through the `Display` impls of its results.

mod accept;
mod anchor;
mod base;
mod colour;
mod compound;
mod fit;
mod input;
pub mod output;
mod params;
mod plane_check;
mod prepare;
mod refine;
mod report;
mod rest;
mod rigid;
mod search;
mod select;
mod shell;
mod space;
mod support;
mod verify;
mod visibility;

pub use colour::{check_colour, detect_all_checked, detect_checked};
pub use fit::{Fit, fit_pose, fit_pose_tol, measure_of_fit};
pub use params::{Acceptance, Params};
pub use prepare::Scene;
use report::ms;
pub use report::{Detection, PartResult, Report, Timing};

use crate::model::Model;
use anchor::AnchorPart;
use std::time::Instant;

/// Rounds of search at most. A second round with fresh seeds runs when the first finds nothing
/// acceptable, and refines and scores only the places the first did not reach: "not here" costs
/// a second round of trials, a found object costs no more, and a search that missed the object
/// in one round rarely misses it in two.
const SEARCH_ROUNDS: u64 = 2;

/// Fewer points than this off the plane hold nothing to fit.
const MIN_SCENE_POINTS: usize = 10;

/// Detect `model` in `cloud` (finite and non-finite points; non-finite are skipped).
pub fn detect(cloud: &[[f32; 3]], model: &Model, params: &Params) -> Report {
    on_pool(|| {
        let t = Instant::now();
        let scene = std::sync::Arc::new(scene(cloud, params));
        detect_in(&scene, model, params, ms(t))
    })
}

/// Run `f` on a thread of rayon's pool (at once, when called on one). Each parallel stage of
/// a detection then shares its work with the pool's other threads directly; called from
/// another thread, every stage would hand its work to the pool and wait to be woken, a dozen
/// times a detection.
fn on_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::scope(|_| f())
}

/// The cloud filtered and its support plane removed, as [`detect_in`] takes it: made once, it
/// serves the detections of any number of objects with the same viewpoint, range cut and plane
/// setting (`params.viewpoint`, `max_range`, `remove_plane`; the rest is not looked at).
pub fn scene(cloud: &[[f32; 3]], params: &Params) -> Scene {
    on_pool(|| prepare::scene(cloud, params))
}

/// [`detect`] on a prepared [`scene`]; `plane_ms` is what the scene cost this detection (0 for
/// one made before), reported as the plane's time.
pub fn detect_in(scene: &std::sync::Arc<Scene>, model: &Model, params: &Params, plane_ms: f64) -> Report {
    on_pool(|| detect_on_pool(scene, model, params, plane_ms))
}

fn detect_on_pool(scene: &std::sync::Arc<Scene>, model: &Model, params: &Params, plane_ms: f64) -> Report {
    let start = Instant::now();
    let mut timing = Timing {
        plane_ms,
        ..Timing::default()
    };
    let scene = scene.clone();
    let mut report = Report {
        object: model.name.clone(),
        detections: Vec::new(),
        plane: scene.plane,
        points: scene.input_points,
        scene_points: scene.objects.len(),
        timing,
    };
    if scene.objects.len() < MIN_SCENE_POINTS {
        report.timing.total_ms = plane_ms + ms(start);
        return report;
    }
    let t = Instant::now();
    let prep = prepare::index(scene, model, params);
    let anchor = AnchorPart::choose(model, params, &prep.scene.objects);
    timing.search_ms += ms(t);
    let mut candidates: Vec<Detection> = Vec::new();
    let mut searched: Vec<crate::geometry::PlacedSuperquadric> = Vec::new();
    for round in 0..SEARCH_ROUNDS {
        let t = Instant::now();
        let found = anchor::search(&prep, model, &anchor, params, round, &searched);
        searched.extend(found.hypotheses.iter().map(|h| h.placed));
        timing.search_ms += ms(t);
        let t = Instant::now();
        let mut anchors = anchor::rank(&prep, &anchor, found, params.gamma);
        timing.verify_ms += ms(t);
        let first_new = candidates.len();
        // How many of the new candidates have been through the free-space check already.
        let checked = if model.is_compound() {
            let t = Instant::now();
            let picked = compound::pick(&prep, model, &mut anchors, params);
            timing.search_ms += ms(t);
            let (found, checked) =
                compound::round_candidates(&prep, model, &anchors, &picked, params, round, &mut timing);
            candidates.extend(found);
            checked
        } else {
            let t = Instant::now();
            let (found, checked) = anchors.single_part_candidates(&prep, model, params);
            candidates.extend(found);
            timing.verify_ms += ms(t);
            checked
        };
        let t = Instant::now();
        let accepted = accept::free_space(&prep, &mut candidates, first_new, checked, params);
        timing.verify_ms += ms(t);
        if accepted > 0 {
            break;
        }
    }
    if let Some(plane) = &report.plane {
        select::flag_upright(&mut candidates, model, plane);
    }
    report.detections = select::select(candidates, params.all, params.overlapping, prep.max_size);
    if let Some(plane) = &report.plane {
        select::stand_on_plane(&mut report.detections, model, plane);
    }
    timing.total_ms = plane_ms + ms(start);
    report.timing = timing;
    report
}
