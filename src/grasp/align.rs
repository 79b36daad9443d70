//! The pads close on what the sensor saw: a candidate's contacts, placed on the fitted surface,
//! move along the closing line by how far the object's own measured points under each pad lie
//! outside the fitted surface (the median of their distances from it, along its normal: a
//! curved side under a flat pad is not taken for a surface set back).
//!
//! Why: the fitted pose is off by the detection's error (a few millimetres on a partly hidden
//! object), and the contacts and the open fingers inherit it. Where the sensor saw the surface
//! under a pad, that surface is where the pad will touch it: a grasp across a can whose fit
//! sits 5 mm to one side swings its open finger into the can, and a grasp across a bowl's rim
//! placed on a fit 5 mm inside the true rim puts its outer pad on nothing. Where a pad's side
//! was not seen (the back of an object), the fitted surface is all there is, and the grasp
//! moves as the seen side says.

use super::candidates::{Candidate, Kind, line_hits};
use super::gripper::Gripper;
use crate::cloud::grid::Grid;
use crate::geometry::{PlacedKernel, PlacedSuperquadric};
use nalgebra::{Isometry3, Point3, Vector3};
use std::f64::consts::FRAC_1_SQRT_2;

/// Measured points the object has under a pad before they say where its surface is: a few
/// voxels of the thinned cloud.
const MIN_POINTS: usize = 6;
/// How far a grasp moves back along its approach where the face towards the palm was not seen
/// (m): the fit's error along an axis the view leaves open, on a partly seen object.
const UNSEEN_MARGIN: f64 = 0.01;

/// The object's own measured points (the scene's points on or inside its fitted parts, thinned)
/// with a grid to find those under a pad.
pub(super) struct Seen {
    points: Vec<Point3<f64>>,
    grid: Option<Grid>,
}

impl Seen {
    pub(super) fn new(points: Vec<Point3<f64>>) -> Seen {
        let grid = (!points.is_empty()).then(|| Grid::new(&points, 0.01));
        Seen { points, grid }
    }

    pub(super) fn len(&self) -> usize {
        self.points.len()
    }

    /// The signed distances (m, outward) from the fitted part `kernel` of the measured points
    /// within `radius` of `around` that lie in `region` (given a point's coordinates in the
    /// grasp's frame, `at`), within `reach` of the fitted surface and where the fit faces within
    /// 45 degrees of `facing`: the face a pad or the palm meets, not the edge or the next face.
    fn distances(
        &self,
        kernel: &PlacedKernel,
        at: &Isometry3<f64>,
        near: (&Point3<f64>, f64),
        (region, facing): (impl Fn(&Vector3<f64>) -> bool, &Vector3<f64>),
        reach: f64,
    ) -> Vec<f64> {
        self.values(at, near, |p, q| {
            if !region(q) {
                return None;
            }
            let (d, n) = kernel.surface_distance_normal(p);
            (d.abs() <= reach && n.dot(facing) >= FRAC_1_SQRT_2).then_some(d)
        })
    }

    /// `value` of each measured point within `radius` of `around` (given the point and its
    /// coordinates in the grasp's frame, `at`), where it has one.
    fn values(
        &self,
        at: &Isometry3<f64>,
        (around, radius): (&Point3<f64>, f64),
        value: impl Fn(&Point3<f64>, &Vector3<f64>) -> Option<f64>,
    ) -> Vec<f64> {
        let Some(grid) = &self.grid else {
            return Vec::new();
        };
        // Into the grasp's frame by a matrix: a quaternion a point costs several times as much.
        let rt = at.rotation.to_rotation_matrix().into_inner().transpose();
        let t = at.translation.vector;
        let mut out = Vec::new();
        grid.for_each_within(&self.points, around, radius, |i| {
            let p = self.points[i];
            if let Some(v) = value(&p, &(rt * (p.coords - t))) {
                out.push(v);
            }
        });
        out
    }
}

/// The median of `v` (reordered), if it holds enough points.
fn median(v: &mut [f64]) -> Option<f64> {
    if v.len() < MIN_POINTS {
        return None;
    }
    crate::numeric::median(v)
}

