//! The volumes a gripper sweeps for a grasp and the checks against them: the scene's points
//! that are not the object's, the object's own model surface and the support plane.

use super::gripper::Gripper;
use crate::cloud::grid::Grid;
use crate::cloud::plane::Plane;
use nalgebra::{Isometry3, Point3, Vector3};

/// An axis-aligned box in the grasp's frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct Cuboid {
    pub(super) lo: Vector3<f64>,
    pub(super) hi: Vector3<f64>,
}

impl Cuboid {
    fn holds(&self, q: &Vector3<f64>, margin: f64) -> bool {
        (0..3).all(|k| q[k] > self.lo[k] - margin && q[k] < self.hi[k] + margin)
    }

    /// The box `centre ± half` in the cloud's frame that holds this one, widened by `margin`,
    /// for the grasp at `pose`.
    fn bounds(&self, pose: &Isometry3<f64>, margin: f64) -> (Point3<f64>, Vector3<f64>) {
        let centre = pose.transform_point(&Point3::from(0.5 * (self.lo + self.hi)));
        let half = 0.5 * (self.hi - self.lo) + Vector3::repeat(margin);
        let r = pose.rotation.to_rotation_matrix().into_inner().abs();
        // A nanometre more: the points are taken into the grasp's frame another way, and one on
        // a face of an unturned box could round to just outside bounds reckoned exactly.
        (centre, (r * half).add_scalar(1e-9))
    }

    fn corners(&self) -> impl Iterator<Item = Vector3<f64>> + '_ {
        (0..8).map(move |c| {
            Vector3::new(
                if c & 1 == 0 { self.lo.x } else { self.hi.x },
                if c & 2 == 0 { self.lo.y } else { self.hi.y },
                if c & 4 == 0 { self.lo.z } else { self.hi.z },
            )
        })
    }
}

/// The map from the cloud's frame into the grasp's, as a matrix: a quaternion per point would
/// cost several times as much, and the checks take thousands of points per grasp.
fn to_grasp(pose: &Isometry3<f64>) -> impl Fn(&Point3<f64>) -> Vector3<f64> {
    let rt = pose.rotation.to_rotation_matrix().into_inner().transpose();
    let t = pose.translation.vector;
    move |p| rt * (p.coords - t)
}

/// What the gripper occupies for a grasp of opening `width`, in the grasp's frame.
#[derive(Debug, Clone)]
pub struct Swept {
    /// The fingers (open by the clearance on each side) and the palm, from the pre-grasp pose to
    /// the grasp: each box stretched back along -z by the pre-grasp distance.
    pub(super) solid: [Cuboid; 3],
    /// Where the pads close, from the open fingers to the contacts: the object's own surface
    /// may not reach in here beyond the contacts (it would stop the fingers early).
    pub(super) closing: [Cuboid; 2],
    /// Between the pads at the grasp: a point of something else here would be squeezed.
    pub(super) gap: Cuboid,
}

/// How far apart [`Swept::surface_points`] lie (m).
const SURFACE_SPACING: f64 = 0.01;

/// How far past the contacts the object's surface may stand inside the closing fingers' path
/// (m): its sampled surface and the contact line's ray hit differ by this much on a flat face.
const CONTACT_SLACK: f64 = 0.002;

impl Swept {
    /// What `g` sweeps for a grasp of opening `width`.
    pub fn new(g: &Gripper, width: f64) -> Swept {
        let open = (width + 2.0 * g.clearance).min(g.max_opening).max(width);
        let (half, half_open) = (0.5 * width, 0.5 * open);
        let fw = 0.5 * g.finger_width;
        let root = -(g.finger_depth - g.pad_from_tip);
        let tip = g.pad_from_tip;
        let back = g.pregrasp;
        let t = g.finger_thickness;
        let finger = |s: f64| {
            let (a, b) = (s * half_open, s * (half_open + t));
            Cuboid {
                lo: Vector3::new(a.min(b), -fw, root - back),
                hi: Vector3::new(a.max(b), fw, tip),
            }
        };
        let (px, py, pz) = (0.5 * g.palm[0], 0.5 * g.palm[1], g.palm[2]);
        let palm = Cuboid {
            lo: Vector3::new(-px, -py, root - pz - back),
            hi: Vector3::new(px, py, root),
        };
        let closing = |s: f64| {
            let (a, b) = (s * (half + CONTACT_SLACK), s * half_open);
            Cuboid {
                lo: Vector3::new(a.min(b), -fw, root),
                hi: Vector3::new(a.max(b), fw, tip),
            }
        };
        Swept {
            solid: [finger(1.0), finger(-1.0), palm],
            closing: [closing(1.0), closing(-1.0)],
            gap: Cuboid {
                lo: Vector3::new(-half, -fw, root),
                hi: Vector3::new(half, fw, tip),
            },
        }
    }

    /// Whether one of `others` (points that are not the object's, in the cloud's frame) lies in
    /// the swept solid within `clearance`, or between the pads.
    /// `grid` holds `others`: only the points in the cells each box's bounds meet are tested.
    pub(super) fn hits_others(
        &self,
        pose: &Isometry3<f64>,
        others: &[Point3<f64>],
        grid: &Grid,
        clearance: f64,
    ) -> bool {
        if others.is_empty() {
            return false;
        }
        let local = to_grasp(pose);
        let boxes = self.solid.iter().map(|b| (b, clearance)).chain([(&self.gap, 0.0)]);
        boxes.into_iter().any(|(b, margin)| {
            let (centre, half) = b.bounds(pose, margin);
            grid.any_in_box(&centre, &half, |i| b.holds(&local(&others[i]), margin))
        })
    }

