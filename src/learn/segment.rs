//! Segmentation: the object's points apart from the plane it stands on and from the rest of the
//! scene (voxel flood fill, strays, subsampling).

use super::params::LearnParams;
use crate::cloud::grid::voxel_subsample;
use crate::cloud::plane::{Plane, RangeScale, remove_dominant_plane};
use nalgebra::{Point3, Vector3};
use std::collections::{HashMap, VecDeque};

/// The object's points and the plane it stands on.
#[derive(Debug, Clone)]
pub struct Segmentation {
    /// Normal pointing to the object's side.
    pub plane: Option<Plane>,
    /// Indices of the object's points in the input.
    pub object: Vec<usize>,
}

/// Remove the supporting plane and keep the largest connected cluster standing on it.
pub fn segment(points: &[Point3<f64>], params: &LearnParams) -> Segmentation {
    let (plane, kept) = off_the_plane(points, params);
    let clusters = clusters(points, &kept, params.cluster_voxel);
    // Standing on the plane: the cluster's lowest seen point is within 6 cm of it (a bowl hides
    // its foot under its rim).
    let on_plane = |c: &Vec<usize>| match &plane {
        Some(pl) => {
            c.iter()
                .map(|&i| pl.signed_distance(&points[i]))
                .fold(f64::INFINITY, f64::min)
                < 0.06
        }
        None => true,
    };
    let Some(best) = clusters
        .iter()
        .position(on_plane)
        .or((!clusters.is_empty()).then_some(0))
    else {
        return Segmentation {
            plane,
            object: Vec::new(),
        };
    };
    let object = with_nearby_clusters(points, &clusters, best, MERGE_GAP, plane.as_ref());
    Segmentation { plane, object }
}

/// How far (m) from the point given to [`segment_at`] an object's nearest point may lie.
pub const AT_REACH: f64 = 0.05;

/// The object shown by a point: the supporting plane removed, the connected cluster (of at least
/// 10 points) with a point nearest to `at`, within [`AT_REACH`], and the clusters that belong
/// to it as in [`segment`] (an open container's inside); of that cluster only what reaches the
/// point without crossing a concave crease ([`super::convex::convex_region`]): objects that
/// touch each other (a mug standing on a tin) meet in one. `Err` says how far the nearest
/// object is.
pub fn segment_at(points: &[Point3<f64>], params: &LearnParams, at: &Point3<f64>) -> Result<Segmentation, String> {
    let (plane, kept, residue) = above_the_residue(points, params);
    let clusters = clusters(points, &kept, params.cluster_voxel);
    let nearest = clusters
        .iter()
        .enumerate()
        .filter(|(_, c)| c.len() >= 10)
        .map(|(k, c)| {
            let d = c.iter().map(|&i| (points[i] - at).norm()).fold(f64::INFINITY, f64::min);
            (k, d)
        })
        .min_by(|a, b| a.1.total_cmp(&b.1));
    match nearest {
        Some((k, d)) if d <= AT_REACH => {
            // Of that cluster, the part that reaches the point without crossing a concave crease:
            // what touches the object (the book a mug stands on) stays out.
            let v = params.viewpoint.unwrap_or_else(Point3::origin);
            let whole = clusters[k].len();
            let object = match &plane {
                Some(pl) => {
                    let object = super::convex::object_at(points, &clusters[k], at, &v, &pl.normal);
                    tracing::debug!(
                        "at: {} of the {whole} points of the nearest cluster belong to the object by local convexity",
                        object.len()
                    );
                    // Other clusters, as an open container's inside seen through its opening,
                    // by the same rule.
                    let others: Vec<Vec<usize>> = clusters
                        .into_iter()
                        .enumerate()
                        .filter(|(j, c)| *j != k && c.len() >= 10)
                        .map(|(_, c)| c)
                        .collect();
                    super::convex::merge_belonging(points, object, others, &pl.normal, true)
                }
                None => {
                    let mut clusters = clusters;
                    clusters[k] = super::convex::convex_region(points, &clusters[k], at, &v);
                    with_nearby_clusters(points, &clusters, k, MERGE_GAP, None)
                }
            };
            let object = with_residue_under(points, object, &residue, plane.as_ref(), params.cluster_voxel);
            Ok(Segmentation { object, plane })
        }
        Some((_, d)) => Err(format!(
            "the nearest object's points are {:.0} mm away (at most {:.0} mm)",
            d * 1e3,
            AT_REACH * 1e3
        )),
        None => Err("no object off the supporting plane".into()),
    }
}

/// The object's points in an axis-aligned box of the cloud's frame (`min`, `max` corners), over
/// the supporting plane's residue (with the residue's pieces within their outline, as
/// [`segment_at`] takes them).
pub fn segment_box(points: &[Point3<f64>], params: &LearnParams, min: &Point3<f64>, max: &Point3<f64>) -> Segmentation {
    let (plane, kept, residue) = above_the_residue(points, params);
    let in_box = |i: &usize| (0..3).all(|k| points[*i][k] >= min[k] && points[*i][k] <= max[k]);
    let object = kept.into_iter().filter(in_box).collect();
    let residue: Vec<usize> = residue.into_iter().filter(in_box).collect();
    let object = with_residue_under(points, object, &residue, plane.as_ref(), params.cluster_voxel);
    Segmentation { plane, object }
}

