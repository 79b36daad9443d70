//! Hypotheses of a part resting on the support plane. A box lying flat at the bottom of a stack,
//! a tin with a pot standing on it: their tops are hidden, and what the sensor sees is a strip of
//! wall between the table and the thing on top. RANSAC trials of the full pose on such a strip
//! rarely land (its samples are a band a few centimetres high, and whatever stands on top draws
//! the fit). Resting on the plane, the part has three degrees of freedom left (two for a round
//! part standing on an end), and the seen wall fixes them in the plane's own coordinates: a box's
//! face is a line of its outline, a round part's wall an arc of a circle of known radius.
//!
//! For each way the part can rest (a box on any of its faces, a round part on either end), the
//! subsampled points at the heights of its walls are projected onto the plane; lines (boxes) or
//! circles of the section's radius (round parts) through random pairs of them, counted by the
//! points within the band, give the outline's place. The part is set behind the wall seen, away
//! from the viewpoint, and along a face at either end of the points seen (or at their middle when
//! they span the face). These poses join the search's hypotheses before refinement, which frees
//! them again: the plane fixes nothing beyond the start.

use super::fit::{Fit, measure_of_fit};
use super::space::{SearchSpace, consensus, inliers_in, refine_band};
use crate::cloud::plane::{Plane, orthonormal_basis};
use crate::geometry::{PlacedSuperquadric, Superquadric};
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector2, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Resting poses kept for refinement in the first round of search, most supported first: each
/// costs a refinement (and, for a compound, the search of its other parts), and the scene's own
/// trials usually reach an object in full view.
pub const FIRST_ROUND: usize = 2;
/// Resting poses kept in a later round (run when the first found nothing acceptable).
pub const LATER_ROUNDS: usize = 6;
/// Random pairs of wall points tried for each way of resting.
const PAIRS: usize = 150;
/// Outlines (lines or circles) kept per way of resting, each giving a few poses.
const OUTLINES: usize = 4;
/// Fewest wall points (of the subsample) an outline must hold.
const MIN_WALL_POINTS: usize = 12;
/// An elliptic exponent at or below this gives a flat face; at or above [`ROUND`], a round
/// section.
const FLAT: f64 = 0.5;
const ROUND: f64 = 0.8;

/// The plane's coordinates: an origin on it and two orthonormal directions in it.
struct PlaneFrame {
    origin: Point3<f64>,
    u: Vector3<f64>,
    v: Vector3<f64>,
    n: Vector3<f64>,
}

impl PlaneFrame {
    fn new(plane: &Plane) -> PlaneFrame {
        let n = plane.normal.normalize();
        let (u, v) = orthonormal_basis(&n);
        PlaneFrame {
            origin: Point3::from(-plane.d * n),
            u,
            v,
            n,
        }
    }

    /// In-plane coordinates and the height above the plane.
    fn project(&self, p: &Point3<f64>) -> (Vector2<f64>, f64) {
        let r = p - self.origin;
        (Vector2::new(r.dot(&self.u), r.dot(&self.v)), r.dot(&self.n))
    }

    fn lift(&self, c: &Vector2<f64>, height: f64) -> Point3<f64> {
        self.origin + c.x * self.u + c.y * self.v + height * self.n
    }

    /// The in-plane direction at angle `theta` from `u`.
    fn direction(&self, theta: f64) -> Vector3<f64> {
        theta.cos() * self.u + theta.sin() * self.v
    }
}

/// One way of resting: which local axis points up (and which way), and the two local axes lying
/// in the plane. The centre's height over the plane is the half-size along the axis up.
#[derive(Debug, Clone, Copy)]
struct Rest {
    up: usize,
    sign: f64,
    /// The local axes in the plane, `first` turned to the outline's angle.
    first: usize,
    second: usize,
}

impl Rest {
    fn height(&self, shape: &Superquadric) -> f64 {
        shape.a[self.up]
    }

    /// The pose with the centre over `c` and local axis `first` along the in-plane angle `theta`.
    fn pose(&self, frame: &PlaneFrame, shape: &Superquadric, c: &Vector2<f64>, theta: f64) -> Isometry3<f64> {
        let mut cols = [Vector3::zeros(); 3];
        cols[self.up] = self.sign * frame.n;
        cols[self.first] = frame.direction(theta);
        cols[self.second] = frame.n.cross(&frame.direction(theta));
        let mut m = Matrix3::from_columns(&cols);
        if m.determinant() < 0.0 {
            m.set_column(self.second, &(-cols[self.second]));
        }
        let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
        Isometry3::from_parts(Translation3::from(frame.lift(c, self.height(shape)).coords), rotation)
    }
}