    /// Whether the object's own surface (`surface`, samples in the cloud's frame) lies within
    /// `margin` of the swept solid or of the pads' path beyond the contacts.
    pub fn hits_object(&self, pose: &Isometry3<f64>, surface: &[Point3<f64>], margin: f64) -> bool {
        let local = to_grasp(pose);
        surface.iter().any(|p| {
            let q = local(p);
            self.solid.iter().chain(&self.closing).any(|b| b.holds(&q, margin))
        })
    }

    /// Whether one of `points` (in the cloud's frame) lies in the swept solid itself, the open
    /// fingers and the palm from the pre-grasp pose on: what the gripper would run into before
    /// its pads close.
    pub fn solid_hits(&self, pose: &Isometry3<f64>, points: &[Point3<f64>]) -> bool {
        let local = to_grasp(pose);
        points.iter().any(|p| {
            let q = local(p);
            self.solid.iter().any(|b| b.holds(&q, 0.0))
        })
    }

    /// Points on the faces of the swept solid about [`SURFACE_SPACING`] apart, in the cloud's
    /// frame for the grasp at `pose`: what [`super::unseen`] looks along the lines of sight for.
    pub(super) fn surface_points(&self, pose: &Isometry3<f64>) -> Vec<Point3<f64>> {
        let mut out = Vec::new();
        for b in &self.solid {
            let size = b.hi - b.lo;
            let n = size.map(|v| ((v / SURFACE_SPACING).ceil() as usize).max(1));
            for k in 0..3 {
                let (i, j) = ((k + 1) % 3, (k + 2) % 3);
                for side in [b.lo[k], b.hi[k]] {
                    for a in 0..=n[i] {
                        for c in 0..=n[j] {
                            let mut q = Vector3::zeros();
                            q[k] = side;
                            q[i] = b.lo[i] + size[i] * a as f64 / n[i] as f64;
                            q[j] = b.lo[j] + size[j] * c as f64 / n[j] as f64;
                            out.push(pose.transform_point(&Point3::from(q)));
                        }
                    }
                }
            }
        }
        out
    }

    /// The farthest the swept solid reaches from the pads' centre (m).
    pub(super) fn reach(&self) -> f64 {
        self.solid
            .iter()
            .flat_map(|b| b.corners().collect::<Vec<_>>())
            .map(|c| c.norm())
            .fold(0.0, f64::max)
    }

    /// Whether `p` (in the cloud's frame) lies within `margin` of the swept solid, or between
    /// the pads.
    pub fn holds(&self, pose: &Isometry3<f64>, p: &Point3<f64>, margin: f64) -> bool {
        let q = pose.inverse_transform_point(p).coords;
        self.solid.iter().any(|b| b.holds(&q, margin)) || self.gap.holds(&q, 0.0)
    }

    /// The least height over `plane` of the swept solid's corners (m).
    pub fn lowest_over(&self, pose: &Isometry3<f64>, plane: &Plane) -> f64 {
        self.solid
            .iter()
            .flat_map(|b| b.corners().collect::<Vec<_>>())
            .map(|c| plane.signed_distance(&pose.transform_point(&Point3::from(c))))
            .fold(f64::INFINITY, f64::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    /// Read through the grid, each point another object leaves in the swept gripper is found,
    /// and none other, as a scan of every point finds them: for grasps unturned, turned by
    /// quarter turns and turned every way, with points on either side of each box's faces
    /// (within and beyond the clearance) among others all around.
    #[test]
    fn the_gridded_check_of_other_points_matches_a_scan_of_all() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let g = Gripper::default();
        let swept = Swept::new(&g, 0.05);
        let quarter = std::f64::consts::FRAC_PI_2;
        let mut checked = 0;
        for t in 0..60 {
            let rotation = match t % 3 {
                0 => Vector3::zeros(),
                1 => Vector3::new(quarter * (t % 4) as f64, 0.0, quarter),
                _ => Vector3::new(
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                ),
            };
            let pose = Isometry3::new(
                Vector3::new(rng.random_range(-0.1..0.1), rng.random_range(-0.1..0.1), 0.0),
                rotation,
            );
            let mut points: Vec<Point3<f64>> = (0..400)
                .map(|_| {
                    Point3::new(
                        rng.random_range(-0.3..0.3),
                        rng.random_range(-0.3..0.3),
                        rng.random_range(-0.3..0.3),
                    )
                })
                .collect();
            // Just inside and just outside every face of every box, widened as it is checked.
            for (b, margin) in swept.solid.iter().map(|b| (b, g.clearance)).chain([(&swept.gap, 0.0)]) {
                for k in 0..3 {
                    for (face, out) in [(b.lo[k] - margin, -1.0), (b.hi[k] + margin, 1.0)] {
                        for step in [-1e-4, 1e-4] {
                            let mut q = 0.5 * (b.lo + b.hi);
                            q[k] = face + out * step;
                            points.push(pose * Point3::from(q));
                        }
                    }
                }
            }
            let local = to_grasp(&pose);
            let hit = |p: &Point3<f64>| {
                let q = local(p);
                swept.solid.iter().any(|b| b.holds(&q, g.clearance)) || swept.gap.holds(&q, 0.0)
            };
            let (hits, misses): (Vec<Point3<f64>>, Vec<Point3<f64>>) = points.into_iter().partition(|p| hit(p));
            let grid = Grid::new(&misses, 0.015);
            assert!(
                !swept.hits_others(&pose, &misses, &grid, g.clearance),
                "pose {t}: a miss found"
            );
            for h in hits.iter().take(40) {
                let mut with = misses.clone();
                with.push(*h);
                let grid = Grid::new(&with, 0.015);
                assert!(
                    swept.hits_others(&pose, &with, &grid, g.clearance),
                    "pose {t}: {h} not found"
                );
                checked += 1;
            }
        }
        assert!(checked > 1000, "{checked} hits checked");
    }
}
