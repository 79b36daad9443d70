//! Refinement of a hypothesis (paper III-B-1, "refined on the points near it"): coarse rounds on
//! the subsampled points in a band halved each round, then fine rounds at the final band on the
//! `mid` points until M stops improving. Split in two so that [`refine_fits`] can merge the
//! hypotheses that meet after the coarse rounds before paying for the fine ones, or leave the
//! fine ones until a hypothesis is judged ([`Refine::Deferred`]). A refined pose is then turned
//! the way up its opening says and lifted onto the support plane where it reaches through it.

use super::base;
use super::fit::{Fit, Freedom, fit_pose_with, measure_of_fit};
use super::plane_check::PlaneCheck;
use super::space::{
    Hypothesis, MIN_SAMPLE, SearchSettings, SearchSpace, inliers_in, refine_band, same_pose, sample_radius, thin,
};
use crate::cloud::plane::Plane;
use crate::geometry::PlacedSuperquadric;
use nalgebra::{Point3, UnitQuaternion, Vector3};
use rayon::prelude::*;

/// LM iterations of a refinement round at the final band: the pose is close by then.
const FINE_ITERATIONS: usize = 10;
/// Refinement rounds at most.
const REFINE_ROUNDS: usize = 6;
/// Refinement fits use at most this many of the points near the surface, evenly spread: six
/// pose parameters are as well determined by 600 points as by 6000, at a tenth of the time.
pub(super) const REFINE_POINTS: usize = 600;
/// The coarse rounds of a placement that is only ranked (a compound's further part, whose
/// combination is fitted again as one rigid object; a single part's hypothesis, whose fine
/// rounds wait until it is judged) fit at most this many: they only bring it to its points,
/// and its M is still measured over `REFINE_POINTS`.
pub(super) const RANKED_POINTS: usize = 300;

/// A pose after the coarse rounds of a refinement ([`refine_coarse`]), and what the fine rounds
/// ([`refine_fine`]) need. A refinement fits a pose on the points near it (`mid`) until M stops
/// improving. With a `rest_axis` (an open container on the support plane) the part's axis is
/// turned onto it first and keeps that direction: only the position and the spin are fitted.
#[derive(Debug, Clone, Copy)]
pub struct Coarse {
    fit: Fit,
    placed: PlacedSuperquadric,
    freedom: Freedom,
    band: f64,
    final_band: f64,
    rounds: usize,
    iterations: usize,
}

impl Coarse {
    pub fn placed(&self) -> &PlacedSuperquadric {
        &self.placed
    }
}

/// The coarse rounds of a refinement: a pose fitted to a small patch can be off by a good part of
/// the object's size, so the first round gathers points in a wide band and each round halves
/// it, down to the final band, fitting at most `points` of those it gathers. `Err` is the answer
/// when too few points are near the pose to go on.
pub fn refine_coarse(
    space: &SearchSpace<'_>,
    fit: &Fit,
    iterations: usize,
    rest_axis: Option<Vector3<f64>>,
    points: usize,
) -> Result<Coarse, Hypothesis> {
    let shape = fit.placed.shape;
    let mut fit = *fit;
    let freedom = match rest_axis {
        Some(n) => {
            let z = fit.placed.pose.rotation * Vector3::z();
            let target = if z.dot(&n) >= 0.0 { n } else { -n };
            if let Some(turn) = UnitQuaternion::rotation_between(&z, &target) {
                fit.placed.pose.rotation = turn * fit.placed.pose.rotation;
            }
            Freedom::AxisFixed
        }
        None if shape.is_revolution() => Freedom::FiveDof,
        None => Freedom::Free,
    };
    let final_band = refine_band(
        &shape,
        space.noise.at(&Point3::from(fit.placed.pose.translation.vector)),
    );
    let mut band = (0.3 * sample_radius(&shape)).max(final_band);
    let mut placed = fit.placed;
    let mut rounds = 0;
    while rounds < REFINE_ROUNDS && band > final_band {
        rounds += 1;
        // Coarse rounds run on the subsampled points: the pose moves a lot and a fraction of
        // the points steers it as well.
        let inliers = inliers_in(space.sub, space.sub_grid, &placed, band);
        if inliers.len() < MIN_SAMPLE {
            return Err(Hypothesis {
                placed: fit.placed,
                m: fit.m,
            });
        }
        let inliers = thin(inliers, points);
        band = (0.5 * band).max(final_band);
        // M over a wider band is not comparable with M over the final one: just fit. Nor does
        // the next round need this pose to better than the trials' 0.1 %: it gathers the points
        // anew in a band half as wide and fits again. (Converging each coarse round to 1e-6
        // took up to the full 20 iterations over 600 points, a third of the search's time.)
        placed = fit_pose_with(&placed, &inliers, iterations, freedom, 1e-3).placed;
    }
    Ok(Coarse {
        fit,
        placed,
        freedom,
        band,
        final_band,
        rounds,
        iterations,
    })
}

