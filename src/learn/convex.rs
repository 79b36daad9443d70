//! The object around a point, apart from what touches it: the region grown from that point over
//! a voxel grid that does not cross a concave crease (after Stein et al., "Object Partitioning
//! using Local Convexity", CVPR 2014). An everyday object's visible surface is convex or gently
//! curved; where a mug stands on a book, a box leans on a box or a can touches a tin, the two
//! surfaces meet in a concave crease.

use nalgebra::{Point3, Vector3};
use std::collections::{HashMap, VecDeque};

/// Voxel side (m).
const VOXEL: f64 = 0.008;
/// A voxel's normal is that of the voxel centroids within this many voxels (a 12.5 mm
/// neighbourhood: the noise of a Kinect-class sensor at a metre is a few millimetres).
const NORMAL_CELLS: i64 = 2;
/// A link between neighbouring voxels is cut when their normals close towards each other along
/// it by more than this (`(n_i - n_j) . (c_i - c_j) / |c_i - c_j|`, about `-2 sin(bend / 2)`:
/// 0.2 is a bend of 11.5 degrees from one voxel to the next). The normals blur a sharp crease
/// over the neighbourhood, a few voxels, which still bend by 20 degrees or more per voxel; noise
/// on a flat face and the inside of a bowl bend by less.
const CONCAVE: f64 = 0.2;

/// Neighbouring voxels whose normals are closer than this (cosine; 15 degrees) lie on one
/// surface unless the link bends concavely by more than [`CONCAVE`].
const SMOOTH: f64 = 0.966;
/// A link between voxels at an angle is judged only across the line where their planes meet:
/// within 60 degrees of that line (cosine 0.5) it is cut.
const ALONG: f64 = 0.5;

type Cell = [i64; 3];

/// The voxels of a point set with their centroids and normals.
struct Voxels {
    cells: HashMap<Cell, Vec<usize>>,
    centroid: HashMap<Cell, Vector3<f64>>,
    normal: HashMap<Cell, Vector3<f64>>,
}

impl Voxels {
    fn new(points: &[Point3<f64>], members: &[usize], viewpoint: &Point3<f64>) -> Voxels {
        let key = |p: &Point3<f64>| -> Cell { [0, 1, 2].map(|k| (p[k] / VOXEL).floor() as i64) };
        let mut cells: HashMap<Cell, Vec<usize>> = HashMap::new();
        for &i in members {
            if points[i].coords.iter().all(|c| c.is_finite()) {
                cells.entry(key(&points[i])).or_default().push(i);
            }
        }
        let centroid: HashMap<Cell, Vector3<f64>> = cells
            .iter()
            .map(|(c, m)| {
                (
                    *c,
                    m.iter().map(|&i| points[i].coords).sum::<Vector3<f64>>() / m.len() as f64,
                )
            })
            .collect();
        let normal: HashMap<Cell, Vector3<f64>> = centroid
            .iter()
            .filter_map(|(c, x)| {
                let mut near: Vec<Vector3<f64>> = Vec::new();
                for dx in -NORMAL_CELLS..=NORMAL_CELLS {
                    for dy in -NORMAL_CELLS..=NORMAL_CELLS {
                        for dz in -NORMAL_CELLS..=NORMAL_CELLS {
                            if let Some(q) = centroid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                                near.push(*q);
                            }
                        }
                    }
                }
                if near.len() < 5 {
                    return None;
                }
                let n = crate::numeric::least_spread_direction(&near);
                let n = if n.dot(&(viewpoint.coords - x)) < 0.0 { -n } else { n };
                n.iter().all(|v| v.is_finite()).then_some((*c, n))
            })
            .collect();
        Voxels {
            cells,
            centroid,
            normal,
        }
    }

    /// Whether neighbouring voxels `a` and `b` lie on one locally convex surface.
    fn linked(&self, a: &Cell, b: &Cell) -> bool {
        let (Some(na), Some(nb)) = (self.normal.get(a), self.normal.get(b)) else {
            // Too few neighbours to tell (a thin part, an edge): linked.
            return true;
        };
        let Some(d) = (self.centroid[a] - self.centroid[b]).try_normalize(1e-12) else {
            return true;
        };
        let bend = (na - nb).dot(&d);
        if na.dot(nb) > SMOOTH {
            return bend > -CONCAVE;
        }
        // Two surfaces at an angle: the link tells convex from concave only across the line
        // where their planes meet. Along it (a face's corner beside the table it stands on,
        // whose crease with the hidden side wall is out of view) it says nothing, and is cut
        // (LCCP's sanity criterion).
        let along = na.cross(nb).try_normalize(1e-12).map_or(0.0, |s| s.dot(&d).abs());
        along < ALONG && bend > 0.0
    }

    /// The voxels linked to `start`, and their points.
    fn grow(&self, start: Cell, taken: &mut HashMap<Cell, ()>) -> Vec<usize> {
        taken.insert(start, ());
        let mut queue = VecDeque::from([start]);
        let mut out = Vec::new();
        while let Some(c) = queue.pop_front() {
            out.extend_from_slice(&self.cells[&c]);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let n = [c[0] + dx, c[1] + dy, c[2] + dz];
                        if self.cells.contains_key(&n) && !taken.contains_key(&n) && self.linked(&c, &n) {
                            taken.insert(n, ());
                            queue.push_back(n);
                        }
                    }
                }
            }
        }
        out
    }

    /// The voxel whose centroid is nearest `p`.
    fn nearest(&self, p: &Point3<f64>) -> Option<Cell> {
        self.centroid
            .iter()
            .min_by(|a, b| {
                (a.1 - p.coords)
                    .norm_squared()
                    .total_cmp(&(b.1 - p.coords).norm_squared())
            })
            .map(|(c, _)| *c)
    }
}

