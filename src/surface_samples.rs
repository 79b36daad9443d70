//! A part's surface samples (points with their outward normals, in the shape's frame), kept
//! between detections: they depend on the shape and the spacing alone. The detector's scores
//! sample at the data's spacing, its support plane check at half the part's smallest size, and
//! the grasp checks at a few millimetres.

use crate::geometry::Superquadric;
use nalgebra::Vector3;
use std::sync::{Arc, Mutex};

/// Surface points with their outward normals, in the shape's frame.
pub type LocalSamples = Vec<(Vector3<f64>, Vector3<f64>)>;

/// The samples of `shape` at `spacing` (without the lid when `open`), sampled once.
pub fn local_samples(shape: &Superquadric, spacing: f64, open: bool) -> Arc<LocalSamples> {
    SAMPLES.get(shape, spacing, open)
}

/// The surface samples of the shapes detected lately. They depend on the shape and the spacing
/// alone, and the spacing is most often set by the shape (a sixth of its smallest size): a
/// daemon asked for the same objects sweep after sweep would otherwise sample the same surfaces
/// again on every sweep, which costs as much as a tenth of a single part's detection.
pub static SAMPLES: SampleCache = SampleCache(Mutex::new(Vec::new()));

/// Shapes at most: a few models' parts, at the spacings their scenes give.
pub const CACHED_SHAPES: usize = 32;

pub struct SampleCache(pub Mutex<Vec<(SampleKey, Arc<LocalSamples>)>>);

/// A shape, a spacing and whether the part is open, to the bit.
type SampleKey = [u64; 9];

impl SampleCache {
    fn get(&self, shape: &Superquadric, spacing: f64, open: bool) -> Arc<LocalSamples> {
        let key: SampleKey = [
            shape.a[0].to_bits(),
            shape.a[1].to_bits(),
            shape.a[2].to_bits(),
            shape.e1.to_bits(),
            shape.e2.to_bits(),
            shape.kx.to_bits(),
            shape.ky.to_bits(),
            spacing.to_bits(),
            open as u64,
        ];
        let lookup =
            |cache: &Vec<(SampleKey, Arc<LocalSamples>)>| cache.iter().find(|(k, _)| *k == key).map(|(_, v)| v.clone());
        // A poisoned lock only means another detection panicked while holding it: the list is
        // still a list of finished entries.
        if let Some(hit) = lookup(&self.0.lock().unwrap_or_else(|e| e.into_inner())) {
            return hit;
        }
        // Sampled without the lock held: detections of other shapes need not wait.
        let local = Arc::new(sample_local(shape, spacing, open));
        let mut cache = self.0.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(hit) = lookup(&cache) {
            return hit;
        }
        if cache.len() >= CACHED_SHAPES {
            cache.remove(0);
        }
        cache.push((key, local.clone()));
        local
    }
}

/// The samples themselves, made afresh.
pub fn sample_local(shape: &Superquadric, spacing: f64, open: bool) -> LocalSamples {
    // An open part's lid is no surface: nothing is expected there.
    shape
        .sample_surface(spacing)
        .into_iter()
        .filter_map(|q| shape.residual_grad(&q).grad.try_normalize(1e-300).map(|n| (q, n)))
        .filter(|(_, n)| !(open && crate::model::is_lid(n)))
        .collect()
}
