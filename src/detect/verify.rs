//! Pose verification (paper III-B-2) and, beyond the paper, the acceptance test that lets the
//! detector say "not here".
//!
//! Over 600 lines on purpose: the scores of one hypothesis and the line-of-sight test share the
//! surface samples and the coverage rules; split them only together.
//!
//! The paper's criteria: within `1.2 max(a)` of a hypothesis' centre, `I` counts the points with
//! `F^e1 < 1 - gamma` (inside the object, where a single view can see nothing) and `S` those with
//! `1 - gamma <= F^e1 < 1 + gamma` (on its surface); hypotheses are ranked by M (ascending), S
//! (descending) and I (ascending) and the lowest rank sum wins.
//!
//! Ranked voting always names a winner, even when the object is not there. Whether the winner
//! *is* the object is judged on measures that do not depend on the other hypotheses:
//! - coverage: the share of the model surface that faces the viewpoint (and is not seen too
//!   obliquely) that has a measured point near it. An object that is there is seen on most of its
//!   visible side unless something hides it; a similar shape fitted to a patch of something else
//!   leaves much of its visible side empty;
//! - the interior ratio `I / S`: a wrong shape or size swallows points of the real surface;
//! - the RMS Euclidean (radial) distance of the surface points, against the sensor noise.

use super::base::BaseCap;
use super::plane_check::approximation_tolerance;

use super::space::{SearchSpace, sample_radius};
use super::support::Support;
use crate::cloud::grid::Grid;
use crate::geometry::{NearBatch, PlacedSuperquadric};
use crate::numeric::lanes::widened;
use nalgebra::{Point3, Vector3};
use std::fmt;

/// Surface samples seen more obliquely than this (cosine) are not expected to hold points.
pub(super) const MIN_VIEW_COSINE: f64 = 0.3;

/// The verification measures of one hypothesis.
#[derive(Debug, Clone, Copy, Default)]
pub struct Scores {
    /// The paper's measure of fit (eq. 3).
    pub m: f64,
    /// The paper's surface points S (eq. 5).
    pub s: usize,
    /// The paper's interior points I (eq. 4); for an open container, the points on its lid.
    pub i: usize,
    /// Share of the expected visible surface that holds measured points, 0..1.
    pub coverage: f64,
    /// RMS distance (m) of the points within the Euclidean surface band.
    pub rms: f64,
    /// Points within the Euclidean surface band.
    pub surface_points: usize,
    /// Points inside the surface by more than the band: what a single view cannot see (for an
    /// open container: the points on its lid).
    pub inside_points: usize,
    /// Points just outside the band (within 0.3 of the sample radius) that continue the explained
    /// surface: a larger object of the same shape around a too-small fit leaves its surface here.
    pub shell_points: usize,
    /// Points up to [`CONTINUATION`] outside the surface that lie in the plane of the explained
    /// surface next to them: a face of a larger object going on past the model's edge (a small
    /// box's model on a large box's face), which the shell sees only in its first millimetres.
    pub continued_points: usize,
    /// For a part with a rounded cross-section: the RMS distance of its side wall's points from
    /// the best two straight lines across the axis, over their RMS distance from the model's
    /// surface (see [`flat_faces`]). Below 1 the wall is better explained by flat faces: a box
    /// edge, not a can. Infinite when there is nothing to compare.
    pub faces: f64,
    /// For a container standing on its rim: how far (m) the middle of its top, which is its
    /// base, lies below the ring round it (see [`BaseCap`]); minus infinity when too little of the
    /// top was seen. `None` for anything else.
    pub base_recess: Option<f64>,
    /// For a part whose lowest point lies above the support plane by more than it may stand off
    /// its support (see `Support::raised`): that height (m), and the points of a level surface
    /// around its base at that height (not inside an open container standing upright), on
    /// which it may rest (counted up to [`RESTING_COUNTED`]). `None` for a part on the plane, or
    /// without one.
    pub raised: Option<(f64, usize)>,
}

impl Scores {
    /// The paper's M, S and I alone; the acceptance measures say nothing was seen (no coverage,
    /// no surface points).
    fn votes(m: f64, s: usize, i: usize) -> Scores {
        Scores {
            m,
            s,
            i,
            rms: f64::INFINITY,
            faces: f64::INFINITY,
            ..Default::default()
        }
    }

    /// Inside points per surface point.
    pub fn interior_ratio(&self) -> f64 {
        self.inside_points as f64 / (self.surface_points as f64).max(1.0)
    }
}