/// The fine rounds of a refinement, at the final band on the `mid` points, until M stops
/// improving by 1 % a round; the last round's fit is kept where it improves at all.
pub fn refine_fine(space: &SearchSpace<'_>, c: &Coarse) -> Hypothesis {
    let mut best = Hypothesis {
        placed: c.placed,
        m: f64::INFINITY,
    };
    let mut placed = c.placed;
    debug_assert!(c.band <= c.final_band || c.rounds == REFINE_ROUNDS);
    for _ in c.rounds..REFINE_ROUNDS {
        let inliers = inliers_in(space.mid, space.mid_grid, &placed, c.band);
        if inliers.len() < MIN_SAMPLE {
            break;
        }
        let inliers = thin(inliers, REFINE_POINTS);
        let before = measure_of_fit(&placed, &inliers);
        if before >= best.m {
            break;
        }
        best = Hypothesis { placed, m: before };
        let f = fit_pose_with(&placed, &inliers, c.iterations.min(FINE_ITERATIONS), c.freedom, 1e-6);
        if f.m >= before * 0.99 {
            if f.m < before {
                best = Hypothesis {
                    placed: f.placed,
                    m: f.m,
                };
            }
            break;
        }
        placed = f.placed;
    }
    if best.m.is_infinite() {
        best = Hypothesis {
            placed: c.fit.placed,
            m: c.fit.m,
        };
    }
    best
}

/// [`refine_fine`], and for a container standing on the support plane (its axis held on the
/// plane's normal) whose fit floats above the plane by more than the plane check's tolerance,
/// the fine rounds again from where it would rest on the plane: the one of the two that fits
/// better (M in the final band). With the axis held, a fit can settle a centimetre too high, its
/// top above the vessel's rim and its wall on the upper part of the vessel's: the plain mug of
/// mOSD learn39, a few millimetres taller than its model, 16 mm above the table on one seed of
/// eight (M 0.124 there, 0.113 resting on the table). A vessel that rests on something else (a
/// book, a tin: [`rests_on_something`]) stays: lowered into it, its fit can take in the top of
/// what it stands on and measure better.
fn refine_fine_resting(space: &SearchSpace<'_>, check: &PlaneCheck, c: &Coarse) -> Hypothesis {
    let h = refine_fine(space, c);
    if c.freedom != Freedom::AxisFixed {
        return h;
    }
    let Some(plane) = space.plane else { return h };
    let gap = -check.penetration(&h.placed, &plane);
    if !(gap > check.tolerance) || rests_on_something(space, check, &h.placed, &plane, gap) {
        return h;
    }
    let mut lowered = *c;
    lowered.placed = h.placed;
    lowered.placed.pose.translation.vector -= plane.normal * gap;
    let g = refine_fine(space, &lowered);
    if g.m < h.m { g } else { h }
}

