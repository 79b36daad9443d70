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

mod allows;
mod compound;
mod convex;
mod family;
mod gradient;
mod model_file;
mod params;
mod prism;
mod profile;
mod raised;
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

use nalgebra::Point3;
use seen::Outline;
use segment::others_near;
use stages::fit_superquadric;

pub use allows::{REACH, SizeSeen};
pub use compound::learn_parts;
pub use model_file::{Provenance, model_pose, model_toml};
pub use params::{Cost, LearnError, LearnParams, MIN_POINTS, Recovered, ShapeFamily};
pub use raised::{RaisedSupport, raised_support};
pub use seen::seen_extent;
pub use segment::{AT_REACH, Segmentation, segment, segment_at, segment_box, support_below};

impl Learned {
    /// The plane the object rests on in the fits: the surface it stands on where it is raised,
    /// else the support plane.
    pub fn rests_on(&self) -> Option<crate::cloud::plane::Plane> {
        self.support.map(|r| r.plane).or(self.segmentation.plane)
    }
}

/// Everything [`learn`] found.
#[derive(Debug, Clone)]
pub struct Learned {
    pub segmentation: Segmentation,
    /// The surface the object stands on where it is raised off the support plane (another
    /// object's top): the fits rest it there instead of on the plane.
    pub support: Option<RaisedSupport>,
    pub parts: Vec<Recovered>,
    /// Each part's sizes as the view shows them and as far as the scene lets them grow.
    pub sizes: Vec<[SizeSeen; 3]>,
    /// Points of the object (before subsampling).
    pub object_points: usize,
    /// The colours of the object's points ([`crate::appearance::histogram`]), where the cloud
    /// has colours: the caller, who has them, sets it; the model file keeps it.
    pub colour: Option<Vec<f64>>,
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
    let support = segmentation
        .plane
        .as_ref()
        .and_then(|pl| raised_support(points, &segmentation.object, pl));
    if let Some(r) = &support {
        tracing::debug!(
            "stands on a level surface {:.1} mm over the plane ({} points beside its foot): fitted resting there",
            1e3 * r.height,
            r.points
        );
    }
    let plane = support.map(|r| r.plane).or(segmentation.plane);
    let free = free_points(points, &segmentation.object, &object, plane.as_ref());
    let rec = fit_superquadric(&object, &free, plane.as_ref(), params)?;
    let sizes = sizes_seen(std::slice::from_ref(&rec), &object, &free, plane.as_ref(), params);
    Ok(Learned {
        object_points: object.len(),
        segmentation,
        support,
        parts: vec![rec],
        sizes,
        colour: None,
    })
}

/// The scene points near the object whose rays are free space for its fit.
fn free_points(
    points: &[Point3<f64>],
    indices: &[usize],
    object: &[Point3<f64>],
    plane: Option<&crate::cloud::plane::Plane>,
) -> Vec<Point3<f64>> {
    let mut free = others_near(points, indices, 0.4);
    if let Some(pl) = plane {
        // An open container's inside bottom lies in the plane band and went with the table; the
        // sensor saw it through the opening, so rays to it are not free space.
        let outline = Outline::of(object, &pl.normal);
        free.retain(|p| !outline.holds(p));
    }
    free
}

/// Each part's sizes as the view shows them and as far as the scene lets them grow
/// ([`allows::view_allows`]): `object` the object's points, `free` the scene's points near it
/// ([`free_points`]), `plane` what it rests on.
fn sizes_seen(
    parts: &[Recovered],
    object: &[Point3<f64>],
    free: &[Point3<f64>],
    plane: Option<&crate::cloud::plane::Plane>,
    params: &LearnParams,
) -> Vec<[SizeSeen; 3]> {
    let sizes: Vec<[SizeSeen; 3]> = parts
        .iter()
        .map(|r| allows::view_allows(&r.placed, object, free, plane, params))
        .collect();
    for (i, s) in sizes.iter().enumerate() {
        tracing::debug!(
            "part {i} sizes {:.1} x {:.1} x {:.1} mm, seen {:.1} x {:.1} x {:.1}, the scene allows up to {} x {} x {}",
            1e3 * s[0].size,
            1e3 * s[1].size,
            1e3 * s[2].size,
            1e3 * s[0].seen,
            1e3 * s[1].seen,
            1e3 * s[2].seen,
            at_most(&s[0]),
            at_most(&s[1]),
            at_most(&s[2]),
        );
    }
    sizes
}

/// A size's bound in millimetres, or `-` when nothing in view stops it.
fn at_most(s: &SizeSeen) -> String {
    s.at_most.map_or_else(|| "-".to_string(), |m| format!("{:.1}", 1e3 * m))
}
