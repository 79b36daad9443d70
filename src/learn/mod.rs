//! Learning a model by showing the object: full superquadric recovery from a single-view scan.
//! See `docs/LEARN.md` for the method and its choices.
//!
//! 1. [`segment`](mod@segment) (`segment.rs`): remove the supporting plane and keep the largest connected
//!    cluster standing on it (a voxel flood fill).
//! 2. The fit (`stages.rs`): robust Levenberg-Marquardt (`robust.rs`) over the 13 parameters of
//!    `state.rs` (a1 a2 a3, e1 e2, kx ky, 3 rotation, 3 translation) from several starts
//!    (`starts.rs`), with the Jacobian of `gradient.rs`, on the residuals of `residual.rs`: the
//!    visible points (in the later stages along their sensor rays), the free space and the surface that must have been seen (`seen.rs`), the support
//!    plane, and the visible points' twins turned 180 degrees about the vertical axis (a symmetry
//!    of any superquadric that rests on a table with one of its axes vertical). `family.rs`
//!    chooses between a general shape and a body of revolution. An open container standing
//!    upright is learned instead from its outer wall's profile (`profile.rs`), a closed object
//!    standing on the plane with its top in view from its top's outline (`prism.rs`).
//! 3. [`learn_parts`] (`compound.rs`): two or three parts, each fitted to what the others leave.
//! 4. [`model_toml`] (`model_file.rs`): the result as a model file that `sqscan detect` takes as
//!    it is.

mod compound;
mod convex;
mod family;
mod gradient;
mod model_file;
mod prism;
mod profile;
mod residual;
mod robust;
mod seen;
mod segment;
pub mod simulated;
mod stages;
mod starts;
mod state;
#[cfg(test)]
mod tests;
mod wall_circle;

use crate::cloud::plane::Plane;
use crate::geometry::PlacedSuperquadric;
use nalgebra::{Point3, Vector3};
use seen::{footprint, inside_convex};
use segment::others_near;
use stages::fit_superquadric;

pub use compound::learn_parts;
pub use model_file::{Provenance, model_pose, model_toml};
pub use seen::seen_extent;
pub use segment::{AT_REACH, Segmentation, segment, segment_at, segment_box, support_below};

/// Which residual the LM minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cost {
    /// The radial Euclidean distance `|p| |F^(-e1/2) - 1|` (METHOD_NOTES): in metres, so the
    /// inlier weighting has a physical scale, and unbiased towards larger or smaller shapes.
    Radial,
    /// Paper eq. (2) with Solina's volume factor: `sqrt(a1 a2 a3) (F^e1 - 1)`.
    Solina,
    /// The first-order geometric distance `g / |grad g|` of `g = F^(e1/2) - 1` (Taubin): in
    /// metres like the radial distance, but along the surface normal, where the radial
    /// distance runs along the ray from the centre and overstates distances on the flat parts
    /// of an elongated or flat shape (a bowl's top, 3x at its rim), which biases fits towards
    /// shapes that make the rays meet the surface square.
    Normal,
}

/// The shapes [`fit_superquadric`] chooses from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShapeFamily {
    /// A body of revolution unless the general shape explains the view clearly better.
    Auto,
    /// Any superquadric (13 parameters).
    General,
    /// A body of revolution about its z axis (the user knows the object is round: a can, a
    /// bowl), for views that do not tell.
    Revolution,
}

/// Options of [`learn`].
#[derive(Debug, Clone)]
pub struct LearnParams {
    /// Where the sensor was (orients the plane normal, places the first centre behind the
    /// visible surface, decides whether the object is open).
    pub viewpoint: Option<Point3<f64>>,
    /// The up direction when no supporting plane is found or given.
    pub up: Option<Vector3<f64>>,
    /// Remove the dominant plane and pick the largest cluster on it; false: all points are the
    /// object (already segmented).
    pub segment: bool,
    /// A known supporting plane (normal towards the object), e.g. from labelled table points.
    pub plane: Option<Plane>,
    /// Add the visible points turned 180 degrees about the vertical axis through the centre.
    pub mirror: bool,
    /// Use the support plane as a residual (the bottom touches it).
    pub support: bool,
    /// Add free space just outside the silhouette of the points as seen from the viewpoint
    /// (for clouds segmented beforehand, with a known single viewpoint; off by default: a
    /// scanner that moves during the sweep has no single viewpoint).
    pub silhouette: bool,
    pub cost: Cost,
    /// From stage C on, fit the distance along the sensor's ray through each point (the
    /// sensor's error, `ray_read`) instead of `cost`; needs the viewpoint.
    pub along_rays: bool,
    /// Which shape families the fit may return.
    pub shape: ShapeFamily,
    /// A closed object standing on the plane with its top in view is measured from its top's
    /// outline rather than fitted (see `prism.rs`).
    pub measure_top: bool,
    /// At most this many points go into the fit (voxel subsampling).
    pub max_points: usize,
    /// Voxel of the cluster flood fill (m).
    pub cluster_voxel: f64,
    /// Drop points farther than this from the viewpoint (m).
    pub max_range: Option<f64>,
}

