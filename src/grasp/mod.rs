//! Grasps for a found object: where a parallel-jaw gripper can take it, from its fitted
//! superquadrics, checked against everything else the scan saw (`docs/GRASPS.md`).
//!
//! A superquadric says in closed form where its surface is and which way it faces, so the
//! candidates need no sampling of the cloud: closing lines across each part's axes (around the
//! axis of a body of revolution) through its centre and half way to its ends, and across the
//! wall at an open container's rim; each approached from every direction around the closing
//! line that the arm can reach. A candidate is kept where both contacts hold within the
//! friction cone, and the fingers and palm, swept open from the pre-grasp pose to the grasp,
//! stay clear of every scene point that is not the object's, of the object's own model beyond
//! the contacts and of the support plane. Candidates are checked best first; one that passes on
//! the fit has its pads closed on the object's measured points ([`align`]) and is checked again
//! there. One grasp is kept of each set that the object's symmetry makes equal.

mod align;
mod candidates;
mod collide;
mod gripper;
#[cfg(test)]
mod tests;
mod unseen;

pub use candidates::{Kind, grasp_pose, line_hits};
pub use collide::Swept;
pub use gripper::{Gripper, GripperError};

use crate::cloud::grid::{Grid, VoxelBits, floor_i64};
use crate::cloud::plane::Plane;
use crate::geometry::{PlacedKernel, PlacedSuperquadric};
use candidates::{Candidate, Frame};
use nalgebra::{Isometry3, Point3, Translation3, Vector3};
use rayon::prelude::*;
use std::collections::{HashMap, HashSet};

/// One grasp, in the cloud's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Grasp {
    /// The part grasped (an index into the model's parts).
    pub part: usize,
    pub kind: Kind,
    /// The pads' centre: x the closing direction, z the approach.
    pub pose: Isometry3<f64>,
    /// Distance between the contacts (m).
    pub opening: f64,
    /// Where the pads touch the object, the +x pad's first: on the fitted surface, moved to
    /// the measured one where the sensor saw it under the pads.
    pub contacts: [Point3<f64>; 2],
    /// The pose the gripper moves in from, open, along z.
    pub pregrasp: Isometry3<f64>,
    /// Lower is better: off the centre of mass, away from straight down, near the friction
    /// cone's edge.
    pub cost: f64,
}

impl Grasp {
    /// The grasp of part `part` of `kind` at `pose`, its pre-grasp pose the gripper's
    /// pre-grasp distance back along the approach.
    pub fn new(
        (part, kind): (usize, Kind),
        pose: Isometry3<f64>,
        opening: f64,
        contacts: [Point3<f64>; 2],
        cost: f64,
        gripper: &Gripper,
    ) -> Grasp {
        let back = Translation3::from(pose.rotation * Vector3::new(0.0, 0.0, -gripper.pregrasp));
        Grasp {
            part,
            kind,
            pregrasp: back * pose,
            pose,
            opening,
            contacts,
            cost,
        }
    }

    /// A rim grasp of the open part `placed` at `angle` around its axis, the pads `depth` below
    /// its rim, as the planner makes them (at twelve angles and half the fingers' reach).
    pub fn at_rim(placed: &PlacedSuperquadric, angle: f64, depth: f64, gripper: &Gripper) -> Option<Grasp> {
        let kernel = crate::geometry::Kernel::new(&placed.shape);
        let (outer, n, down) = candidates::rim_contact(&placed.shape, &kernel, angle, depth)?;
        let r = placed.pose.rotation;
        let (nw, zw) = (r * n, r * down);
        let outer = placed.pose.transform_point(&Point3::from(outer));
        let tcp = outer - nw * (0.5 * gripper.wall);
        let pose = candidates::grasp_pose(&tcp, &nw, &zw);
        Some(Grasp::new(
            (0, Kind::Rim),
            pose,
            gripper.wall,
            [outer, outer - nw * gripper.wall],
            0.0,
            gripper,
        ))
    }
}

/// One part of the object to grasp: its fitted pose and whether it is an open container.
#[derive(Debug, Clone, Copy)]
pub struct Part {
    pub placed: PlacedSuperquadric,
    pub open: bool,
}

