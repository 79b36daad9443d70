//! The superquadric's unit tests. Over 600 lines: each property (the inside-outside function,
//! its gradient, distances, sampling, the kernel) is checked against a direct
//! evaluation, finite differences or a count.

use super::*;
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A random tapered superquadric with sizes 1-30 cm and the full exponent range.
fn random_sq(rng: &mut ChaCha8Rng) -> Superquadric {
    Superquadric::new(
        [
            rng.random_range(0.01..0.3),
            rng.random_range(0.01..0.3),
            rng.random_range(0.01..0.3),
        ],
        rng.random_range(0.1..=2.0),
        rng.random_range(0.1..=2.0),
        rng.random_range(-0.9..0.9),
        rng.random_range(-0.9..0.9),
    )
    .unwrap()
}

fn random_pose(rng: &mut ChaCha8Rng) -> Isometry3<f64> {
    let axis = Vector3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    );
    let rot = UnitQuaternion::from_scaled_axis(axis * 3.0);
    Isometry3::from_parts(
        Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(0.0..2.0),
        )
        .into(),
        rot,
    )
}

/// The textbook evaluation of eq. (1), for comparison where it is accurate.
fn f_direct(sq: &Superquadric, p: &Vector3<f64>) -> f64 {
    let q = sq.untaper(p);
    let xy = (q.x / sq.a[0]).abs().powf(2.0 / sq.e2) + (q.y / sq.a[1]).abs().powf(2.0 / sq.e2);
    xy.powf(sq.e2 / sq.e1) + (q.z / sq.a[2]).abs().powf(2.0 / sq.e1)
}

#[test]
fn rejects_out_of_range_parameters() {
    assert!(matches!(
        Superquadric::new([0.0, 0.1, 0.1], 1.0, 1.0, 0.0, 0.0),
        Err(ShapeError::Size { name: "a1", .. })
    ));
    assert!(matches!(
        Superquadric::new([0.1, 0.1, f64::NAN], 1.0, 1.0, 0.0, 0.0),
        Err(ShapeError::Size { name: "a3", .. })
    ));
    assert!(matches!(
        Superquadric::new([0.1; 3], 0.05, 1.0, 0.0, 0.0),
        Err(ShapeError::Exponent { name: "e1", .. })
    ));
    assert!(matches!(
        Superquadric::new([0.1; 3], 1.0, 2.5, 0.0, 0.0),
        Err(ShapeError::Exponent { name: "e2", .. })
    ));
    assert!(matches!(
        Superquadric::new([0.1; 3], 1.0, 1.0, 1.0, 0.0),
        Err(ShapeError::Taper { name: "kx", .. })
    ));
}

#[test]
fn sphere_values_are_exact() {
    let s = Superquadric::untapered([0.1; 3], 1.0, 1.0).unwrap();
    let p = Vector3::new(0.06, 0.0, 0.08); // on the surface, on the y = 0 coordinate plane
    assert!((s.inside_outside(&p) - 1.0).abs() < 1e-14);
    assert!(s.residual(&p).abs() < 1e-14);
    let p2 = Vector3::new(0.0, 0.0, 0.2);
    assert!((s.inside_outside(&p2) - 4.0).abs() < 1e-13);
    assert!((s.radial_distance(&p2) - 0.1).abs() < 1e-14);
    assert_eq!(s.inside_outside(&Vector3::zeros()), 0.0);
}

#[test]
fn finite_and_accurate_on_planes_small_exponents_and_far_away() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for _ in 0..2000 {
        let mut sq = random_sq(&mut rng);
        if rng.random_bool(0.3) {
            sq.e1 = 0.1;
        }
        if rng.random_bool(0.3) {
            sq.e2 = 0.1;
        }
        let scale = [1e-6, 1e-3, 0.5, 1.0, 2.0, 10.0, 1e3][rng.random_range(0..7)];
        let mut p = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .component_mul(&Vector3::from(sq.a))
            * scale;
        // Put a third of the points on coordinate planes.
        match rng.random_range(0..6) {
            0 => p.x = 0.0,
            1 => p.y = 0.0,
            2 => p.z = 0.0,
            _ => {}
        }
        let f = sq.inside_outside(&p);
        let g = sq.f_pow_e1(&p);
        assert!(f.is_finite() && f >= 0.0, "F = {f} at {p:?} for {sq}");
        assert!(g.is_finite() && g >= 0.0, "F^e1 = {g} at {p:?} for {sq}");
        let rg = sq.residual_grad(&p);
        assert!(
            rg.grad.iter().all(|v| v.is_finite()),
            "gradient {:?} at {p:?} for {sq}",
            rg.grad
        );
        let d = f_direct(&sq, &p);
        if d.is_finite() && d > 1e-200 && d < 1e200 {
            assert!((f - d).abs() <= 1e-9 * d, "F = {f}, direct {d} at {p:?} for {sq}");
        }
    }
}