/// `M .. S .. I .. cov .. rms .. surf .. inside .. shell .. faces ..`: the paper's criteria, then the
/// acceptance measures.
impl fmt::Display for Scores {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "M {:.4} S {} I {} cov {:.2} rms {:.4} surf {} inside {} shell {} continued {} faces {:.2} base {} raised {}",
            self.m,
            self.s,
            self.i,
            self.coverage,
            self.rms,
            self.surface_points,
            self.inside_points,
            self.shell_points,
            self.continued_points,
            self.faces,
            match self.base_recess {
                Some(r) => format!("{:.1} mm", r * 1e3),
                None => "-".to_string(),
            },
            match self.raised {
                Some((h, n)) => format!("{:.1} mm on {n}", h * 1e3),
                None => "-".to_string(),
            }
        )
    }
}

widened! {
/// Compute the paper's S and I and the acceptance measures for a hypothesis.
pub fn score(
    space: &SearchSpace<'_>,
    placed: &PlacedSuperquadric,
    m: f64,
    gamma: f64,
    samples: &SurfaceSamples,
) -> Scores {
    let around = Around::new(space, placed, gamma, samples);
    let on_rim = samples.open && around.up_sign.is_some_and(|s| s < 0.0);
    let mut tally = Tally::new(&placed.shape, around.band);
    let mut batch = NearBatch::within(&around.kernel, around.reach, |k, q, rg| {
        tally.add(space, &around, &placed.shape, gamma, on_rim, &space.points[k], q, rg)
    });
    space.grid.for_each_within_box(
        space.points,
        &around.centre,
        around.search,
        &around.kernel.frame_box(&around.reach),
        |k| batch.push(k, &space.points[k]),
    );
    batch.finish();
    tally.scores(space, placed, m, samples, &around, on_rim)
}
}

/// Points a raised part may rest on are counted up to this many: three times what the acceptance
/// test asks (`accept::MIN_RESTING_ON`), a margin of 2.
const RESTING_COUNTED: usize = 30;

/// The points around a hypothesis, sorted by where they lie against its surface.
struct Tally {
    /// The paper's S and I: points within its radius near the surface and inside.
    s: usize,
    i: usize,
    /// Points within the band of the surface, with their distances (for the faces test) and
    /// the sum of their squares.
    near_surface: Vec<Point3<f64>>,
    near_distance: Vec<f64>,
    ss: f64,
    /// Points inside a closed part, where there should be none.
    inside_points: usize,
    /// Points on the lid of an open container.
    lid: usize,
    /// Just outside, within the shell; and anything outside up to the wide reach.
    outside_near: Vec<Point3<f64>>,
    beyond: Vec<Point3<f64>>,
    base: BaseCap,
    /// Outside the band but within the tolerance: the object's own.
    tolerated: Vec<Point3<f64>>,
    /// An open container's inner wall, seen through its opening.
    inner_wall: Vec<Point3<f64>>,
    /// Points of a level surface at the base's height of a raised part: what it rests on.
    resting_on: usize,
}

impl Tally {
    fn new(shape: &crate::geometry::Superquadric, band: f64) -> Tally {
        Tally {
            s: 0,
            i: 0,
            near_surface: Vec::new(),
            near_distance: Vec::new(),
            ss: 0.0,
            inside_points: 0,
            lid: 0,
            outside_near: Vec::new(),
            beyond: Vec::new(),
            base: BaseCap::new(shape, band),
            tolerated: Vec::new(),
            inner_wall: Vec::new(),
            resting_on: 0,
        }
    }

