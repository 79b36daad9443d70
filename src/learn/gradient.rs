//! The Jacobian of the learner's residuals in one pass over the points.
//!
//! The signed radial distance is differentiated with dual numbers ([`crate::numeric::dual`])
//! with respect to the local point and the seven shape parameters; the pose's six columns follow
//! from the local point's gradient (a point's local coordinates move by `q x w` under a local
//! rotation `w` and by `-R^T t` under a translation `t`). A distance along a sensor ray that hits
//! the surface is the root `t*` of `g(q + d t) = 0`, so by the implicit function theorem its
//! derivative is `-dg/dθ / (grad g . d)` at the hit point: one differentiated evaluation where
//! forward differences would repeat the whole ray search per parameter. A ray that passes the
//! surface reads its closest approach: the envelope theorem gives the gap's change, and the
//! closest approach's shift is `-g_tθ / g_tt` from differences along the ray. Grazing hits,
//! misses where the distance is flat along the ray and the few hundred residuals after the
//! points (support, size, seen surface) keep forward differences.

use super::params::Cost;
use super::residual::{FREE_WEIGHT, Problem, RAY_WINDOW, RayRead};
use super::seen::SeenUnit;
use super::state::{Mat, NP, STEPS, State, Vect, sk_param};
use crate::geometry::{PlacedSuperquadric, Superquadric};
use crate::numeric::dual::Dual;
use nalgebra::{UnitQuaternion, Vector3};
use rayon::prelude::*;

/// Derivatives with respect to the local point (0-2), ln a1..a3 (3-5), e1, e2 (6, 7), kx, ky
/// (8, 9).
type D = Dual<10>;

/// Closer to the surface than this (m) the distance is differentiated in its first-order form.
const ON_SURFACE: f64 = 1e-9;

/// [`Superquadric::signed_radial_distance`] with its gradient, the same arithmetic step for
/// step (to first order within [`ON_SURFACE`] of the surface).
pub(super) fn signed_radial_distance(sq: &Superquadric, p: &Vector3<f64>) -> D {
    let (x, y, z) = (D::variable(p.x, 0), D::variable(p.y, 1), D::variable(p.z, 2));
    // d a / d ln a = a.
    let a = [0, 1, 2].map(|k| {
        let mut v = D::constant(sq.a[k]);
        v.d[3 + k] = sq.a[k];
        v
    });
    let (e1, e2) = (D::variable(sq.e1, 6), D::variable(sq.e2, 7));
    let (kx, ky) = (D::variable(sq.kx, 8), D::variable(sq.ky, 9));
    let factor = |k: D, h: D| (k * (h / a[2]) + 1.0).max((k.abs() * -0.5) + 0.5);
    let (fx, fy) = (factor(kx, z), factor(ky, z));
    let (qx, qy) = (x / fx, y / fy);
    let lx = (qx / a[0]).ln_abs();
    let ly = (qy / a[1]).ln_abs();
    let lz = (z / a[2]).ln_abs();
    let two_e2 = D::constant(2.0) / e2;
    let ls = D::log_sum_exp(lx.scale_log(two_e2), ly.scale_log(two_e2));
    let lf = D::log_sum_exp(ls.scale_log(e2 / e1), lz.scale_log(D::constant(2.0) / e1));
    if !lf.v.is_finite() {
        let m = sq.min_size();
        return D::constant(if lf.v == f64::NEG_INFINITY { -m } else { m });
    }
    let s = (e1 * -0.5 * lf).exp();
    let zs = z * s;
    let (sx, sy) = (qx * s * factor(kx, zs), qy * s * factor(ky, zs));
    let (dx, dy, dz) = (x - sx, y - sy, z - zs);
    let d2 = dx * dx + dy * dy + dz * dz;
    if d2.v < ON_SURFACE * ON_SURFACE {
        // On the surface (where a ray's hit is): |p - S| has no direction there, but the signed
        // distance is smooth across it. To first order p - S = (1 - s) dS/ds at s = 1, so its
        // gradient is that of (1 - s) |dS/ds|. S = (x s fx(z s), y s fy(z s), z s).
        let along = |q: f64, k: f64| {
            let f = k * zs.v / sq.a[2] + 1.0;
            if f >= 0.5 * (1.0 - k.abs()) {
                q * (f + s.v * k * z.v / sq.a[2])
            } else {
                q * 0.5 * (1.0 - k.abs())
            }
        };
        let ds = Vector3::new(along(qx.v, sq.kx), along(qy.v, sq.ky), z.v).norm();
        return (-s + 1.0) * ds;
    }
    let d = d2.sqrt();
    if lf.v < 0.0 { -d } else { d }
}

