//! The fitted parameter vector (log sizes, exponents, tapers, rotation, translation), its bounds
//! and its steps.

use crate::geometry::{EPSILON_MAX, EPSILON_MIN, PlacedSuperquadric, Superquadric};
use nalgebra::{Isometry3, SMatrix, SVector, Translation3, UnitQuaternion, Vector3};

/// Parameters of the fit: ln a1..a3, e1, e2, kx, ky, rotation vector (local, about the current
/// orientation), translation.
pub(super) const NP: usize = 13;
pub(super) type Mat = SMatrix<f64, NP, NP>;
pub(super) type Vect = SVector<f64, NP>;

/// Largest taper the fit may use (the model format allows 0.99; a learned taper near it would be
/// a degenerate cone).
pub(super) const TAPER_BOUND: f64 = 0.9;
/// Smallest and largest half-size (m).
pub(super) const SIZE_MIN: f64 = 0.001;
pub(super) const SIZE_MAX: f64 = 1.0;

/// The fit's state: shape parameters and pose.
#[derive(Debug, Clone, Copy)]
pub(super) struct State {
    pub(super) ln_a: [f64; 3],
    pub(super) e: [f64; 2],
    pub(super) k: [f64; 2],
    pub(super) rot: UnitQuaternion<f64>,
    pub(super) t: Vector3<f64>,
    /// Constrained to a body of revolution about z (a1 = a2, e2 = 1, kx = ky): 9 free
    /// parameters and an unobservable spin, which the damping holds.
    pub(super) rev: bool,
}

impl State {
    /// The nearest body of revolution about the same z axis.
    pub(super) fn as_revolution(&self) -> State {
        let mut s = *self;
        let ln_a = 0.5 * (s.ln_a[0] + s.ln_a[1]);
        s.ln_a = [ln_a, ln_a, s.ln_a[2]];
        s.e[1] = 1.0;
        let k = 0.5 * (s.k[0] + s.k[1]);
        s.k = [k, k];
        s.rev = true;
        s
    }

    pub(super) fn shape(&self) -> Superquadric {
        Superquadric {
            a: self.ln_a.map(f64::exp),
            e1: self.e[0],
            e2: self.e[1],
            kx: self.k[0],
            ky: self.k[1],
        }
    }

    pub(super) fn placed(&self) -> PlacedSuperquadric {
        PlacedSuperquadric::new(
            self.shape(),
            Isometry3::from_parts(Translation3::from(self.t), self.rot),
        )
    }

    /// The state moved by `d` (rotation as a local rotation vector), clamped to the bounds.
    pub(super) fn step(&self, d: &Vect) -> State {
        let mut s = *self;
        for k in 0..3 {
            s.ln_a[k] = (s.ln_a[k] + d[k]).clamp(SIZE_MIN.ln(), SIZE_MAX.ln());
        }
        for k in 0..2 {
            s.e[k] = (s.e[k] + d[3 + k]).clamp(EPSILON_MIN, EPSILON_MAX);
            s.k[k] = (s.k[k] + d[5 + k]).clamp(-TAPER_BOUND, TAPER_BOUND);
        }
        s.rot = self.rot * UnitQuaternion::from_scaled_axis(Vector3::new(d[7], d[8], d[9]));
        s.t += Vector3::new(d[10], d[11], d[12]);
        if s.rev {
            // The tied parameters follow the free ones (their Jacobian columns are zero).
            s.ln_a[1] = s.ln_a[0];
            s.e[1] = 1.0;
            s.k[1] = s.k[0];
        }
        s
    }
}

/// Finite-difference steps of the parameters.
pub(super) const STEPS: [f64; NP] = [
    1e-5, 1e-5, 1e-5, 1e-5, 1e-5, 1e-5, 1e-5, 1e-6, 1e-6, 1e-6, 1e-7, 1e-7, 1e-7,
];

pub(super) fn sk_param(s: &State, k: usize) -> f64 {
    match k {
        0..=2 => s.ln_a[k],
        3 | 4 => s.e[k - 3],
        5 | 6 => s.k[k - 5],
        _ => f64::NAN, // rotation and translation have no bounds (NaN never compares equal)
    }
}