/// Scene points within this distance of the object's fitted surface (or inside it) are the
/// object's (m): a Kinect-class sensor's noise at a metre, three sigmas.
const OBJECT_BAND: f64 = 0.006;
/// The scene's points are thinned to one per cube of this edge (m) before the checks: the
/// gripper's clearance is coarser.
const THIN: f64 = 0.003;
/// The cell (m) of the grid of the points around the object that are not its own: about a
/// finger's width, so a finger's box meets a few dozen cells.
const OTHERS_CELL: f64 = 0.015;
/// The object's model surface is sampled this far apart (m) for the check of the gripper
/// against it.
const MODEL_SPACING: f64 = 0.005;
/// The gripper keeps this much further from a compound's smaller parts (m): a handle is fitted
/// to a few dozen points, and its pose is the least certain of the object's.
const SMALL_PART_MARGIN: f64 = 0.008;
/// Candidates checked at most for one object: the best several hundred of thousands are as
/// good as any, and the checks stay within a millisecond or two.
const MAX_CHECKED: usize = 600;

/// Samples `model`'s surface for the checks of the gripper against it, ahead of its first
/// plan: the samples depend on the shape alone and are kept between detections, so only the
/// first plan for a model would pay for them (2-4 ms for a catalogue object's part).
pub fn warm(model: &crate::model::Model) {
    for p in &model.parts {
        model_samples(&p.shape, p.open);
    }
}

/// A part's surface samples for the checks of the gripper against it (kept between plans).
fn model_samples(
    shape: &crate::geometry::Superquadric,
    open: bool,
) -> std::sync::Arc<crate::surface_samples::LocalSamples> {
    crate::surface_samples::local_samples(shape, MODEL_SPACING, open)
}

/// Up to `max` grasps of the object made of `parts`, best first, checked against `scene` (the
/// whole cloud, in the parts' frame, seen from `viewpoint`) and the support `plane` (its normal
/// towards the objects).
pub fn plan(
    parts: &[Part],
    scene: &[[f32; 3]],
    plane: Option<&Plane>,
    viewpoint: Option<Point3<f64>>,
    gripper: &Gripper,
    max: usize,
) -> Vec<Grasp> {
    if parts.is_empty() || max == 0 || gripper.validate().is_err() {
        return Vec::new();
    }
    let frame = frame(parts, plane);
    let reach = parts
        .iter()
        .map(|p| {
            (Point3::from(p.placed.pose.translation.vector) - frame.centre).norm() + p.placed.shape.bounding_radius()
        })
        .fold(0.0, f64::max)
        + Swept::new(gripper, gripper.max_opening).reach();
    let t0 = std::time::Instant::now();
    let kernels: Vec<PlacedKernel> = parts.iter().map(|p| PlacedKernel::new(&p.placed)).collect();
    let (others, own) = around(&kernels, scene, plane, &frame.centre, reach, gripper.clearance);
    let own = align::Seen::new(own);
    let t1 = std::time::Instant::now();
    let surface = model_surface(parts, &frame.share);
    let unseen = viewpoint
        .filter(|_| gripper.occupy_unseen)
        .map(|v| unseen::Shadows::new(scene, v, &frame.centre, reach));
    let t2 = std::time::Instant::now();
    let mut candidates: Vec<Candidate> = parts
        .iter()
        .enumerate()
        .flat_map(|(i, p)| candidates::of_part(i, &p.placed, p.open, gripper, &frame))
        .collect();
    candidates.sort_by(|a, b| a.cost.total_cmp(&b.cost));
    let t3 = std::time::Instant::now();
    let world = World {
        others,
        others_grid: std::cell::OnceCell::new(),
        own,
        kernels,
        surface,
        unseen,
        plane,
        gripper,
        parts,
    };
    let total = candidates.len();
    let (out, refused) = world.choose(candidates, max);
    let ms = |a: std::time::Instant, b: std::time::Instant| (b - a).as_secs_f64() * 1e3;
    tracing::debug!(
        "grasps: {} kept of {total} candidates ({} points around, {} of the object's, {} on the model); refused for the plane {}, the object's own surface {}, other points {}, unseen space {}, the measured surface {}; ms: points {:.2}, model {:.2}, candidates {:.2}, checks {:.2}",
        out.len(),
        world.others.len(),
        world.own.len(),
        world.surface.len(),
        refused[0],
        refused[1],
        refused[2],
        refused[3],
        refused[4],
        ms(t0, t1),
        ms(t1, t2),
        ms(t2, t3),
        ms(t3, std::time::Instant::now()),
    );
    out
}

