//! Grasp candidates in closed form from a fitted part: across its axes where its section fits
//! the opening, and across the wall at the rim of an open container. Each candidate carries its
//! contacts on the fitted surface, checked against the friction cone, and its cost.

use super::gripper::Gripper;
use crate::geometry::{Kernel, PlacedSuperquadric, Superquadric};
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, UnitQuaternion, Vector3};
use std::f64::consts::{FRAC_PI_2, PI};

/// What a grasp holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kind {
    /// Across a part, the pads on opposite sides of it.
    Across = 0,
    /// Across an open container's wall at its rim, one pad inside.
    Rim = 1,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::Across => "across",
            Kind::Rim => "rim",
        }
    }
}

/// One grasp before the collision checks.
#[derive(Debug, Clone)]
pub(super) struct Candidate {
    pub(super) part: usize,
    pub(super) kind: Kind,
    /// The pads' centre: x closing, z approach.
    pub(super) pose: Isometry3<f64>,
    /// Distance between the contacts (m).
    pub(super) width: f64,
    /// On the +x side first.
    pub(super) contacts: [Point3<f64>; 2],
    /// Lower is better: what `push` weighs.
    pub(super) cost: f64,
    /// Equal for grasps that the part's symmetry (and the gripper's half turn) maps onto each
    /// other.
    pub(super) key: Vec<i64>,
}

impl Candidate {
    /// Move an across grasp's contacts to where the pads meet the part: a pad is flat, and
    /// touches the part where it stands out furthest along the closing line over the pad's
    /// face, which is the closing line's own point only on a flat face (a can taken along a
    /// chord is wider deeper in). The part's extent is found along lines across the pads' faces;
    /// the grasp is dropped where the opening then exceeds the gripper's, or a new contact lies
    /// outside the friction cone.
    pub(super) fn settle(&mut self, placed: &PlacedSuperquadric, g: &Gripper) -> bool {
        if self.kind != Kind::Across {
            return true;
        }
        let kernel = Kernel::new(&placed.shape);
        let (x, y, z) = (
            self.pose.rotation * Vector3::x(),
            self.pose.rotation * Vector3::y(),
            self.pose.rotation * Vector3::z(),
        );
        let centre = Point3::from(self.pose.translation.vector);
        let (root, tip) = (-(g.finger_depth - g.pad_from_tip), g.pad_from_tip);
        // The outermost point on either side, as its offset along x and the point.
        let mut ends: [Option<(f64, Point3<f64>)>; 2] = [None, None];
        // The middle line first, and each line from the fingertips back: a round part is
        // widest under the middle, and a part too wide for the opening is refused as soon as
        // the lines so far show it (the width only grows line by line).
        let (middle, lines) = (PAD_LINES.0 / 2, PAD_LINES.0);
        for i in (0..lines).map(|i| (i + middle) % lines) {
            let v = g.finger_width * (i as f64 / (PAD_LINES.0 - 1) as f64 - 0.5);
            for j in (0..PAD_LINES.1).rev() {
                let w = root + (tip - root) * j as f64 / (PAD_LINES.1 - 1) as f64;
                let Some(hits) = line_hits(placed, &(centre + y * v + z * w), &x) else {
                    continue;
                };
                for (k, (s, p)) in [(1.0, hits.0), (-1.0, hits.1)].into_iter().enumerate() {
                    let out = s * (p - centre).dot(&x);
                    if ends[k].is_none_or(|(best, _)| out > best) {
                        ends[k] = Some((out, p));
                    }
                }
                if let [Some((a, _)), Some((b, _))] = ends
                    && a + b + 2.0 * g.clearance > g.max_opening
                {
                    return false;
                }
            }
        }
        let [Some((a, c1)), Some((b, c2))] = ends else {
            return false;
        };
        let width = a + b;
        if width < g.min_opening || width + 2.0 * g.clearance > g.max_opening {
            return false;
        }
        let cos = g.cone().cos();
        let holds = |c: &Point3<f64>, along: Vector3<f64>| {
            let n = placed.pose.rotation
                * kernel
                    .residual_grad(&placed.to_local(c))
                    .grad
                    .try_normalize(1e-12)
                    .unwrap_or_else(Vector3::zeros);
            n.dot(&along) >= cos
        };
        if !holds(&c1, x) || !holds(&c2, -x) {
            return false;
        }
        let shift = x * (0.5 * (a - b));
        self.pose = Isometry3::from_parts((centre.coords + shift).into(), self.pose.rotation);
        self.width = width;
        self.contacts = [c1, c2];
        true
    }
}

/// Lines across a pad's face along which [`Candidate::settle`] measures the part: across the
/// finger's width (its edges and its middle: a round part stands out furthest under the middle,
/// and measured at the edges alone its contacts would lie on a chord, inside its surface) and
/// along its depth.
const PAD_LINES: (usize, usize) = (3, 4);