    /// One point `p` (`q` in the part's frame, `rg` its residual and gradient there).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn add(
        &mut self,
        space: &SearchSpace<'_>,
        around: &Around,
        shape: &crate::geometry::Superquadric,
        gamma: f64,
        on_rim: bool,
        p: &Point3<f64>,
        q: &Vector3<f64>,
        rg: &crate::geometry::ResidualGrad,
    ) {
        let within_paper_radius = (p - around.centre).norm() <= around.radius;
        let g = rg.residual + 1.0;
        if within_paper_radius {
            if g < 1.0 - gamma {
                self.i += 1;
            } else if g < 1.0 + gamma {
                self.s += 1;
            }
        }
        let (band, tolerance) = (around.band, around.tolerance);
        let d = PlacedSuperquadric::distance_from(rg);
        // The raised middle of a vessel's base lies inside the model's end, which is flat.
        let in_base = on_rim && self.base.add(q);
        // Enough to rest on is enough: counting stops where the margin could no longer be the
        // least of a detection's (each point costs a neighbourhood's plane).
        // Not what lies inside an open container standing upright: its inside bottom faces up at
        // its base's height too, and is its own. What lies just outside its flaring foot counts
        // (the top of the pot a bowl stands on), and so does what a closed part's too-long model
        // reaches into by its tolerance.
        let own_inside = around.opening_up && d < 0.0;
        if self.resting_on < RESTING_COUNTED
            && d > -tolerance - band
            && !own_inside
            && around.support.rests_on(space, p)
        {
            self.resting_on += 1;
        }
        if around.opening_up && d.abs() < band && on_lid(shape, q, &rg.grad) {
            // On the lid of an open container, where there is nothing to see: a closed lookalike
            // (a canister for a mug) shows itself here. Counted as the interior of a closed part.
            self.lid += 1;
        } else if d.abs() < band {
            self.near_surface.push(*p);
            self.near_distance.push(d);
            self.ss += d * d;
        } else if d < 0.0 {
            // Inside an open container is its inner wall, seen through the opening.
            if !around.opening_up {
                // A vessel on its rim shows only its outside, which its model follows to
                // within the approximation tolerance (the plane check allows as much): the
                // upturned mOSD white bowl's wall lay 3-6 mm inside the model's near its base.
                let followed = on_rim && d > -tolerance;
                if !in_base && !followed {
                    self.inside_points += 1;
                }
            } else if d > -tolerance {
                self.inner_wall.push(*p);
            }
        } else if d < tolerance {
            self.tolerated.push(*p);
        } else if d < around.shell && !around.support.holds(space, p) {
            self.outside_near.push(*p);
            self.beyond.push(*p);
        } else if d < around.wide && !around.support.holds(space, p) {
            self.beyond.push(*p);
        }
    }

    /// The scores of what was tallied.
    fn scores(
        mut self,
        space: &SearchSpace<'_>,
        placed: &PlacedSuperquadric,
        m: f64,
        samples: &SurfaceSamples,
        around: &Around,
        on_rim: bool,
    ) -> Scores {
        let (band, shape) = (around.band, &placed.shape);
        // Of the points just outside, those that continue the explained surface (a neighbour on
        // it within reach): the data goes on past the model's edge, as when a smaller model sits
        // on a larger object of the same shape. Points of another object across a gap do not
        // count.
        let reach = (2.5 * samples.data_spacing).max(band);
        let shell_points = if self.outside_near.is_empty() || self.near_surface.is_empty() {
            0
        } else {
            // The explained surface, widened by the tolerance.
            let explained: Vec<Point3<f64>> = self.near_surface.iter().chain(&self.tolerated).copied().collect();
            let g = Grid::new(&explained, reach);
            self.outside_near
                .iter()
                .filter(|p| g.any_within(&explained, p, reach))
                .count()
        };
        let shell_points =
            shell_points + beyond_the_ends(space, placed, band + approximation_tolerance(shape), around.up_sign);
        let continued_points = continued(&self.near_surface, &self.beyond, band);
        let faces = flat_faces(placed, &self.near_surface, &self.near_distance);
        let surface_points = self.near_surface.len();
        let rms = if surface_points > 0 {
            (self.ss / surface_points as f64).sqrt()
        } else {
            f64::INFINITY
        };
        let coverage = if around.opening_up {
            let wall: Vec<Point3<f64>> = self.near_surface.iter().chain(&self.inner_wall).copied().collect();
            coverage(placed, &wall, space.viewpoint, samples, true)
        } else {
            coverage(placed, &self.near_surface, space.viewpoint, samples, false)
        };
        // For an open part the paper's I (points that should not be there) are the lid points.
        let (i, inside_points) = if around.opening_up {
            (self.lid, self.lid)
        } else {
            (self.i, self.inside_points)
        };
        Scores {
            m,
            s: self.s,
            i,
            coverage,
            rms,
            surface_points,
            inside_points,
            shell_points,
            continued_points,
            faces,
            base_recess: on_rim.then(|| self.base.recess()),
            raised: around.support.raised().map(|h| (h, self.resting_on)),
        }
    }
}

/// How far past the model's surface (beyond the tolerance) [`continued`] looks (m): the size
/// difference of two boxes of a shelf that the shell's first millimetres do not see.
pub const CONTINUATION: f64 = 0.02;

