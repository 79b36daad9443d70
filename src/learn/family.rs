//! Shape families and the shape's final form: general against body of revolution, open or
//! closed, the canonical axes, the true volume.

use super::state::State;
use crate::geometry::{PlacedSuperquadric, Superquadric};
use nalgebra::{Point3, UnitQuaternion, Vector3};

/// The volume of an untapered superquadric (Jaklic et al. 2000):
/// `2 a1 a2 a3 e1 e2 B(e1/2 + 1, e1) B(e2/2, e2/2)`. A linear taper adds only a second-order
/// term (`kx ky` times the second moment along z), left out.
pub fn volume(sq: &Superquadric) -> f64 {
    let beta = |x: f64, y: f64| (ln_gamma(x) + ln_gamma(y) - ln_gamma(x + y)).exp();
    2.0 * sq.a[0] * sq.a[1] * sq.a[2] * sq.e1 * sq.e2 * beta(0.5 * sq.e1 + 1.0, sq.e1) * beta(0.5 * sq.e2, 0.5 * sq.e2)
}

/// `ln Gamma(x)` for `x > 0` (Lanczos, g = 7, 9 terms: about 15 digits).
pub(super) fn ln_gamma(x: f64) -> f64 {
    const G: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Gamma(x) Gamma(1 - x) = pi / sin(pi x).
        return (std::f64::consts::PI / (std::f64::consts::PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let t = x + 7.5;
    let sum = G[1..]
        .iter()
        .enumerate()
        .fold(G[0], |acc, (i, g)| acc + g / (x + i as f64 + 1.0));
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + sum.ln()
}

/// A body of revolution is taken unless the general shape's score (Huber over the points, free
/// space, support and seen surface, with the distance along the normal) is lower by more than
/// this share.
pub(super) const REVOLUTION_TOLERANCE: f64 = 0.05;

/// The general or the revolution result of [`fit_superquadric`](super::stages::fit_superquadric)'s stages (Occam: one view
/// rarely tells a slightly oval or squarish section from a round one, and the round one is what
/// the detector fits with 5 DoF and scores modulo its spin).
pub(super) fn choose_family(mut finals: Vec<FamilyResult>) -> FamilyResult {
    let general = finals.iter().position(|f| !f.state.rev);
    let rev = finals.iter().position(|f| f.state.rev);
    let pick = match (general, rev) {
        (Some(g), Some(r)) => {
            if finals[r].score <= finals[g].score * (1.0 + REVOLUTION_TOLERANCE) {
                r
            } else {
                g
            }
        }
        (Some(i), None) | (None, Some(i)) => i,
        (None, None) => unreachable!("every family has starts"),
    };
    finals.swap_remove(pick)
}

/// One family's result after stage C.
pub(super) struct FamilyResult {
    /// The winning start.
    pub(super) name: String,
    pub(super) state: State,
    /// The final Huber threshold.
    pub(super) delta: f64,
    /// The score the families are compared by.
    pub(super) score: f64,
    /// The points stage C fitted (the visible ones and their mirrored twins).
    pub(super) fitted: Vec<Point3<f64>>,
    /// The axis the twins were turned about (a point on it, its direction).
    pub(super) mirror_at: Option<(Vector3<f64>, Vector3<f64>)>,
}

/// An open container: over 10 % of the points are seen from inside, with the outward normal of
/// the fitted surface at them facing away from the sensor (a closed solid shows only surfaces
/// that face it).
pub(super) fn is_open(placed: &PlacedSuperquadric, points: &[Point3<f64>], viewpoint: Option<&Point3<f64>>) -> bool {
    let Some(v) = viewpoint else { return false };
    let inside_seen = points
        .iter()
        .filter(|p| {
            let g = placed.shape.residual_grad(&placed.to_local(p)).grad;
            let n = placed.pose.rotation * g;
            match (n.try_normalize(1e-12), (v - *p).try_normalize(1e-12)) {
                (Some(n), Some(to_sensor)) => n.dot(&to_sensor) < -0.2,
                _ => false,
            }
        })
        .count();
    inside_seen as f64 > 0.10 * points.len() as f64
}

/// Put the z axis up when it is within 30 degrees of up (tapers change sign with it), so an open
/// container opens upwards; for a body of revolution pick x along the frame's x.
pub(super) fn canonicalise(placed: &mut PlacedSuperquadric, up: Option<&Vector3<f64>>) {
    let Some(u) = up else { return };
    let z = placed.pose.rotation * Vector3::z();
    if z.dot(u) < -0.866 {
        // Turn 180 degrees about the local x axis: z -> -z, y -> -y; the taper flips sign.
        placed.pose.rotation *= UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        placed.shape.kx = -placed.shape.kx;
        placed.shape.ky = -placed.shape.ky;
    }
}

/// A learned shape that is a body of revolution to within what one view can tell (x and y
/// sizes within 10 %, e2 within 0.1 of 1, tapers within 0.05 of each other) made exactly one, so
/// the detector fits it with 5 degrees of freedom and scores it modulo its spin. `None` when it
/// is not.
pub fn snap_revolution(sq: &Superquadric) -> Option<Superquadric> {
    let (a1, a2) = (sq.a[0], sq.a[1]);
    let close = (a1 - a2).abs() <= 0.10 * a1.max(a2) && (sq.e2 - 1.0).abs() <= 0.1 && (sq.kx - sq.ky).abs() <= 0.05;
    close.then(|| {
        let a = 0.5 * (a1 + a2);
        let k = 0.5 * (sq.kx + sq.ky);
        Superquadric {
            a: [a, a, sq.a[2]],
            e1: sq.e1,
            e2: 1.0,
            kx: k,
            ky: k,
        }
    })
}