/// The gradient of a residual in the fit's 13 parameters from its dual at local point `q`.
fn state_row(g: &D, q: &Vector3<f64>, rotation: &UnitQuaternion<f64>, s: &State, fix_taper: bool) -> Vect {
    let gq = Vector3::new(g.d[0], g.d[1], g.d[2]);
    let turn = gq.cross(q);
    let shift = -(rotation * gq);
    let mut row = Vect::from_fn(|k, _| match k {
        0..=6 => g.d[3 + k],
        7..=9 => turn[k - 7],
        _ => shift[k - 10],
    });
    if s.rev {
        // The tied parameters move with the free ones (`State::step`).
        row[0] += row[1];
        row[1] = 0.0;
        row[4] = 0.0;
        row[5] += row[6];
        row[6] = 0.0;
    }
    if fix_taper {
        row[5] = 0.0;
        row[6] = 0.0;
    }
    row
}

/// The state forward-difference column `k` is taken at, and its step (a parameter at its bound
/// steps inwards); `None` for a held parameter (its column is zero: the step leaves it alone).
pub(super) fn column_step(problem: &Problem, s: &State, k: usize) -> Option<(State, f64)> {
    if problem.fix_taper && matches!(k, 5 | 6) {
        return None;
    }
    let mut d = Vect::zeros();
    d[k] = STEPS[k];
    let sk = s.step(&d);
    Some(if sk_param(&sk, k) == sk_param(s, k) {
        d[k] = -STEPS[k];
        (s.step(&d), -STEPS[k])
    } else {
        (sk, STEPS[k])
    })
}

/// Per parameter, the placed shape of [`column_step`], its inverse rotation and its step.
type Shifted = [Option<(PlacedSuperquadric, UnitQuaternion<f64>, f64)>; NP];

/// The placed shapes of [`column_step`], with their inverse rotations.
fn perturbed(problem: &Problem, s: &State) -> Shifted {
    std::array::from_fn(|k| {
        column_step(problem, s, k).map(|(sk, h)| {
            let placed = sk.placed();
            (placed, placed.pose.rotation.inverse(), h)
        })
    })
}

/// Points per parallel chunk: fixed, so the sums are added in the same order however the work
/// is shared (the same answer on any machine).
const CHUNK: usize = 256;