#[test]
fn sampled_points_lie_on_the_surface_and_scaling_moves_them_in_and_out() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for _ in 0..60 {
        let sq = random_sq(&mut rng);
        let placed = PlacedSuperquadric::new(sq, random_pose(&mut rng));
        let spacing = sq.min_size() / 3.0;
        let pts = placed.sample_surface(spacing);
        assert!(!pts.is_empty());
        let centre = Point3::from(placed.pose.translation.vector);
        for p in &pts {
            assert!(
                placed.residual(p).abs() < 1e-9,
                "residual {} for {sq}",
                placed.residual(p)
            );
            assert!(
                placed.radial_distance(p) < 1e-9,
                "radial {} for {sq}",
                placed.radial_distance(p)
            );
            let inner = centre + (p - centre) * 0.9;
            let outer = centre + (p - centre) * 1.1;
            assert!(
                placed.residual(&inner) < 0.0,
                "0.9 x a surface point is not inside {sq}"
            );
            assert!(
                placed.residual(&outer) > 0.0,
                "1.1 x a surface point is not outside {sq}"
            );
        }
    }
}

#[test]
fn sampling_is_uniform_over_the_area() {
    // A sphere: the count follows the area, and nearest neighbours sit about one spacing apart.
    let r = 0.05;
    let spacing = 0.004;
    let s = Superquadric::untapered([r; 3], 1.0, 1.0).unwrap();
    let pts = s.sample_surface(spacing);
    let expected = 4.0 * std::f64::consts::PI * r * r / (spacing * spacing);
    let n = pts.len() as f64;
    assert!(
        (n - expected).abs() < 0.03 * expected,
        "{n} points, area says {expected}"
    );
    // A prolate spheroid: the share of points in the band |z| < c/2 follows the share of area,
    // which the angle parametrisation gets badly wrong for elongated shapes.
    let (a, c) = (0.02, 0.1);
    let sph = Superquadric::untapered([a, a, c], 1.0, 1.0).unwrap();
    let pts = sph.sample_surface(0.002);
    let band = pts.iter().filter(|p| p.z.abs() < 0.5 * c).count() as f64 / pts.len() as f64;
    let ecc = (1.0 - a * a / (c * c)).sqrt();
    let area_all = 2.0 * std::f64::consts::PI * a * a * (1.0 + c / (a * ecc) * ecc.asin());
    // Band area by the midpoint rule on the surface of revolution x(z) = a sqrt(1 - z^2/c^2).
    let steps = 20000;
    let area_band: f64 = (0..steps)
        .map(|i| {
            let z = -0.5 * c + c * (i as f64 + 0.5) / steps as f64;
            let x = a * (1.0 - z * z / (c * c)).sqrt();
            let dx = -a * z / (c * c) / (1.0 - z * z / (c * c)).sqrt();
            2.0 * std::f64::consts::PI * x * (1.0 + dx * dx).sqrt() * (c / steps as f64)
        })
        .sum();
    assert!(
        (band - area_band / area_all).abs() < 0.01,
        "band share {band} vs {}",
        area_band / area_all
    );
    let n = pts.len() as f64 * 0.002 * 0.002;
    assert!(
        (n - area_all).abs() < 0.03 * area_all,
        "area from count {n} vs {area_all}"
    );
    // A box-like shape (e = 0.1) of very unequal sides: rounding its edges takes a few per cent
    // off the sharp box's area, never more.
    let b = Superquadric::untapered([0.1, 0.05, 0.01], 0.1, 0.1).unwrap();
    let n = b.sample_surface(0.003).len() as f64 * 0.003 * 0.003;
    let sharp = 8.0 * (0.1 * 0.05 + 0.1 * 0.01 + 0.05 * 0.01);
    assert!(
        n < sharp && n > 0.93 * sharp,
        "box area from count {n} vs sharp {sharp}"
    );
    // Nearest-neighbour distances on the sphere: no clumps, no holes.
    let s_pts = s.sample_surface(spacing);
    let mut nn: Vec<f64> = s_pts
        .iter()
        .map(|p| {
            s_pts
                .iter()
                .filter(|q| *q != p)
                .map(|q| (p - q).norm())
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    nn.sort_by(|a, b| a.total_cmp(b));
    let median = nn[nn.len() / 2];
    assert!(median > 0.5 * spacing && median < 1.2 * spacing, "median NN {median}");
    assert!(
        nn[nn.len() * 99 / 100] < 2.0 * spacing,
        "largest gaps {}",
        nn[nn.len() * 99 / 100]
    );
}

#[test]
fn pose_jacobian_matches_finite_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut checked = 0;
    for _ in 0..300 {
        let mut sq = random_sq(&mut rng);
        // Keep exponents where the residual is smooth enough for central differences.
        sq.e1 = rng.random_range(0.2..1.5);
        sq.e2 = rng.random_range(0.2..1.5);
        let placed = PlacedSuperquadric::new(sq, random_pose(&mut rng));
        let local = Vector3::new(
            rng.random_range(-1.3..1.3) * sq.a[0],
            rng.random_range(-1.3..1.3) * sq.a[1],
            rng.random_range(-1.0..1.0) * sq.a[2],
        );
        let p = placed.pose.transform_point(&Point3::from(local));
        let (r, j) = placed.residual_pose_jacobian(&p);
        assert!((r - placed.residual(&p)).abs() < 1e-12);
        let h = 1e-7;
        for k in 0..6 {
            let mut d = [0.0; 6];
            d[k] = h;
            let rp = placed.perturbed(&d).residual(&p);
            d[k] = -h;
            let rm = placed.perturbed(&d).residual(&p);
            let fd = (rp - rm) / (2.0 * h);
            let scale = j.iter().map(|v| v.abs()).fold(1.0, f64::max);
            assert!(
                (fd - j[k]).abs() < 1e-4 * scale,
                "param {k}: analytic {} vs fd {fd} for {sq}",
                j[k]
            );
        }
        checked += 1;
    }
    assert_eq!(checked, 300);
}

#[test]
fn spin_of_a_body_of_revolution_is_the_wz_column() {
    let cyl = Superquadric::untapered([0.04, 0.04, 0.05], 0.1, 1.0).unwrap();
    assert!(cyl.is_revolution());
    let placed = PlacedSuperquadric::new(cyl, Isometry3::translation(0.5, 0.1, 0.8));
    for p in cyl.sample_surface(0.01) {
        let (_, j) = placed.residual_pose_jacobian(&placed.pose.transform_point(&Point3::from(p)));
        assert!(j[5].abs() < 1e-9, "wz column {}", j[5]);
    }
    let handle = Superquadric::untapered([0.03, 0.023, 0.008], 0.5, 1.0).unwrap();
    assert!(!handle.is_revolution());
}

#[test]
fn ray_hits_lie_on_the_surface_and_are_the_first_hit() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut hits = 0;
    for _ in 0..3000 {
        let sq = random_sq(&mut rng);
        let placed = PlacedSuperquadric::new(sq, random_pose(&mut rng));
        // Aim from well outside at a point inside the shape (a surface point pulled inwards).
        let surface = sq.sample_surface(sq.min_size() / 2.0);
        let target_local = surface[rng.random_range(0..surface.len())] * rng.random_range(0.0..0.9);
        let dir_local = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize();
        let origin_local = target_local - dir_local * (3.0 * sq.bounding_radius());
        let origin = placed.pose.transform_point(&Point3::from(origin_local));
        let dir = placed.pose.transform_vector(&dir_local);
        let t = placed
            .ray_hit(&origin, &dir, 10.0)
            .expect("a ray through an inside point must hit");
        let hit = origin + dir * t;
        assert!(
            placed.residual(&hit).abs() < 1e-6,
            "residual {} at the hit",
            placed.residual(&hit)
        );
        // Nothing before the hit is inside (checked densely).
        for i in 0..200 {
            let s = t * i as f64 / 200.0;
            assert!(placed.residual(&(origin + dir * s)) > 0.0);
        }
        hits += 1;
    }
    assert_eq!(hits, 3000);
    // Misses and a ray that starts inside.
    let s = Superquadric::untapered([0.1; 3], 1.0, 1.0).unwrap();
    assert_eq!(s.ray_hit(&Vector3::new(-1.0, 0.2, 0.0), &Vector3::x(), 5.0), None);
    assert_eq!(s.ray_hit(&Vector3::new(-1.0, 0.0, 0.0), &Vector3::x(), 0.5), None);
    assert_eq!(s.ray_hit(&Vector3::zeros(), &Vector3::x(), 5.0), Some(0.0));
    let t = s.ray_hit(&Vector3::new(-1.0, 0.0, 0.0), &Vector3::x(), 5.0).unwrap();
    assert!((t - 0.9).abs() < 1e-7);
}