/// Whether something a standing part may rest on lies around its base: at least
/// `MIN_SAMPLE` points within the plane check's tolerance of the base's height (`gap` above the
/// support plane), outside its footprint by more than the tolerance and within a third of its
/// sample radius beyond that: the top of a book, a tin or a box it stands on. The part's own wall
/// reaches down to the base inside that ring.
fn rests_on_something(
    space: &SearchSpace<'_>,
    check: &PlaneCheck,
    placed: &PlacedSuperquadric,
    plane: &Plane,
    gap: f64,
) -> bool {
    let shape = &placed.shape;
    let n = plane.normal;
    let z = placed.pose.rotation * Vector3::z();
    // The end that is lowest: the base of a container on its base, the rim of one on its rim.
    let down = if z.dot(&n) >= 0.0 { -1.0 } else { 1.0 };
    // The cross-section at that end, tapered (`X = (kx z / a3 + 1) x`).
    let footprint = (shape.a[0] * (1.0 + down * shape.kx)).max(shape.a[1] * (1.0 + down * shape.ky));
    let inner = footprint + check.tolerance;
    let outer = inner + 0.3 * sample_radius(shape);
    let centre = Point3::from(placed.pose.translation.vector);
    let base = centre + z * (down * shape.a[2]);
    let base_height = plane.signed_distance(&base).min(gap);
    let mut count = 0usize;
    space.mid_grid.for_each_within(space.mid, &base, outer, |k| {
        let p = space.mid[k];
        let height = plane.signed_distance(&p);
        if (height - base_height).abs() > check.tolerance {
            return;
        }
        let v = p - base;
        let r = (v - n * v.dot(&n)).norm();
        if r > inner {
            count += 1;
        }
    });
    count >= MIN_SAMPLE
}

/// A pose after the coarse rounds as it is, with its M over the `mid` points in the final band
/// (the fine rounds' first measure).
pub fn measured(space: &SearchSpace<'_>, c: &Coarse) -> Hypothesis {
    measured_on(space.mid, space.mid_grid, c)
}

/// [`measured`] over the subsampled points the coarse rounds fit.
pub fn measured_coarse(space: &SearchSpace<'_>, c: &Coarse) -> Hypothesis {
    measured_on(space.sub, space.sub_grid, c)
}

fn measured_on(points: &[Point3<f64>], grid: &crate::cloud::grid::Grid, c: &Coarse) -> Hypothesis {
    let inliers = thin(inliers_in(points, grid, &c.placed, c.band), REFINE_POINTS);
    if inliers.len() < MIN_SAMPLE {
        return Hypothesis {
            placed: c.fit.placed,
            m: c.fit.m,
        };
    }
    Hypothesis {
        placed: c.placed,
        m: measure_of_fit(&c.placed, &inliers),
    }
}

/// How far [`refine_fits`] refines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refine {
    /// The coarse rounds and the fine ones.
    Fine,
    /// The coarse rounds alone, on at most `RANKED_POINTS`: a placement that is only ranked.
    Ranked,
    /// The coarse rounds as for [`Refine::Ranked`], the fine ones deferred
    /// ([`Refined::deferred`]) until the hypothesis is judged ([`finish_deferred`]): its M, S
    /// and I for the ranking are taken after the coarse rounds, M on the subsampled points
    /// they fit (the vote compares the hypotheses with each other, all measured alike).
    Deferred,
}

/// What [`refine_fits`] gives.
pub struct Refined {
    /// Distinct, best first.
    pub hypotheses: Vec<Hypothesis>,
    /// For each fit, the index of the hypothesis that stands for it: its own, or that of an
    /// earlier fit it met in the coarse rounds; none where it met a `known` pose or cannot stand
    /// on the support plane.
    pub stands_for: Vec<Option<usize>>,
    /// For each hypothesis, with [`Refine::Deferred`], where its coarse rounds left it (none
    /// where they could not start).
    pub deferred: Vec<Option<Coarse>>,
}

