//! The acceptance stage. Ranked voting always names a winner; whether a candidate is the object
//! at all ("not here") is judged on measures that do not depend on the other candidates: the
//! coverage of its visible surface, the points inside it and just outside it, its fit against
//! the noise and, for a compound, its connection errors. The candidates that pass, and may be
//! reported, are then checked against the free space the sensor saw through.

use super::prepare::Prepared;
use super::report::{Detection, PartResult};
use super::space::RangeNoise;
use super::visibility;
use super::{Acceptance, Params};
use crate::model::Model;
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use rayon::prelude::*;
use std::fmt;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// How far (m) the middle of a vessel's base must lie below its foot ring for a container
/// standing on its rim to be told from a closed part of its shape. Ceramic mugs and bowls stand
/// on a ring a few millimetres proud of the middle; lids and can tops are flat or domed.
pub const MIN_BASE_RECESS: f64 = 0.0015;

/// Points of a level surface around the base of an object raised above the support plane that
/// let it rest there: the top of a box, a book or a tin it stands on, seen beside its foot. An
/// object does not float; a model lifted off the table onto the upper part of a larger
/// object's walls (a thin box's model on a thick box lying flat, its top on the thick box's top)
/// has nothing level under it, only the larger object's walls going on down.
pub const MIN_RESTING_ON: f64 = 10.0;

/// Turn part placements into a detection: the object pose, the acceptance test, the confidence.
pub fn assess(
    model: &Model,
    parts: Vec<PartResult>,
    connection_errors: Vec<(f64, f64)>,
    noise: &RangeNoise,
    acc: &Acceptance,
) -> Detection {
    let pose = object_pose(model, &parts);
    // The fit is judged against the sensor's noise where the object is.
    let noise = noise.at(&Point3::from(pose.translation.vector));
    // Pool the measures over the parts found (a hidden part lowers coverage by its share).
    let (mut covered, mut expected_weight, mut surface, mut inside, mut ss) = (0.0, 0.0, 0usize, 0usize, 0.0);
    let mut shell = 0usize;
    let mut continued = 0usize;
    let mut faces = f64::INFINITY;
    let mut base_recess: Option<f64> = None;
    // What the raised parts may rest on (the most any of them has); the object rests on the
    // plane when any of its parts does.
    let mut resting_on: Option<usize> = None;
    let mut on_plane = false;
    for (p, r) in model.parts.iter().zip(&parts) {
        // Weight a part's coverage by its surface size.
        let w = p.shape.a[0] * p.shape.a[1] + p.shape.a[1] * p.shape.a[2] + p.shape.a[0] * p.shape.a[2];
        expected_weight += w;
        if r.placed.is_some() {
            covered += w * r.scores.coverage;
            surface += r.scores.surface_points;
            inside += r.scores.inside_points;
            shell += r.scores.shell_points;
            continued += r.scores.continued_points;
            faces = faces.min(r.scores.faces);
            match r.scores.raised {
                Some((_, n)) => resting_on = resting_on.max(Some(n)),
                None => on_plane = true,
            }
            if let Some(b) = r.scores.base_recess {
                base_recess = Some(base_recess.map_or(b, |x: f64| x.min(b)));
            }
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
        // A round wall that two flat faces explain better is a box's edge.
        (faces - 1.0) / 0.3,
        (acc.max_continued_ratio - continued as f64 / (surface as f64).max(1.0)) / 0.05,
    ];
    // A container on its rim shows only its outside and its base, and only a vessel's base (its
    // middle raised inside a foot ring) tells it from a closed can or a lidded canister.
    if let Some(b) = base_recess {
        margins.push((b - MIN_BASE_RECESS) / MIN_BASE_RECESS);
    }
    if let Some(n) = resting_on.filter(|_| !on_plane && !model.held) {
        margins.push((n as f64 - MIN_RESTING_ON) / MIN_RESTING_ON);
    }
    margins.extend(connection_margins(model, &connection_errors, acc));
    let t = pose.translation.vector;
    tracing::trace!("at ({:.3} {:.3} {:.3}) {}", t.x, t.y, t.z, Margins(&margins));
    let worst = margins.iter().copied().fold(f64::INFINITY, f64::min);
    let worst = if worst.is_nan() { f64::NEG_INFINITY } else { worst };
    let confidence = 1.0 / (1.0 + (-4.0 * worst).exp());
    // Short of coverage alone: the surface missing may be hidden by what stands in front.
    let others = margins[1..].iter().copied().fold(f64::INFINITY, f64::min);
    // (Not a compound missing a part: nothing says that part is hidden.)
    let all_placed = parts.iter().all(|p| p.placed.is_some());
    let short_of_coverage =
        (worst < 0.0 && others >= 0.0 && all_placed && coverage >= acc.min_coverage_hidden).then_some(others);
    Detection {
        found: worst >= 0.0,
        confidence,
        pose,
        parts,
        connection_errors,
        upright: None,
        short_of_coverage,
        colour: None,
    }
}

/// The margins of the angle and the distance error of each connection whose parts were both
/// found (a missing part's errors are infinite, and its absence already lowers the coverage).
fn connection_margins<'a>(
    model: &'a Model,
    connection_errors: &'a [(f64, f64)],
    acc: &'a Acceptance,
) -> impl Iterator<Item = f64> + 'a {
    model
        .connections
        .iter()
        .zip(connection_errors)
        .filter(|(_, (a, _))| a.is_finite())
        .flat_map(|(c, &(a, d))| {
            let dmax = acc.max_distance_error * c.distance.max(0.02);
            [(acc.max_angle_error - a) / acc.max_angle_error, (dmax - d) / dmax]
        })
}