/// The supporting plane (given or found) and the indices of the points off it, on the objects'
/// side.
fn off_the_plane(points: &[Point3<f64>], params: &LearnParams) -> (Option<Plane>, Vec<usize>) {
    let (plane, kept, _) = off_the_plane_with_band(points, params);
    (plane, kept)
}

/// [`off_the_plane`], with the removal's band and how it scales with the range (`None` for a
/// given plane: [`GIVEN_PLANE_BAND`]).
fn off_the_plane_with_band(
    points: &[Point3<f64>],
    params: &LearnParams,
) -> (Option<Plane>, Vec<usize>, Option<(f64, RangeScale)>) {
    match params.plane {
        Some(pl) => {
            let kept = (0..points.len())
                .filter(|&i| pl.signed_distance(&points[i]) > GIVEN_PLANE_BAND)
                .collect();
            (Some(pl), kept, None)
        }
        None => {
            let r = remove_dominant_plane(points, false, params.viewpoint);
            (r.plane, r.kept, Some((r.band, r.range_scale)))
        }
    }
}

/// Points less than this many removal bands over the plane are the plane's, left by the removal
/// (the detector's rule too): its noise tail and its unevenness. Where an object is chosen by a
/// place rather than by its own cluster (`--at`, `--box`), a sheet of them reaches it at its foot
/// and joins it (in mOSD learn43, 991 points of the table 3-8 mm over the plane, spread over
/// 22 cm in front of the tall tin, were taken with it, and it was learned as an open box).
const PLANE_RESIDUE: f64 = 2.0;

/// [`off_the_plane`], split at [`PLANE_RESIDUE`] bands (at their range) over the plane: the
/// points above it, and the residue below it.
fn above_the_residue(points: &[Point3<f64>], params: &LearnParams) -> (Option<Plane>, Vec<usize>, Vec<usize>) {
    let (plane, kept, band) = off_the_plane_with_band(points, params);
    let Some(pl) = plane else {
        return (plane, kept, Vec::new());
    };
    let (above, residue) = kept.into_iter().partition(|&i| {
        let p = &points[i];
        let band = band.as_ref().map_or(GIVEN_PLANE_BAND, |(b, scale)| b * scale.at(p));
        pl.signed_distance(p) > PLANE_RESIDUE * band
    });
    (plane, above, residue)
}

/// The plane's residue under the object seen from above is the object's own where it lies apart
/// from the rest of the residue, mostly (80 %) within the object's outline along the plane's
/// normal: an open container's inside bottom, a few millimetres over the table, which says it is
/// open. The residue's sheet on the table reaches under a bowl's flaring wall, within its
/// outline, but goes on outside it.
fn with_residue_under(
    points: &[Point3<f64>],
    mut object: Vec<usize>,
    residue: &[usize],
    plane: Option<&Plane>,
    voxel: f64,
) -> Vec<usize> {
    let Some(pl) = plane else { return object };
    let own: Vec<Point3<f64>> = object.iter().map(|&i| points[i]).collect();
    let outline = super::seen::Outline::of(&own, &pl.normal);
    let inside = |i: &usize| outline.holds(&points[*i]);
    for c in clusters(points, residue, voxel) {
        if c.iter().filter(|i| inside(i)).count() as f64 >= 0.8 * c.len() as f64 {
            object.extend(c);
        }
    }
    object.sort_unstable();
    object
}

/// The band (m) over a given plane within which points are its own.
const GIVEN_PLANE_BAND: f64 = 0.004;

/// Clusters this close to the object's, seen from above, are the object's too; for a large
/// object, clusters within [`MERGE_SHARE`] of its radius.
pub(super) const MERGE_GAP: f64 = 0.03;
/// The share of the object's radius seen from above within which a cluster is part of it: the
/// part of an open container's inside hidden behind its near wall grows with the container
/// (the mOSD white bowl's near wall is 31 mm from the inside the sensor saw, seen from above).
pub(super) const MERGE_SHARE: f64 = 0.5;