/// Closing directions tried across a body of revolution's axis, over half a turn.
const ROUND_DIRECTIONS: usize = 6;
/// Approach directions tried about each closing line, over a whole turn.
const APPROACHES: usize = 12;
/// Points of the rim tried around an open container.
const RIM_POINTS: usize = 12;
/// Symmetry keys round positions to this (m) and direction components to a twentieth.
const KEY_POSITION: f64 = 0.005;
const KEY_DIRECTION: f64 = 0.05;

/// What a candidate's cost weighs, in its units: the pads' centre away from the object's
/// centre (per object size), the approach away from straight down (per right angle), the
/// contacts' normals away from the closing line (per friction cone).
const W_CENTRE: f64 = 1.0;
const W_TILT: f64 = 0.5;
const W_FRICTION: f64 = 0.25;
/// And the part's smallness (one less its share of the object's volume): a compound's small
/// parts (a handle) are fitted to fewer points, their poses the least certain.
const W_PART: f64 = 0.5;

/// Where the candidates are judged: the object's centre of mass and size, and up.
pub(super) struct Frame {
    pub(super) centre: Point3<f64>,
    pub(super) size: f64,
    pub(super) up: Vector3<f64>,
    /// Each part's share of the object's volume.
    pub(super) share: Vec<f64>,
    /// The object is this one part, so the part's symmetries are the object's: a compound's
    /// other parts (a mug's handle) tell grasps apart that its body alone would not.
    pub(super) single: bool,
}

/// The candidates of one part.
pub(super) fn of_part(
    index: usize,
    placed: &PlacedSuperquadric,
    open: bool,
    g: &Gripper,
    frame: &Frame,
) -> Vec<Candidate> {
    let mut out = Vec::new();
    across(index, placed, open, g, frame, &mut out);
    if open {
        rim(index, placed, g, frame, &mut out);
    }
    out
}

/// The first point where the line `o + t dir` (local frame) meets the shape, coming from far
/// along `-dir`.
fn hit(shape: &Superquadric, o: &Vector3<f64>, dir: &Vector3<f64>) -> Option<Vector3<f64>> {
    let reach = 2.0 * shape.bounding_radius() + 0.01;
    let start = o - dir * reach;
    let t = shape.ray_hit(&start, dir, 2.0 * reach)?;
    (t > 0.0).then(|| start + dir * t)
}

/// Where the line through `o` along `x` (in the cloud's frame) meets the part: on its +x side
/// and on its -x side.
pub fn line_hits(placed: &PlacedSuperquadric, o: &Point3<f64>, x: &Vector3<f64>) -> Option<(Point3<f64>, Point3<f64>)> {
    let (lo, lx) = (placed.to_local(o), placed.pose.inverse_transform_vector(x));
    let (c1, c2) = (hit(&placed.shape, &lo, &-lx)?, hit(&placed.shape, &lo, &lx)?);
    let world = |c: Vector3<f64>| placed.pose.transform_point(&Point3::from(c));
    Some((world(c1), world(c2)))
}

/// The outward unit normal at a local surface point.
fn normal(kernel: &Kernel, q: &Vector3<f64>) -> Option<Vector3<f64>> {
    kernel.residual_grad(q).grad.try_normalize(1e-12)
}

