//! A shape placed in a frame, prepared for many frame points: the pose's rotation and
//! translation as they are applied, the box the shape lies in (the cheap test before an
//! evaluation, and the grid cells a query needs to visit), the pose Jacobian of the residual, and
//! [`NearBatch`], which evaluates the points near the shape four at a time.

use super::kernel::{Kernel, lanes_of};
use super::superquadric::{PlacedSuperquadric, ResidualGrad};
use crate::numeric::lanes::Lanes;
use nalgebra::{Matrix3, Point3, Vector3};

/// A placed shape prepared for evaluating many points given in the frame its pose maps into.
#[derive(Debug, Clone, Copy)]
pub struct PlacedKernel {
    pub kernel: Kernel,
    /// The pose's rotation (local to frame) and translation.
    rotation: Matrix3<f64>,
    translation: Vector3<f64>,
    /// Half-sizes of the local box the shape lies in.
    half_extents: Vector3<f64>,
}

impl PlacedKernel {
    pub fn new(placed: &PlacedSuperquadric) -> PlacedKernel {
        PlacedKernel {
            kernel: Kernel::new(&placed.shape),
            rotation: placed.pose.rotation.to_rotation_matrix().into_inner(),
            translation: placed.pose.translation.vector,
            half_extents: placed.shape.local_half_extents(),
        }
    }

    /// [`Self::surface_distance`] of a frame point within `band` of the shape's local box, `None`
    /// for a point outside it: no point of the surface lies within `band` of such a point, and a
    /// box test is a tenth of the cost of the distance.
    #[inline]
    pub fn surface_distance_near(&self, p: &Point3<f64>, band: f64) -> Option<f64> {
        let q = self.to_local(p);
        if outside(&q, &self.half_extents.add_scalar(band)) {
            return None;
        }
        Some(PlacedSuperquadric::distance_from(&self.kernel.residual_grad(&q)))
    }

    /// Half-sizes, along the frame's axes, of a box that holds the shape's local box grown by
    /// `band`: where a point must lie to pass [`NearBatch`]'s box test.
    pub fn frame_reach(&self, band: f64) -> Vector3<f64> {
        self.frame_box(&self.half_extents.add_scalar(band))
    }

    /// Half-sizes, along the frame's axes, of a box that holds the local box `±half`.
    pub fn frame_box(&self, half: &Vector3<f64>) -> Vector3<f64> {
        // A micrometre more, so that rounding cannot leave a point on the box's edge out.
        (self.rotation.abs() * half).add_scalar(1e-6)
    }

    /// Half-sizes of the local box outside which `F^e1` exceeds `level` (at least 1): the
    /// shape's box scaled by `s = sqrt(level)`, widened by the taper over the `|z| <= s a3` it
    /// spans. Beyond `|z| > s a3` the z term alone exceeds it; inside, the untapered `|x|` is
    /// `|X| / (kx z/a3 + 1) > s a1` there.
    pub fn level_box(&self, level: f64) -> Vector3<f64> {
        let s = level.max(1.0).sqrt();
        let shape = &self.kernel.shape;
        Vector3::new(
            s * shape.a[0] * (1.0 + shape.kx.abs() * s),
            s * shape.a[1] * (1.0 + shape.ky.abs() * s),
            s * shape.a[2],
        )
    }

    /// Whether a frame point lies within `band` of the shape's local box.
    #[inline]
    pub fn in_box(&self, p: &Point3<f64>, band: f64) -> bool {
        let q = self.to_local(p);
        !outside(&q, &self.half_extents.add_scalar(band))
    }

    /// A frame point in the local frame.
    #[inline(always)]
    pub fn to_local(&self, p: &Point3<f64>) -> Vector3<f64> {
        let [x, y, z] = self.to_local_lanes(lanes_of::<1>(std::slice::from_ref(p)));
        Vector3::new(x.0[0], y.0[0], z.0[0])
    }

    /// `L` frame points (their x, y and z coordinates) in the local frame.
    #[inline(always)]
    pub fn to_local_lanes<const L: usize>(&self, p: [Lanes<L>; 3]) -> [Lanes<L>; 3] {
        let t = &self.translation;
        let d = [p[0] - t.x, p[1] - t.y, p[2] - t.z];
        let r = &self.rotation;
        std::array::from_fn(|i| d[0] * r[(0, i)] + d[1] * r[(1, i)] + d[2] * r[(2, i)])
    }

    /// The residual `F^e1 - 1` of a frame point.
    #[inline]
    pub fn residual(&self, p: &Point3<f64>) -> f64 {
        self.kernel.residual(&self.to_local(p))
    }

    /// Signed first-order distance to the surface (see [`PlacedSuperquadric::surface_distance`]).
    #[inline]
    pub fn surface_distance(&self, p: &Point3<f64>) -> f64 {
        PlacedSuperquadric::distance_from(&self.kernel.residual_grad(&self.to_local(p)))
    }