impl Default for LearnParams {
    fn default() -> Self {
        LearnParams {
            viewpoint: None,
            up: None,
            segment: true,
            plane: None,
            mirror: true,
            support: true,
            silhouette: false,
            cost: Cost::Radial,
            along_rays: true,
            measure_top: true,
            max_points: 1200,
            cluster_voxel: 0.01,
            max_range: None,
            shape: ShapeFamily::Auto,
        }
    }
}

/// A recovered superquadric.
#[derive(Debug, Clone)]
pub struct Recovered {
    pub placed: PlacedSuperquadric,
    /// RMS of the residual over the inliers (m for [`Cost::Radial`]).
    pub rms: f64,
    /// Median absolute residual over all the fitted (visible) points.
    pub median_abs: f64,
    /// Share of the fitted points with Huber weight 1 at the end.
    pub inlier_share: f64,
    /// Points that went into the fit (after subsampling).
    pub fitted_points: usize,
    /// An open container: many points were seen on the far side of the centre, which a closed
    /// solid hides.
    pub open: bool,
    /// Which start won.
    pub start: String,
}

/// Point sets with fewer points than this are refused.
pub const MIN_POINTS: usize = 30;

/// Why a recovery failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LearnError {
    #[error("only {0} object points (need at least {MIN_POINTS})")]
    TooFewPoints(usize),
}

/// Everything [`learn`] found.
#[derive(Debug, Clone)]
pub struct Learned {
    pub segmentation: Segmentation,
    pub parts: Vec<Recovered>,
    /// Points of the object (before subsampling).
    pub object_points: usize,
}

/// Segment (unless `params.segment` is false) and recover one superquadric.
pub fn learn(points: &[Point3<f64>], params: &LearnParams) -> Result<Learned, LearnError> {
    let points: Vec<Point3<f64>> = match params.max_range {
        Some(r) => {
            let v = params.viewpoint.unwrap_or_else(Point3::origin);
            points.iter().filter(|p| (*p - v).norm() <= r).copied().collect()
        }
        None => points.to_vec(),
    };
    let segmentation = if params.segment {
        segment(&points, params)
    } else {
        Segmentation {
            plane: params.plane,
            object: (0..points.len()).collect(),
        }
    };
    learn_segmented(&points, segmentation, params)
}

/// Recover one superquadric from given object points (`segmentation.object` indexes `points`;
/// the other points serve as free space).
pub fn learn_segmented(
    points: &[Point3<f64>],
    segmentation: Segmentation,
    params: &LearnParams,
) -> Result<Learned, LearnError> {
    let object: Vec<Point3<f64>> = segmentation.object.iter().map(|&i| points[i]).collect();
    let mut free = others_near(points, &segmentation.object, 0.4);
    if let Some(pl) = &segmentation.plane {
        // An open container's inside bottom lies in the plane band and went with the table; the
        // sensor saw it through the opening, so rays to it are not free space.
        let hull = footprint(&object, &pl.normal);
        let (u, v) = crate::cloud::plane::orthonormal_basis(&pl.normal);
        free.retain(|p| !inside_convex(&hull, (p.coords.dot(&u), p.coords.dot(&v))));
    }
    let rec = fit_superquadric(&object, &free, segmentation.plane.as_ref(), params)?;
    Ok(Learned {
        object_points: object.len(),
        segmentation,
        parts: vec![rec],
    })
}