/// Whether every part of a combination was found and every connection between them, as found,
/// is within the acceptance test's bounds.
pub fn connections_hold(model: &Model, connection_errors: &[(f64, f64)], acc: &Acceptance) -> bool {
    connection_errors.iter().all(|(a, _)| a.is_finite())
        && connection_margins(model, connection_errors, acc).all(|m| m >= 0.0)
}

/// Each measure's margin to its threshold in units of its scale (negative: the test fails):
/// `acceptance margins [coverage, interior, shell, rms, faces, continued, (base,) (resting,) connections..] [..]`.
struct Margins<'a>(&'a [f64]);

impl fmt::Display for Margins<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(
            "acceptance margins [coverage, interior, shell, rms, faces, continued, (base,) (resting,) connections..] [",
        )?;
        for (k, m) in self.0.iter().enumerate() {
            if k > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{m:.2}")?;
        }
        f.write_str("]")
    }
}

/// The free-space check of the candidates from `first_new` on that the acceptance test passed:
/// a part where the sensor saw through it is not there. Only the candidates that may be reported
/// are checked (it is the most expensive test per candidate, and most candidates fail cheaper
/// ones first): the first that passes, or with `Params::all` every one. The first `checked` of
/// them have been through it already ([`check_free_space`]). Returns how many candidates are
/// accepted in all.
pub fn free_space(
    prep: &Prepared,
    candidates: &mut [Detection],
    first_new: usize,
    checked: usize,
    params: &Params,
) -> usize {
    let limit = if params.all { usize::MAX } else { 1 };
    let mut accepted = candidates[..first_new].iter().filter(|d| d.found).count();
    for (i, d) in candidates[first_new..].iter_mut().enumerate() {
        if accepted >= limit {
            break;
        }
        if !d.found && d.short_of_coverage.is_none() {
            continue;
        }
        if i >= checked {
            check_free_space(prep, d, params);
        }
        if d.found {
            accepted += 1;
        }
    }
    accepted
}

