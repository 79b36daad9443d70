//! A closed object standing on the plane with its top in view (a box on any face, a standing
//! can or tin) is measured rather than fitted: its top's outline gives the cross-section, its
//! orientation and its centre, the top's height over the plane its height.
//!
//! Why: the fit of `stages.rs` holds a closed shape's hidden back only through the free space
//! and the seen surface, which sample it coarsely (a tenth of a size apart, and a few
//! millimetres of tolerance), and the mirror of stage C then fixes whatever depth the first fits
//! filled in. On the everyday objects of the mOSD learn scenes the fitted boxes and cans came
//! out 10-20 mm too deep or too wide (a Pringles can 73 mm across learned as 85 mm), which is
//! the size of the next box on the shelf. The top of a convex object on the table, seen from
//! above, is seen whole: its outline is the cross-section, to within the sensor's noise.
//!
//! Over 600 lines, a third of them tests: the measurement's checks (standing, a flat top, walls
//! under it) are tested together, on synthetic views of boxes, cans and their neighbours.

use super::seen::hull2d;
use super::state::State;
use super::wall_circle::wall_circle;
use crate::cloud::plane::{Plane, orthonormal_basis};
use crate::geometry::EPSILON_MIN;
use nalgebra::{Point3, Rotation3, UnitQuaternion, Vector2, Vector3};

/// Points within this height of the top's median height are the top (m): three sigmas of a
/// Kinect-class sensor at a metre.
const TOP_BAND: f64 = 0.008;
/// Below the top, the walls may reach this far outside the top's outline (m) and still be the
/// walls of a prism (the sensor's noise and its mixed pixels at the edges).
const WALL_MARGIN: f64 = 0.01;
/// A flat top's middle stands at most this much higher than its edge (m): a sensor's noise
/// leaves the two medians within a millimetre or two.
const FLAT_DROP: f64 = 0.004;
/// Share of the wall points that must lie within the grown outline: what `learn --at` keeps of
/// a neighbour (a tenth of the points, behind a box shown among others) leaves a prism one;
/// an upturned pot or bowl, flaring out below its base, has most of its wall outside.
const WALL_SHARE: f64 = 0.85;
/// A convex outline filling less than this share of its smallest bounding rectangle is round
/// (an ellipse fills pi/4 = 0.785 of it, a rectangle all of it).
const ROUND_BELOW: f64 = 0.88;
/// A round object's wall is measured between these shares of its height: clear of the table
/// (and what lies on it) and of the rim.
const WALL_BAND: (f64, f64) = (0.2, 0.8);

/// What was measured.
#[derive(Debug, Clone)]
pub(super) struct Prism {
    /// The cross-section's centre in the plane's basis ([`orthonormal_basis`] of its normal).
    pub(super) centre: Vector2<f64>,
    /// The cross-section's half-sizes along `axis` and across it (m).
    pub(super) half: [f64; 2],
    /// The direction of the first half-size in the plane's basis.
    pub(super) axis: Vector2<f64>,
    /// The top's height over the plane (m).
    pub(super) height: f64,
    /// Round (an ellipse) rather than rectangular.
    pub(super) round: bool,
    /// How much of its bounding rectangle the top's outline fills.
    pub(super) fill: f64,
    /// Points on the top.
    pub(super) top_points: usize,
    /// For a round object, the radius its top's outline gives, where the wall gave the
    /// cross-section instead (m).
    pub(super) top_radius: Option<f64>,
}

impl std::fmt::Display for Prism {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} {:.1} x {:.1} mm, {:.1} mm tall (the top's {} points fill {:.2} of their bounding rectangle)",
            if self.round { "round" } else { "rectangular" },
            2e3 * self.half[0],
            2e3 * self.half[1],
            1e3 * self.height,
            self.top_points,
            self.fill
        )?;
        if let Some(r) = self.top_radius {
            write!(
                f,
                "; across from the wall's circle, the top's outline gave {:.1} mm",
                2e3 * r
            )?;
        }
        Ok(())
    }
}

/// The `f`-quantile (0..1) of `v`, as [`crate::numeric::quantile`] picks it, of a copy (the
/// callers keep their order; an empty `v` gives NaN).
fn quantile(v: &[f64], f: f64) -> f64 {
    crate::numeric::quantile(&mut v.to_vec(), f).unwrap_or(f64::NAN)
}