/// Of the points `beyond` the surface, those that lie in the plane of the explained surface
/// next to them: within `band` (and a tenth of the distance, for a gently curved face) of the
/// plane through the nearest point of `near_surface` within [`CONTINUATION`] and its neighbours
/// there. The face of a larger object goes on in its plane past the model's edge; another
/// object touching it and the table below it leave the plane. (The data's plane, not the
/// model's: near its edges a model's normal turns towards the next face.)
fn continued(near_surface: &[Point3<f64>], beyond: &[Point3<f64>], band: f64) -> usize {
    if near_surface.is_empty() || beyond.is_empty() {
        return 0;
    }
    let grid = Grid::new(near_surface, CONTINUATION);
    let mut normals: std::collections::HashMap<usize, Option<Vector3<f64>>> = std::collections::HashMap::new();
    let mut normal_at = |i: usize| -> Option<Vector3<f64>> {
        *normals.entry(i).or_insert_with(|| {
            let mut near: Vec<Vector3<f64>> = Vec::new();
            grid.for_each_within(near_surface, &near_surface[i], NORMAL_RADIUS, |k| {
                near.push(near_surface[k].coords)
            });
            if near.len() < 6 {
                return None;
            }
            Some(crate::numeric::least_spread_direction(&near))
        })
    };
    beyond
        .iter()
        .filter(|p| {
            let mut nearest: Option<(f64, usize)> = None;
            grid.for_each_within(near_surface, p, CONTINUATION, |i| {
                let d2 = (near_surface[i] - *p).norm_squared();
                if nearest.is_none_or(|(b, _)| d2 < b) {
                    nearest = Some((d2, i));
                }
            });
            nearest.is_some_and(|(d2, i)| {
                normal_at(i).is_some_and(|n| (*p - near_surface[i]).dot(&n).abs() < band + 0.1 * d2.sqrt())
            })
        })
        .count()
}

/// The radius of the neighbourhood whose plane [`continued`] takes (m).
const NORMAL_RADIUS: f64 = 0.01;

/// Across the middle of an open part's opening, within this share of its cross-section: where a
/// closed lookalike's lid has points and a vessel has none.
const LID_MIDDLE: f64 = 0.7;

/// Whether a local point, at the surface with the local normal `grad`, lies on the lid of an
/// open part: where the surface faces out of the opening, across its middle. A rounded top (a
/// bowl's superellipsoid, e1 = 1/3) curves into the opening's plane over its outer part, which
/// is where the vessel's rim is: the rim of the mOSD white bowl seen steeply from above gave
/// a sixth as many points there as on its wall.
fn on_lid(shape: &crate::geometry::Superquadric, q: &Vector3<f64>, grad: &Vector3<f64>) -> bool {
    if !crate::model::is_lid(grad) {
        return false;
    }
    let u = shape.untaper(q);
    shape.section_radius(u.x, u.y) < LID_MIDDLE
}

/// Where [`score`] and [`votes`] look around a placement, and how they tell the points apart.
struct Around {
    centre: Point3<f64>,
    /// The paper's radius (1.2 max(a)) within which S and I are counted.
    radius: f64,
    /// The Euclidean surface band: three noise sigmas.
    band: f64,
    /// How far outside the surface a point is still the object's own (see [`Around::new`]).
    tolerance: f64,
    /// How far outside the surface data past the model's edge counts against it.
    shell: f64,
    /// How far outside the surface a face going on past the model's edge is looked for.
    wide: f64,
    /// For an open container on the support plane, the sign of its axis along the plane's normal.
    up_sign: Option<f64>,
    /// An open container seen from above (or off any plane): its I counts its lid points.
    opening_up: bool,
    kernel: crate::geometry::PlacedKernel,
    /// The local box holding every point that can count.
    reach: Vector3<f64>,
    /// The radius about the centre holding them.
    search: f64,
    /// Where whatever the part rests on would lie.
    support: Support,
}

