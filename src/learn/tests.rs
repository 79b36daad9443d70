//! Unit tests of the learner's stages.

use super::family::*;
use super::residual::*;
use super::segment::*;
use super::stages::*;
use super::*;
use crate::cloud::plane::Plane;
use crate::geometry::{PlacedSuperquadric, Superquadric};
use nalgebra::{Isometry3, Point3, Vector3};

/// A box-like shaft along x, 12 mm thick, seen from above at 45 degrees in the xz plane.
fn shaft() -> (Superquadric, Vector3<f64>) {
    let sq = Superquadric::new([0.06, 0.012, 0.012], 0.1, 0.1, 0.0, 0.0).unwrap();
    let d = Vector3::new(1.0, 0.0, -1.0).normalize();
    (sq, d)
}

#[test]
fn ray_residual_is_the_error_along_the_ray() {
    let (sq, d) = shaft();
    // A point of the top face moved along its ray: in front of the surface (towards the
    // sensor) reads positive, behind it (inside) negative, by the distance moved.
    for x in [-0.04, 0.0, 0.03] {
        let on = Vector3::new(x, 0.0, sq.a[2]);
        for delta in [-0.004, -0.001, 0.002, 0.005] {
            let r = ray_residual(&sq, &(on + d * delta), &d, false).unwrap();
            assert!((r + delta).abs() < 1e-6, "x {x}, moved {delta}: {r}");
        }
    }
}

#[test]
fn a_point_pushed_inside_near_an_edge_reads_its_own_face() {
    let (sq, d) = shaft();
    // The top 3 mm short of the far end (found from above: the edge is rounded a little),
    // pushed 3 mm along its ray into the shaft: the end face is nearer than the top, but
    // the ray entered through the top, 3 mm back, which is the point's error. Fitting the
    // nearest surface reads less and pulls the end face in: it rounds the edge.
    let x = sq.a[0] - 0.003;
    let down = -Vector3::z();
    let t = sq.ray_hit(&Vector3::new(x, 0.0, 0.1), &down, 1.0).unwrap();
    let on = Vector3::new(x, 0.0, 0.1 - t);
    let p = on + d * 0.003;
    let along = ray_residual(&sq, &p, &d, false).unwrap();
    assert!((along + 0.003).abs() < 1e-6, "{along}");
    let nearest = normal_distance(&sq, &p).abs();
    assert!(nearest < 0.0015, "nearest {nearest}");
}

#[test]
fn a_ray_that_misses_reads_its_gap_continuously() {
    // Rays straight down beside an egg's side at y = a2 + s: a miss for s > 0 reads about s
    // (the gap at the closest approach, which is at the point: the sign there is either,
    // the size is what the fit weighs), a graze at s = 0 about 0.
    let sq = Superquadric::new([0.03, 0.02, 0.04], 1.0, 1.0, 0.0, 0.0).unwrap();
    let d = -Vector3::z();
    let mut last = 0.0;
    for k in 0..8 {
        let s = 0.0005 * k as f64;
        let p = Vector3::new(0.0, sq.a[1] + s, 0.0);
        let r = ray_residual(&sq, &p, &d, false).unwrap().abs();
        assert!(r >= last - 1e-9, "not growing with the gap: {r} after {last}");
        assert!((r - s).abs() < 0.0002, "gap {s}: {r}");
        last = r;
    }
}

#[test]
fn an_open_containers_inside_seen_through_its_opening_is_left_to_the_nearest_surface() {
    let sq = Superquadric::new([0.06, 0.06, 0.03], 0.3, 1.0, 0.0, 0.0).unwrap();
    let d = Vector3::new(0.3, 0.0, -1.0).normalize();
    // A point on the inner wall 5 mm under the opening: its ray enters through the lid.
    let p = Vector3::new(0.0, 0.0, sq.a[2] - 0.005);
    assert_eq!(ray_residual(&sq, &p, &d, true), None);
    assert!(ray_residual(&sq, &p, &d, false).unwrap() < -0.004);
}

#[test]
fn volume_of_known_shapes() {
    let v = |a: [f64; 3], e1: f64, e2: f64| volume(&Superquadric::new(a, e1, e2, 0.0, 0.0).unwrap());
    let pi = std::f64::consts::PI;
    // Sphere and ellipsoid: 4/3 pi abc.
    assert!((v([1.0, 1.0, 1.0], 1.0, 1.0) - 4.0 / 3.0 * pi).abs() < 1e-9);
    assert!((v([0.03, 0.02, 0.05], 1.0, 1.0) - 4.0 / 3.0 * pi * 0.03 * 0.02 * 0.05).abs() < 1e-12);
    // Octahedron (e1 = e2 = 2): 4/3 abc.
    assert!((v([1.0, 2.0, 3.0], 2.0, 2.0) - 8.0).abs() < 1e-9);
    // Towards a box (e -> 0: 8 abc) and a cylinder (e1 -> 0, e2 = 1: 2 pi a^2 c).
    let boxy = v([1.0, 1.0, 1.0], 0.1, 0.1);
    assert!(boxy < 8.0 && boxy > 7.5, "{boxy}");
    let can = v([1.0, 1.0, 1.0], 0.1, 1.0);
    assert!(can < 2.0 * pi && can > 0.95 * 2.0 * pi, "{can}");
    // Gamma(5) = 24, Gamma(0.5) = sqrt(pi).
    assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-12);
    assert!((ln_gamma(0.5) - pi.sqrt().ln()).abs() < 1e-12);
}

