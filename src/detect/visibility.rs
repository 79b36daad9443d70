//! The free-space test: what the sensor's lines of sight say about a placed part's visible
//! surface. Where the sensor saw through a place the part's surface would be, the part is not
//! there.

use super::verify::{MIN_VIEW_COSINE, SurfaceSamples};
use crate::cloud::grid::Grid;
use crate::geometry::PlacedSuperquadric;
use nalgebra::Point3;
use std::fmt;

/// What the sensor's line of sight says about each surface sample of a placed part that faces
/// the viewpoint.
#[derive(Debug, Clone, Copy, Default)]
pub struct Visibility {
    /// Samples facing the viewpoint.
    pub facing: usize,
    /// ... with a measured point on them.
    pub covered: usize,
    /// ... without, but with a measured surface in front of them: hidden, no evidence either way.
    pub occluded: usize,
    /// ... without, and with a measured surface behind them: the sensor saw through where the
    /// part would be, so it is not there.
    pub see_through: usize,
    /// ... without, and nothing measured along the line of sight at all (outside the scan, or
    /// no return).
    pub unknown: usize,
    /// See-through samples farther than [`DEEP_SEE_THROUGH`] from every covered sample: the
    /// part reaching into free space, not its outline a few millimetres off.
    pub deep: usize,
    /// The farthest any see-through sample lies from a covered one (m), up to 1 m; measured only
    /// where debug logging is on (it is for the log), else 0.
    pub deepest: f64,
    /// The surface area (m²) one sample stands for.
    pub sample_area: f64,
}

impl Visibility {
    /// Share of the samples that could have been seen and were: covered over covered, seen
    /// through and unknown. A hidden part is not held against the object; a part the sensor saw
    /// through, or that lies where nothing was scanned, is.
    pub fn seen_ratio(&self) -> f64 {
        let could = self.covered + self.see_through + self.unknown;
        if could == 0 {
            1.0
        } else {
            self.covered as f64 / could as f64
        }
    }
}

impl Visibility {
    /// More than `max_share` of the facing samples, and more than [`MIN_DEEP_AREA`] of surface,
    /// lie deep in space the sensor saw through.
    pub fn reaches_into_free_space(&self, max_share: f64) -> bool {
        self.deep as f64 > max_share * self.facing as f64 && self.deep as f64 * self.sample_area > MIN_DEEP_AREA
    }
}

/// Surface (m²) of a part that may lie deep in free space whatever the part's size: a bowl seen
/// into from close by shows a few samples of its outside past the rim, a patch of a few
/// centimetres square, where the model's rim is a little higher than the bowl's.
const MIN_DEEP_AREA: f64 = 0.0004;

/// `facing .. covered .. occluded .. see-through .. unknown .. seen ..`.
impl fmt::Display for Visibility {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "facing {} covered {} occluded {} see-through {} unknown {} seen {:.2} deep {} deepest {:.3}",
            self.facing,
            self.covered,
            self.occluded,
            self.see_through,
            self.unknown,
            self.seen_ratio(),
            self.deep,
            self.deepest
        )
    }
}

/// Classify the visible side of a placed part by the lines of sight from `viewpoint` through
/// `all_points` (every measured point, the support plane's included). Without a viewpoint nothing
/// can be said and every count is zero.
pub fn visibility(
    all_points: &[Point3<f64>],
    all_grid: &Grid,
    placed: &PlacedSuperquadric,
    viewpoint: Option<Point3<f64>>,
    plane: Option<&crate::cloud::plane::Plane>,
    samples: &SurfaceSamples,
) -> Visibility {
    let mut vis = Visibility {
        sample_area: samples.spacing * samples.spacing,
        ..Default::default()
    };
    let Some(v) = viewpoint else { return vis };
    let reach = 1.2 * samples.spacing;
    let any_near = |q: &Point3<f64>, r: f64| all_grid.any_within(all_points, q, r);
    // In the part's own frame: what matters is where on its surface they lie.
    let mut covered_at: Vec<Point3<f64>> = Vec::new();
    let mut through_at: Vec<Point3<f64>> = Vec::new();
    for (q, n) in samples.local.iter() {
        let p = placed.pose.transform_point(&Point3::from(*q));
        let n = placed.pose.rotation * n;
        let to_view = v - p;
        let dist = to_view.norm();
        let view = to_view / dist;
        if n.dot(&view) < MIN_VIEW_COSINE {
            continue;
        }
        vis.facing += 1;
        if any_near(&p, reach) {
            vis.covered += 1;
            covered_at.push(Point3::from(*q));
            continue;
        }
        // The viewpoint is one pose for a whole sweep (and the laser and the camera are a
        // baseline apart), so the tolerance around the line of sight grows along it.
        let tolerance = |t: f64| reach + 0.03 * t;
        // In front: towards the sensor, up to the sensor.
        let step = 2.0 * reach;
        let mut t = 2.0 * reach;
        let mut occluded = false;
        while t < dist - 0.05 {
            if any_near(&(p + view * t), tolerance(t)) {
                occluded = true;
                break;
            }
            t += step;
        }
        if occluded {
            vis.occluded += 1;
            continue;
        }
        // Behind: the support plane where the line of sight meets it, else any nearer surface.
        let mut behind = false;
        if let Some(pl) = plane {
            let denom = pl.normal.dot(&view);
            let t = pl.signed_distance(&p) / denom;
            if denom > 1e-6 && t > 2.0 * reach {
                behind = any_near(&(p - view * t), 2.0 * reach);
            }
        }
        let mut t = 2.0 * reach;
        while !behind && t < SEE_THROUGH_DEPTH {
            behind = any_near(&(p - view * t), tolerance(t));
            t += step;
        }
        if behind {
            vis.see_through += 1;
            through_at.push(Point3::from(*q));
        } else {
            vis.unknown += 1;
        }
    }
    if !through_at.is_empty() {
        let grid = Grid::new(&covered_at, DEEP_SEE_THROUGH);
        vis.deep = through_at
            .iter()
            .filter(|t| !grid.any_within(&covered_at, t, DEEP_SEE_THROUGH))
            .count();
        if tracing::enabled!(tracing::Level::DEBUG) {
            vis.deepest = through_at
                .iter()
                .map(|t| covered_at.iter().map(|c| (c - t).norm()).fold(1.0f64, f64::min))
                .fold(0.0, f64::max);
        }
    }
    vis
}

/// How far from every covered sample a see-through sample must lie to count as the part reaching
/// into free space (m).
pub const DEEP_SEE_THROUGH: f64 = 0.02;

/// How far behind a missing surface the see-through test looks for a nearer surface seen
/// instead (m); the support plane is looked for wherever the line of sight meets it.
const SEE_THROUGH_DEPTH: f64 = 0.15;