/// The points of `members` (indices into `points`) connected to the one nearest `seed` without
/// crossing a concave crease, as seen from `viewpoint` (which orients the normals).
pub(super) fn convex_region(
    points: &[Point3<f64>],
    members: &[usize],
    seed: &Point3<f64>,
    viewpoint: &Point3<f64>,
) -> Vec<usize> {
    let v = Voxels::new(points, members, viewpoint);
    match v.nearest(seed) {
        Some(start) => v.grow(start, &mut HashMap::new()),
        None => Vec::new(),
    }
}

/// The object around `seed`: its [`convex_region`] with the other locally convex regions of
/// `members` that belong to it, seen along `up` (the supporting plane's normal): a region
/// mostly within the object's outline and no higher (an open container's inside bottom behind a
/// crease, a fragment of the object cut off by noise), or one whose outline holds the object
/// and that rises higher (the container's walls, when the point given was on its inside). What
/// the object stands on holds it too, but lies lower; what stands beside it lies outside it.
pub(super) fn object_at(
    points: &[Point3<f64>],
    members: &[usize],
    seed: &Point3<f64>,
    viewpoint: &Point3<f64>,
    up: &Vector3<f64>,
) -> Vec<usize> {
    let v = Voxels::new(points, members, viewpoint);
    let Some(start) = v.nearest(seed) else {
        return Vec::new();
    };
    let mut taken = HashMap::new();
    let object = v.grow(start, &mut taken);
    let mut keys: Vec<Cell> = v.cells.keys().copied().collect();
    keys.sort();
    let mut regions: Vec<Vec<usize>> = Vec::new();
    for k in keys {
        if !taken.contains_key(&k) {
            let r = v.grow(k, &mut taken);
            if r.len() >= 10 {
                regions.push(r);
            }
        }
    }
    tracing::debug!(
        "at: local convexity splits the cluster into {} and {} further regions of {:?} points",
        object.len(),
        regions.len(),
        regions.iter().map(|r| r.len()).take(12).collect::<Vec<_>>()
    );
    merge_belonging(points, object, regions, up, true)
}