impl Around {
    fn new(space: &SearchSpace<'_>, placed: &PlacedSuperquadric, gamma: f64, samples: &SurfaceSamples) -> Around {
        let centre = Point3::from(placed.pose.translation.vector);
        let shape = &placed.shape;
        let radius = 1.2 * shape.max_size();
        let band = (2.5 * space.noise.at(&centre)).max(0.002);
        // An open container's wall has two measured surfaces, the outside and the inside seen
        // through the opening, where its model has one: the fit settles between them (both lie
        // within the refinement band), and the outside is then measured up to a wall's thickness
        // outside the model. So for an open part, points out to the approximation tolerance (a
        // tenth of the smallest size, as the support plane check allows) beyond the noise band
        // are the object's own wall, and the shell, where data past the model's edge counts
        // against it, starts beyond that. (Measured on the mOSD bowls: the wooden bowl's wall is
        // about 5 mm thick, and its outside lay 3-7 mm outside the fitted model, 0.15 shell
        // points per surface point against the limit of 0.08.) A closed part keeps the shell
        // right outside the band.
        let tolerance = if samples.open {
            band + approximation_tolerance(shape)
        } else {
            band
        };
        let shell = tolerance + 0.3 * sample_radius(shape);
        let wide = shell.max(tolerance + CONTINUATION);
        // A container standing on its rim shows neither its inside nor its opening: its points
        // are scored as those of a closed part.
        let up_sign = if samples.open {
            space
                .plane
                .map(|p| (placed.pose.rotation * Vector3::z()).dot(&p.normal).signum())
        } else {
            None
        };
        let opening_up = samples.open && up_sign.is_none_or(|s| s > 0.0);
        let kernel = crate::geometry::PlacedKernel::new(placed);
        // One evaluation of the shape gives F^e1 (the paper's criteria), the first-order surface
        // distance and the normal (the lid test). Only points that can count are evaluated:
        // those with F^e1 < 1 + gamma (S and I), which lie in the level box, and those within
        // the shell of the surface, which lie within the shell of the shape's box. (The
        // first-order distance shrinks far from a shape with small exponents: a point
        // decimetres off a box-like part's face could pass for one a few millimetres off.)
        let reach = kernel
            .level_box(1.0 + gamma)
            .sup(&shape.local_half_extents().add_scalar(wide));
        Around {
            centre,
            radius,
            band,
            tolerance,
            shell,
            wide,
            up_sign,
            opening_up,
            kernel,
            reach,
            search: radius.max(shape.bounding_radius() + wide),
            support: Support::new(
                space,
                placed,
                band + approximation_tolerance(shape),
                band,
                &samples.local,
            ),
        }
    }
}

widened! {
/// The paper's M (given), S and I of a placement, S and I counted as [`score`] counts them,
/// without the acceptance measures: all that ranking a placement among others asks (see
/// `Scores::votes`). For an open container seen from above, I counts its lid points.
pub fn votes(
    space: &SearchSpace<'_>,
    placed: &PlacedSuperquadric,
    m: f64,
    gamma: f64,
    samples: &SurfaceSamples,
) -> Scores {
    let around = Around::new(space, placed, gamma, samples);
    let Around {
        centre,
        radius,
        band,
        opening_up,
        ref kernel,
        ..
    } = around;
    // A closed part's S and I lie in the level box; an open one's lid points anywhere `score`
    // looks.
    let (reach, search) = if opening_up {
        (around.reach, around.search)
    } else {
        // The same test of the distance as `score` makes decides; the grid's own (on squares)
        // must not drop a point it keeps.
        (kernel.level_box(1.0 + gamma), 1.01 * radius)
    };
    let (mut s, mut i, mut lid) = (0usize, 0usize, 0usize);
    let mut batch = NearBatch::within(kernel, reach, |k, q, rg| {
        if (space.points[k] - centre).norm() <= radius {
            let g = rg.residual + 1.0;
            if g < 1.0 - gamma {
                i += 1;
            } else if g < 1.0 + gamma {
                s += 1;
            }
        }
        if opening_up
            && PlacedSuperquadric::distance_from(rg).abs() < band
            && on_lid(&placed.shape, q, &rg.grad)
        {
            lid += 1;
        }
    });
    space.grid.for_each_within_box(
        space.points,
        &centre,
        search,
        &kernel.frame_box(&reach),
        |k| batch.push(k, &space.points[k]),
    );
    batch.finish();
    Scores::votes(m, s, if opening_up { lid } else { i })
}
}