#[test]
fn plain_and_log_domain_evaluations_agree_for_integer_exponents() {
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let nice = [0.1, 0.2, 0.4, 0.5, 1.0, 2.0];
    for _ in 0..3000 {
        let mut sq = random_sq(&mut rng);
        sq.e1 = nice[rng.random_range(0..nice.len())];
        sq.e2 = nice[rng.random_range(0..nice.len())];
        let scale = [0.0, 1e-3, 0.5, 1.0, 1.5, 5.0, 100.0][rng.random_range(0..7)];
        let mut p = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .component_mul(&Vector3::from(sq.a))
            * scale;
        if rng.random_bool(0.3) {
            p.y = 0.0;
        }
        let fast = sq.f_pow_e1(&p);
        let reference = sq.f_pow_e1_log(&p);
        assert!(
            (fast - reference).abs() <= 1e-10 * reference.max(1e-300),
            "{fast} vs {reference} at {p:?} for {sq}"
        );
        // The gradient against central differences, away from the coordinate planes where the
        // shape has kinks for e = 2.
        if p.iter().all(|c| c.abs() > 1e-4) && scale > 0.1 && scale < 10.0 {
            let g = sq.residual_grad(&p).grad;
            let h = 1e-8;
            for k in 0..3 {
                let mut d = Vector3::zeros();
                d[k] = h;
                let fd = (sq.residual(&(p + d)) - sq.residual(&(p - d))) / (2.0 * h);
                let tol = 1e-4 * g.norm().max(1.0);
                assert!((fd - g[k]).abs() < tol, "d/d{k}: {} vs {fd} at {p:?} for {sq}", g[k]);
            }
        }
    }
}