/// `J^T W J` and `J^T W r` of the radial-distance residuals at `s`, given its residuals `r0`.
/// `None` for a cost this does not differentiate (the caller takes forward differences).
/// `reads`: what each point's ray read at `s` (empty without rays).
pub(super) fn normal_equations(
    problem: &Problem,
    s: &State,
    r0: &[f64],
    reads: &[Option<RayRead>],
    weights: &[f64],
) -> Option<(Mat, Vect)> {
    if problem.cost != Cost::Radial {
        return None;
    }
    let placed = s.placed();
    let rotation = placed.pose.rotation;
    let shifted = perturbed(problem, s);
    let (np, nf) = (problem.points.len(), problem.free.len());
    let accumulate = |range: std::ops::Range<usize>| {
        let mut h = Mat::zeros();
        let mut g = Vect::zeros();
        for i in range {
            let (w, r) = (weights[i], r0[i]);
            if w == 0.0 || !r.is_finite() {
                continue;
            }
            let row = if i < np {
                Some(point_row(
                    problem,
                    s,
                    &placed,
                    &shifted,
                    reads.get(i).copied().flatten(),
                    i,
                    r,
                ))
            } else if r < 0.0 {
                // A free-space sample inside the shape (outside it the residual is zero).
                let q = placed.to_local(&problem.free[i - np]);
                Some(
                    state_row(
                        &signed_radial_distance(&placed.shape, &q),
                        &q,
                        &rotation,
                        s,
                        problem.fix_taper,
                    ) * FREE_WEIGHT,
                )
            } else {
                None
            };
            if let Some(j) = row.filter(|j| j.iter().all(|v| v.is_finite())) {
                h.ger(w, &j, &j, 1.0);
                g += j * (w * r);
            }
        }
        (h, g)
    };
    let n = np + nf;
    let parts: Vec<(Mat, Vect)> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| accumulate(c * CHUNK..((c + 1) * CHUNK).min(n)))
        .collect();
    let (mut h, mut g) = parts
        .into_iter()
        .fold((Mat::zeros(), Vect::zeros()), |(h, g), (hc, gc)| (h + hc, g + gc));
    // The rest by forward differences, on the rest alone.
    let tail_weights = weights.get(n..).unwrap_or_default();
    add_tail_by_differences(problem, &placed, &shifted, &r0[n..], tail_weights, &mut h, &mut g);
    Some((h, g))
}

/// `J^T W J` and `J^T W r` of the residuals after the points' and the free space's (`tail`,
/// weighted by `weights`), by forward differences along the shifted states.
fn add_tail_by_differences(
    problem: &Problem,
    placed: &PlacedSuperquadric,
    shifted: &Shifted,
    tail: &[f64],
    weights: &[f64],
    h: &mut Mat,
    g: &mut Vect,
) {
    if tail.is_empty() {
        return;
    }
    // The pose's columns (7..13) move the samples of the shape at `s` without re-sampling.
    // The sizes' and tapers' columns reuse its exponents' share of the seen samples.
    let unit = problem.seen.map(|_| SeenUnit::new(placed.shape.e1, placed.shape.e2));
    let local = problem.tail_local(&placed.shape, unit.as_ref());
    let columns: Vec<Option<Vec<f64>>> = shifted
        .par_iter()
        .enumerate()
        .map(|(k, c)| {
            c.as_ref().map(|(moved, _, _)| {
                let mut out = Vec::with_capacity(tail.len());
                if k < 7 {
                    problem.tail_of(&problem.tail_local(&moved.shape, unit.as_ref()), moved, &mut out);
                } else {
                    problem.tail_of(&local, moved, &mut out);
                }
                out
            })
        })
        .collect();
    for (t, r) in tail.iter().enumerate() {
        let w = weights[t];
        if w == 0.0 || !r.is_finite() {
            continue;
        }
        let j = Vect::from_fn(|k, _| match (&columns[k], &shifted[k]) {
            (Some(col), Some((_, _, step))) => (col[t] - r) / step,
            _ => 0.0,
        });
        if j.iter().all(|v| v.is_finite()) {
            h.ger(w, &j, &j, 1.0);
            *g += j * (w * r);
        }
    }
}