/// Whether the side wall is round or made of flat faces. A can fitted to the edge of a box (or
/// a mug to a tea box) can reach a surface RMS within the noise when the box is small and its
/// faces are seen at a slant, yet the wall's cross-section is two straight lines meeting at a
/// corner, where a round object's is an arc. Both explanations see the same noise, so their
/// ratio does not depend on it: the points of the side wall (away from the ends), taken across
/// the axis (untapered), are fitted with two straight lines split at the best azimuth (total
/// least squares each), and the RMS of that fit is divided by the RMS of their distances from
/// the model's surface. A round wall seen over a good part of its circumference leaves the
/// lines centimetres of sagitta; flat faces leave them the noise alone. Only shapes with a
/// rounded cross-section (e2 above 0.5) are tested; fewer than 20 wall points say nothing.
/// `distances` are the points' surface distances.
pub fn flat_faces(placed: &PlacedSuperquadric, near_surface: &[Point3<f64>], distances: &[f64]) -> f64 {
    let shape = &placed.shape;
    if shape.e2 < 0.5 {
        return f64::INFINITY;
    }
    let mut wall: Vec<(f64, [f64; 2])> = Vec::new();
    let mut ss = 0.0;
    for (p, d) in near_surface.iter().zip(distances) {
        let q = placed.to_local(p);
        if q.z.abs() > 0.8 * shape.a[2] {
            continue;
        }
        let u = shape.untaper(&q);
        wall.push((u.y.atan2(u.x), [q.x, q.y]));
        ss += d * d;
    }
    const MIN_SIDE: usize = 10;
    if wall.len() < 2 * MIN_SIDE {
        return f64::INFINITY;
    }
    let model_rms = (ss / wall.len() as f64).sqrt().max(1e-6);
    // Sort round the axis, starting in the widest gap, so that a run of azimuths is a run of
    // the wall.
    wall.sort_by(|a, b| a.0.total_cmp(&b.0));
    let n = wall.len();
    let gap_end = (0..n)
        .max_by(|&i, &j| {
            let gap = |k: usize| {
                let prev = wall[(k + n - 1) % n].0;
                (wall[k].0 - prev).rem_euclid(std::f64::consts::TAU)
            };
            gap(i).total_cmp(&gap(j))
        })
        .unwrap_or(0);
    wall.rotate_left(gap_end);
    // Prefix moments for the total least squares line of any run.
    let mut pre = vec![[0.0f64; 5]; n + 1];
    for (k, (_, [x, y])) in wall.iter().enumerate() {
        let m = pre[k];
        pre[k + 1] = [m[0] + x, m[1] + y, m[2] + x * x, m[3] + x * y, m[4] + y * y];
    }
    let sse = |lo: usize, hi: usize| {
        let c = (hi - lo) as f64;
        let m: [f64; 5] = std::array::from_fn(|i| pre[hi][i] - pre[lo][i]);
        let (mx, my) = (m[0] / c, m[1] / c);
        let sxx = m[2] - c * mx * mx;
        let sxy = m[3] - c * mx * my;
        let syy = m[4] - c * my * my;
        // The smaller eigenvalue of the scatter matrix: the squared distances from the line.
        let tr = sxx + syy;
        let det = sxx * syy - sxy * sxy;
        (0.5 * tr - (0.25 * tr * tr - det).max(0.0).sqrt()).max(0.0)
    };
    let best = (MIN_SIDE..=n - MIN_SIDE)
        .map(|k| sse(0, k) + sse(k, n))
        .fold(f64::INFINITY, f64::min);
    (best / n as f64).sqrt() / model_rms
}

/// For an open container (a mug, a bowl), the points that continue its side wall past either
/// end: on the wall's extension (within `tolerance` of the end cross-section, widened along the
/// axis) from a margin beyond the rim or the base out to half the part's height. The model's
/// height is the container's whole extent, so data there means a taller object of the same
/// girth: a mug model fitted to a capped canister twice its height explains one end of it and
/// leaves the rest here (mOSD test64), while a real mug has empty space above its rim and the
/// removed table below its base. The margin (a fifth of the height, at least 1 cm) lets a real
/// container be somewhat taller than its model, and keeps a supporting surface under the base
/// (a book under a mug) out: that lies at the base's height, not below it.
///
/// An open container on a support plane stands on its base or its rim, so the space above its
/// top end, across its whole cross-section, is free as well: data there is the top of a taller
/// object (a tea box, a canister) whose side the container's wall was fitted to. Those points
/// count too: `up_sign` is the local sign of the up direction for such a container.
fn beyond_the_ends(
    space: &SearchSpace<'_>,
    placed: &PlacedSuperquadric,
    tolerance: f64,
    up_sign: Option<f64>,
) -> usize {
    let shape = &placed.shape;
    let (a1, a2, a3) = (shape.a[0], shape.a[1], shape.a[2]);
    let margin = (0.2 * a3).max(0.01);
    let reach = 1.5 * a3;
    if reach <= a3 + margin {
        return 0;
    }
    let centre = Point3::from(placed.pose.translation.vector);
    let mut count = 0usize;
    space
        .grid
        .for_each_within(space.points, &centre, (a1.max(a2) + tolerance).hypot(reach), |k| {
            let q = placed.to_local(&space.points[k]);
            let beyond = q.z.abs() - a3;
            if !(beyond > margin && q.z.abs() <= reach) {
                return;
            }
            // The end's cross-section, extended along the axis.
            let end = shape.untaper(&nalgebra::Vector3::new(q.x, q.y, a3.copysign(q.z)));
            let rho = shape.section_radius(end.x, end.y);
            let over_the_top = up_sign.is_some_and(|s| q.z * s > 0.0) && rho < 1.0;
            if over_the_top || ((rho - 1.0) * a1.min(a2)).abs() < tolerance {
                count += 1;
            }
        });
    count
}