#[test]
fn lowest_z_matches_dense_sampling() {
    let shapes = [
        Superquadric::new([0.05, 0.05, 0.04], 0.3, 1.0, 0.2, 0.0).unwrap(),
        Superquadric::new([0.004, 0.004, 0.07], 1.0, 1.0, 0.0, 0.0).unwrap(),
        Superquadric::new([0.06, 0.03, 0.02], 0.1, 0.1, 0.0, 0.0).unwrap(),
        Superquadric::new([0.03, 0.02, 0.05], 1.6, 0.4, -0.5, 0.3).unwrap(),
    ];
    for (k, shape) in shapes.iter().enumerate() {
        for (r, p, y) in [
            (0.0, 0.0, 0.0),
            (0.4, 1.2, -0.3),
            (std::f64::consts::FRAC_PI_2, 0.0, 0.7),
            (2.8, -0.5, 2.0),
        ] {
            let placed = PlacedSuperquadric::new(
                *shape,
                Isometry3::from_parts(
                    Vector3::new(0.3, -0.1, 0.8).into(),
                    UnitQuaternion::from_euler_angles(r, p, y),
                ),
            );
            let dense = placed
                .sample_surface(shape.min_size() / 40.0)
                .iter()
                .map(|q| q.z)
                .fold(f64::INFINITY, f64::min);
            let fast = placed.lowest_z();
            // Never above a surface point, and below the densest sample by less than its spacing.
            assert!(
                fast <= dense + 1e-9,
                "shape {k} rpy {r},{p},{y}: {fast} above sampled {dense}"
            );
            assert!(
                dense - fast < shape.min_size() / 40.0,
                "shape {k} rpy {r},{p},{y}: {fast} vs {dense}"
            );
        }
    }
}