/// The ways `shape` can rest on the plane that its seen walls can place: a box (flat faces) on any
/// of its three pairs of faces; a part with a round section standing on either end (one, when no
/// taper tells its ends apart). A round part lying on its side is left to the search.
fn rests(shape: &Superquadric) -> Vec<Rest> {
    let mut out = Vec::new();
    if shape.e1 <= FLAT && shape.e2 <= FLAT {
        for up in 0..3 {
            out.push(Rest {
                up,
                sign: 1.0,
                first: (up + 1) % 3,
                second: (up + 2) % 3,
            });
        }
    } else if shape.e1 <= FLAT && shape.e2 >= ROUND && round_section(shape) {
        let signs: &[f64] = if shape.is_tapered() { &[1.0, -1.0] } else { &[1.0] };
        for &sign in signs {
            out.push(Rest {
                up: 2,
                sign,
                first: 0,
                second: 1,
            });
        }
    }
    out
}

/// Whether the section is near enough a circle for a circle's fit to place it.
fn round_section(shape: &Superquadric) -> bool {
    (shape.a[0] - shape.a[1]).abs() <= 0.1 * shape.a[0].max(shape.a[1])
}

/// A wall point in the plane's coordinates, with its height over the plane.
#[derive(Debug, Clone, Copy)]
struct WallPoint {
    at: Vector2<f64>,
    height: f64,
}

/// Up to `kept` poses of `shape` resting on the plane, with their consensus, from the seen
/// walls; none without a plane.
pub fn resting_fits(space: &SearchSpace<'_>, shape: &Superquadric, seed: u64, kept: usize) -> Vec<(usize, Fit)> {
    let Some(plane) = space.plane else {
        return Vec::new();
    };
    let frame = PlaneFrame::new(&plane);
    let noise = space.noise.reference();
    let band2d = (2.0 * noise).max(0.002);
    let viewpoint = space.viewpoint.map(|p| frame.project(&p).0);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut poses: Vec<Isometry3<f64>> = Vec::new();
    let projected: Vec<WallPoint> = space
        .sub
        .iter()
        .map(|p| {
            let (at, height) = frame.project(p);
            WallPoint { at, height }
        })
        .collect();
    for rest in rests(shape) {
        let top = 2.0 * rest.height(shape);
        // The wall between the table's residue and the top's edge.
        let margin = (3.0 * noise).max(0.1 * top).max(0.003);
        let wall: Vec<WallPoint> = projected
            .iter()
            .filter(|w| w.height > margin && w.height < top - margin)
            .copied()
            .collect();
        if wall.len() < MIN_WALL_POINTS {
            continue;
        }
        if rest.up == 2 && shape.e2 >= ROUND {
            for c in circles(shape, &rest, &wall, viewpoint, band2d, &mut rng) {
                poses.push(rest.pose(&frame, shape, &c, 0.0));
            }
        } else {
            for line in lines(shape, &rest, &wall, band2d, &mut rng) {
                for (c, theta) in boxes_behind(shape, &rest, &line, viewpoint) {
                    poses.push(rest.pose(&frame, shape, &c, theta));
                }
            }
        }
    }
    let band = refine_band(shape, noise);
    let mut fits: Vec<(usize, Fit)> = poses
        .into_iter()
        .map(|pose| {
            let placed = PlacedSuperquadric::new(*shape, pose);
            // Points deep inside the part count against it: a pose through another object
            // gathers its walls too.
            let support = consensus(space, &placed, band).saturating_sub(inside(space, &placed, band));
            let m = measure_of_fit(&placed, &inliers_in(space.coarse, space.coarse_grid, &placed, band));
            (
                support,
                Fit {
                    placed,
                    m,
                    iterations: 0,
                },
            )
        })
        .filter(|(support, _)| *support >= MIN_WALL_POINTS)
        .collect();
    fits.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.m.total_cmp(&b.1.m)));
    fits.truncate(kept);
    for (support, f) in &fits {
        tracing::trace!(
            "resting start at ({:.3} {:.3} {:.3}) support {support} M {:.4}",
            f.placed.pose.translation.x,
            f.placed.pose.translation.y,
            f.placed.pose.translation.z,
            f.m
        );
    }
    fits
}

