//! Grasps judged against the simulator's truth: whether the first grasp planned for a found
//! object holds on the true object and clears the true scene, and whether a brute-force sampler
//! over the true object and scene finds any valid grasp at all (where none exists, returning
//! none is right).

use crate::detect::Detection;
use crate::geometry::{Kernel, PlacedSuperquadric};
use crate::grasp::{Grasp, Gripper, Kind, Part, Swept, grasp_pose, line_hits, plan};
use crate::model::Model;
use crate::sim::Scene;
use nalgebra::{Isometry3, Point3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

/// A grasp holds on the truth where its contacts lie within this of the true surface, and the
/// gripper clears the true table and every other true object by this (m).
pub const TRUTH_TOLERANCE_M: f64 = 0.003;
/// Random grasps the brute-force sampler tries at most.
pub const SAMPLES: usize = 4000;
/// The true scene's surfaces are sampled this far apart (m) for the clearance check.
const SPACING: f64 = 0.002;

/// What became of one found object's grasps.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// A grasp was planned.
    pub planned: bool,
    /// The first grasp holds on the truth (`None` when none was planned), and why not.
    pub first_valid: Option<Result<(), &'static str>>,
    /// The brute-force sampler found a valid grasp on the truth.
    pub exists: bool,
    /// Planning time (ms).
    pub time_ms: f64,
}

/// The true scene as the checks take it.
pub struct Truth {
    /// The object's parts at their true poses.
    parts: Vec<Part>,
    /// Samples of every other object's true surface (the free parts' too).
    others: Vec<Point3<f64>>,
    /// Samples of the object's own true surface (without an open part's opening).
    own: Vec<Point3<f64>>,
    /// Planes the gripper must stay above: the table's top where the object stands over it,
    /// the floor.
    floors: Vec<crate::cloud::plane::Plane>,
    /// Up, for the arm's reach (the approach's tilt from straight down).
    up: Vector3<f64>,
    /// How far (m) the gripper must clear the floors and the other objects.
    margin: f64,
}

impl Truth {
    /// The truth of `scene` around its object `object`, of which `model` is the model at
    /// `pose`.
    pub fn new(scene: &Scene, object: &str, model: &Model, pose: &Isometry3<f64>) -> Truth {
        let parts: Vec<Part> = model
            .placed_parts(pose)
            .into_iter()
            .zip(&model.parts)
            .map(|(placed, m)| Part { placed, open: m.open })
            .collect();
        let mut others = Vec::new();
        for o in scene.objects.iter().filter(|o| o.name != object) {
            for placed in o.model.placed_parts(&o.pose) {
                others.extend(placed.sample_surface(SPACING));
            }
        }
        for f in &scene.free_parts {
            others.extend(f.placed.sample_surface(SPACING));
        }
        let own = parts
            .iter()
            .flat_map(|p| {
                crate::surface_samples::local_samples(&p.placed.shape, SPACING, p.open)
                    .iter()
                    .map(|(q, _)| p.placed.pose.transform_point(&Point3::from(*q)))
                    .collect::<Vec<_>>()
            })
            .collect();
        let c = pose.translation.vector;
        let mut heights = Vec::new();
        if let Some(t) = scene.table.as_ref().filter(|t| t.contains_xy(c.x, c.y)) {
            heights.push(t.height);
        }
        if scene.floor {
            heights.push(0.0);
        }
        let floors = heights
            .into_iter()
            .map(|h| crate::cloud::plane::Plane {
                normal: Vector3::z(),
                d: -h,
            })
            .collect();
        Truth {
            parts,
            others,
            own,
            floors,
            up: Vector3::z(),
            margin: TRUTH_TOLERANCE_M,
        }
    }