#[test]
fn signed_radial_distance_is_the_radial_distance_negative_inside() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for _ in 0..200 {
        let sq = random_sq(&mut rng);
        for _ in 0..20 {
            let p = Vector3::new(
                rng.random_range(-2.0..2.0) * sq.a[0],
                rng.random_range(-2.0..2.0) * sq.a[1],
                rng.random_range(-2.0..2.0) * sq.a[2],
            );
            let d = sq.signed_radial_distance(&p);
            let want = sq.radial_distance(&p);
            assert!(
                (d.abs() - want).abs() <= 1e-12 * (1.0 + want),
                "{sq:?} {p:?}: {d} vs {want}"
            );
            let f = sq.inside_outside(&p);
            // Off the surface the sign is the side (on it, within rounding, either will do).
            if (f - 1.0).abs() > 1e-9 {
                assert_eq!(d < 0.0, f < 1.0, "{sq:?} {p:?}: {d}, F = {f}");
            }
        }
    }
    let s = Superquadric::new([0.1, 0.1, 0.1], 1.0, 1.0, 0.0, 0.0).unwrap();
    assert!((s.signed_radial_distance(&Vector3::new(0.0, 0.05, 0.0)) + 0.05).abs() < 1e-14);
    assert!((s.signed_radial_distance(&Vector3::new(0.0, 0.0, 0.3)) - 0.2).abs() < 1e-14);
    assert_eq!(s.signed_radial_distance(&Vector3::zeros()), -0.1);
}

/// A kernel, prepared once for many points, gives what the shape and the placed shape give point
/// by point: residuals (also of the shapes without a plain form), distances and pose Jacobians.
#[test]
fn kernels_agree_with_the_pointwise_evaluation() {
    let mut rng = ChaCha8Rng::seed_from_u64(33);
    let nice = [0.1, 0.2, 0.4, 0.5, 1.0, 2.0];
    for _ in 0..2000 {
        let mut sq = random_sq(&mut rng);
        if rng.random_bool(0.6) {
            sq.e1 = nice[rng.random_range(0..nice.len())];
            sq.e2 = nice[rng.random_range(0..nice.len())];
        }
        let placed = PlacedSuperquadric::new(sq, random_pose(&mut rng));
        let k = PlacedKernel::new(&placed);
        let centre = Point3::from(placed.pose.translation.vector);
        let scale = [0.3, 1.0, 2.0, 50.0][rng.random_range(0..4)];
        let p = centre
            + Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            ) * sq.max_size()
                * scale;
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1e-12);
        let reference = sq.f_pow_e1_log(&placed.to_local(&p)) - 1.0;
        assert!(
            close(k.residual(&p), reference),
            "{} vs {reference} for {sq}",
            k.residual(&p)
        );
        assert!(close(k.surface_distance(&p), placed.surface_distance(&p)));
        let (r0, j0) = placed.residual_pose_jacobian(&p);
        let (r1, j1) = k.residual_pose_jacobian(&p);
        assert!(close(r0, r1));
        let size = j0.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (a, b) in j0.iter().zip(&j1) {
            assert!((a - b).abs() <= 1e-9 * size.max(1e-12), "{j0:?} vs {j1:?} for {sq}");
        }
    }
}

/// Four points evaluated together give what each gives alone, to the bit: also when some of them
/// leave the plain form (far away, the centre, a zero coordinate) or the shape has none.
#[test]
fn four_points_at_once_are_four_points_one_at_a_time() {
    use crate::numeric::lanes::Lanes;
    let mut rng = ChaCha8Rng::seed_from_u64(34);
    let nice = [0.1, 0.2, 0.25, 1.0 / 3.0, 0.4, 0.5, 1.0, 2.0];
    for _ in 0..3000 {
        let mut sq = random_sq(&mut rng);
        if rng.random_bool(0.7) {
            sq.e1 = nice[rng.random_range(0..nice.len())];
            sq.e2 = nice[rng.random_range(0..nice.len())];
        }
        if rng.random_bool(0.3) {
            (sq.kx, sq.ky) = (0.0, 0.0);
        }
        let k = Kernel::new(&sq);
        let points: [Vector3<f64>; 4] = std::array::from_fn(|_| {
            let scale = [0.0, 0.3, 1.0, 2.0, 1e5][rng.random_range(0..5)];
            let mut p = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            ) * sq.max_size()
                * scale;
            if rng.random_bool(0.1) {
                p[rng.random_range(0..3)] = 0.0;
            }
            p
        });
        let lanes: [Lanes<4>; 3] = std::array::from_fn(|c| Lanes(std::array::from_fn(|i| points[i][c])));
        let (r, g) = k.residual_grad_lanes(lanes);
        for (i, p) in points.iter().enumerate() {
            let one = k.residual_grad(p);
            assert_eq!(r.0[i].to_bits(), one.residual.to_bits(), "{p:?} of {sq}");
            for c in 0..3 {
                assert_eq!(g[c].0[i].to_bits(), one.grad[c].to_bits(), "{p:?} of {sq}");
            }
            if one.residual.is_finite() && one.residual.abs() < 1e6 {
                let reference = sq.f_pow_e1_log(p) - 1.0;
                let tol = 1e-9 * one.residual.abs().max(reference.abs()).max(1e-12);
                assert!(
                    (one.residual - reference).abs() <= tol,
                    "{} vs {reference} at {p:?} of {sq}",
                    one.residual
                );
            }
        }
    }
}