/// What a candidate is checked against.
struct World<'a> {
    /// The scene's points that are not the object's, around it.
    others: Vec<Point3<f64>>,
    /// `others` in cells of [`OTHERS_CELL`]: a grasp checks those in the cells its gripper's
    /// boxes meet, not every point around the object. Built for the first candidate that gets
    /// as far as that check.
    others_grid: std::cell::OnceCell<Grid>,
    /// The object's own measured points, and its parts prepared to measure them against.
    own: align::Seen,
    kernels: Vec<PlacedKernel>,
    surface: ModelSurface,
    unseen: Option<unseen::Shadows>,
    plane: Option<&'a Plane>,
    gripper: &'a Gripper,
    parts: &'a [Part],
}

impl World<'_> {
    /// Up to `max` of `candidates` (best first) that pass the checks, one for each set the
    /// symmetry makes equal, and how many were refused for each reason of [`Self::refusal`] and
    /// (4) for the opening out of range once the pads closed on the measured surface.
    fn choose(&self, candidates: Vec<Candidate>, max: usize) -> (Vec<Grasp>, [usize; 5]) {
        let (parts, gripper) = (self.parts, self.gripper);
        let mut seen: HashSet<Vec<i64>> = HashSet::new();
        let mut swept: HashMap<u64, Swept> = HashMap::new();
        let mut out = Vec::new();
        let mut refused = [0usize; 5];
        for mut c in candidates.into_iter().take(MAX_CHECKED) {
            if seen.contains(&c.key) || !c.settle(&parts[c.part].placed, gripper) {
                continue;
            }
            // Checked on the fit first: most candidates are refused there, and closing the pads
            // on the measured points costs more than the checks. What passes is checked again
            // where the pads close, against everything but the object's own model: the pads
            // moved with the object as it was seen, and the model around them moved with it.
            let mut check = |c: &Candidate, model: bool| {
                let s = swept
                    .entry(c.width.to_bits())
                    .or_insert_with(|| Swept::new(gripper, c.width));
                self.refusal(c, s, model)
            };
            let why = check(&c, true).or_else(|| {
                let part = (&parts[c.part].placed, &self.kernels[c.part]);
                if c.close_on(part, &self.own, gripper, OBJECT_BAND) {
                    check(&c, false)
                } else {
                    Some(4)
                }
            });
            if let Some(k) = why {
                refused[k] += 1;
                tracing::trace!(
                    "grasp {} of part {} at {:?} refused ({})",
                    c.kind.name(),
                    c.part,
                    c.pose.translation.vector.as_slice(),
                    [
                        "plane",
                        "object",
                        "other points",
                        "unseen space",
                        "the measured surface"
                    ][k]
                );
                continue;
            }
            seen.insert(c.key.clone());
            out.push(Grasp::new(
                (c.part, c.kind),
                c.pose,
                c.width,
                c.contacts,
                c.cost,
                gripper,
            ));
            if out.len() == max {
                break;
            }
        }
        (out, refused)
    }

    /// Why candidate `c`, sweeping `s`, is refused, if it is: the plane (0), the object's own
    /// surface (1, checked with `model`), other points (2), unseen space (3).
    fn refusal(&self, c: &Candidate, s: &Swept, model: bool) -> Option<usize> {
        let g = self.gripper;
        if self.plane.is_some_and(|pl| s.lowest_over(&c.pose, pl) < g.clearance) {
            Some(0)
        } else if model
            && (s.hits_object(&c.pose, &self.surface.main, 0.0)
                || s.hits_object(&c.pose, &self.surface.small, SMALL_PART_MARGIN))
        {
            Some(1)
        } else if s.hits_others(
            &c.pose,
            &self.others,
            self.others_grid.get_or_init(|| Grid::new(&self.others, OTHERS_CELL)),
            g.clearance,
        ) {
            Some(2)
        } else if self.unseen.as_ref().is_some_and(|u| {
            let outside = |p: &Point3<f64>| self.parts.iter().all(|q| q.placed.surface_distance(p) > g.clearance);
            u.hides(&s.surface_points(&c.pose), outside, g.clearance)
        }) {
            Some(3)
        } else {
            None
        }
    }
}

/// The object's centre of mass (its parts' volumes as weights), its size and up.
fn frame(parts: &[Part], plane: Option<&Plane>) -> Frame {
    let (mut sum, mut w) = (Vector3::zeros(), 0.0);
    for p in parts {
        let v = p.placed.shape.box_volume().max(1e-12);
        sum += p.placed.pose.translation.vector * v;
        w += v;
    }
    let centre = Point3::from(sum / w);
    let size = parts
        .iter()
        .map(|p| 2.0 * p.placed.shape.max_size())
        .fold(0.0, f64::max);
    let up = plane.map_or_else(Vector3::z, |pl| pl.normal);
    let share = parts
        .iter()
        .map(|p| p.placed.shape.box_volume().max(1e-12) / w)
        .collect();
    Frame {
        centre,
        size,
        up,
        share,
        single: parts.len() == 1,
    }
}