/// A shape's surface samples with their outward normals, in the shape's frame, spaced for the
/// coverage test: twice the data's point spacing (so a covered sample always has a point within
/// reach), and at most a sixth of the smallest size.
pub struct SurfaceSamples {
    pub(super) spacing: f64,
    data_spacing: f64,
    /// The part is an open container: its lid is an opening (see `model::Part::open`).
    open: bool,
    pub(super) local: std::sync::Arc<crate::surface_samples::LocalSamples>,
}

impl SurfaceSamples {
    pub fn new(shape: &crate::geometry::Superquadric, data_spacing: f64, open: bool) -> SurfaceSamples {
        let spacing = (2.0 * data_spacing).max(shape.min_size() / 6.0);
        SurfaceSamples {
            spacing,
            data_spacing,
            open,
            local: crate::surface_samples::local_samples(shape, spacing, open),
        }
    }
}

/// Share of the visible model surface that has a measured point within reach. With
/// `opening_up` (an open container standing on its base), the inside of its wall is visible too
/// where the line of sight leaves through the opening: a bowl seen from above shows little of
/// its outside and most of its inside, and the wall is one surface to the model.
fn coverage(
    placed: &PlacedSuperquadric,
    observed: &[Point3<f64>],
    viewpoint: Option<Point3<f64>>,
    samples: &SurfaceSamples,
    opening_up: bool,
) -> f64 {
    if observed.is_empty() {
        return 0.0;
    }
    let centre = Point3::from(placed.pose.translation.vector);
    // Without a viewpoint, look from far away in the direction the observed points face.
    let mean_dir = observed.iter().fold(Vector3::zeros(), |a, p| a + (p - centre)) / observed.len() as f64;
    let reach = 1.2 * samples.spacing;
    let grid = Grid::new(observed, reach);
    let (mut expected, mut covered) = (0usize, 0usize);
    for (q, n) in samples.local.iter() {
        let p = placed.pose.transform_point(&Point3::from(*q));
        let n = placed.pose.rotation * n;
        let view = match viewpoint {
            Some(v) => (v - p).normalize(),
            None => mean_dir.try_normalize(1e-300).unwrap_or(Vector3::z()),
        };
        let outside_seen = n.dot(&view) >= MIN_VIEW_COSINE;
        let inside_seen = opening_up
            && n.dot(&view) <= -MIN_VIEW_COSINE
            && through_opening(&placed.shape, q, &(placed.pose.rotation.inverse() * view));
        if !outside_seen && !inside_seen {
            continue;
        }
        expected += 1;
        if grid.any_within(observed, &p, reach) {
            covered += 1;
        }
    }
    if expected == 0 {
        0.0
    } else {
        covered as f64 / expected as f64
    }
}

/// Whether the line from the local surface point `q` along the local direction `d` leaves an
/// open part through its opening (the top end's cross-section) rather than through its wall.
fn through_opening(shape: &crate::geometry::Superquadric, q: &Vector3<f64>, d: &Vector3<f64>) -> bool {
    if d.z <= 1e-9 {
        return false;
    }
    let a3 = shape.a[2];
    let t = (a3 - q.z) / d.z;
    let top = shape.untaper(&Vector3::new(q.x + t * d.x, q.y + t * d.y, a3));
    shape.section_radius(top.x, top.y) < 1.0
}

/// Ranks of values (1 = best), ties sharing the better rank.
pub fn ranks(values: &[f64], ascending: bool) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..values.len()).collect();
    idx.sort_by(|&a, &b| {
        let o = values[a].total_cmp(&values[b]);
        if ascending { o } else { o.reverse() }
    });
    let mut out = vec![0; values.len()];
    let mut rank = 1;
    for (pos, &k) in idx.iter().enumerate() {
        if pos > 0 && values[k] != values[idx[pos - 1]] {
            rank = pos + 1;
        }
        out[k] = rank;
    }
    out
}