impl Candidate {
    /// Move the candidate's pads along the closing line onto the measured surface (at most
    /// `reach` per pad): an across grasp's each pad to the median of the points under it,
    /// the other following where only one side was seen; a rim grasp as a whole, its outer
    /// pad to the median of the wall's points between and under its pads. False where the
    /// opening then leaves the gripper's range.
    pub(super) fn close_on(
        &mut self,
        (placed, kernel): (&PlacedSuperquadric, &PlacedKernel),
        seen: &Seen,
        g: &Gripper,
        reach: f64,
    ) -> bool {
        let (root, tip) = (-(g.finger_depth - g.pad_from_tip), g.pad_from_tip);
        let half_width = 0.5 * g.finger_width;
        let on_pad = |q: &Vector3<f64>| q.y.abs() <= half_width && q.z >= root && q.z <= tip;
        let (x, z) = (self.pose.rotation * Vector3::x(), self.pose.rotation * Vector3::z());
        let centre = Point3::from(self.pose.translation.vector);
        let (a, b) = (0.5 * self.width, reach);
        // The middle of the pads' faces, and how far from it a point under a pad may lie:
        // half the face's length and width, and `across` along the closing line.
        let middle = centre + z * (0.5 * (root + tip));
        let radius = |across: f64| (0.25 * (tip - root).powi(2) + half_width.powi(2) + across.powi(2)).sqrt();
        // How far each contact moves outward along its own side's direction (+x, -x).
        let (d0, d1) = match self.kind {
            Kind::Across => {
                let side = |s: f64| {
                    let mut d = seen.distances(
                        kernel,
                        &self.pose,
                        (&(middle + x * (s * a)), radius(b)),
                        (
                            |q: &Vector3<f64>| on_pad(q) && s * q.x > 0.0 && (s * q.x - a).abs() <= b,
                            &(x * s),
                        ),
                        reach,
                    );
                    median(&mut d)
                };
                match (side(1.0), side(-1.0)) {
                    (Some(a), Some(b)) => (a, b),
                    (Some(a), None) => (a, -a),
                    (None, Some(b)) => (-b, b),
                    (None, None) => (0.0, 0.0),
                }
            }
            Kind::Rim => {
                // Both faces of the wall lie between the pads, and all its points count: their
                // offsets from the outer contact along the closing line (the approach runs down
                // the wall, so the pads' faces lie along it; a distance from the fit along its
                // normal would count how the rim's edge and the lip curve, not the shift across).
                let mut d = seen.values(&self.pose, (&middle, radius(a + b)), |_, q| {
                    (on_pad(q) && q.x.abs() <= a + b).then_some(q.x - a)
                });
                match median(&mut d) {
                    Some(a) => (a, -a),
                    None => (0.0, 0.0),
                }
            }
        };
        let width = self.width + d0 + d1;
        if width < g.min_opening.min(self.width) || width + 2.0 * g.clearance > g.max_opening {
            return false;
        }
        self.contacts = [self.contacts[0] + x * d0, self.contacts[1] - x * d1];
        self.pose.translation.vector += x * (0.5 * (d0 - d1));
        self.width = width;
        self.kind == Kind::Rim || self.back_from_palm((placed, kernel), seen, g, reach)
    }