/// The scene's points within `reach` of `centre` that are not the support plane's (below
/// `clearance` over it: the plane is checked as a plane), thinned to one per [`THIN`] cube:
/// those that are not the object's, and those that are (within [`OBJECT_BAND`] of a part's
/// surface or inside one).
fn around(
    kernels: &[PlacedKernel],
    scene: &[[f32; 3]],
    plane: Option<&Plane>,
    centre: &Point3<f64>,
    reach: f64,
    clearance: f64,
) -> (Vec<Point3<f64>>, Vec<Point3<f64>>) {
    let inv = 1.0 / THIN;
    // The reach test in single precision, as the points are given, over the whole cloud (a
    // Kinect frame's 307,200 points): a centimetre more reach covers its rounding. NaN fails
    // the comparison and is skipped with the far points.
    let reach2 = ((reach + 0.01) * (reach + 0.01)) as f32;
    let c = [centre.x as f32, centre.y as f32, centre.z as f32];
    // The voxels a point within reach can lie in.
    let r = reach + 0.02;
    let corner = |s: f64| {
        let v = centre.coords.add_scalar(s * r) * inv;
        (floor_i64(v.x), floor_i64(v.y), floor_i64(v.z))
    };
    let (lo, hi) = (corner(-1.0), corner(1.0));
    // In chunks on the pool's threads, each thinned on its own: a voxel that two chunks share
    // keeps a point from each, which costs a check and changes no answer.
    scene
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut cells = VoxelBits::new(lo, hi);
            let (mut out, mut own) = (Vec::new(), Vec::new());
            for q in chunk {
                let (dx, dy, dz) = (q[0] - c[0], q[1] - c[1], q[2] - c[2]);
                if !(dx * dx + dy * dy + dz * dz <= reach2) {
                    continue;
                }
                let p = Point3::new(q[0] as f64, q[1] as f64, q[2] as f64);
                // An infinite point passes the reach test of an object whose reach is itself
                // beyond f32's range; the grids take finite points only.
                if !p.coords.iter().all(|v| v.is_finite()) {
                    continue;
                }
                if plane.is_some_and(|pl| pl.signed_distance(&p) < clearance) {
                    continue;
                }
                // Thinned before the object's test, the costly one.
                let cell = (floor_i64(p.x * inv), floor_i64(p.y * inv), floor_i64(p.z * inv));
                if !cells.insert(cell) {
                    continue;
                }
                // Inside a part (a negative distance) or on its surface.
                if kernels.iter().any(|k| {
                    k.surface_distance_near(&p, OBJECT_BAND)
                        .is_some_and(|d| d < OBJECT_BAND)
                }) {
                    own.push(p);
                } else {
                    out.push(p);
                }
            }
            (out, own)
        })
        .reduce(
            || (Vec::new(), Vec::new()),
            |(mut a, mut b), (c, d)| {
                a.extend(c);
                b.extend(d);
                (a, b)
            },
        )
}

/// Points a thread takes at a time in [`around`].
const CHUNK: usize = 32_768;

/// Samples of the object's model surface, without the opening of an open part (where there is
/// nothing to touch): of its largest part, and of the others.
struct ModelSurface {
    main: Vec<Point3<f64>>,
    small: Vec<Point3<f64>>,
}

impl ModelSurface {
    fn len(&self) -> usize {
        self.main.len() + self.small.len()
    }
}

fn model_surface(parts: &[Part], share: &[f64]) -> ModelSurface {
    let largest = (0..parts.len())
        .max_by(|&a, &b| share[a].total_cmp(&share[b]))
        .unwrap_or(0);
    let mut out = ModelSurface {
        main: Vec::new(),
        small: Vec::new(),
    };
    for (i, p) in parts.iter().enumerate() {
        let local = model_samples(&p.placed.shape, p.open);
        let to = if i == largest { &mut out.main } else { &mut out.small };
        to.extend(
            local
                .iter()
                .map(|(q, _)| p.placed.pose.transform_point(&Point3::from(*q))),
        );
    }
    out
}