/// The paper's ranked voting: the sum over criteria of each candidate's rank. `criteria` holds
/// one value per candidate for each criterion with its sort direction (`true` = smaller is
/// better).
pub fn rank_sums(criteria: &[(Vec<f64>, bool)]) -> Vec<usize> {
    let n = criteria.first().map_or(0, |c| c.0.len());
    let mut sums = vec![0; n];
    for (values, ascending) in criteria {
        for (k, r) in ranks(values, *ascending).into_iter().enumerate() {
            sums[k] += r;
        }
    }
    sums
}

/// The paper's three criteria: M ascending, S descending, I ascending.
pub fn paper_criteria(scores: &[Scores]) -> Vec<(Vec<f64>, bool)> {
    vec![
        (scores.iter().map(|s| s.m).collect(), true),
        (scores.iter().map(|s| s.s as f64).collect(), false),
        (scores.iter().map(|s| s.i as f64).collect(), true),
    ]
}

/// Median nearest-neighbour distance of a point set (its sampling spacing), from up to 500 points,
/// neighbours looked for within 2 cm.
pub fn median_spacing(points: &[Point3<f64>]) -> f64 {
    const NEAR: f64 = 0.005;
    const FAR: f64 = 0.02;
    if points.len() < 2 {
        return NEAR;
    }
    // Most points have a neighbour within a few millimetres: a fine grid finds it among a few
    // dozen points where a 2 cm search passes over hundreds in dense data; the rest look again
    // out to 2 cm.
    let grid = Grid::new(points, NEAR);
    let nearest = |p: &Point3<f64>, r: f64| {
        let mut best = f64::INFINITY;
        grid.for_each_within(points, p, r, |k| {
            let e = (points[k] - p).norm();
            if e > 0.0 && e < best {
                best = e;
            }
        });
        best
    };
    let step = (points.len() / 500).max(1);
    let mut d: Vec<f64> = points
        .iter()
        .step_by(step)
        .filter_map(|p| {
            let near = nearest(p, NEAR);
            let best = if near.is_finite() { near } else { nearest(p, FAR) };
            best.is_finite().then_some(best)
        })
        .collect();
    if d.is_empty() {
        return FAR;
    }
    let mid = d.len() / 2;
    *d.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface_samples::{CACHED_SHAPES, SAMPLES, sample_local};

    /// A shape's samples at one spacing are made once and shared; another spacing, another
    /// shape or the open flag give their own, the same as sampled afresh; the cache stays
    /// bounded however many shapes pass through it.
    #[test]
    fn surface_samples_are_made_once_per_shape_and_spacing() {
        use crate::geometry::Superquadric;
        let shape = Superquadric::new([0.0611, 0.0611, 0.0203], 0.31, 1.0, 0.27, 0.27).unwrap();
        let min = shape.min_size();
        let a = SurfaceSamples::new(&shape, 0.001, true);
        let b = SurfaceSamples::new(&shape, 0.0011, true);
        assert!(
            std::sync::Arc::ptr_eq(&a.local, &b.local),
            "the spacing is the shape's in both"
        );
        assert_eq!(a.data_spacing, 0.001);
        assert_eq!(b.data_spacing, 0.0011);
        let closed = SurfaceSamples::new(&shape, 0.001, false);
        assert!(closed.local.len() > a.local.len(), "an open part has no lid samples");
        let coarser = SurfaceSamples::new(&shape, min / 2.0, true);
        assert!(coarser.local.len() < a.local.len());
        for s in [&a, &closed, &coarser] {
            assert_eq!(*s.local, sample_local(&shape, s.spacing, s.open));
        }
        for k in 0..2 * CACHED_SHAPES {
            let other = Superquadric::untapered([0.02 + 0.001 * k as f64, 0.03, 0.04], 0.5, 0.5).unwrap();
            let s = SurfaceSamples::new(&other, 0.001, false);
            assert_eq!(*s.local, sample_local(&other, s.spacing, false));
        }
        assert!(SAMPLES.0.lock().unwrap().len() <= CACHED_SHAPES);
    }

    #[test]
    fn ranked_voting_sums_ranks_with_ties() {
        assert_eq!(ranks(&[0.3, 0.1, 0.3, 0.2], true), vec![3, 1, 3, 2]);
        assert_eq!(ranks(&[5.0, 9.0, 1.0], false), vec![2, 1, 3]);
        let sums = rank_sums(&[
            (vec![0.1, 0.2, 0.3], true),
            (vec![10.0, 30.0, 20.0], false),
            (vec![0.0, 5.0, 1.0], true),
        ]);
        assert_eq!(sums, vec![1 + 3 + 1, 2 + 1 + 3, 3 + 2 + 2]);
    }
}