/// Judge candidates in the order the answer is chosen in: `make` gives each item's candidate
/// (with a value the caller keeps). With `lazy`, a candidate that passes the acceptance test is
/// checked against the free space on the same thread, and the judging stops at the first that
/// passes both: a later one could not change the answer. Each thread takes the next item in the
/// order as soon as it is free (candidates cost several times more or less than each other), and
/// none takes one past an item that has passed. Without `lazy`, every item is made, all side by
/// side. Returns what was made, in order, up to the first that passed, and whether one did.
pub fn judge_in_order<T: Sync, R: Send>(
    prep: &Prepared,
    params: &Params,
    items: &[T],
    lazy: bool,
    make: impl Fn(&T) -> (R, Detection) + Sync,
) -> (Vec<(R, Detection)>, bool) {
    if !lazy {
        return (items.par_iter().map(&make).collect(), false);
    }
    let next = AtomicUsize::new(0);
    let first_passed = AtomicUsize::new(usize::MAX);
    let made: Vec<Mutex<Option<(R, Detection)>>> = items.iter().map(|_| Mutex::new(None)).collect();
    let threads = rayon::current_num_threads().min(items.len()).max(1);
    (0..threads).into_par_iter().with_max_len(1).for_each(|_| {
        loop {
            let i = next.fetch_add(1, Ordering::SeqCst);
            if i >= items.len() || i > first_passed.load(Ordering::SeqCst) {
                break;
            }
            let (r, mut d) = make(&items[i]);
            if d.found || d.short_of_coverage.is_some() {
                check_free_space(prep, &mut d, params);
            }
            let passed = d.found;
            *made[i].lock().unwrap_or_else(|e| e.into_inner()) = Some((r, d));
            if passed {
                first_passed.fetch_min(i, Ordering::SeqCst);
            }
        }
    });
    let passed = first_passed.into_inner();
    let out: Vec<(R, Detection)> = made
        .into_iter()
        .take(passed.saturating_add(1))
        .map(|m| {
            m.into_inner()
                .unwrap_or_else(|e| e.into_inner())
                .expect("every item up to the first that passed is judged")
        })
        .collect();
    (out, passed != usize::MAX)
}

/// The free-space check of one candidate: each part's visible surface must not be where the
/// sensor saw through; it clears `found` when a part fails and bounds the confidence by the
/// margin.
///
/// A candidate short of coverage alone is accepted here where each part's covered and hidden
/// surface together reach the coverage bound, and what of it the sensor could see it did
/// (`min_seen_hidden`): an object behind another, or under what stands on it, shows less than
/// its visible side.
pub fn check_free_space(prep: &Prepared, d: &mut Detection, params: &Params) {
    let acc = &params.acceptance;
    let hidden_rescue = if d.found { None } else { d.short_of_coverage };
    if let Some(others) = hidden_rescue {
        // Judged again with the hidden surface counted: the other margins, and the coverage
        // with what is hidden below.
        d.found = true;
        d.confidence = 1.0 / (1.0 + (-4.0 * others).exp());
    }
    for (k, part) in d.parts.iter().enumerate() {
        let Some(placed) = part.placed else { continue };
        let vis = visibility::visibility(
            &prep.scene.points,
            &prep.scene.all_grid,
            &placed,
            params.viewpoint,
            prep.scene.plane.as_ref(),
            &prep.samples[k],
        );
        let t = placed.pose.translation.vector;
        tracing::debug!("visibility {} at ({:.3} {:.3} {:.3}) {vis}", part.name, t.x, t.y, t.z);
        let mut margin = (vis.seen_ratio() - acc.min_seen) / 0.1;
        if hidden_rescue.is_some() {
            let hidden = vis.occluded as f64 / (vis.facing as f64).max(1.0);
            let with_hidden = (part.scores.coverage + hidden - acc.min_coverage) / 0.15;
            margin = margin
                .min((vis.seen_ratio() - acc.min_seen_hidden) / 0.1)
                .min(with_hidden);
        }
        if margin < 0.0 || vis.reaches_into_free_space(acc.max_deep_see_through) {
            d.found = false;
        }
        d.confidence = d.confidence.min(1.0 / (1.0 + (-4.0 * margin).exp()));
    }
}