/// Measure the object as a prism standing on `plane`, seen from `viewpoint`; the reason it is
/// not one otherwise.
pub(super) fn measure(points: &[Point3<f64>], plane: &Plane, viewpoint: &Point3<f64>) -> Result<Prism, String> {
    let Standing { points, h, level } = standing_with_top_in_view(points, plane, viewpoint)?;
    let (u, w) = orthonormal_basis(&plane.normal);
    let flat = |p: &Point3<f64>| Vector2::new(p.coords.dot(&u), p.coords.dot(&w));
    // The top's points, in the plane's basis, with their heights.
    let (top_xy, top_z): (Vec<Vector2<f64>>, Vec<f64>) = points
        .iter()
        .zip(&h)
        .filter(|(_, z)| (**z - level).abs() < TOP_BAND)
        .map(|(p, z)| (flat(p), *z))
        .unzip();
    if top_xy.len() < 50 || top_xy.len() * 10 < points.len() {
        return Err(format!(
            "{} of {} points on a level top: not a closed top in view",
            top_xy.len(),
            points.len()
        ));
    }
    let rect = smallest_rectangle(&top_xy);
    if rect.half[0].min(rect.half[1]) < 0.005 {
        return Err("the top is a sliver".into());
    }
    let fill = outline_fill(&top_xy, &rect);
    let round = fill < ROUND_BELOW;
    // The 1-99 % extents cut a share of the outline's edge that its shape fixes: 1 % of the
    // width at each side of a uniformly sampled rectangle, 5.6 % of the radius of an ellipse
    // (where the cap beyond holds 1 % of its area).
    let cut = if round { 0.944 } else { 0.98 };
    let half = [rect.half[0] / cut, rect.half[1] / cut];
    let local = |q: &Vector2<f64>| rect.local(q);
    check_flat_top(&top_xy, &top_z, &local, half)?;
    let walls: Vec<Vector2<f64>> = points
        .iter()
        .zip(&h)
        .filter(|(_, z)| **z < level - TOP_BAND)
        .map(|(p, _)| local(&flat(p)))
        .collect();
    check_walls_under_top(&walls, half, round)?;
    let (mut centre, mut half, mut top_radius) = (rect.centre, half, None);
    if round {
        let wall: Vec<Vector2<f64>> = points
            .iter()
            .zip(&h)
            .filter(|(_, z)| **z > WALL_BAND.0 * level && **z < WALL_BAND.1 * level)
            .map(|(p, _)| flat(p))
            .collect();
        if let Some((c, r)) = round_cross_section(&wall, half) {
            top_radius = Some(0.5 * (half[0] + half[1]));
            centre = c;
            half = [r, r];
        }
    }
    Ok(Prism {
        centre,
        half,
        axis: rect.axis,
        height: level,
        round,
        fill,
        top_points: top_xy.len(),
        top_radius,
    })
}

/// An object standing on the plane with its top in view.
struct Standing {
    /// Its finite points.
    points: Vec<Point3<f64>>,
    /// Their heights over the plane (m).
    h: Vec<f64>,
    /// The height of its top (m).
    level: f64,
}

/// The object where it stands on the plane, is tall enough to have a top and the sensor looks
/// down on that top; else why not.
fn standing_with_top_in_view(
    points: &[Point3<f64>],
    plane: &Plane,
    viewpoint: &Point3<f64>,
) -> Result<Standing, String> {
    let points: Vec<Point3<f64>> = points
        .iter()
        .filter(|p| p.coords.iter().all(|c| c.is_finite()))
        .copied()
        .collect();
    if points.len() < 50 {
        return Err(format!("{} points are too few", points.len()));
    }
    if !plane.signed_distance(viewpoint).is_finite() {
        return Err("the sensor's position is not finite".into());
    }
    let h: Vec<f64> = points.iter().map(|p| plane.signed_distance(p)).collect();
    let top = quantile(&h, 0.99);
    if top < 0.015 {
        return Err(format!("{:.1} mm tall: too flat for a top", top * 1e3));
    }
    let above = plane.signed_distance(viewpoint) - top;
    if above < 0.05 {
        return Err(format!(
            "the sensor is {:.0} mm above the top, too little to see it",
            above * 1e3
        ));
    }
    let low = quantile(&h, 0.01);
    if low > 0.02f64.max(0.15 * top) {
        return Err(format!(
            "the lowest points are {:.0} mm above the plane: not standing on it",
            low * 1e3
        ));
    }
    let near_top: Vec<f64> = h.iter().copied().filter(|&z| z > top - 2.0 * TOP_BAND).collect();
    let level = quantile(&near_top, 0.5);
    Ok(Standing { points, h, level })
}