    /// A real scan's stand-in for the truth around a found object: its fitted `parts`, the
    /// scan's points labelled as other objects, the table or nothing (`others`, those within
    /// reach of a gripper at the object) and its own labelled points (`own`), and the support
    /// plane found. The gripper must clear the others' points and the plane (no margin: the
    /// points are the measurement), and its contacts hold on the fit.
    pub fn of_scan(
        parts: Vec<Part>,
        others: &[Point3<f64>],
        own: Vec<Point3<f64>>,
        plane: Option<&crate::cloud::plane::Plane>,
        gripper: &Gripper,
    ) -> Truth {
        let reach = parts
            .iter()
            .map(|p| p.placed.shape.bounding_radius())
            .fold(0.0, f64::max)
            + gripper.finger_depth
            + gripper.palm.iter().fold(0.0, |m: f64, &v| m.max(v))
            + gripper.pregrasp
            + gripper.max_opening;
        let centre = parts
            .first()
            .map_or_else(Point3::origin, |p| Point3::from(p.placed.pose.translation.vector));
        Truth {
            others: others
                .iter()
                .filter(|p| (*p - centre).norm() < reach)
                .copied()
                .collect(),
            own,
            floors: plane.into_iter().copied().collect(),
            up: plane.map_or_else(Vector3::z, |p| p.normal),
            margin: 0.0,
            parts,
        }
    }

    /// Whether grasp `g` holds on the truth: its contacts within 3 mm of the true surface and
    /// within the friction cone there, the swept gripper 3 mm clear of the floors and the other
    /// objects, and its open fingers and palm clear of the object itself.
    pub fn check(&self, g: &Grasp, gripper: &Gripper) -> Result<(), &'static str> {
        let x = g.pose.rotation * Vector3::x();
        let on_surface = if g.kind == Kind::Rim { 1 } else { 2 };
        let cos = gripper.cone().cos();
        for (k, c) in g.contacts.iter().take(on_surface).enumerate() {
            let Some((d, n)) = self.nearest(c) else {
                return Err("no true surface");
            };
            if d > TRUTH_TOLERANCE_M {
                return Err("a contact off the true surface");
            }
            let along = if k == 0 { x } else { -x };
            if n.dot(&along) < cos - 1e-9 {
                return Err("a contact outside the friction cone");
            }
        }
        let swept = Swept::new(gripper, g.opening);
        for floor in &self.floors {
            if swept.lowest_over(&g.pose, floor) < self.margin {
                return Err("the gripper within 3 mm of the table or floor");
            }
        }
        if self.others.iter().any(|p| swept.holds(&g.pose, p, self.margin)) {
            return Err("the gripper within 3 mm of another object");
        }
        // The pads close until they touch: the object may stand out past the planned contacts
        // (by the fit's error), as long as the open fingers and the palm clear it.
        if swept.solid_hits(&g.pose, &self.own) {
            return Err("the open gripper into the object");
        }
        Ok(())
    }

    /// The distance from `p` to the nearest true part's surface, and that part's outward
    /// normal there.
    fn nearest(&self, p: &Point3<f64>) -> Option<(f64, Vector3<f64>)> {
        self.parts
            .iter()
            .map(|part| {
                let q = part.placed.to_local(p);
                let g = Kernel::new(&part.placed.shape).residual_grad(&q).grad;
                let n = part.placed.pose.rotation * g.try_normalize(1e-12).unwrap_or_else(Vector3::z);
                (part.placed.surface_distance(p).abs(), n)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
    }

    /// Whether a valid grasp exists: up to [`SAMPLES`] random grasps on the true object (a
    /// random point in a part's box, a random closing direction and approach; at an open part,
    /// also random points of its rim), each checked as a planned one is.
    pub fn any_valid(&self, gripper: &Gripper, seed: u64) -> bool {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..SAMPLES).any(|_| {
            let part = &self.parts[rng.random_range(0..self.parts.len())];
            let g = if part.open && rng.random_bool(0.3) {
                random_rim(&part.placed, gripper, &mut rng)
            } else {
                random_across(&part.placed, gripper, &mut rng)
            };
            g.is_some_and(|g| {
                let tilt = (g.pose.rotation * Vector3::z()).dot(&-self.up).clamp(-1.0, 1.0).acos();
                tilt <= gripper.max_tilt && self.check(&g, gripper).is_ok()
            })
        })
    }
}

/// A unit vector uniform on the sphere.
fn random_direction(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    loop {
        let v = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let n = v.norm();
        if n > 0.1 && n <= 1.0 {
            return v / n;
        }
    }
}