/// The cluster `best` with every other cluster of at least 10 points that comes within `gap` of
/// it seen along the plane normal (in 3-D without a plane), or within [`MERGE_SHARE`] of its
/// radius seen that way when that is more. The inside of an open container seen through its
/// opening is bounded by grazing views at both sides, where no points are returned, so it is a
/// cluster of its own, centimetres from the outer wall in 3-D but on the same outline seen from
/// above (mOSD labels the two apart as well: a mug's body and its inside).
pub(super) fn with_nearby_clusters(
    points: &[Point3<f64>],
    clusters: &[Vec<usize>],
    best: usize,
    gap: f64,
    plane: Option<&Plane>,
) -> Vec<usize> {
    let flat = |p: &Point3<f64>| match plane {
        Some(pl) => p - pl.normal * pl.signed_distance(p),
        None => *p,
    };
    let main: Vec<Point3<f64>> = clusters[best].iter().map(|&i| flat(&points[i])).collect();
    let gap = gap.max(MERGE_SHARE * flat_radius(&main));
    let grid = crate::cloud::grid::Grid::new(&main, gap);
    let mut object = clusters[best].clone();
    for (k, c) in clusters.iter().enumerate() {
        if k == best || c.len() < 10 {
            continue;
        }
        let near = c.iter().any(|&i| grid.any_within(&main, &flat(&points[i]), gap));
        if near {
            object.extend_from_slice(c);
        }
    }
    object
}

/// The 98th percentile of the points' distances from their centroid (m).
fn flat_radius(points: &[Point3<f64>]) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let c = points.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / points.len() as f64;
    let mut d: Vec<f64> = points.iter().map(|p| (p.coords - c).norm()).collect();
    crate::numeric::quantile(&mut d, 0.98).unwrap_or(0.0)
}

/// Connected clusters of the points `idx` (26-neighbourhood of voxels of side `voxel`), largest
/// first.
pub fn clusters(points: &[Point3<f64>], idx: &[usize], voxel: f64) -> Vec<Vec<usize>> {
    let key = |p: &Point3<f64>| [0, 1, 2].map(|k| (p[k] / voxel).floor() as i64);
    let mut cells: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for &i in idx {
        cells.entry(key(&points[i])).or_default().push(i);
    }
    let mut label: HashMap<[i64; 3], usize> = HashMap::with_capacity(cells.len());
    let mut out: Vec<Vec<usize>> = Vec::new();
    let mut keys: Vec<[i64; 3]> = cells.keys().copied().collect();
    keys.sort();
    for start in keys {
        if label.contains_key(&start) {
            continue;
        }
        let id = out.len();
        let mut members = Vec::new();
        let mut queue = VecDeque::from([start]);
        label.insert(start, id);
        while let Some(c) = queue.pop_front() {
            members.extend_from_slice(&cells[&c]);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let n = [c[0] + dx, c[1] + dy, c[2] + dz];
                        if cells.contains_key(&n) && !label.contains_key(&n) {
                            label.insert(n, id);
                            queue.push_back(n);
                        }
                    }
                }
            }
        }
        out.push(members);
    }
    out.sort_by_key(|c| std::cmp::Reverse(c.len()));
    out
}

/// The points with at least `min_neighbours` others within `radius` (a radius outlier filter:
/// stereo and edge strays are isolated).
pub fn remove_stray_points(points: &[Point3<f64>], radius: f64, min_neighbours: usize) -> Vec<Point3<f64>> {
    let grid = crate::cloud::grid::Grid::new(points, radius);
    points
        .iter()
        .filter(|p| {
            let mut n = 0usize;
            grid.for_each_within(points, p, radius, |_| n += 1);
            n > min_neighbours
        })
        .copied()
        .collect()
}

/// Voxel-subsample to at most `max` points.
pub fn subsample(points: &[Point3<f64>], max: usize) -> Vec<Point3<f64>> {
    if points.len() <= max {
        return points.to_vec();
    }
    let mut voxel = 0.002;
    loop {
        let idx = voxel_subsample(points, voxel);
        if idx.len() <= max {
            return idx.into_iter().map(|i| points[i]).collect();
        }
        voxel *= 1.25;
    }
}

/// For a segmented object with a known up direction: the surface it stands on, across up at
/// its lowest points (the 1st percentile along up, so a few strays below do not move it). The
/// support bounds the hidden bottom; one view of a can on a table shows its foot.
pub fn support_below(points: &[Point3<f64>], up: Option<&Vector3<f64>>) -> Option<Plane> {
    let u = up?.try_normalize(1e-12)?;
    let mut h: Vec<f64> = points
        .iter()
        .map(|p| u.dot(&p.coords))
        .filter(|h| h.is_finite())
        .collect();
    h.sort_by(f64::total_cmp);
    let low = *h.get(h.len() / 100)?;
    Some(Plane { normal: u, d: -low })
}

/// The points that are not the object's, within `radius` of its centroid, subsampled to 4 mm.
pub fn others_near(points: &[Point3<f64>], object: &[usize], radius: f64) -> Vec<Point3<f64>> {
    if object.is_empty() {
        return Vec::new();
    }
    let c = object.iter().fold(Vector3::zeros(), |a, &i| a + points[i].coords) / object.len() as f64;
    let mut is_object = vec![false; points.len()];
    for &i in object {
        is_object[i] = true;
    }
    let near: Vec<Point3<f64>> = (0..points.len())
        .filter(|&i| !is_object[i] && (points[i].coords - c).norm() < radius)
        .map(|i| points[i])
        .collect();
    voxel_subsample(&near, 0.004).into_iter().map(|i| near[i]).collect()
}
