//! The space the sensor could not see: behind a point it measured, along the line of sight
//! from the viewpoint. With `occupy_unseen`, a gripper that would pass through such space
//! outside the object's model is refused: something the sensor could not see may stand there.

use nalgebra::{Point3, Vector3};
use std::collections::HashMap;

/// Lines of sight are binned by direction in cells of this angle (rad): a Kinect-class sensor's
/// pixel is 1.7 mrad, a sweep's columns a few; a cell holds a few of either.
const CELL: f64 = 0.005;

/// The nearest range the sensor measured in each direction near the object.
pub(super) struct Shadows {
    viewpoint: Point3<f64>,
    nearest: HashMap<(i64, i64), f64>,
}

/// The cell of a direction: its azimuth and elevation in [`CELL`]s.
fn cell(d: &Vector3<f64>) -> (i64, i64) {
    let az = d.y.atan2(d.x);
    let el = d.z.atan2(d.x.hypot(d.y));
    ((az / CELL).floor() as i64, (el / CELL).floor() as i64)
}

impl Shadows {
    /// The nearest ranges of the `scene`'s points within `reach` of `centre`, seen from
    /// `viewpoint`.
    pub(super) fn new(scene: &[[f32; 3]], viewpoint: Point3<f64>, centre: &Point3<f64>, reach: f64) -> Shadows {
        let mut nearest: HashMap<(i64, i64), f64> = HashMap::new();
        for q in scene {
            let p = Point3::new(q[0] as f64, q[1] as f64, q[2] as f64);
            if !((p - centre).norm() <= reach) {
                continue;
            }
            let d = p - viewpoint;
            let r = d.norm();
            if !(r > 0.0) {
                continue;
            }
            let e = nearest.entry(cell(&d)).or_insert(f64::INFINITY);
            *e = e.min(r);
        }
        Shadows { viewpoint, nearest }
    }

    /// Whether one of `points` lies more than `margin` behind what the sensor measured in its
    /// direction, where `outside` (outside the object) holds.
    pub(super) fn hides(&self, points: &[Point3<f64>], outside: impl Fn(&Point3<f64>) -> bool, margin: f64) -> bool {
        points.iter().any(|p| {
            let d = p - self.viewpoint;
            let behind = self.nearest.get(&cell(&d)).is_some_and(|&r| d.norm() > r + margin);
            behind && outside(p)
        })
    }
}