#[test]
fn normal_distance_is_the_distance_along_the_normal() {
    // A flat, tapered shape (a bowl): points moved 2 mm along the outward normal from
    // surface points read 2 mm; the radial distance reads more on the flat top.
    let sq = Superquadric::new([0.06, 0.06, 0.02], 0.4, 1.0, 0.3, 0.3).unwrap();
    let mut worst_normal = 0.0f64;
    let mut worst_radial = 0.0f64;
    for q in sq.sample_surface(0.01) {
        let n = sq.residual_grad(&q).grad.normalize();
        for d in [0.002, -0.002] {
            let p = q + n * d;
            worst_normal = worst_normal.max((normal_distance(&sq, &p) - d).abs());
            let r = sq.radial_distance(&p) * d.signum();
            worst_radial = worst_radial.max((r - d).abs());
        }
    }
    assert!(worst_normal < 0.0005, "normal distance off by {worst_normal}");
    assert!(
        worst_radial > 2.0 * worst_normal,
        "radial distance off by only {worst_radial} (normal {worst_normal})"
    );
}

#[test]
fn support_below_a_segmented_object() {
    let mut pts: Vec<Point3<f64>> = (0..1000)
        .map(|i| Point3::new(0.0, 0.0, -0.1 + 0.2 * i as f64 / 999.0))
        .collect();
    pts.push(Point3::new(0.0, 0.0, -0.5)); // a stray far below
    let pl = support_below(&pts, Some(&Vector3::new(0.0, 0.0, 2.0))).unwrap();
    assert!((pl.normal - Vector3::z()).norm() < 1e-12);
    assert!((-pl.d + 0.1).abs() < 0.003, "plane at {}", -pl.d);
    assert!(support_below(&pts, None).is_none());
}

#[test]
fn a_revolution_only_fit_is_a_body_of_revolution() {
    let truth = Superquadric::new([0.04, 0.03, 0.05], 0.3, 1.0, 0.0, 0.0).unwrap();
    let placed = PlacedSuperquadric::new(truth, Isometry3::translation(0.8, 0.0, 0.77));
    let view = Point3::new(0.0, 0.0, 1.35);
    let c = placed.pose.translation.vector;
    let pts: Vec<Point3<f64>> = placed
        .sample_surface(0.004)
        .into_iter()
        .filter(|p| (p.coords - c).dot(&(view.coords - c)) > 0.0 && p.z > 0.722)
        .collect();
    let plane = Plane {
        normal: Vector3::z(),
        d: -0.72,
    };
    let params = LearnParams {
        viewpoint: Some(view),
        shape: ShapeFamily::Revolution,
        ..Default::default()
    };
    let r = fit_superquadric(&pts, &[], Some(&plane), &params).unwrap();
    let sq = r.placed.shape;
    assert!(sq.a[0] == sq.a[1] && sq.e2 == 1.0 && sq.kx == sq.ky, "{sq}");
    // Between the two true radii.
    assert!(sq.a[0] > 0.029 && sq.a[0] < 0.041, "{sq}");
}

#[test]
fn recovers_a_tapered_shape_from_its_visible_half_on_a_plane() {
    let truth_sq = Superquadric::new([0.05, 0.035, 0.03], 0.5, 0.7, 0.2, 0.1).unwrap();
    let mut truth = PlacedSuperquadric::new(truth_sq, Isometry3::translation(0.8, 0.1, 0.0));
    let low = truth.lowest_z();
    truth.pose.translation.vector.z = 0.72 - low;
    let view = Point3::new(0.0, 0.0, 1.35);
    let c = truth.pose.translation.vector;
    let pts: Vec<Point3<f64>> = truth
        .sample_surface(0.003)
        .into_iter()
        .filter(|p| (p.coords - c).dot(&(view.coords - c)) > 0.0)
        .collect();
    let plane = Plane {
        normal: Vector3::z(),
        d: -0.72,
    };
    let params = LearnParams {
        viewpoint: Some(view),
        ..Default::default()
    };
    let r = fit_superquadric(&pts, &[], Some(&plane), &params).unwrap();
    let sq = r.placed.shape;
    let (a, b) = if (sq.a[0] - 0.05).abs() < (sq.a[1] - 0.05).abs() {
        (sq.a[0], sq.a[1])
    } else {
        (sq.a[1], sq.a[0])
    };
    assert!(
        (a - 0.05).abs() < 0.003 && (b - 0.035).abs() < 0.003 && (sq.a[2] - 0.03).abs() < 0.003,
        "{sq} ({})",
        r.start
    );
    assert!((sq.e1 - 0.5).abs() < 0.1 && (sq.e2 - 0.7).abs() < 0.1, "{sq}");
}