/// The coarse subsample's points deeper inside the placed part than `band`.
fn inside(space: &SearchSpace<'_>, placed: &PlacedSuperquadric, band: f64) -> usize {
    let centre = Point3::from(placed.pose.translation.vector);
    let mut n = 0;
    space
        .coarse_grid
        .for_each_within(space.coarse, &centre, placed.shape.bounding_radius(), |i| {
            if placed.surface_distance(&space.coarse[i]) < -band {
                n += 1;
            }
        });
    n
}

/// A straight run of wall points: a point on it, its unit direction, and the extent of its
/// points along it (from the point).
#[derive(Debug, Clone, Copy)]
struct Line {
    at: Vector2<f64>,
    dir: Vector2<f64>,
    from: f64,
    to: f64,
    count: usize,
}

/// The best supported lines through pairs of wall points, each no longer than the part's longest
/// side in the plane; distinct in angle or offset.
fn lines(shape: &Superquadric, rest: &Rest, wall: &[WallPoint], band: f64, rng: &mut ChaCha8Rng) -> Vec<Line> {
    let longest = 2.0 * shape.a[rest.first].max(shape.a[rest.second]);
    let shortest = 0.2 * shape.a[rest.first].min(shape.a[rest.second]);
    let mut found: Vec<Line> = Vec::new();
    for _ in 0..PAIRS {
        let p = wall[rng.random_range(0..wall.len())].at;
        let q = wall[rng.random_range(0..wall.len())].at;
        let d = q - p;
        let len = d.norm();
        if !(shortest..=longest).contains(&len) {
            continue;
        }
        let dir = d / len;
        if let Some(line) = run_along(wall, p, dir, band, longest) {
            found.push(line);
        }
    }
    found.sort_by_key(|l| std::cmp::Reverse(l.count));
    let mut kept: Vec<Line> = Vec::new();
    for l in found {
        let same = kept.iter().any(|k| {
            let normal = Vector2::new(-k.dir.y, k.dir.x);
            k.dir.dot(&l.dir).abs() > 0.98 && normal.dot(&(l.at - k.at)).abs() < 4.0 * band
        });
        if !same {
            kept.push(l);
            if kept.len() == OUTLINES {
                break;
            }
        }
    }
    kept
}

/// The wall points within `band` of the line through `p` along `dir`: the longest run of them
/// without a gap wider than a tenth of `longest`, if it holds enough points and is no longer
/// than `longest` (and a little).
fn run_along(wall: &[WallPoint], p: Vector2<f64>, dir: Vector2<f64>, band: f64, longest: f64) -> Option<Line> {
    let normal = Vector2::new(-dir.y, dir.x);
    let mut ts: Vec<f64> = wall
        .iter()
        .filter(|w| normal.dot(&(w.at - p)).abs() < band)
        .map(|w| dir.dot(&(w.at - p)))
        .collect();
    if ts.len() < MIN_WALL_POINTS {
        return None;
    }
    ts.sort_by(f64::total_cmp);
    let gap = 0.1 * longest;
    let (mut best, mut start) = ((0usize, 0usize), 0usize);
    for k in 1..=ts.len() {
        if k == ts.len() || ts[k] - ts[k - 1] > gap {
            if k - start > best.1 - best.0 {
                best = (start, k);
            }
            start = k;
        }
    }
    let (from, to) = (ts[best.0], ts[best.1 - 1]);
    let count = best.1 - best.0;
    (count >= MIN_WALL_POINTS && to - from <= longest * 1.05).then_some(Line {
        at: p,
        dir,
        from,
        to,
        count,
    })
}