    /// [`Self::surface_distance`] and the direction of the residual's gradient there in the
    /// frame (the outward normal of the level surface through `p`; zero where it vanishes).
    pub fn surface_distance_normal(&self, p: &Point3<f64>) -> (f64, Vector3<f64>) {
        let rg = self.kernel.residual_grad(&self.to_local(p));
        let n = (self.rotation * rg.grad)
            .try_normalize(1e-12)
            .unwrap_or_else(Vector3::zeros);
        (PlacedSuperquadric::distance_from(&rg), n)
    }

    /// The residual and its Jacobian with respect to the pose perturbation (see
    /// [`PlacedSuperquadric::residual_pose_jacobian`]).
    #[inline]
    pub fn residual_pose_jacobian(&self, p: &Point3<f64>) -> (f64, [f64; 6]) {
        let (r, j) = self.residual_pose_jacobian_lanes(lanes_of::<1>(std::slice::from_ref(p)));
        (r.0[0], j.map(|j| j.0[0]))
    }

    /// [`Self::residual_pose_jacobian`] of `L` frame points at once, the same to the bit.
    #[inline(always)]
    pub fn residual_pose_jacobian_lanes<const L: usize>(&self, p: [Lanes<L>; 3]) -> (Lanes<L>, [Lanes<L>; 6]) {
        let q = self.to_local_lanes(p);
        let (r, g) = self.kernel.residual_grad_lanes(q);
        let rot = &self.rotation;
        let dt: [Lanes<L>; 3] =
            std::array::from_fn(|i| -(g[0] * rot[(i, 0)] + g[1] * rot[(i, 1)] + g[2] * rot[(i, 2)]));
        (
            r,
            [
                dt[0],
                dt[1],
                dt[2],
                g[1] * q[2] - g[2] * q[1],
                g[2] * q[0] - g[0] * q[2],
                g[0] * q[1] - g[1] * q[0],
            ],
        )
    }
}

/// Points near a placed shape, evaluated four at a time: [`NearBatch::push`] each candidate,
/// then [`NearBatch::finish`]. Those within `band` of the shape's local box reach the callback
/// with their local coordinates and residual and gradient, in the order they were pushed; the
/// others are dropped after the box test (no point of the surface lies within `band` of them).
pub struct NearBatch<'k, F: FnMut(usize, &Vector3<f64>, &ResidualGrad)> {
    kernel: &'k PlacedKernel,
    reach: Vector3<f64>,
    index: [usize; BATCH],
    local: [[f64; BATCH]; 3],
    n: usize,
    f: F,
}

const BATCH: usize = 4;

impl<'k, F: FnMut(usize, &Vector3<f64>, &ResidualGrad)> NearBatch<'k, F> {
    #[inline(always)]
    pub fn new(kernel: &'k PlacedKernel, band: f64, f: F) -> Self {
        Self::within(kernel, kernel.half_extents.add_scalar(band), f)
    }

    /// Those within the local box `±reach` reach the callback.
    #[inline(always)]
    pub fn within(kernel: &'k PlacedKernel, reach: Vector3<f64>, f: F) -> Self {
        NearBatch {
            kernel,
            reach,
            index: [0; BATCH],
            local: [[0.0; BATCH]; 3],
            n: 0,
            f,
        }
    }

    #[inline(always)]
    pub fn push(&mut self, i: usize, p: &Point3<f64>) {
        let q = self.kernel.to_local(p);
        if outside(&q, &self.reach) {
            return;
        }
        let n = self.n;
        self.index[n] = i;
        for k in 0..3 {
            self.local[k][n] = q[k];
        }
        self.n = n + 1;
        if self.n == BATCH {
            let (r, g) = self.kernel.kernel.residual_grad_lanes(self.local.map(Lanes));
            for l in 0..BATCH {
                let q = Vector3::new(self.local[0][l], self.local[1][l], self.local[2][l]);
                let rg = ResidualGrad {
                    residual: r.0[l],
                    grad: Vector3::new(g[0].0[l], g[1].0[l], g[2].0[l]),
                };
                (self.f)(self.index[l], &q, &rg);
            }
            self.n = 0;
        }
    }

    /// Evaluate what is left (one at a time: the same values as in a group).
    #[inline(always)]
    pub fn finish(mut self) {
        for l in 0..self.n {
            let q = Vector3::new(self.local[0][l], self.local[1][l], self.local[2][l]);
            let rg = self.kernel.kernel.residual_grad(&q);
            (self.f)(self.index[l], &q, &rg);
        }
    }
}

/// Whether a local point lies outside the box `±reach`: the test every evaluation near a shape
/// starts with.
#[inline(always)]
fn outside(q: &Vector3<f64>, reach: &Vector3<f64>) -> bool {
    q.x.abs() > reach.x || q.y.abs() > reach.y || q.z.abs() > reach.z
}
