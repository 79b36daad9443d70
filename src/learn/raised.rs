//! An object shown standing on another object: the level surface under its foot, which takes the
//! support plane's place in the fit. The table is not what a can standing on a tin rests on; fitted
//! down to the table, its model takes the tin's height as its own (the mOSD floral canister on the
//! biscuit tin came out 171 mm tall for 104).

use super::seen::Outline;
use crate::cloud::grid::Grid;
use crate::cloud::plane::Plane;
use crate::numeric::{least_spread_direction, median};
use nalgebra::{Point3, Vector3};

/// The surface an object raised off the support plane stands on, parallel to that plane.
#[derive(Debug, Clone, Copy)]
pub struct RaisedSupport {
    /// The surface as a plane (its normal the support plane's).
    pub plane: Plane,
    /// Its height over the support plane (m).
    pub height: f64,
    /// Points of it seen beside the object's foot.
    pub points: usize,
}

/// Above this height over the support plane (m) the object's lowest points are not on it: the
/// learner's test of an object standing on the plane (`prism.rs`) allows as much.
const RAISED: f64 = 0.02;

/// The object's foot: its points within this height (m) of its lowest.
const FOOT: f64 = 0.01;

/// How far from the foot (m) the surface it stands on is looked for.
const BESIDE: f64 = 0.03;

/// How far below the foot's lowest point (m) that surface may lie: the foot's own lowest points
/// may be hidden (seen from above, the near side of a can's foot shows down to its edge, a box's
/// bottom edge is rounded).
const BELOW_FOOT: f64 = 0.03;

/// The surface's points lie within this height (m) of its median: a level top, not the side
/// wall of what stands beside the object.
const LEVEL_BAND: f64 = 0.005;

/// Least points of the surface beside the foot.
const MIN_POINTS: usize = 30;

/// The surface faces up within this angle of the support plane's normal (its cosine, 26 deg).
const LEVEL_COS: f64 = 0.9;

/// Least share of the foot's points within the surface's outline: what the object stands on
/// reaches under its foot. The top of an object in front of it, whose edge meets the line of
/// sight at the height of the lowest points the sensor sees, lies between the foot and the
/// sensor, not round it.
const MIN_FOOT_INSIDE: f64 = 0.5;