/// The refined hypotheses of `fits`. Unless `refine` is [`Refine::Fine`], a hypothesis is its
/// pose after the coarse rounds, measured in the final band.
#[allow(clippy::too_many_arguments)]
pub fn refine_fits(
    space: &SearchSpace<'_>,
    fits: &[Fit],
    settings: &SearchSettings,
    open: bool,
    check: &PlaneCheck,
    known: &[PlacedSuperquadric],
    refine: Refine,
) -> Refined {
    let rest_axis = check.rest_axis(space);
    let points = match refine {
        Refine::Ranked | Refine::Deferred => RANKED_POINTS,
        Refine::Fine => REFINE_POINTS,
    };
    let coarse: Vec<Result<Coarse, Hypothesis>> = fits
        .par_iter()
        .map(|f| refine_coarse(space, f, settings.fit_iterations, rest_axis, points))
        .collect();
    // Copies of one object that the trials left apart (a few centimetres, a turned axis) meet
    // in the coarse rounds: the fine rounds, the scores and the vote need only the first (the
    // trials' best consensus).
    let mut kept: Vec<Result<Coarse, Hypothesis>> = Vec::with_capacity(coarse.len());
    let mut stands_for: Vec<Option<usize>> = Vec::with_capacity(coarse.len());
    for c in coarse {
        if let Ok(cc) = &c {
            if known.iter().any(|k| same_pose(k, cc.placed())) {
                stands_for.push(None);
                continue;
            }
            let met = kept
                .iter()
                .position(|k| matches!(k, Ok(k) if same_pose(k.placed(), cc.placed())));
            if met.is_some() {
                stands_for.push(met);
                continue;
            }
        }
        stands_for.push(Some(kept.len()));
        kept.push(c);
    }
    let refined: Vec<Option<(Hypothesis, Option<Coarse>)>> = kept
        .into_par_iter()
        .map(|c| {
            let (h, deferred) = match c {
                Ok(c) if refine == Refine::Fine => (refine_fine_resting(space, check, &c), None),
                Ok(c) if refine == Refine::Ranked => (measured(space, &c), None),
                Ok(c) => (measured_coarse(space, &c), Some(c)),
                Err(h) => (h, None),
            };
            let h = settled(space, check, open, h);
            let allowed = check.allows(space, &h.placed);
            if !allowed && tracing::enabled!(tracing::Level::TRACE) {
                let t = h.placed.pose.translation.vector;
                let through = space.plane.map_or(f64::NAN, |p| check.penetration(&h.placed, &p));
                tracing::trace!(
                    "refined hypothesis at ({:.3} {:.3} {:.3}) not possible on the plane: {:.1} mm through it, {:.1} mm allowed",
                    t.x,
                    t.y,
                    t.z,
                    through * 1e3,
                    check.tolerance * 1e3
                );
            }
            allowed.then_some((h, deferred))
        })
        .collect();
    let mut index = vec![None; refined.len()];
    let mut hypotheses = Vec::with_capacity(refined.len());
    let mut deferred = Vec::with_capacity(refined.len());
    for (j, h) in refined.into_iter().enumerate() {
        if let Some((h, d)) = h {
            index[j] = Some(hypotheses.len());
            hypotheses.push(h);
            deferred.push(d);
        }
    }
    let stands_for = stands_for.into_iter().map(|k| k.and_then(|j| index[j])).collect();
    Refined {
        hypotheses,
        stands_for,
        deferred,
    }
}

/// A refined pose turned the way up its opening says (an open container) and lifted onto the
/// support plane where it reaches through it.
fn settled(space: &SearchSpace<'_>, check: &PlaneCheck, open: bool, mut h: Hypothesis) -> Hypothesis {
    if open {
        orient_opening(space, &mut h.placed);
    }
    lift_onto_plane(space, check, &mut h);
    h
}

/// The fine rounds deferred by [`Refine::Deferred`], from where the coarse rounds left the
/// hypothesis. Where the support plane does not allow the pose they give, the hypothesis stays
/// as ranked (`ranked`, which it does allow).
pub fn finish_deferred(
    space: &SearchSpace<'_>,
    check: &PlaneCheck,
    open: bool,
    coarse: &Coarse,
    ranked: Hypothesis,
) -> Hypothesis {
    let h = settled(space, check, open, refine_fine_resting(space, check, coarse));
    if check.allows(space, &h.placed) { h } else { ranked }
}

/// Lift a refined pose that reaches through the support plane by more than the check allows
/// onto the deepest pose it allows, and measure it there. The object rests on the plane, so of
/// the possible poses the one sitting on it explains the points best: a model a few millimetres
/// taller than the object (a mug learned from its taller sibling), fitted to the object's base
/// upside down, sinks its rim into the table.
fn lift_onto_plane(space: &SearchSpace<'_>, check: &PlaneCheck, h: &mut Hypothesis) {
    let Some(plane) = space.plane else { return };
    let Some((placed, _)) = check.lifted(&h.placed, &plane) else {
        return;
    };
    let centre = Point3::from(placed.pose.translation.vector);
    let band = refine_band(&placed.shape, space.noise.at(&centre));
    let inliers = thin(inliers_in(space.mid, space.mid_grid, &placed, band), REFINE_POINTS);
    if inliers.len() < MIN_SAMPLE {
        return;
    }
    *h = Hypothesis {
        placed,
        m: measure_of_fit(&placed, &inliers),
    };
}

