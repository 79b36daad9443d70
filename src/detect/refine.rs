//! Refinement of a hypothesis (paper III-B-1, "refined on the points near it"): coarse rounds on
//! the subsampled points in a band halved each round, then fine rounds at the final band on the
//! `mid` points until M stops improving. Split in two so that [`super::search::search_part`] can
//! merge the hypotheses that meet after the coarse rounds before paying for the fine ones.

use super::fit::{Fit, Freedom, fit_pose_with, measure_of_fit};
use super::search::{Hypothesis, MIN_SAMPLE, SearchSpace, inliers_in, sample_radius, thin};
use crate::geometry::{PlacedSuperquadric, Superquadric};
use nalgebra::{Point3, UnitQuaternion, Vector3};

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

/// The inlier band for refinement: three noise sigmas, at least a tenth of the smallest size
/// (so a rough RANSAC pose still gathers its object's points), at most half of it.
pub fn refine_band(shape: &Superquadric, noise: f64) -> f64 {
    (3.0 * noise)
        .max(0.1 * shape.min_size())
        .min(0.5 * shape.min_size())
        .max(0.002)
}

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