/// The smallest rectangle (by whole degrees) that holds the 1-99 % extents of the top's points.
struct Rectangle {
    area: f64,
    centre: Vector2<f64>,
    half: [f64; 2],
    /// The direction of the first half-size.
    axis: Vector2<f64>,
}

impl Rectangle {
    /// A point of the plane's basis in the rectangle's frame.
    fn local(&self, q: &Vector2<f64>) -> Vector2<f64> {
        let across = Vector2::new(-self.axis.y, self.axis.x);
        Vector2::new((q - self.centre).dot(&self.axis), (q - self.centre).dot(&across))
    }
}

fn smallest_rectangle(top_xy: &[Vector2<f64>]) -> Rectangle {
    let mut best: Option<Rectangle> = None;
    for deg in 0..90 {
        let t = (deg as f64).to_radians();
        let (d1, d2) = (Vector2::new(t.cos(), t.sin()), Vector2::new(-t.sin(), t.cos()));
        let x: Vec<f64> = top_xy.iter().map(|q| q.dot(&d1)).collect();
        let y: Vec<f64> = top_xy.iter().map(|q| q.dot(&d2)).collect();
        let (x0, x1, y0, y1) = (
            quantile(&x, 0.01),
            quantile(&x, 0.99),
            quantile(&y, 0.01),
            quantile(&y, 0.99),
        );
        let area = (x1 - x0) * (y1 - y0);
        if best.as_ref().is_none_or(|b| area < b.area) {
            best = Some(Rectangle {
                area,
                centre: d1 * (0.5 * (x0 + x1)) + d2 * (0.5 * (y0 + y1)),
                half: [0.5 * (x1 - x0), 0.5 * (y1 - y0)],
                axis: d1,
            });
        }
    }
    best.expect("ninety angles tried")
}

/// How much of the rectangle the top's outline fills, on the top points within it (a stray
/// point outside would stretch the hull).
fn outline_fill(top_xy: &[Vector2<f64>], rect: &Rectangle) -> f64 {
    let inside: Vec<(f64, f64)> = top_xy
        .iter()
        .map(|q| rect.local(q))
        .filter(|l| l.x.abs() <= rect.half[0] && l.y.abs() <= rect.half[1])
        .map(|l| (l.x, l.y))
        .collect();
    let hull = hull2d(inside);
    let hull_area = 0.5
        * (0..hull.len())
            .map(|i| {
                let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
                a.0 * b.1 - b.0 * a.1
            })
            .sum::<f64>()
            .abs();
    hull_area / rect.area
}

/// A flat top is as high at its edges as in its middle; a dome (a ball, a mouse) or a lying
/// cylinder is not, and its outline at the top is no cross-section. Each pair of edges on its
/// own: along a lying shaft the top is level, across it it falls away.
fn check_flat_top(
    top_xy: &[Vector2<f64>],
    top_z: &[f64],
    local: &impl Fn(&Vector2<f64>) -> Vector2<f64>,
    half: [f64; 2],
) -> Result<(), String> {
    let top_local: Vec<(Vector2<f64>, f64)> = top_xy
        .iter()
        .zip(top_z)
        .map(|(q, z)| {
            let l = local(q);
            (Vector2::new(l.x / half[0], l.y / half[1]), *z)
        })
        .collect();
    let middle: Vec<f64> = top_local
        .iter()
        .filter(|(r, _)| r.amax() < 0.5)
        .map(|(_, z)| *z)
        .collect();
    if middle.len() < 10 {
        return Err(format!(
            "{} points in the top's middle: too few to tell it flat",
            middle.len()
        ));
    }
    let middle = quantile(&middle, 0.5);
    for k in 0..2 {
        let edge: Vec<f64> = top_local
            .iter()
            .filter(|(r, _)| r[k].abs() > 0.8)
            .map(|(_, z)| *z)
            .collect();
        if edge.len() < 10 {
            return Err(format!(
                "{} points at the top's edges: too few to tell it flat",
                edge.len()
            ));
        }
        let drop = middle - quantile(&edge, 0.5);
        if drop > FLAT_DROP {
            return Err(format!(
                "the top falls {:.1} mm from its middle to its edges: not flat",
                drop * 1e3
            ));
        }
    }
    Ok(())
}