    /// The grasp moved back along its approach where the part's face towards the palm stands
    /// out of the fit, or was not seen; false where its closing line then misses the part.
    fn back_from_palm(
        &mut self,
        (placed, kernel): (&PlacedSuperquadric, &PlacedKernel),
        seen: &Seen,
        g: &Gripper,
        reach: f64,
    ) -> bool {
        let root = -(g.finger_depth - g.pad_from_tip);
        let a = 0.5 * self.width;
        let x = self.pose.rotation * Vector3::x();
        // The face towards the palm, where the line along the approach through the pads' centre
        // meets the part: where it was seen standing out of the fit (the median distance of the
        // points there, between the pads and off the sides they hold), the grasp moves back so
        // that the palm keeps its clearance from what was seen. Where it was not seen (the top of
        // a can above the sweep, the back of a box), it may stand out by the fit's error along
        // the axis the view leaves open, and the palm keeps `UNSEEN_MARGIN` more. Either way the
        // closing line must still meet the part.
        let z = self.pose.rotation * Vector3::z();
        let centre = Point3::from(self.pose.translation.vector);
        let Some((_, near)) = line_hits(placed, &centre, &z) else {
            return true;
        };
        let near = (near - centre).dot(&z);
        let palm_face = root + g.clearance;
        if near > palm_face + UNSEEN_MARGIN + reach {
            return true;
        }
        // The face between the pads, as wide as the palm along y.
        let (px, py) = ((0.5 * g.palm[0]).min(a), 0.5 * g.palm[1]);
        let mut d = seen.distances(
            kernel,
            &self.pose,
            (&(centre + z * near), (px * px + py * py + reach * reach).sqrt()),
            (
                |q: &Vector3<f64>| q.x.abs() <= px && q.y.abs() <= py && (q.z - near).abs() <= reach,
                &-z,
            ),
            reach,
        );
        let back = match median(&mut d) {
            Some(m) => palm_face - (near - m),
            None => palm_face + UNSEEN_MARGIN - near,
        };
        if back > 0.0 {
            let back = z * back;
            if line_hits(placed, &(centre - back), &x).is_none() {
                return false;
            }
            self.pose.translation.vector -= back;
            self.contacts = self.contacts.map(|c| c - back);
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Superquadric;
    use nalgebra::{Isometry3, UnitQuaternion};

    /// A can 80 mm tall, 60 mm across, standing on z = 0, and the candidate across it from
    /// above whose palm keeps the clearance from its fitted top.
    fn can_from_above(g: &Gripper) -> (PlacedSuperquadric, Candidate) {
        let shape = Superquadric::new([0.03, 0.03, 0.04], 0.1, 1.0, 0.0, 0.0).unwrap();
        let placed = PlacedSuperquadric::new(
            shape,
            Isometry3::from_parts(Vector3::new(0.0, 0.0, 0.04).into(), UnitQuaternion::identity()),
        );
        let palm_from_pads = g.finger_depth - g.pad_from_tip;
        let tcp = Point3::new(0.0, 0.0, 0.08 + g.clearance - palm_from_pads);
        let c = Candidate {
            part: 0,
            kind: Kind::Across,
            pose: super::super::grasp_pose(&tcp, &Vector3::x(), &-Vector3::z()),
            width: 0.06,
            contacts: [tcp + Vector3::x() * 0.03, tcp - Vector3::x() * 0.03],
            cost: 0.0,
            key: Vec::new(),
        };
        (placed, c)
    }

    fn surface(placed: &PlacedSuperquadric, below: f64) -> Seen {
        Seen::new(
            placed
                .sample_surface(0.003)
                .into_iter()
                .filter(|p| p.z > 0.001 && p.z < below)
                .collect(),
        )
    }

    #[test]
    fn a_grasp_whose_palm_faces_an_unseen_top_moves_back_by_the_margin() {
        let g = Gripper::default();
        let (placed, c) = can_from_above(&g);
        let kernel = PlacedKernel::new(&placed);
        // Seen whole: the grasp stays where it was planned.
        let mut seen = c.clone();
        assert!(seen.close_on((&placed, &kernel), &surface(&placed, 1.0), &g, 0.006));
        assert!((seen.pose.translation.vector - c.pose.translation.vector).norm() < 5e-4);
        // The top 20 mm not seen: the palm keeps the margin more, straight back up.
        let mut unseen = c.clone();
        assert!(unseen.close_on((&placed, &kernel), &surface(&placed, 0.06), &g, 0.006));
        let moved = unseen.pose.translation.vector - c.pose.translation.vector;
        assert!((moved - Vector3::z() * UNSEEN_MARGIN).norm() < 1e-6, "moved {moved}");
        assert!((unseen.contacts[0] - c.contacts[0] - moved).norm() < 1e-9);
        // Seen standing 3 mm higher than its fit: the grasp moves back 3 mm.
        let higher: Vec<Point3<f64>> = placed
            .sample_surface(0.003)
            .into_iter()
            .filter(|p| p.z > 0.001)
            .map(|p| p + Vector3::z() * 0.003)
            .collect();
        let mut up = c.clone();
        assert!(up.close_on((&placed, &kernel), &Seen::new(higher), &g, 0.006));
        let moved = up.pose.translation.vector - c.pose.translation.vector;
        assert!((moved.z - 0.003).abs() < 5e-4, "moved {moved}");
    }
}