/// `object` with those of `regions` that belong to it, seen along `up`, as [`object_at`] tells
/// (a region must come within [`BELONGS_WITHIN`] of it as well); with `rims`, also a region level
/// with the object's top ([`RIM_LEVEL`]) inside the circle of that top ([`rim_circle`]): an open
/// container's inside seen through its opening beyond its near wall, which lie side by side
/// seen from above (the mOSD white bowl of learn35 shown at its labelled centroid, on its wall).
pub(super) fn merge_belonging(
    points: &[Point3<f64>],
    mut object: Vec<usize>,
    mut regions: Vec<Vec<usize>>,
    up: &Vector3<f64>,
    rims: bool,
) -> Vec<usize> {
    let (u, w) = crate::cloud::plane::orthonormal_basis(up);
    let flat = |i: &usize| (points[*i].coords.dot(&u), points[*i].coords.dot(&w));
    let top = |r: &[usize]| {
        let mut h: Vec<f64> = r.iter().map(|&i| points[i].coords.dot(up)).collect();
        crate::numeric::quantile(&mut h, 0.98).unwrap_or(f64::NEG_INFINITY)
    };
    let within = |r: &[usize], hull: &[(f64, f64)]| {
        r.iter().filter(|i| super::seen::inside_convex(hull, flat(i))).count() as f64 >= 0.8 * r.len() as f64
    };
    loop {
        let hull = super::seen::hull2d(object.iter().map(flat).collect());
        let object_top = top(&object);
        let object_points: Vec<Point3<f64>> = object.iter().map(|&i| points[i]).collect();
        let grid = crate::cloud::grid::Grid::new(&object_points, BELONGS_WITHIN);
        // Only where a region is near and level with the object's top.
        let level_near = |r: &[usize]| {
            (top(r) - object_top).abs() <= RIM_LEVEL
                && r.iter()
                    .any(|&i| grid.any_within(&object_points, &points[i], BELONGS_WITHIN))
        };
        let rim = if rims && regions.iter().any(|r| level_near(r)) {
            rim_circle(points, &object, &hull, up, object_top)
        } else {
            None
        };
        let within_rim = |r: &[usize]| {
            rim.is_some_and(|(c, radius)| {
                r.iter()
                    .filter(|i| {
                        let (x, y) = flat(i);
                        (x - c.x).hypot(y - c.y) <= radius + RIM_MARGIN
                    })
                    .count() as f64
                    >= 0.8 * r.len() as f64
            })
        };
        let joins = regions.iter().position(|r| {
            let r_top = top(r);
            r.iter()
                .any(|&i| grid.any_within(&object_points, &points[i], BELONGS_WITHIN))
                && ((r_top <= object_top + 0.01 && within(r, &hull))
                    || (r_top > object_top && within(&object, &super::seen::hull2d(r.iter().map(flat).collect())))
                    || ((r_top - object_top).abs() <= RIM_LEVEL && within_rim(r)))
        });
        match joins {
            Some(k) => object.extend(regions.swap_remove(k)),
            None => return object,
        }
    }
}

/// A region that belongs to an object comes this close to it (m).
const BELONGS_WITHIN: f64 = 0.05;

/// An open container's outer wall and its inside seen through the opening reach the same rim:
/// their tops lie within this of each other (m), and the rim is the band this deep below the
/// wall's top.
const RIM_LEVEL: f64 = 0.01;
/// How far (m) outside the rim's circle the inside's points may lie: the noise, and the rim's
/// thickness.
const RIM_MARGIN: f64 = 0.005;

