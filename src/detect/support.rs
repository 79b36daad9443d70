//! What a part rests on, where that is not the support plane (the shell test of
//! [`super::verify`] leaves it out).

use super::space::SearchSpace;
use crate::geometry::PlacedSuperquadric;
use nalgebra::{Point3, Vector3};

/// The radius (m) of the patch around a point that tells a surface parallel to the support
/// plane from a wall.
const SUPPORT_PATCH: f64 = 0.012;

/// The surface a part may rest on, where it is not the support plane: the plane through its
/// lowest point along the support plane's normal, parallel to it. The top of a box, a tin or a
/// book that an object stands on continues outwards from its base, just outside its surface; it
/// is not the object's own surface going on past the model's edge (a larger object of the same
/// shape), and it is not counted in the shell. The side wall of a larger object around a
/// too-small fit goes on past the base's height, and still counts there.
#[derive(Clone, Copy)]
pub(super) struct Support {
    /// The support plane's normal (towards the objects) and the part's lowest height along it;
    /// `None` without a support plane, or where the part rests on it.
    base: Option<(Vector3<f64>, f64)>,
    /// How far from that height (m) a point is on the support.
    band: f64,
}

impl Support {
    pub(super) fn new(space: &SearchSpace<'_>, placed: &PlacedSuperquadric, band: f64) -> Support {
        let base = space.plane.and_then(|plane| {
            let n = plane.normal;
            let r = placed.pose.rotation.to_rotation_matrix();
            let half = placed.shape.local_half_extents();
            let depth: f64 = (0..3).map(|i| n.dot(&r.matrix().column(i)).abs() * half[i]).sum();
            let lowest = n.dot(&placed.pose.translation.vector) - depth;
            // On the support plane itself there is nothing to leave out: the plane's points are
            // gone, and what is left at the base's height there is other objects' walls (a
            // larger box's, around a fit on its lower part).
            (lowest + plane.d > band).then_some((n, lowest))
        });
        Support { base, band }
    }

    /// Whether a point lies on the surface the part may rest on: at the base's height, on a
    /// surface parallel to the support plane there. Most of its neighbours within
    /// [`SUPPORT_PATCH`] (four in five) lie within half that of its height; on the side wall of
    /// a larger object around the fit, which also crosses the base's height, they spread over
    /// the whole patch. (So does the top of a support next to its edge, where its side wall
    /// drops away: an upturned bowl whose rim rests near the edge of a tin is held to its shell
    /// test there.)
    pub(super) fn holds(&self, space: &SearchSpace<'_>, p: &Point3<f64>) -> bool {
        let Some((n, h)) = self.base else { return false };
        let height = n.dot(&p.coords);
        if (height - h).abs() > self.band {
            return false;
        }
        let (mut level, mut all) = (0usize, 0usize);
        space.grid.for_each_within(space.points, p, SUPPORT_PATCH, |k| {
            all += 1;
            level += usize::from((n.dot(&space.points[k].coords) - height).abs() <= 0.5 * SUPPORT_PATCH);
        });
        5 * level >= 4 * all
    }
}