/// The whole-number powers of the plain form, for every exponent it can take; the unrolled ones
/// the same to the bit as the square and multiply they replace.
#[test]
fn integer_powers_of_lanes_agree_with_powi() {
    use crate::numeric::lanes::Lanes;
    let square_and_multiply = |x: f64, n: u32| {
        let (mut acc, mut base, mut e) = (1.0f64, x, n);
        loop {
            if e & 1 == 1 {
                acc *= base;
            }
            e >>= 1;
            if e == 0 {
                return acc;
            }
            base *= base;
        }
    };
    for n in [10, 19, 20] {
        for x in [0.3, 0.9, 1.0, 1.7, 3.5, 0.123456789] {
            let got = super::kernel::ipow_lanes(Lanes::<1>([x]), n).0[0];
            assert_eq!(got.to_bits(), square_and_multiply(x, n as u32).to_bits(), "{x}^{n}");
        }
    }
    for n in 0..=64 {
        for x in [0.0, 0.3, 0.9, 1.0, 1.7, 3.5] {
            let got = super::kernel::ipow_lanes(Lanes::<1>([x]), n).0[0];
            let want = f64::powi(x, n);
            assert!((got - want).abs() <= 1e-14 * want.abs(), "{x}^{n}: {got} vs {want}");
        }
    }
}

/// Every point that passes a placed shape's box test lies within its frame reach of the centre.
#[test]
fn the_frame_reach_holds_the_turned_box() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for _ in 0..50 {
        let sq = random_sq(&mut rng);
        let placed = PlacedSuperquadric::new(sq, random_pose(&mut rng));
        let kernel = PlacedKernel::new(&placed);
        let band = rng.random_range(0.0..0.01);
        let reach = kernel.frame_reach(band);
        let h = sq.local_half_extents().add_scalar(band);
        for _ in 0..200 {
            // Corners and random points of the grown local box.
            let q = Vector3::new(
                h.x * [-1.0, 1.0, rng.random_range(-1.0..1.0)][rng.random_range(0..3)],
                h.y * [-1.0, 1.0, rng.random_range(-1.0..1.0)][rng.random_range(0..3)],
                h.z * [-1.0, 1.0, rng.random_range(-1.0..1.0)][rng.random_range(0..3)],
            );
            let p = placed.pose * Point3::from(q);
            assert!(kernel.in_box(&p, band + 1e-9));
            let d = p.coords - placed.pose.translation.vector;
            assert!((0..3).all(|k| d[k].abs() <= reach[k]), "{d} outside {reach}");
        }
    }
}

/// Outside a shape's level box `F^e1` exceeds the level, tapered or not: the score may leave
/// those points out of S and I without changing them.
#[test]
fn outside_the_level_box_f_exceeds_the_level() {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    for _ in 0..100 {
        let sq = random_sq(&mut rng);
        let placed = PlacedSuperquadric::new(sq, random_pose(&mut rng));
        let kernel = PlacedKernel::new(&placed);
        let level = rng.random_range(1.0..1.5);
        let b = kernel.level_box(level);
        for _ in 0..300 {
            // A point just outside one face of the box, anywhere across the others.
            let mut q = Vector3::new(
                rng.random_range(-1.0..1.0) * b.x,
                rng.random_range(-1.0..1.0) * b.y,
                rng.random_range(-1.0..1.0) * b.z,
            );
            let k = rng.random_range(0..3);
            q[k] = b[k] * rng.random_range(1.0001..1.05) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let g = sq.residual_grad(&q).residual + 1.0;
            assert!(g > level, "{sq:?} at {q}: F^e1 {g} <= {level}");
        }
    }
}