/// The centres and angles of the part set behind `line`: either of its in-plane sides along the
/// line (when the run fits it), the other side's half behind it (away from the viewpoint, or
/// either way without one), and along the line at either end of the run, or at its middle when
/// the run spans the side.
fn boxes_behind(
    shape: &Superquadric,
    rest: &Rest,
    line: &Line,
    viewpoint: Option<Vector2<f64>>,
) -> Vec<(Vector2<f64>, f64)> {
    let normal = Vector2::new(-line.dir.y, line.dir.x);
    let mid = line.at + line.dir * (0.5 * (line.from + line.to));
    let behind: Vec<Vector2<f64>> = match viewpoint {
        Some(v) if normal.dot(&(mid - v)).abs() > 1e-9 => vec![normal * normal.dot(&(mid - v)).signum()],
        _ => vec![normal, -normal],
    };
    let run = line.to - line.from;
    let angle = line.dir.y.atan2(line.dir.x);
    let mut out = Vec::new();
    for (along, across, theta) in [
        (shape.a[rest.first], shape.a[rest.second], angle),
        (
            shape.a[rest.second],
            shape.a[rest.first],
            angle + std::f64::consts::FRAC_PI_2,
        ),
    ] {
        // A run longer than the side is another face (or a larger box).
        let slack = 0.1 * along + 0.005;
        if run > 2.0 * along + slack {
            continue;
        }
        let offsets: Vec<f64> = if run >= 2.0 * along - slack {
            vec![0.5 * (line.from + line.to)]
        } else {
            vec![line.from + along, line.to - along]
        };
        for t in offsets {
            for b in &behind {
                out.push((line.at + line.dir * t + b * across, theta));
            }
        }
    }
    out
}