/// A random grasp across `placed`: the closing line through a random point of its box along a
/// random direction, the pads where the line meets the surface.
fn random_across(placed: &PlacedSuperquadric, g: &Gripper, rng: &mut ChaCha8Rng) -> Option<Grasp> {
    let h = placed.shape.local_half_extents();
    let local = Vector3::new(
        rng.random_range(-h.x..=h.x),
        rng.random_range(-h.y..=h.y),
        rng.random_range(-h.z..=h.z),
    );
    let o = placed.pose.transform_point(&Point3::from(local));
    let x = random_direction(rng);
    let (c1, c2) = line_hits(placed, &o, &x)?;
    let opening = (c1 - c2).norm();
    if opening < g.min_opening || opening + 2.0 * g.clearance > g.max_opening || opening < 1e-4 {
        return None;
    }
    let r = random_direction(rng);
    let z = (r - x * x.dot(&r)).try_normalize(1e-6)?;
    let tcp = Point3::from(0.5 * (c1.coords + c2.coords));
    Some(Grasp::new(
        (0, Kind::Across),
        grasp_pose(&tcp, &x, &z),
        opening,
        [c1, c2],
        0.0,
        g,
    ))
}

/// A random grasp across an open part's wall: a random point of its wall below the rim, as the
/// planner's rim grasps are made.
fn random_rim(placed: &PlacedSuperquadric, g: &Gripper, rng: &mut ChaCha8Rng) -> Option<Grasp> {
    let angle = rng.random_range(0.0..std::f64::consts::TAU);
    let depth = rng.random_range(0.0..(g.finger_depth - g.pad_from_tip).min(2.0 * placed.shape.a[2]));
    Grasp::at_rim(placed, angle, depth, g)
}

/// What a detection was made on: the points, the support plane found, the viewpoint.
pub struct Scan<'a> {
    pub cloud: &'a [[f32; 3]],
    pub plane: Option<&'a crate::cloud::plane::Plane>,
    pub viewpoint: Option<Point3<f64>>,
}

/// Plan grasps for `detection` (of `model`, found in `scan`) and judge the first against the
/// truth; `seed` seeds the brute-force sampler.
pub fn judge(
    truth: &Truth,
    detection: &Detection,
    model: &Model,
    scan: &Scan<'_>,
    gripper: &Gripper,
    seed: u64,
) -> Verdict {
    let parts: Vec<Part> = detection.grasp_parts(model).into_iter().map(|(p, _)| p).collect();
    let t = Instant::now();
    let planned = plan(&parts, scan.cloud, scan.plane, scan.viewpoint, gripper, 1);
    let time_ms = t.elapsed().as_secs_f64() * 1e3;
    let first_valid = planned.first().map(|g| truth.check(g, gripper));
    Verdict {
        planned: !planned.is_empty(),
        exists: first_valid.is_some_and(|v| v.is_ok()) || truth.any_valid(gripper, seed),
        first_valid,
        time_ms,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::plane::Plane;
    use crate::geometry::Superquadric;

    /// A box standing on a table at z = 0 as a scan shows it: its fit, its surface's points
    /// and the table's round it (a 4 mm grid out to 0.3 m, less its footprint).
    fn box_on_table(a: [f64; 3], gripper: &Gripper) -> Truth {
        let shape = Superquadric::new(a, 0.1, 0.1, 0.0, 0.0).unwrap();
        let placed = PlacedSuperquadric::new(shape, Isometry3::translation(0.0, 0.0, a[2]));
        let own = placed.sample_surface(0.004);
        let mut table = Vec::new();
        for i in -75..=75 {
            for j in -75..=75 {
                let (x, y) = (0.004 * i as f64, 0.004 * j as f64);
                if x.abs() > a[0] + 0.002 || y.abs() > a[1] + 0.002 {
                    table.push(Point3::new(x, y, 0.0));
                }
            }
        }
        let plane = Plane {
            normal: Vector3::z(),
            d: 0.0,
        };
        Truth::of_scan(vec![Part { placed, open: false }], &table, own, Some(&plane), gripper)
    }

    /// On a scan, a grasp exists across a box narrower than the stroke and none across one
    /// wider every way it can be reached (from above, or from the side with a finger under the
    /// table): the sampler answers both ways.
    #[test]
    fn a_scan_has_a_grasp_across_a_narrow_box_and_none_across_a_wide_flat_one() {
        let gripper = Gripper::default();
        assert!(box_on_table([0.03, 0.06, 0.08], &gripper).any_valid(&gripper, 1));
        // A Weetabix box lying flat: 261 x 196 x 58 mm.
        assert!(!box_on_table([0.13, 0.098, 0.029], &gripper).any_valid(&gripper, 1));
    }
}