/// The object's pose from its parts' placements. The anchor part (the largest found) fixes the
/// pose up to that part's own symmetries; the other parts choose among those symmetries and, for
/// a body of revolution, fix the spin.
pub fn object_pose(model: &Model, parts: &[PartResult]) -> Isometry3<f64> {
    let Some(a) = (0..parts.len())
        .filter(|&k| parts[k].placed.is_some())
        .max_by(|&x, &y| {
            model.parts[x]
                .shape
                .box_volume()
                .total_cmp(&model.parts[y].shape.box_volume())
        })
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Judged lazily, the candidates come back in their order up to the first that passes and
    /// no further, on any number of threads and whatever each costs; with none passing, all of
    /// them; without `lazy`, all of them and none is said to pass.
    #[test]
    fn judging_in_order_stops_at_the_first_that_passes() {
        let (_, params, prep) = super::super::prepare::simulated("fig3_table", 1, "bowl");
        let detection = |found: bool| Detection {
            found,
            confidence: if found { 1.0 } else { 0.0 },
            pose: Isometry3::identity(),
            parts: Vec::new(),
            connection_errors: Vec::new(),
            upright: None,
            short_of_coverage: None,
            colour: None,
        };
        let items: Vec<usize> = (0..12).collect();
        let make = |passing: &'static [usize]| {
            move |&k: &usize| {
                // The early items cost the most: a free thread runs ahead of a busy one.
                std::thread::sleep(std::time::Duration::from_micros(((12 - k) * 300) as u64));
                (k, detection(passing.contains(&k)))
            }
        };
        for threads in [1, 2, 3, 5] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let (out, passed) = judge_in_order(&prep, &params, &items, true, make(&[5, 9]));
                assert!(passed, "{threads} threads");
                assert_eq!(
                    out.iter().map(|(k, _)| *k).collect::<Vec<_>>(),
                    (0..=5).collect::<Vec<_>>()
                );
                assert!(out[..5].iter().all(|(_, d)| !d.found) && out[5].1.found);
                let (out, passed) = judge_in_order(&prep, &params, &items, true, make(&[]));
                assert!(!passed && out.len() == 12 && out.iter().enumerate().all(|(i, (k, _))| i == *k));
                let (out, passed) = judge_in_order(&prep, &params, &items, false, make(&[0]));
                assert!(!passed && out.len() == 12 && out[0].1.found);
            });
        }
    }

    /// The resting margin, from the parts' measures alone: a raised single part with nothing to
    /// rest on is refused, unless its model is held up by the rest of its object; a compound
    /// rests where any of its parts rests, on the plane or on what it stands on.
    #[test]
    fn an_object_rests_where_any_part_rests_and_a_held_part_need_not() {
        use super::super::verify::Scores;
        let part = "[[part]]\nname = \"{}\"\na = [0.03, 0.03, 0.05]\ne1 = 0.1\ne2 = 1.0\n";
        let one = |held: bool| {
            let text = format!("held = {held}\n{}", part.replace("{}", "body"));
            Model::from_toml_str(&text, std::path::Path::new("one.toml")).unwrap()
        };
        let two = {
            let text = format!(
                "{}{}pose = {{ position = [0.0, 0.0, 0.2] }}\n[[connection]]\nparts = [\"body\", \"top\"]\nangle_deg = 0.0\ndistance = 0.2\n",
                part.replace("{}", "body"),
                part.replace("{}", "top")
            );
            Model::from_toml_str(&text, std::path::Path::new("two.toml")).unwrap()
        };
        let measured = |raised: Option<(f64, usize)>| Scores {
            coverage: 1.0,
            rms: 0.0005,
            surface_points: 1000,
            faces: f64::INFINITY,
            raised,
            ..Scores::default()
        };
        let parts = |model: &Model, raised: &[Option<(f64, usize)>]| -> Vec<PartResult> {
            model
                .parts
                .iter()
                .zip(raised)
                .map(|(p, &r)| PartResult {
                    name: p.name.clone(),
                    placed: Some(crate::geometry::PlacedSuperquadric::new(p.shape, p.pose_in_object)),
                    scores: measured(r),
                })
                .collect()
        };
        let found = |model: &Model, raised: &[Option<(f64, usize)>]| {
            let errors = vec![(0.0, 0.0); model.connections.len()];
            assess(
                model,
                parts(model, raised),
                errors,
                &RangeNoise::uniform(0.002),
                &Acceptance::default(),
            )
            .found
        };
        assert!(found(&one(false), &[None]), "on the plane");
        assert!(!found(&one(false), &[Some((0.05, 0))]), "floating");
        assert!(!found(&one(false), &[Some((0.05, 9))]), "too little under it");
        assert!(found(&one(false), &[Some((0.05, 10))]), "on something");
        assert!(found(&one(true), &[Some((0.05, 0))]), "held");
        assert!(found(&two, &[None, Some((0.2, 0))]), "one part on the plane");
        assert!(
            found(&two, &[Some((0.05, 30)), Some((0.2, 0))]),
            "one part on something"
        );
        assert!(!found(&two, &[Some((0.05, 0)), Some((0.2, 0))]), "both floating");
    }
}
