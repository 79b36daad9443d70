//! What learning is asked ([`LearnParams`]: the viewpoint, the plane, the residual, the shape
//! families) and what one fitted part is ([`Recovered`]).

use crate::cloud::plane::Plane;
use crate::geometry::PlacedSuperquadric;
use nalgebra::{Point3, Vector3};

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

/// The shapes the fit (`stages.rs`) chooses from.
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

/// Options of [`learn`](super::learn).
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