/// Grasps across the part: the closing line along each axis (around the axis of a body of
/// revolution), through the centre and, on a long part, half way to either end.
fn across(index: usize, placed: &PlacedSuperquadric, open: bool, g: &Gripper, frame: &Frame, out: &mut Vec<Candidate>) {
    let shape = &placed.shape;
    let kernel = Kernel::new(shape);
    let ext = shape.local_half_extents();
    let round = shape.is_revolution();
    let mut closings: Vec<Vector3<f64>> = if round {
        (0..ROUND_DIRECTIONS)
            .map(|j| {
                let t = PI * j as f64 / ROUND_DIRECTIONS as f64;
                Vector3::new(t.cos(), t.sin(), 0.0)
            })
            .collect()
    } else {
        vec![Vector3::x(), Vector3::y()]
    };
    // Across an open part's axis the pads would close on the opening.
    if !open {
        closings.push(Vector3::z());
    }
    // How deep the pads may reach past the object's near face: the fingers' length to the
    // pads, less the clearance the palm keeps.
    let depth = g.finger_depth - g.pad_from_tip - g.clearance;
    for u in closings {
        // Along the longest axis across the closing line, the pads may sit off the centre.
        let along = (0..3)
            .map(|k| Vector3::ith(k, 1.0))
            .filter(|v: &Vector3<f64>| v.dot(&u).abs() < 0.5)
            .max_by(|a, b| a.dot(&ext).abs().total_cmp(&b.dot(&ext).abs()))
            .unwrap_or_else(Vector3::z);
        let reach = along.dot(&ext).abs();
        let side = along.cross(&u);
        for k in 0..APPROACHES {
            let phi = 2.0 * PI * k as f64 / APPROACHES as f64;
            let z = along * phi.cos() + side * phi.sin();
            // An approach the arm cannot take needs no contacts (the line hits are the cost).
            if tilt(placed, &z, frame) > g.max_tilt + 1e-9 {
                continue;
            }
            let offsets: &[f64] = if reach > 2.0 * g.finger_width && z.dot(&along).abs() < 0.5 {
                &[0.0, 0.5, -0.5]
            } else {
                &[0.0]
            };
            for &f in offsets {
                let line = along * (f * reach);
                // An object deeper than the fingers along the approach is taken at its near
                // end: the pads move back towards the palm until the near face is within reach.
                let Some(near) = hit(shape, &line, &z) else {
                    continue;
                };
                // Further back too: a round part taken from the side along a chord is wider
                // deeper in, where the fingertips reach.
                let to_near = z.dot(&(line - near));
                let least = (to_near - depth).max(0.0);
                for back in [0.0, 0.25, 0.5].map(|f| least + f * to_near) {
                    if back >= to_near {
                        continue;
                    }
                    let o = line - z * back;
                    let (Some(c1), Some(c2)) = (hit(shape, &o, &-u), hit(shape, &o, &u)) else {
                        continue;
                    };
                    let width = (c1 - c2).norm();
                    if width < g.min_opening || width + 2.0 * g.clearance > g.max_opening {
                        continue;
                    }
                    let (Some(n1), Some(n2)) = (normal(&kernel, &c1), normal(&kernel, &c2)) else {
                        continue;
                    };
                    let friction = n1
                        .dot(&u)
                        .clamp(-1.0, 1.0)
                        .acos()
                        .max(n2.dot(&-u).clamp(-1.0, 1.0).acos());
                    // Where the pads touch, and so the friction there, is settled when the
                    // candidate is checked (`settle`): a chord's ends are not where the pads'
                    // tips meet the part. The line's angle only ranks the candidate.
                    let friction = friction.min(g.cone());
                    let tcp = 0.5 * (c1 + c2);
                    push(
                        index,
                        Kind::Across,
                        placed,
                        (&tcp, &u, &z),
                        width,
                        [c1, c2],
                        friction,
                        g,
                        frame,
                        out,
                    );
                }
            }
        }
    }
}

/// Grasps across an open container's wall at its rim: the pads a little below the rim, one
/// inside and one outside, closing along the wall's normal and approaching down along the wall.
fn rim(index: usize, placed: &PlacedSuperquadric, g: &Gripper, frame: &Frame, out: &mut Vec<Candidate>) {
    let shape = &placed.shape;
    let kernel = Kernel::new(shape);
    if g.wall < g.min_opening || g.wall + 2.0 * g.clearance > g.max_opening {
        return;
    }
    let depth = (0.5 * (g.finger_depth - g.pad_from_tip)).min(shape.a[2]);
    for j in 0..RIM_POINTS {
        let angle = 2.0 * PI * j as f64 / RIM_POINTS as f64;
        let Some((outer, n, down)) = rim_contact(shape, &kernel, angle, depth) else {
            continue;
        };
        let inner = outer - n * g.wall;
        let tcp = outer - n * (0.5 * g.wall);
        push(
            index,
            Kind::Rim,
            placed,
            (&tcp, &n, &down),
            g.wall,
            [outer, inner],
            0.0,
            g,
            frame,
            out,
        );
    }
}

/// Where a grasp across an open part's wall at `angle` around its axis, the pads `depth` below
/// its rim, touches the outer wall (local frame): the contact, the wall's outward normal there
/// (the closing direction) and the approach. The pads lie along the wall, so the approach
/// follows it down: a flared bowl's wall leans out by its taper, and a gripper coming straight
/// down would meet it above the pads.
pub(super) fn rim_contact(
    shape: &Superquadric,
    kernel: &Kernel,
    angle: f64,
    depth: f64,
) -> Option<(Vector3<f64>, Vector3<f64>, Vector3<f64>)> {
    let d = Vector3::new(angle.cos(), angle.sin(), 0.0);
    let outer = hit(shape, &Vector3::new(0.0, 0.0, shape.a[2] - depth), &-d)?;
    let n = normal(kernel, &outer)?;
    let down = (n * n.z - Vector3::z()).try_normalize(1e-9)?;
    Some((outer, n, down))
}