/// Turn an untapered open container the way up that what the sensor saw at its top end says. A
/// tapered part's fit settles which end is wide, and so which is its opening; an untapered one
/// (a mug's cylinder) fits the same either way up, and so does one tapered by a few percent. A
/// container standing on its base shows its inside (its inner wall and bottom) through the
/// opening; one standing on its rim shows its solid base there, a flat cap at the top of the
/// wall.
fn orient_opening(space: &SearchSpace<'_>, placed: &mut PlacedSuperquadric) {
    let Some(plane) = space.plane else { return };
    let shape = placed.shape;
    // A taper under a tenth (a learned mug's few percent) fits nearly the same either way up.
    if shape.kx.abs().max(shape.ky.abs()) >= 0.1 {
        return;
    }
    let z = placed.pose.rotation * Vector3::z();
    let up = if z.dot(&plane.normal) >= 0.0 { 1.0 } else { -1.0 };
    let a3 = shape.a[2];
    let centre = Point3::from(placed.pose.translation.vector);
    let band = (2.5 * space.noise.at(&centre)).max(0.002);
    // The cap is as deep as a vessel's base may be recessed inside its foot ring (see
    // `base::BaseCap`); the inside seen through an opening lies deeper.
    let window = base::window(&shape, band);
    let (mut cap, mut inside) = (0usize, 0usize);
    space
        .mid_grid
        .for_each_within(space.mid, &centre, shape.bounding_radius(), |k| {
            let q = placed.to_local(&space.mid[k]);
            // Well inside the wall, across the axis.
            let r = shape.section_radius(q.x, q.y);
            if r > 0.8 {
                return;
            }
            let h = up * q.z;
            if (h - a3).abs() < window {
                // A base covers the middle; near an opening's edge is the inner wall.
                if r < 0.6 {
                    cap += 1;
                }
            } else if h < a3 - window && h > -a3 {
                inside += 1;
            }
        });
    if (up > 0.0) != (inside >= cap) {
        placed.pose.rotation *= UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::search::{distinct, region_fits};
    use crate::model::axis_angle;

    /// A hypothesis on the object whose fine rounds were deferred (its coarse rounds on fewer
    /// points) ends, once they run, where the fine rounds take the same trial's fit at once, to
    /// a fraction of the noise, and fits as well: the bowl (tapered) and the mug (open) on the
    /// paper's Fig. 3.
    #[test]
    fn deferred_fine_rounds_end_where_the_fine_rounds_do() {
        for name in ["bowl", "mug"] {
            let (model, _, prep) = crate::detect::prepare::simulated("fig3_table", 2, name);
            let space = prep.space();
            let (shape, open, check) = (&model.parts[0].shape, model.parts[0].open, &prep.checks[0]);
            let seeds: Vec<usize> = (0..space.sub.len()).collect();
            let fits = distinct(region_fits(&space, shape, &seeds, 10, &prep.settings, check, 3), &[]);
            let fine = refine_fits(&space, &fits, &prep.settings, open, check, &[], Refine::Fine);
            let later = refine_fits(&space, &fits, &prep.settings, open, check, &[], Refine::Deferred);
            let best = fine.hypotheses.iter().map(|h| h.m).fold(f64::INFINITY, f64::min);
            let mut compared = 0;
            for (j, (a, b)) in fine.stands_for.iter().zip(&later.stands_for).enumerate() {
                let (Some(a), Some(b)) = (a, b) else { continue };
                let f = fine.hypotheses[*a];
                let c = later.deferred[*b].as_ref().expect("deferred");
                let done = finish_deferred(&space, check, open, c, later.hypotheses[*b]);
                let moved = (done.placed.pose.translation.vector - f.placed.pose.translation.vector).norm();
                let turned = axis_angle(
                    &(done.placed.pose.rotation * Vector3::z()),
                    &(f.placed.pose.rotation * Vector3::z()),
                    shape.is_tapered(),
                )
                .to_degrees();
                if f.m > 1.1 * best {
                    // Off the object, a fit can wander to another place either way.
                    continue;
                }
                assert!(
                    moved < 1.5e-3 && turned < 1.0 && done.m < 1.05 * f.m,
                    "{name} fit {j}: {moved} m, {turned} deg apart, M {} against {}",
                    done.m,
                    f.m
                );
                compared += 1;
            }
            assert!(compared >= 2, "{name}: {compared} fits compared");
        }
    }
}