/// The best supported centres of circles through pairs of wall points, each point's circle the
/// section's radius at its height; the centre behind the points (away from the viewpoint).
fn circles(
    shape: &Superquadric,
    rest: &Rest,
    wall: &[WallPoint],
    viewpoint: Option<Vector2<f64>>,
    band: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<Vector2<f64>> {
    let h = rest.height(shape);
    let radius = |w: &WallPoint| {
        let side = shape.taper(&Vector3::new(shape.a[0], shape.a[1], rest.sign * (w.height - h)));
        0.5 * (side.x + side.y)
    };
    let mut found: Vec<(usize, Vector2<f64>)> = Vec::new();
    for _ in 0..PAIRS {
        let p = &wall[rng.random_range(0..wall.len())];
        let q = &wall[rng.random_range(0..wall.len())];
        for c in circle_centres(p.at, radius(p), q.at, radius(q)) {
            let mid = 0.5 * (p.at + q.at);
            if viewpoint.is_some_and(|v| (c - mid).dot(&(mid - v)) <= 0.0) {
                continue;
            }
            let count = wall
                .iter()
                .filter(|w| ((w.at - c).norm() - radius(w)).abs() < band)
                .count();
            if count >= MIN_WALL_POINTS {
                found.push((count, c));
            }
        }
    }
    found.sort_by_key(|f| std::cmp::Reverse(f.0));
    let mut kept: Vec<Vector2<f64>> = Vec::new();
    let apart = 0.25 * shape.a[0].min(shape.a[1]);
    for (_, c) in found {
        if kept.iter().all(|k| (k - c).norm() > apart) {
            kept.push(c);
            if kept.len() == OUTLINES {
                break;
            }
        }
    }
    kept
}

/// The centres of the circles of radius `rp` through `p` and `rq` through `q`: where the two
/// circles about the points meet. None when the points are too close together to place one (a
/// short chord fixes the centre poorly) or too far apart.
fn circle_centres(p: Vector2<f64>, rp: f64, q: Vector2<f64>, rq: f64) -> Vec<Vector2<f64>> {
    let d = q - p;
    let dist = d.norm();
    if !(rp > 0.0 && rq > 0.0) || dist < 0.5 * rp.min(rq) || dist >= rp + rq {
        return Vec::new();
    }
    let along = (dist * dist + rp * rp - rq * rq) / (2.0 * dist);
    let h2 = rp * rp - along * along;
    if h2 < 0.0 {
        return Vec::new();
    }
    let e = d / dist;
    let base = p + e * along;
    let off = Vector2::new(-e.y, e.x) * h2.sqrt();
    vec![base + off, base - off]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::prepare::simulated_model;
    use crate::model::Model;

    /// `scenes/stacked/flat_under_others.toml`'s table top (m) in the base frame.
    const TABLE: f64 = 0.72;

    fn model(name: &str, part: &str) -> Model {
        let text = format!("name = \"{name}\"\n[[part]]\nname = \"body\"\n{part}\n");
        Model::from_toml_str(&text, std::path::Path::new("test.toml")).unwrap()
    }

    /// Whether `pose` puts every local axis of the shape along the truth's (either way).
    fn axes_match(pose: &Isometry3<f64>, truth: &UnitQuaternion<f64>, degrees: f64) -> bool {
        (0..3).all(|k| {
            let c = (pose.rotation * Vector3::ith(k, 1.0)).dot(&(truth * Vector3::ith(k, 1.0)));
            c.abs() >= degrees.to_radians().cos()
        })
    }

    #[test]
    fn a_flat_box_under_another_box_gets_a_resting_start_at_its_pose() {
        let m = model("flat_box", "a = [0.13, 0.09, 0.028]\ne1 = 0.1\ne2 = 0.1");
        let truth_at = Vector3::new(0.85, -0.16, TABLE + 0.028);
        let truth = UnitQuaternion::from_euler_angles(0.0, 0.0, 25f64.to_radians());
        for sim_seed in 1..=3 {
            let (model, _, prep) = simulated_model("stacked/flat_under_others", sim_seed, m.clone());
            let fits = resting_fits(&prep.space(), &model.parts[0].shape, 5, LATER_ROUNDS);
            assert!(!fits.is_empty() && fits.len() <= LATER_ROUNDS);
            let right = fits.iter().any(|(_, f)| {
                (f.placed.pose.translation.vector - truth_at).norm() < 0.01 && axes_match(&f.placed.pose, &truth, 3.0)
            });
            assert!(right, "seed {sim_seed}: no start at the box: {fits:?}");
        }
    }

    #[test]
    fn a_flat_tin_under_a_box_gets_a_resting_start_at_its_place() {
        let m = model("tin", "a = [0.09, 0.09, 0.035]\ne1 = 0.1\ne2 = 1.0");
        let truth_at = Vector3::new(0.85, 0.2, TABLE + 0.035);
        for sim_seed in 1..=3 {
            let (model, _, prep) = simulated_model("stacked/flat_under_others", sim_seed, m.clone());
            let fits = resting_fits(&prep.space(), &model.parts[0].shape, 5, LATER_ROUNDS);
            let right = fits.iter().any(|(_, f)| {
                (f.placed.pose.translation.vector - truth_at).norm() < 0.01
                    && (f.placed.pose.rotation * Vector3::z()).z.abs() > 0.999
            });
            assert!(right, "seed {sim_seed}: no start at the tin: {fits:?}");
        }
    }

    #[test]
    fn the_ways_of_resting_follow_the_shape() {
        let shape = |a: [f64; 3], e1, e2, k| Superquadric::new(a, e1, e2, k, k).unwrap();
        assert_eq!(
            rests(&shape([0.1, 0.05, 0.02], 0.1, 0.1, 0.0)).len(),
            3,
            "a box on any face"
        );
        assert_eq!(
            rests(&shape([0.05, 0.05, 0.1], 0.1, 1.0, 0.0)).len(),
            1,
            "a can on its end"
        );
        assert_eq!(
            rests(&shape([0.05, 0.05, 0.1], 0.2, 1.0, -0.3)).len(),
            2,
            "a pot on either end"
        );
        assert!(rests(&shape([0.05, 0.05, 0.05], 1.0, 1.0, 0.0)).is_empty(), "a ball");
        assert!(
            rests(&shape([0.08, 0.03, 0.1], 0.1, 1.0, 0.0)).is_empty(),
            "an oval section"
        );
    }

    #[test]
    fn circle_centres_lie_at_both_radii_and_none_where_the_circles_do_not_meet() {
        let p = Vector2::new(0.1, -0.2);
        let q = Vector2::new(0.15, -0.13);
        let centres = circle_centres(p, 0.09, q, 0.07);
        assert_eq!(centres.len(), 2);
        for c in centres {
            assert!(((c - p).norm() - 0.09).abs() < 1e-12 && ((c - q).norm() - 0.07).abs() < 1e-12);
        }
        assert!(circle_centres(p, 0.02, q, 0.02).is_empty(), "too far apart");
        assert!(
            circle_centres(p, 0.09, p + Vector2::new(0.01, 0.0), 0.09).is_empty(),
            "too close"
        );
        assert!(circle_centres(p, f64::NAN, q, 0.07).is_empty());
    }

    #[test]
    fn without_a_plane_there_is_no_resting_start() {
        let m = model("flat_box", "a = [0.13, 0.09, 0.028]\ne1 = 0.1\ne2 = 0.1");
        let (model, _, prep) = simulated_model("stacked/flat_under_others", 1, m);
        let mut space = prep.space();
        space.plane = None;
        assert!(resting_fits(&space, &model.parts[0].shape, 5, LATER_ROUNDS).is_empty());
    }
}
