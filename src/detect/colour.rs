//! The colour check of found objects ([`crate::appearance`]): the points of the cloud on a found
//! surface must share enough of the model's colours.

use super::{Detection, Report};
use crate::appearance::{MIN_SIMILARITY, histogram, similarity};
use crate::cloud::PointCloud;
use crate::geometry::{PlacedKernel, PlacedSuperquadric};
use crate::model::Model;
use nalgebra::Point3;

/// Points of the scene within this of a found surface (m, either side) are its points.
const SURFACE_BAND: f64 = 0.006;

/// The histogram of the points of `cloud` near the surfaces of a detection's parts.
fn surface_histogram(points: &[[f32; 3]], colours: &[[u8; 3]], parts: &[PlacedSuperquadric]) -> Option<Vec<f64>> {
    let kernels: Vec<PlacedKernel> = parts.iter().map(PlacedKernel::new).collect();
    // The box in the cloud's frame that holds them all: a cloud's points are mostly elsewhere,
    // and six comparisons in f32 turn them away at a thirtieth of the cost of the shape's own
    // box test.
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for (k, s) in kernels.iter().zip(parts) {
        let reach = k.frame_reach(SURFACE_BAND);
        let c = s.pose.translation.vector;
        for i in 0..3 {
            lo[i] = lo[i].min((c[i] - reach[i]) as f32);
            hi[i] = hi[i].max((c[i] + reach[i]) as f32);
        }
    }
    histogram(points.iter().zip(colours).filter_map(|(p, c)| {
        if (0..3).any(|i| !(lo[i]..=hi[i]).contains(&p[i])) {
            return None;
        }
        let q = Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
        kernels
            .iter()
            .any(|k| {
                k.surface_distance_near(&q, SURFACE_BAND)
                    .is_some_and(|d| d.abs() <= SURFACE_BAND)
            })
            .then_some(*c)
    }))
}

/// [`super::detect`] with the colour check. With `all`, [`detect_all_checked`]. A single answer
/// is the detector's, checked; where the colours refuse it and the model and the cloud have
/// colours, the best of every accepted candidate the colours pass is the answer (a lookalike
/// ranked first does not hide the object behind it), or the refused one ("not here") where none
/// passes. Only a refusal costs the second run.
pub fn detect_checked(cloud: &PointCloud, model: &Model, params: &super::Params) -> Report {
    if params.all {
        return detect_all_checked(cloud, model, params).0;
    }
    let mut single = super::detect(&cloud.points, model, params);
    let best_found = single.detections.first().is_some_and(|d| d.found);
    check_colour(&mut single, cloud, model);
    let refused = best_found && single.detections.first().is_some_and(|d| !d.found);
    if !refused {
        return single;
    }
    let (mut r, _) = detect_all_checked(cloud, model, params);
    let Some(first) = r.detections.into_iter().next() else {
        add_timing(&mut single, &r.timing);
        return single;
    };
    r.detections = vec![first];
    add_timing(&mut r, &single.timing);
    r
}

/// Every accepted instance of `model` in `cloud` whose colours pass (`params.all` is taken as
/// set), and how many accepted ones the colours refused. The colours judge the candidates in
/// the order the instances are chosen in, before overlapping ones are set aside: an accepted
/// candidate on a neighbouring object of another colour, ranked above the object's own, would
/// otherwise hide it and then be refused itself. Where the model or the cloud has no colours,
/// [`super::detect`] with `all`.
pub fn detect_all_checked(cloud: &PointCloud, model: &Model, params: &super::Params) -> (Report, usize) {
    let reference = model.colour.as_deref();
    let every = super::Params {
        all: true,
        overlapping: reference.is_some(),
        ..params.clone()
    };
    let mut r = super::detect(&cloud.points, model, &every);
    let Some(reference) = reference else {
        return (r, 0);
    };
    let max_size = super::select::overlap_distance(model);
    let candidates = std::mem::take(&mut r.detections);
    let t = std::time::Instant::now();
    // Unpacking a camera's colours walks every point: only where something was found.
    let colours = if candidates.is_empty() { None } else { cloud.colours() };
    let mut refused = 0;
    r.detections = super::select::distinct(candidates, max_size, |d| {
        let Some(colours) = &colours else { return true };
        let passed = judge(d, reference, &cloud.points, colours);
        refused += usize::from(!passed);
        passed
    });
    let ms = 1e3 * t.elapsed().as_secs_f64();
    r.timing.verify_ms += ms;
    r.timing.total_ms += ms;
    (r, refused)
}

/// Add `spent` to `report`'s times: both runs answered one question.
fn add_timing(report: &mut Report, spent: &super::Timing) {
    report.timing.plane_ms += spent.plane_ms;
    report.timing.search_ms += spent.search_ms;
    report.timing.verify_ms += spent.verify_ms;
    report.timing.total_ms += spent.total_ms;
}

/// Check one found detection against the model's colours `reference`: record its similarity,
/// and clear `found` where it is below [`MIN_SIMILARITY`]. Returns whether it is still found
/// (also where its surface has too few points to say).
fn judge(d: &mut Detection, reference: &[f64], points: &[[f32; 3]], colours: &[[u8; 3]]) -> bool {
    let parts: Vec<_> = d.parts.iter().filter_map(|p| p.placed).collect();
    let Some(h) = surface_histogram(points, colours, &parts) else {
        return d.found;
    };
    let s = similarity(reference, &h);
    d.colour = Some(s);
    if s < MIN_SIMILARITY {
        tracing::debug!(
            "colour: the detection at ({:.3} {:.3} {:.3}) shares {s:.2} of the model's colours (at least {MIN_SIMILARITY} needed): not the object",
            d.pose.translation.x,
            d.pose.translation.y,
            d.pose.translation.z
        );
        d.found = false;
    }
    d.found
}

/// Check every found detection of `report` against the model's colours: a detection whose
/// surface shares less than [`MIN_SIMILARITY`] of them is not the object (`found` cleared),
/// and each checked one records its similarity. Nothing is checked where the model or the cloud
/// has no colours, or a surface has too few points to say. For every instance in a cloud,
/// [`detect_all_checked`]: checked after the detector has set overlapping candidates aside, a
/// refused one would already have hidden those it overlaps.
pub fn check_colour(report: &mut Report, cloud: &PointCloud, model: &Model) {
    let Some(reference) = &model.colour else {
        return;
    };
    // Unpacking a camera's colours walks every point: only for a found object.
    if !report.detections.iter().any(|d| d.found) {
        return;
    }
    let t = std::time::Instant::now();
    let Some(colours) = cloud.colours() else {
        return;
    };
    for d in report.detections.iter_mut().filter(|d| d.found) {
        judge(d, reference, &cloud.points, &colours);
    }
    // It is part of deciding whether a candidate is the object.
    let ms = 1e3 * t.elapsed().as_secs_f64();
    report.timing.verify_ms += ms;
    report.timing.total_ms += ms;
}
