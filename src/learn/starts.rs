//! Where the single-part fit starts: frames from the moments of the points and the up
//! direction, sizes and centres from the points' extents, several exponent pairs and tapers,
//! each also as a body of revolution.

use super::params::{LearnParams, ShapeFamily};
use super::state::{SIZE_MAX, State};
use nalgebra::{Point3, Rotation3, UnitQuaternion, Vector3};

/// The centroid and the covariance's eigenvectors (columns, by decreasing variance).
pub(super) fn moments(points: &[Point3<f64>]) -> (Vector3<f64>, [Vector3<f64>; 3]) {
    let (c, [small, mid, large]) = crate::geometry::principal_axes(points);
    (c, [large, mid, small])
}

/// A right-handed frame with z along `z` and x along the major moment direction across it.
pub(super) fn frame_with_z(points: &[Point3<f64>], centroid: &Vector3<f64>, z: &Vector3<f64>) -> UnitQuaternion<f64> {
    let z = z.normalize();
    let helper = if z.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let u = z.cross(&helper).normalize();
    let v = z.cross(&u);
    let (mut suu, mut suv, mut svv) = (0.0, 0.0, 0.0);
    for p in points {
        let d = p.coords - centroid;
        let (a, b) = (d.dot(&u), d.dot(&v));
        suu += a * a;
        suv += a * b;
        svv += b * b;
    }
    let angle = 0.5 * (2.0 * suv).atan2(suu - svv);
    let x = u * angle.cos() + v * angle.sin();
    let y = z.cross(&x);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_basis_unchecked(&[x, y, z]))
}

/// Start sizes and centre from the extents of the points in a frame (2-98 percent), the centre
/// pushed away from the sensor by half the sizes along the view (only the front half is seen).
pub(super) fn start_state(
    points: &[Point3<f64>],
    rot: UnitQuaternion<f64>,
    viewpoint: Option<&Point3<f64>>,
    e: (f64, f64),
) -> State {
    let local: Vec<Vector3<f64>> = points.iter().map(|p| rot.inverse() * p.coords).collect();
    let mut lo = [0.0; 3];
    let mut hi = [0.0; 3];
    for k in 0..3 {
        let mut v: Vec<f64> = local.iter().map(|q| q[k]).collect();
        v.sort_by(f64::total_cmp);
        lo[k] = v[(v.len() as f64 * 0.02) as usize];
        hi[k] = v[((v.len() as f64 * 0.98) as usize).min(v.len() - 1)];
    }
    let mut a = [0.0; 3];
    let mut c = Vector3::zeros();
    for k in 0..3 {
        a[k] = (0.5 * (hi[k] - lo[k])).clamp(0.003, SIZE_MAX);
        c[k] = 0.5 * (hi[k] + lo[k]);
    }
    if let Some(v) = viewpoint {
        let centre = rot * c;
        if let Some(view) = (centre - v.coords).try_normalize(1e-9) {
            let d = rot.inverse() * view;
            for k in 0..3 {
                c[k] += 0.3 * d[k] * a[k];
            }
        }
    }
    State {
        ln_a: a.map(f64::ln),
        e: [e.0, e.1],
        k: [0.0, 0.0],
        rot,
        t: rot * c,
        rev: false,
    }
}

/// The starts: z along up and along each moment axis, three exponent pairs each, tapered ones
/// standing on the plane, and each also as a body of revolution (as `params.shape` allows).
pub(super) fn starts(
    points: &[Point3<f64>],
    centroid: &Vector3<f64>,
    axes: &[Vector3<f64>; 3],
    up: Option<&Vector3<f64>>,
    params: &LearnParams,
) -> Vec<(String, State)> {
    let mut starts: Vec<(String, State)> = Vec::new();
    let mut zs: Vec<(String, Vector3<f64>)> = Vec::new();
    if let Some(u) = up {
        zs.push(("up".into(), *u));
    }
    for (k, a) in axes.iter().enumerate() {
        // A moment axis within 15 degrees of up duplicates the up start.
        if up.is_some_and(|u| a.dot(u).abs() > 0.966) {
            continue;
        }
        zs.push((format!("moment{k}"), *a));
    }
    for (zn, z) in &zs {
        let rot = frame_with_z(points, centroid, z);
        for e in [(1.0, 1.0), (0.3, 1.0), (0.3, 0.3)] {
            starts.push((
                format!("z={zn} e=({},{})", e.0, e.1),
                start_state(points, rot, params.viewpoint.as_ref(), e),
            ));
        }
        // The z-flipped starts of a tapered shape (EMS's switch): an untapered start standing on
        // the plane can slide into the taper of the wrong sign (a bowl widening downwards).
        if zn == "up" {
            for k in [0.3, -0.3] {
                for e in [(1.0, 1.0), (0.3, 1.0)] {
                    let mut s = start_state(points, rot, params.viewpoint.as_ref(), e);
                    s.k = [k, k];
                    starts.push((format!("z={zn} e=({},{}) k={k}", e.0, e.1), s));
                }
            }
        }
    }
    // Every start also as a body of revolution about its z axis: the simpler family, which the
    // end prefers unless the general shape explains the view clearly better (a hidden foot or
    // back leaves a general shape free to bulge or flatten where nothing was seen).
    let rev: Vec<(String, State)> = starts
        .iter()
        .map(|(n, s)| (format!("{n} revolution"), s.as_revolution()))
        .collect();
    match params.shape {
        ShapeFamily::Auto => starts.extend(rev),
        ShapeFamily::General => {}
        ShapeFamily::Revolution => starts = rev,
    }
    starts
}