/// The walls below the top (`walls`, in the top's frame) lie under its outline (grown by the
/// margin), or the object is no prism: a bowl or pot on its rim is wider below, a lying can's
/// top is a line along it.
fn check_walls_under_top(walls: &[Vector2<f64>], half: [f64; 2], round: bool) -> Result<(), String> {
    let grown = [half[0] + WALL_MARGIN, half[1] + WALL_MARGIN];
    let within = walls
        .iter()
        .filter(|l| {
            if round {
                (l.x / grown[0]).powi(2) + (l.y / grown[1]).powi(2) <= 1.0
            } else {
                l.x.abs() <= grown[0] && l.y.abs() <= grown[1]
            }
        })
        .count();
    if !walls.is_empty() && (within as f64) < WALL_SHARE * walls.len() as f64 {
        return Err(format!(
            "{} of {} points below the top lie outside its outline: not a prism",
            walls.len() - within,
            walls.len()
        ));
    }
    Ok(())
}

/// A round object's wall gives its cross-section better than its top: the top's outline loses
/// its edge to the sensor (a structured-light sensor's edge pixels, the lid's rounded rim
/// falling below the top's band), so that the mOSD tins and cans came out 4-8 mm narrower than
/// their walls, and were missed where the detector measured the wall just outside them. The
/// wall's circle (centre in the plane's basis, radius) where it agrees with the top's outline
/// (`half`) to within a quarter.
fn round_cross_section(wall: &[Vector2<f64>], half: [f64; 2]) -> Option<(Vector2<f64>, f64)> {
    match wall_circle(wall) {
        Ok((c, r)) if (0.8..1.25).contains(&(r / (0.5 * (half[0] + half[1])))) => Some((c, r)),
        Ok((_, r)) => {
            tracing::debug!(
                "the wall's circle ({:.1} mm across) is too far from the top's outline to take",
                2e3 * r
            );
            None
        }
        Err(why) => {
            tracing::debug!("the cross-section from the top's outline: {why}");
            None
        }
    }
}