/// The gradient of point `i`'s residual `r`, given what its ray read.
fn point_row(
    problem: &Problem,
    s: &State,
    placed: &PlacedSuperquadric,
    shifted: &Shifted,
    read: Option<RayRead>,
    i: usize,
    r: f64,
) -> Vect {
    let p = &problem.points[i];
    let q = placed.to_local(p);
    let rotation = &placed.pose.rotation;
    let fix = problem.fix_taper;
    let direction = || {
        let (v, _) = problem.ray_of(i)?;
        (p - v).try_normalize(1e-12).map(|d| rotation.inverse() * d)
    };
    match (read, direction()) {
        (Some(RayRead::Hit(t)), Some(d)) => {
            let x = q + d * t;
            let g = signed_radial_distance(&placed.shape, &x);
            let slope = g.d[0] * d.x + g.d[1] * d.y + g.d[2] * d.z;
            let norm = (g.d[0] * g.d[0] + g.d[1] * g.d[1] + g.d[2] * g.d[2]).sqrt();
            if slope.abs() > 0.05 * norm {
                return state_row(&g, &x, rotation, s, fix) * (-1.0 / slope);
            }
            differences(problem, shifted, i, r)
        }
        (Some(RayRead::Miss { t, .. }), Some(d)) => {
            // r = t_m + g(t_m) sign(t_m) at the closest approach t_m: g's own change there
            // (the envelope theorem), plus t_m's, -g_tθ / g_tt, from differences along the ray.
            let at = |t: f64| {
                let x = q + d * t;
                let g = signed_radial_distance(&placed.shape, &x);
                (g.v, state_row(&g, &x, rotation, s, fix))
            };
            let (g0, row0) = at(t);
            let sign = 1.0f64.copysign(t);
            if t.abs() >= RAY_WINDOW - 1e-9 {
                // At the window's end: the end stays put.
                return row0 * sign;
            }
            const H: f64 = 1e-5;
            let ((gp, rowp), (gm, rowm)) = (at(t + H), at(t - H));
            let curvature = (gp - 2.0 * g0 + gm) / (H * H);
            if curvature.is_nan() || curvature <= 1e-3 {
                // Flat along the ray: the closest approach is not defined by it.
                return differences(problem, shifted, i, r);
            }
            let moves = (rowp - rowm) * (-1.0 / (2.0 * H * curvature));
            moves + row0 * sign
        }
        _ => state_row(&signed_radial_distance(&placed.shape, &q), &q, rotation, s, fix),
    }
}