/// The circle, seen along `up`, of the top of the object's wall: its centre in the plane's
/// basis and its radius (`hull`: the object's outline in that basis). `None` where the top's
/// points do not make a circle no larger than the object: an arc of an open container's rim
/// (its near wall, with the inside seen through the opening beyond it) does; a box's top edge
/// does not.
fn rim_circle(
    points: &[Point3<f64>],
    object: &[usize],
    hull: &[(f64, f64)],
    up: &Vector3<f64>,
    object_top: f64,
) -> Option<(nalgebra::Vector2<f64>, f64)> {
    let (u, w) = crate::cloud::plane::orthonormal_basis(up);
    let flat = |i: usize| nalgebra::Vector2::new(points[i].coords.dot(&u), points[i].coords.dot(&w));
    let rim: Vec<nalgebra::Vector2<f64>> = object
        .iter()
        .filter(|&&i| points[i].coords.dot(up) > object_top - RIM_LEVEL)
        .map(|&i| flat(i))
        .collect();
    if rim.len() < 20 {
        return None;
    }
    let centre = super::profile::circle_fit(&rim)?;
    let mut d: Vec<f64> = rim.iter().map(|p| (p - centre).norm()).collect();
    let radius = crate::numeric::median(&mut d)?;
    // The object's width seen from above: the longest chord of its outline.
    let extent = hull
        .iter()
        .flat_map(|a| hull.iter().map(move |b| (a.0 - b.0).hypot(a.1 - b.1)))
        .fold(0.0, f64::max);
    // The rim points fit the circle, and it is no wider than the object seen from above.
    let spread = crate::numeric::median(&mut d.iter().map(|x| (x - radius).abs()).collect::<Vec<_>>())?;
    (2.0 * radius <= 1.1 * extent && spread <= RIM_MARGIN).then_some((centre, radius))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 100 mm cube's top and front standing on a 300 mm slab's top, seen from above and in
    /// front: from a point on the cube, the cube; from a point on the slab, the slab.
    #[test]
    fn a_box_on_a_slab_is_cut_at_the_crease() {
        let mut pts = Vec::new();
        let grid = |n: i32| (0..n).map(|i| i as f64 * 0.003);
        // The slab's top at z = 0.05, x, y in [-0.15, 0.15].
        for x in grid(101) {
            for y in grid(101) {
                let (x, y) = (x - 0.15, y - 0.15);
                if x.abs() > 0.05 || y.abs() > 0.05 {
                    pts.push(Point3::new(x, y, 0.05));
                }
            }
        }
        let slab = pts.len();
        // The cube on it: its top at z = 0.15 and its front at y = -0.05.
        for x in grid(34) {
            for y in grid(34) {
                pts.push(Point3::new(x - 0.05, y - 0.05, 0.15));
            }
            for z in grid(34) {
                pts.push(Point3::new(x - 0.05, -0.05, 0.05 + z));
            }
        }
        let all: Vec<usize> = (0..pts.len()).collect();
        let v = Point3::new(0.0, -0.6, 0.6);
        let cube = convex_region(&pts, &all, &Point3::new(0.0, 0.0, 0.15), &v);
        assert!(cube.iter().all(|&i| i >= slab || pts[i].z > 0.045), "cube");
        let on_slab = cube.iter().filter(|&&i| i < slab).count();
        assert!(on_slab * 50 < cube.len(), "{on_slab} slab points of {}", cube.len());
        assert!(
            cube.len() * 10 > (pts.len() - slab) * 8,
            "{} of {}",
            cube.len(),
            pts.len() - slab
        );
        let s = convex_region(&pts, &all, &Point3::new(0.12, 0.12, 0.05), &v);
        let on_cube = s.iter().filter(|&&i| i >= slab).count();
        assert!(on_cube * 50 < s.len(), "{on_cube} cube points of {}", s.len());
    }

    #[test]
    fn a_bowls_inside_is_one_region() {
        // A half sphere of 70 mm radius, open upwards, its inside seen from above.
        let mut pts = Vec::new();
        for i in 0..60 {
            for j in 0..120 {
                let th = std::f64::consts::FRAC_PI_2 * (i as f64 + 0.5) / 60.0;
                let ph = std::f64::consts::TAU * j as f64 / 120.0;
                pts.push(Point3::new(
                    0.07 * th.sin() * ph.cos(),
                    0.07 * th.sin() * ph.sin(),
                    0.07 - 0.07 * th.cos(),
                ));
            }
        }
        let all: Vec<usize> = (0..pts.len()).collect();
        let r = convex_region(&pts, &all, &Point3::new(0.0, 0.0, 0.0), &Point3::new(0.0, -0.3, 0.6));
        assert!(r.len() * 100 > pts.len() * 95, "{} of {}", r.len(), pts.len());
    }

    #[test]
    fn nothing_in_nothing_out() {
        assert!(convex_region(&[], &[], &Point3::origin(), &Point3::origin()).is_empty());
        let nan = [Point3::new(f64::NAN, 0.0, 0.0)];
        assert!(convex_region(&nan, &[0], &Point3::origin(), &Point3::origin()).is_empty());
    }
}