/// The level surface the object (`object` indexes `points`) stands on where its lowest points
/// lie more than [`RAISED`] over `plane`: the points of other objects beside its foot at the
/// foot's height, facing up, round the foot. `None` for an object on the plane, or where no such
/// surface shows (it may be hidden under the object).
pub fn raised_support(points: &[Point3<f64>], object: &[usize], plane: &Plane) -> Option<RaisedSupport> {
    let n = plane.normal;
    let mut heights: Vec<f64> = object
        .iter()
        .map(|&i| plane.signed_distance(&points[i]))
        .filter(|h| h.is_finite())
        .collect();
    if heights.is_empty() {
        return None;
    }
    heights.sort_by(f64::total_cmp);
    // The 1st percentile: a few strays below the object do not move it.
    let low = heights[heights.len() / 100];
    if low <= RAISED {
        return None;
    }
    let foot: Vec<Point3<f64>> = object
        .iter()
        .map(|&i| points[i])
        .filter(|p| plane.signed_distance(p) < low + FOOT)
        .collect();
    let mut is_object = vec![false; points.len()];
    for &i in object {
        if let Some(o) = is_object.get_mut(i) {
            *o = true;
        }
    }
    let grid = Grid::new(&foot, BESIDE);
    let beside: Vec<Point3<f64>> = points
        .iter()
        .zip(&is_object)
        .filter(|(p, own)| {
            let h = plane.signed_distance(p);
            !**own && h.is_finite() && h > low - BELOW_FOOT && h < low + LEVEL_BAND
        })
        .map(|(p, _)| *p)
        .filter(|p| grid.any_within(&foot, p, BESIDE))
        .collect();
    if beside.len() < MIN_POINTS {
        return None;
    }
    let mut hs: Vec<f64> = beside.iter().map(|p| plane.signed_distance(p)).collect();
    let height = median(&mut hs)?;
    let level: Vec<Point3<f64>> = beside
        .into_iter()
        .filter(|p| (plane.signed_distance(p) - height).abs() <= LEVEL_BAND)
        .collect();
    // The plane itself beside a foot the sensor does not see down to (a lying can's lower side
    // hidden behind its upper side) says the object stands on the plane.
    if level.len() < MIN_POINTS || height <= RAISED {
        return None;
    }
    let coords: Vec<Vector3<f64>> = level.iter().map(|p| p.coords).collect();
    if least_spread_direction(&coords).dot(&n).abs() < LEVEL_COS {
        return None;
    }
    let outline = Outline::of(&level, &n);
    let inside = foot.iter().filter(|p| outline.holds(p)).count();
    if (inside as f64) < MIN_FOOT_INSIDE * foot.len() as f64 {
        return None;
    }
    Some(RaisedSupport {
        plane: Plane {
            normal: n,
            d: plane.d - height,
        },
        height,
        points: level.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table z = 0 seen as a plane; a can of 40 mm radius whose foot is at `foot` (m), its
    /// wall's near half seen from -x down to the foot; and a level square of `side` (m) at
    /// height `top` centred at (`cx`, 0): the box it stands on, or one in front of it.
    fn scene(foot: f64, top: Option<(f64, f64, f64)>) -> (Vec<Point3<f64>>, Vec<usize>, Plane) {
        let mut points = Vec::new();
        for i in 0..40 {
            for k in 0..20 {
                let phi = std::f64::consts::PI * (0.5 + i as f64 / 39.0);
                let z = foot + 0.005 * k as f64;
                points.push(Point3::new(0.04 * phi.cos(), 0.04 * phi.sin(), z));
            }
        }
        let object: Vec<usize> = (0..points.len()).collect();
        if let Some((side, top, cx)) = top {
            let n = 40;
            for i in 0..n {
                for k in 0..n {
                    let x = cx - 0.5 * side + side * i as f64 / (n - 1) as f64;
                    let y = -0.5 * side + side * k as f64 / (n - 1) as f64;
                    // Not under the can: the sensor sees the box's top round it.
                    if x * x + y * y > 0.04 * 0.04 {
                        points.push(Point3::new(x, y, top));
                    }
                }
            }
        }
        let plane = Plane {
            normal: Vector3::z(),
            d: 0.0,
        };
        (points, object, plane)
    }

    #[test]
    fn a_can_on_a_box_stands_on_the_boxs_top() {
        let (points, object, plane) = scene(0.06, Some((0.2, 0.06, 0.0)));
        let s = raised_support(&points, &object, &plane).expect("the box's top");
        assert!((s.height - 0.06).abs() < 1e-9, "{s:?}");
        assert!((s.plane.signed_distance(&Point3::new(0.0, 0.0, 0.06))).abs() < 1e-9);
        assert!(s.points >= MIN_POINTS);
    }

    #[test]
    fn a_can_on_the_table_has_no_raised_support() {
        let (points, object, plane) = scene(0.0, Some((0.2, 0.0, 0.0)));
        assert!(raised_support(&points, &object, &plane).is_none());
        // Its foot hidden, the table beside it is still the table.
        let (points, object, plane) = scene(0.025, Some((0.2, 0.0, 0.0)));
        assert!(raised_support(&points, &object, &plane).is_none());
    }

    /// A raised foot with nothing level seen round it (a box covering its support's top), and
    /// the top of a box in front of a can whose lower part it hides: the can's lowest seen
    /// points lie at that top's height, but not over it.
    #[test]
    fn no_surface_round_the_foot_is_no_raised_support() {
        let (points, object, plane) = scene(0.06, None);
        assert!(raised_support(&points, &object, &plane).is_none());
        let (points, object, plane) = scene(0.06, Some((0.1, 0.06, -0.095)));
        assert!(raised_support(&points, &object, &plane).is_none());
    }
}