/// Forward differences of point `i`'s residual alone.
fn differences(problem: &Problem, shifted: &Shifted, i: usize, r: f64) -> Vect {
    Vect::from_fn(|k, _| match &shifted[k] {
        Some((placed, to_local, h)) => (problem.point_value(placed, to_local, i) - r) / h,
        None => 0.0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::plane::Plane;
    use crate::learn::residual::Rays;
    use crate::learn::seen::Seen;
    use nalgebra::Point3;
    use rand::{RngExt, SeedableRng};

    /// The truth, the visible points, the free-space samples, the viewpoint and the table.
    type Scene = (State, Vec<Point3<f64>>, Vec<Point3<f64>>, Point3<f64>, Plane);

    /// A tapered, rounded shape standing on the plane z = 0, its visible points with noise, some
    /// free-space samples (a few inside it) and a viewpoint above and in front.
    fn scene() -> Scene {
        let truth = State {
            ln_a: [0.04f64.ln(), 0.03f64.ln(), 0.05f64.ln()],
            e: [0.4, 0.8],
            k: [0.2, -0.1],
            rot: UnitQuaternion::from_euler_angles(0.05, -0.03, 0.4),
            t: Vector3::new(0.6, 0.05, 0.05),
            rev: false,
        };
        let placed = truth.placed();
        let view = Point3::new(0.0, 0.0, 0.5);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut points = Vec::new();
        while points.len() < 400 {
            let d = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let Some(d) = d.try_normalize(1e-9) else { continue };
            let q = placed.shape.radial_surface_point(&(d * 0.01)).expect("off centre");
            let p = placed.pose.transform_point(&Point3::from(q));
            if (view - p).dot(&(placed.pose.rotation * q)) > 0.0 {
                let noise = (p - view).normalize() * rng.random_range(-0.002..0.002);
                points.push(p + noise);
            }
        }
        let free: Vec<Point3<f64>> = (0..300)
            .map(|_| {
                Point3::new(
                    0.6 + rng.random_range(-0.08..0.08),
                    0.05 + rng.random_range(-0.08..0.08),
                    rng.random_range(0.0..0.12),
                )
            })
            .collect();
        let plane = Plane {
            normal: Vector3::z(),
            d: 0.0,
        };
        (truth, points, free, view, plane)
    }

    /// The state a little off the truth, so that every residual has a slope.
    fn off(truth: &State, rev: bool) -> State {
        let mut s = *truth;
        s.ln_a[0] += 0.05;
        s.e[0] += 0.05;
        s.k[1] += 0.05;
        s.rot *= UnitQuaternion::from_euler_angles(0.02, 0.01, -0.03);
        s.t += Vector3::new(0.002, -0.001, 0.003);
        if rev { s.as_revolution() } else { s }
    }

    /// The reference: central differences of every residual, steps `scale` times the
    /// production's (whose forward differences of a ray's hit are off by up to 0.3 % at grazing
    /// incidence). A closest approach is found to about 1e-9 m (the distance is flat there), so
    /// its differences need longer steps than the production's 1e-7 m.
    fn central_differences(problem: &Problem, s: &State, r0: &[f64], weights: &[f64], scale: f64) -> (Mat, Vect) {
        let columns: Vec<Option<Vec<f64>>> = (0..NP)
            .map(|k| {
                if problem.fix_taper && matches!(k, 5 | 6) {
                    return None;
                }
                let at = |h: f64| {
                    let mut d = Vect::zeros();
                    d[k] = h;
                    let mut r = Vec::new();
                    problem.residuals(&s.step(&d), &mut r);
                    r
                };
                let h = STEPS[k] * scale;
                let (rp, rm) = (at(h), at(-h));
                Some(rp.iter().zip(&rm).map(|(p, m)| (p - m) / (2.0 * h)).collect())
            })
            .collect();
        let mut h = Mat::zeros();
        let mut g = Vect::zeros();
        for i in 0..r0.len() {
            let j = Vect::from_fn(|k, _| columns[k].as_ref().map_or(0.0, |c| c[i]));
            if r0[i].is_finite() && j.iter().all(|v| v.is_finite()) {
                h.ger(weights[i], &j, &j, 1.0);
                g += j * (weights[i] * r0[i]);
            }
        }
        (h, g)
    }

    fn compare(problem: &Problem, s: &State, what: &str, scale: f64) {
        let mut r = Vec::new();
        let mut reads = Vec::new();
        problem.residuals_read(s, &mut r, problem.rays.is_some().then_some(&mut reads));
        let weights: Vec<f64> = (0..r.len()).map(|i| 0.5 + (i % 3) as f64 * 0.25).collect();
        let (h, g) = normal_equations(problem, s, &r, &reads, &weights).expect("radial cost");
        let (hf, gf) = central_differences(problem, s, &r, &weights, scale);
        // Per entry, against the scale of its row and column (the parameters differ in units;
        // the gradient's bound is sqrt(h_ii * cost)). A column with next to no weight (the spin
        // of a body of revolution) is measured against a millionth of the mean.
        let cost: f64 = r.iter().zip(&weights).map(|(r, w)| w * r * r).sum();
        let floor = 1e-6 * hf.trace() / NP as f64;
        let diag = |i: usize| hf[(i, i)].max(floor);
        for i in 0..NP {
            let e = (g[i] - gf[i]).abs() / (diag(i) * cost).sqrt();
            assert!(e < 1e-3, "{what}: gradient {i}: {} vs {} ({e})", g[i], gf[i]);
            for j in 0..NP {
                let e = (h[(i, j)] - hf[(i, j)]).abs() / (diag(i) * diag(j)).sqrt();
                assert!(
                    e < 1e-3,
                    "{what}: normal matrix ({i}, {j}): {} vs {} ({e})",
                    h[(i, j)],
                    hf[(i, j)]
                );
            }
        }
    }

    #[test]
    fn the_jacobian_agrees_with_central_differences() {
        let (truth, points, free, view, plane) = scene();
        let seen = Seen::new(view, &points, Some(&plane), false);
        let mut both = points.clone();
        let (c, u) = (truth.t, Vector3::z());
        both.extend(points.iter().map(|p| crate::learn::residual::turn_half(p, &c, &u)));
        let rays = Rays {
            viewpoint: view,
            seen: points.len(),
            twin_viewpoint: crate::learn::residual::turn_half(&view, &c, &u),
            open: false,
        };
        let base = Problem {
            points: &points,
            free: &free,
            support: Some((plane, 3.0)),
            cost: Cost::Radial,
            volume: Some((0.5, 1e-4)),
            seen: Some(&seen),
            rays: None,
            fix_taper: false,
        };
        for rev in [false, true] {
            let s = off(&truth, rev);
            compare(&base, &s, &format!("nearest surface, rev {rev}"), 1.0);
            let along = Problem {
                points: &both,
                rays: Some(rays),
                ..base
            };
            compare(&along, &s, &format!("along the rays, rev {rev}"), 1.0);
            let held = Problem {
                fix_taper: true,
                ..along
            };
            compare(&held, &s, &format!("tapers held, rev {rev}"), 1.0);
        }
        // A pose off the points: many rays miss, and take the closest approach's derivative.
        // Row by row against central differences with steps long enough for the closest
        // approach's precision, where the read at both ends is the same kind.
        let mut far = off(&truth, false);
        far.t += Vector3::new(0.006, 0.004, 0.0);
        let along = Problem {
            points: &both,
            rays: Some(rays),
            ..base
        };
        let mut r = Vec::new();
        let mut reads = Vec::new();
        along.residuals_read(&far, &mut r, Some(&mut reads));
        let placed = far.placed();
        let shifted = perturbed(&along, &far);
        let mut checked = 0;
        for i in 0..both.len() {
            let Some(RayRead::Miss { t, .. }) = reads[i] else {
                continue;
            };
            if t.abs() > RAY_WINDOW - 1e-3 {
                continue;
            }
            let row = point_row(&along, &far, &placed, &shifted, reads[i], i, r[i]);
            let mut reference = Vect::zeros();
            let mut same_kind = true;
            for k in 0..NP {
                let at = |h: f64| {
                    let mut d = Vect::zeros();
                    d[k] = h;
                    let mut out = Vec::new();
                    let mut read = Vec::new();
                    along.residuals_read(&far.step(&d), &mut out, Some(&mut read));
                    (out[i], read[i])
                };
                let h = STEPS[k] * 100.0;
                let ((rp, kp), (rm, km)) = (at(h), at(-h));
                // The same kind, on the same side of the point (the residual jumps where the
                // closest approach passes it).
                same_kind &= matches!((kp, km), (Some(RayRead::Miss { t: a, .. }), Some(RayRead::Miss { t: b, .. }))
                    if a.signum() == t.signum() && b.signum() == t.signum());
                reference[k] = (rp - rm) / (2.0 * h);
            }
            if !same_kind {
                continue;
            }
            checked += 1;
            let e = (row - reference).norm() / reference.norm();
            assert!(e < 1e-3, "miss {i} (t {t}): {row:?} vs {reference:?} ({e})");
        }
        assert!(checked > 20, "only {checked} misses checked");
    }

    #[test]
    fn the_dual_distance_is_the_signed_radial_distance() {
        let sq = Superquadric::new([0.04, 0.03, 0.05], 0.3, 0.7, 0.25, -0.15).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..500 {
            let p = Vector3::new(
                rng.random_range(-0.08..0.08),
                rng.random_range(-0.08..0.08),
                rng.random_range(-0.08..0.08),
            );
            let d = signed_radial_distance(&sq, &p);
            let want = sq.signed_radial_distance(&p);
            assert!(
                (d.v - want).abs() <= 1e-12 * (1.0 + want.abs()),
                "{p:?}: {} vs {want}",
                d.v
            );
        }
    }
}