/// The prism as a fit state: the cross-section's axes along its outline, z along the plane's
/// normal, the centre half its height above the plane.
pub(super) fn state(prism: &Prism, plane: &Plane) -> State {
    let (u, w) = orthonormal_basis(&plane.normal);
    let x = u * prism.axis.x + w * prism.axis.y;
    let y = plane.normal.cross(&x);
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_basis_unchecked(&[x, y, plane.normal]));
    let t: Vector3<f64> = u * prism.centre.x + w * prism.centre.y + plane.normal * (0.5 * prism.height - plane.d);
    let (a1, a2) = if prism.round {
        // A circle unless the view shows clearly otherwise.
        let m = 0.5 * (prism.half[0] + prism.half[1]);
        if (prism.half[0] - prism.half[1]).abs() <= 0.1 * m {
            (m, m)
        } else {
            (prism.half[0], prism.half[1])
        }
    } else {
        (prism.half[0], prism.half[1])
    };
    State {
        ln_a: [a1.ln(), a2.ln(), (0.5 * prism.height).ln()],
        e: [EPSILON_MIN, if prism.round { 1.0 } else { EPSILON_MIN }],
        k: [0.0, 0.0],
        rot,
        t,
        rev: prism.round && a1 == a2,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    const TABLE: Plane = Plane {
        normal: Vector3::new(0.0, 0.0, 1.0),
        d: 0.0,
    };

    /// The sensor half a metre in front of the object and 0.6 m above the table.
    fn sensor() -> Point3<f64> {
        Point3::new(0.0, -0.5, 0.6)
    }

    /// What the sensor sees of a vertical prism at the origin (outline `inside(x, y)` within the
    /// square of half-size `r`, height `h`): its top on a 2 mm grid, and its walls facing the
    /// sensor on 2 mm rings, with 1.5 mm of noise.
    fn prism_view(r: f64, h: f64, inside: impl Fn(f64, f64) -> bool) -> Vec<Point3<f64>> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let mut noise = move || 0.0015 * (rng.random::<f64>() - 0.5) * 2.0;
        let mut pts = Vec::new();
        let steps = (r / 0.002) as i32;
        for i in -steps..=steps {
            for j in -steps..=steps {
                let (x, y) = (i as f64 * 0.002, j as f64 * 0.002);
                if !inside(x, y) {
                    continue;
                }
                pts.push(Point3::new(x, y, h + noise()));
                // The wall below an edge point that faces the sensor (the outline's next step
                // towards it is outside).
                if !inside(x, y - 0.002) {
                    let mut z = 0.002;
                    while z < h - 0.004 {
                        pts.push(Point3::new(x, y + noise(), z));
                        z += 0.002;
                    }
                }
            }
        }
        pts
    }

    #[test]
    fn a_box_is_measured_from_its_top() {
        // 120 x 60 mm, 150 mm tall, turned 30 degrees.
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let pts = prism_view(0.08, 0.15, |x, y| {
            let (u, v) = (c * x + s * y, -s * x + c * y);
            u.abs() <= 0.06 && v.abs() <= 0.03
        });
        let p = measure(&pts, &TABLE, &sensor()).unwrap();
        assert!(!p.round, "{p}");
        let (long, short) = (p.half[0].max(p.half[1]), p.half[0].min(p.half[1]));
        assert!((long - 0.06).abs() < 0.002 && (short - 0.03).abs() < 0.002, "{p}");
        assert!((p.height - 0.15).abs() < 0.002, "{p}");
        assert!(p.centre.norm() < 0.002, "{p}");
        let st = state(&p, &TABLE);
        assert!((st.t - Vector3::new(0.0, 0.0, 0.075)).norm() < 0.003, "{:?}", st.t);
        // The long side's direction, up to its sign.
        let long_axis = st.rot
            * if p.half[0] > p.half[1] {
                Vector3::x()
            } else {
                Vector3::y()
            };
        assert!(long_axis.dot(&Vector3::new(c, s, 0.0)).abs() > 0.99, "{long_axis:?}");
    }

    #[test]
    fn a_can_is_measured_round() {
        let pts = prism_view(0.04, 0.2, |x, y| x * x + y * y <= 0.037 * 0.037);
        let p = measure(&pts, &TABLE, &sensor()).unwrap();
        assert!(p.round, "{p}");
        assert!(
            (p.half[0] - 0.037).abs() < 0.002 && (p.half[1] - 0.037).abs() < 0.002,
            "{p}"
        );
        let s = state(&p, &TABLE);
        assert!(s.rev && s.e == [EPSILON_MIN, 1.0], "{s:?}");
    }

    #[test]
    fn a_box_shown_with_a_fragment_of_the_box_behind_it_is_still_measured() {
        // `learn --at` on the standing Weetabix box of mOSD learn28 kept 300 points of the box
        // behind it: 10.5 % of the points below the top lay outside its outline.
        let mut pts = prism_view(0.06, 0.2, |x, y| x.abs() <= 0.05 && y.abs() <= 0.02);
        let below = pts.iter().filter(|p| p.z < 0.19).count();
        let stray = below * 12 / 88;
        for k in 0..stray {
            let t = k as f64 / stray as f64;
            pts.push(Point3::new(-0.05 + 0.1 * t, 0.05, 0.02 + 0.1 * t));
        }
        let p = measure(&pts, &TABLE, &sensor()).unwrap();
        assert!(!p.round, "{p}");
        assert!((p.half[0].max(p.half[1]) - 0.05).abs() < 0.002, "{p}");
    }

    #[test]
    fn a_can_whose_top_lost_its_edge_is_measured_from_its_wall() {
        // The top seen 4 mm narrower than the wall below it, as a structured-light sensor
        // shows a can's lid; the wall facing the sensor, 4 mm rings, 1 mm of noise.
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let mut noise = move || 0.001 * (rng.random::<f64>() - 0.5) * 2.0;
        let (wall_r, top_r, h) = (0.037, 0.033, 0.12);
        let mut pts = Vec::new();
        let steps = (top_r / 0.002) as i32;
        for i in -steps..=steps {
            for j in -steps..=steps {
                let (x, y) = (i as f64 * 0.002, j as f64 * 0.002);
                if x * x + y * y <= top_r * top_r {
                    pts.push(Point3::new(x + 0.1, y, h + noise()));
                }
            }
        }
        for k in 0..45 {
            // The half facing the sensor (at -y), and a little more.
            let t = std::f64::consts::PI * (1.0 + 1.1 * k as f64 / 45.0) - 0.05;
            let mut z = 0.004;
            while z < h - 0.004 {
                let r = wall_r + noise();
                pts.push(Point3::new(0.1 + r * t.cos(), r * t.sin(), z));
                z += 0.004;
            }
        }
        let p = measure(&pts, &TABLE, &sensor()).unwrap();
        assert!(p.round, "{p}");
        assert!((p.half[0] - wall_r).abs() < 0.001 && p.half[0] == p.half[1], "{p}");
        let (u, w) = orthonormal_basis(&TABLE.normal);
        let axis = Vector3::new(0.1, 0.0, 0.0);
        assert!(
            (p.centre - Vector2::new(axis.dot(&u), axis.dot(&w))).norm() < 0.001,
            "{p}"
        );
        assert!(p.top_radius.is_some_and(|r| (r - top_r).abs() < 0.002), "{p}");
    }

    #[test]
    fn a_pot_on_its_rim_is_no_prism() {
        // Its base on top, 60 mm across; its walls flare out to 100 mm at the table.
        let mut pts: Vec<Point3<f64>> = prism_view(0.04, 0.1, |x, y| x * x + y * y <= 0.03 * 0.03)
            .into_iter()
            .filter(|p| p.z > 0.09)
            .collect();
        for k in 0..=90 {
            let phi = std::f64::consts::PI * (1.0 + k as f64 / 90.0);
            let mut z = 0.0;
            while z < 0.09 {
                let r = 0.05 - 0.02 * z / 0.1;
                pts.push(Point3::new(r * phi.cos(), r * phi.sin(), z));
                z += 0.002;
            }
        }
        let e = measure(&pts, &TABLE, &sensor()).unwrap_err();
        assert!(e.contains("outside its outline"), "{e}");
    }

    #[test]
    fn a_dome_is_not_flat() {
        // A half ball of 50 mm radius.
        let mut pts = Vec::new();
        for i in -25..=25 {
            for j in -25..=25 {
                let (x, y) = (i as f64 * 0.002, j as f64 * 0.002);
                let r2 = x * x + y * y;
                if r2 < 0.05 * 0.05 {
                    pts.push(Point3::new(x, y, (0.05 * 0.05 - r2).sqrt()));
                }
            }
        }
        let e = measure(&pts, &TABLE, &sensor()).unwrap_err();
        assert!(e.contains("not flat") || e.contains("level top"), "{e}");
    }

    #[test]
    fn a_lying_can_is_no_prism() {
        // 35 mm radius, lying along x: its highest line is no top.
        let mut pts = Vec::new();
        for i in -50..=50 {
            for k in 0..=60 {
                let phi = std::f64::consts::PI * k as f64 / 60.0;
                pts.push(Point3::new(
                    i as f64 * 0.002,
                    -0.035 * phi.cos(),
                    0.035 + 0.035 * phi.sin(),
                ));
            }
        }
        assert!(measure(&pts, &TABLE, &sensor()).is_err());
    }

    #[test]
    fn hostile_inputs_are_refused_without_panicking() {
        assert!(measure(&[], &TABLE, &sensor()).is_err());
        let flat: Vec<Point3<f64>> = (0..100).map(|i| Point3::new(i as f64 * 0.001, 0.0, 0.001)).collect();
        assert!(measure(&flat, &TABLE, &sensor()).is_err());
        let mut nan = prism_view(0.04, 0.1, |x, y| x.abs() < 0.03 && y.abs() < 0.03);
        nan.push(Point3::new(f64::NAN, 0.0, 0.05));
        let _ = measure(&nan, &TABLE, &sensor());
        // The sensor below the top.
        let pts = prism_view(0.04, 0.1, |x, y| x.abs() < 0.03 && y.abs() < 0.03);
        assert!(measure(&pts, &TABLE, &Point3::new(0.0, -0.5, 0.08)).is_err());
    }
}