/// The pose of a grasp whose pads' centre is `tcp`, closing along `x` and approaching along `z`
/// (unit and orthogonal).
pub fn grasp_pose(tcp: &Point3<f64>, x: &Vector3<f64>, z: &Vector3<f64>) -> Isometry3<f64> {
    let rot = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[*x, z.cross(x), *z]));
    Isometry3::from_parts(tcp.coords.into(), UnitQuaternion::from_rotation_matrix(&rot))
}

/// How far (rad) the approach `z` (local to the part) leans from straight down.
fn tilt(placed: &PlacedSuperquadric, z: &Vector3<f64>, frame: &Frame) -> f64 {
    (placed.pose.rotation * z).dot(&-frame.up).clamp(-1.0, 1.0).acos()
}

/// Add the candidate with pads' centre `tcp`, closing along `x` and approaching along `z`
/// (local to the part), where the arm can reach that approach.
#[allow(clippy::too_many_arguments)]
fn push(
    index: usize,
    kind: Kind,
    placed: &PlacedSuperquadric,
    (tcp, x, z): (&Vector3<f64>, &Vector3<f64>, &Vector3<f64>),
    width: f64,
    contacts: [Vector3<f64>; 2],
    friction: f64,
    g: &Gripper,
    frame: &Frame,
    out: &mut Vec<Candidate>,
) {
    let r = placed.pose.rotation;
    let (xw, zw) = (r * x, r * z);
    let tilt = tilt(placed, z, frame);
    if tilt > g.max_tilt + 1e-9 {
        return;
    }
    let centre = placed.pose.transform_point(&Point3::from(*tcp));
    let pose = grasp_pose(&centre, &xw, &zw);
    let off_centre = (centre - frame.centre).norm() / frame.size.max(1e-3);
    let small = 1.0 - frame.share.get(index).copied().unwrap_or(1.0);
    let cost = W_CENTRE * off_centre + W_TILT * tilt / FRAC_PI_2 + W_FRICTION * friction / g.cone() + W_PART * small;
    out.push(Candidate {
        part: index,
        kind,
        pose,
        width,
        contacts: contacts.map(|c| placed.pose.transform_point(&Point3::from(c))),
        cost,
        key: if frame.single {
            key(index, kind, placed, tcp, x, z)
        } else {
            plain_key(index, kind, tcp, x, z)
        },
    });
}

/// A grasp's description that the part's symmetries leave unchanged: about the axis of a body
/// of revolution its distance from the axis, its height and the directions' angles with the
/// axis and with the radial direction; for any other part the magnitudes of its coordinates
/// and directions (its half turns about the axes flip their signs in pairs, as does the
/// gripper's own half turn about its approach). A taper makes the sign along z matter.
fn key(
    index: usize,
    kind: Kind,
    placed: &PlacedSuperquadric,
    tcp: &Vector3<f64>,
    x: &Vector3<f64>,
    z: &Vector3<f64>,
) -> Vec<i64> {
    let shape = &placed.shape;
    let zs = |v: f64| if shape.is_tapered() { v } else { v.abs() };
    let p = |v: f64| (v / KEY_POSITION).round() as i64;
    let d = |v: f64| (v / KEY_DIRECTION).round() as i64;
    let mut k = vec![index as i64, kind as i64];
    if shape.is_revolution() {
        let radial = Vector3::new(tcp.x, tcp.y, 0.0).try_normalize(1e-6);
        let along_radial = |v: &Vector3<f64>| radial.map_or(0.0, |r| v.dot(&r).abs());
        k.extend([
            p(tcp.xy().norm()),
            p(zs(tcp.z)),
            d(x.z.abs()),
            d(zs(z.z)),
            d(along_radial(x)),
            d(along_radial(z)),
        ]);
    } else {
        k.extend([p(tcp.x.abs()), p(tcp.y.abs()), p(zs(tcp.z))]);
        k.extend([d(x.x.abs()), d(x.y.abs()), d(x.z.abs())]);
        k.extend([d(z.x.abs()), d(z.y.abs()), d(zs(z.z))]);
    }
    k
}

/// A grasp's description up to the gripper's own half turn about its approach only: the part's
/// coordinates and directions as they are, the closing direction's sign chosen.
fn plain_key(index: usize, kind: Kind, tcp: &Vector3<f64>, x: &Vector3<f64>, z: &Vector3<f64>) -> Vec<i64> {
    let p = |v: f64| (v / KEY_POSITION).round() as i64;
    let d = |v: f64| (v / KEY_DIRECTION).round() as i64;
    let first = x.iter().copied().find(|c| c.abs() > 1e-6).unwrap_or(1.0);
    let x = if first < 0.0 { -x } else { *x };
    let mut k = vec![index as i64, kind as i64];
    k.extend(tcp.iter().map(|&v| p(v)));
    k.extend(x.iter().map(|&v| d(v)));
    k.extend(z.iter().map(|&v| d(v)));
    k
}
