//! A uniform voxel grid over a point set: radius queries and voxel subsampling.
//!
//! Queries in the detector always use radii close to one size (the part's smallest or largest
//! half-size), so a hash grid with cells of about that size answers a radius query by visiting
//! 27 cells, and is built in one pass with one sort — cheaper to build than a k-d tree for the
//! few thousand to few hundred thousand points of a sweep, and as fast to query at these radii.

use crate::numeric::lanes::widened;
use nalgebra::Point3;

/// Points bucketed into cubic cells; every cell's points are contiguous in `order`.
pub struct Grid {
    cell: f64,
    origin: Point3<f64>,
    dims: [usize; 3],
    /// `dims - 1` per axis, as floats.
    top: [f64; 3],
    /// `starts[c]..starts[c + 1]` indexes `order` for cell `c`.
    starts: Vec<u32>,
    order: Vec<u32>,
}

impl Grid {
    /// Build a grid with the given cell size over `points` (all finite).
    pub fn new(points: &[Point3<f64>], cell: f64) -> Grid {
        build(points, cell)
    }

    pub fn cell_size(&self) -> f64 {
        self.cell
    }

    #[inline]
    fn coords(&self, p: &Point3<f64>) -> [usize; 3] {
        // Clamped to the grid as a float first (NaN to 0), then truncated, which is the floor
        // there, without a call to libm's floor; a truncation of a value known to be in range is
        // one instruction, where a saturating cast to usize is a dozen.
        [self.axis(p.x, 0), self.axis(p.y, 1), self.axis(p.z, 2)]
    }

    #[inline(always)]
    fn axis(&self, x: f64, k: usize) -> usize {
        let v = (x - self.origin[k]) / self.cell;
        let v = if v > 0.0 { v } else { 0.0 };
        let v = if v < self.top[k] { v } else { self.top[k] };
        // SAFETY: v is in [0, dims - 1] (NaN became 0), and a grid has at most 2^31 cells.
        unsafe { v.to_int_unchecked::<u32>() as usize }
    }

    #[inline]
    fn cell_index(&self, p: &Point3<f64>) -> usize {
        let c = self.coords(p);
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// Call `f(index)` for every point within `radius` of `centre`.
    pub fn for_each_within(&self, points: &[Point3<f64>], centre: &Point3<f64>, radius: f64, mut f: impl FnMut(usize)) {
        let r2 = radius * radius;
        self.visit_rows(centre, radius, |row| {
            for &i in row {
                let i = i as usize;
                if (points[i] - centre).norm_squared() <= r2 {
                    f(i);
                }
            }
            false
        });
    }

    /// Call `f(index)` for every point within `radius` of `centre`, visiting only the cells that
    /// meet the box `centre ± half` (per axis): a caller that drops the points outside that box
    /// anyway (a placed part's box, turned into the frame) need not pay for the rest of the
    /// sphere, which for a long thin part is most of it. The points come in the order
    /// [`Self::for_each_within`] gives them.
    pub fn for_each_within_box(
        &self,
        points: &[Point3<f64>],
        centre: &Point3<f64>,
        radius: f64,
        half: &nalgebra::Vector3<f64>,
        mut f: impl FnMut(usize),
    ) {
        let r2 = radius * radius;
        let reach = half.map(|h| h.min(radius));
        self.visit_box(centre, &reach, |row| {
            for &i in row {
                let i = i as usize;
                if (points[i] - centre).norm_squared() <= r2 {
                    f(i);
                }
            }
            false
        });
    }

    /// Whether any point lies within `radius` of `centre` (stops at the first).
    pub fn any_within(&self, points: &[Point3<f64>], centre: &Point3<f64>, radius: f64) -> bool {
        let r2 = radius * radius;
        self.visit_rows(centre, radius, |row| {
            row.iter().any(|&i| (points[i as usize] - centre).norm_squared() <= r2)
        })
    }

    /// Whether `f` holds for one of the points in the cells that the box `centre ± half` meets
    /// (stops at the first): the caller tests each point against its own shape in the box.
    pub fn any_in_box(
        &self,
        centre: &Point3<f64>,
        half: &nalgebra::Vector3<f64>,
        mut f: impl FnMut(usize) -> bool,
    ) -> bool {
        self.visit_box(centre, half, |row| row.iter().any(|&i| f(i as usize)))
    }

    /// The points of the cells of the box `centre +- radius`, a row of cells at a time, until
    /// `f` returns true (then true).
    #[inline]
    fn visit_rows(&self, centre: &Point3<f64>, radius: f64, f: impl FnMut(&[u32]) -> bool) -> bool {
        self.visit_box(centre, &nalgebra::Vector3::repeat(radius), f)
    }

    /// The points of the cells of the box `centre ± half`, a row of cells at a time, until `f`
    /// returns true (then true).
    #[inline]
    fn visit_box(
        &self,
        centre: &Point3<f64>,
        half: &nalgebra::Vector3<f64>,
        mut f: impl FnMut(&[u32]) -> bool,
    ) -> bool {
        let lo = self.coords(&(centre - half));
        let hi = self.coords(&(centre + half));
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                let row = (z * self.dims[1] + y) * self.dims[0];
                let (a, b) = (self.starts[row + lo[0]] as usize, self.starts[row + hi[0] + 1] as usize);
                if f(&self.order[a..b]) {
                    return true;
                }
            }
        }
        false
    }

    /// Indices of the points within `radius` of `centre`.
    pub fn within(&self, points: &[Point3<f64>], centre: &Point3<f64>, radius: f64) -> Vec<usize> {
        let mut out = Vec::new();
        self.for_each_within(points, centre, radius, |i| out.push(i));
        out
    }
}

widened! {
fn build(points: &[Point3<f64>], cell: f64) -> Grid {
    let cell = cell.max(1e-6);
    let mut lo = Point3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let mut hi = Point3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
    for p in points {
        for k in 0..3 {
            // Selects, which compile to one instruction each; `f64::min` spends three more
            // on NaN, and the points are finite.
            lo[k] = if p[k] < lo[k] { p[k] } else { lo[k] };
            hi[k] = if p[k] > hi[k] { p[k] } else { hi[k] };
        }
    }
    if points.is_empty() {
        lo = Point3::origin();
        hi = Point3::origin();
    }
    // Bound the cell count: a few stray far points must not make a huge sparse array.
    let mut cell = cell;
    let dims = loop {
        let d = [0, 1, 2].map(|k| (((hi[k] - lo[k]) / cell).floor() as usize).saturating_add(1));
        if d.iter()
            .try_fold(1usize, |acc, &x| acc.checked_mul(x))
            .is_some_and(|n| n <= (8 * points.len().max(1024)).min(1 << 31))
        {
            break d;
        }
        cell *= 1.5;
    };
    let n_cells = dims[0] * dims[1] * dims[2];
    let mut g = Grid {
        cell,
        origin: lo,
        dims,
        top: dims.map(|d| (d - 1) as f64),
        starts: vec![0; n_cells + 1],
        order: Vec::new(),
    };
    let ids: Vec<u32> = points.iter().map(|p| g.cell_index(p) as u32).collect();
    // A counting sort: each cell's count at its index, summed into where each cell ends,
    // then the points placed from the back, so that each cell's end moves to its start
    // and its points stay in input order.
    for &c in &ids {
        g.starts[c as usize] += 1;
    }
    let mut end = 0;
    for s in g.starts.iter_mut() {
        end += *s;
        *s = end;
    }
    g.order = vec![0; points.len()];
    for (i, &c) in ids.iter().enumerate().rev() {
        let at = &mut g.starts[c as usize];
        *at -= 1;
        g.order[*at as usize] = i as u32;
    }
    g
}
}

/// One representative point per voxel of side `voxel` (the point nearest the voxel's centroid is
/// not worth its cost here: the first point in each voxel, in input order, is kept). Returns
/// indices into `points`, in input order.
pub fn voxel_subsample(points: &[Point3<f64>], voxel: f64) -> Vec<usize> {
    if points.is_empty() || !(voxel > 0.0) {
        return (0..points.len()).collect();
    }
    // Room for a key per point: a set that grows rehashes its keys at every doubling, which on a
    // subsample that keeps most points cost more than the inserts.
    let mut seen: VoxelSet = VoxelSet::with_capacity_and_hasher(points.len(), Default::default());
    let mut keep = Vec::new();
    let inv = 1.0 / voxel;
    for (i, p) in points.iter().enumerate() {
        let key = (floor_i64(p.x * inv), floor_i64(p.y * inv), floor_i64(p.z * inv));
        if seen.insert(key) {
            keep.push(i);
        }
    }
    keep
}

/// `v.floor() as i64` without a call to libm's `floor` (baseline x86-64 has no rounding
/// instruction): truncate, then step down where that rounded up.
#[inline(always)]
pub(crate) fn floor_i64(v: f64) -> i64 {
    let t = v as i64;
    // Saturating: below i64's range the cast gave its least value already.
    if (t as f64) > v { t.saturating_sub(1) } else { t }
}

/// A set of voxel keys within a box of the lattice, kept as bits in blocks of 8 x 8 x 8 voxels,
/// each allocated when a key first enters it. A scan's points enter voxels all over the box,
/// and a hash set's lookups then mostly miss the cache; a block holds a neighbourhood in 64
/// bytes. Keys outside the cube of whole blocks that holds the box, and every key of a box too
/// large for the blocks' index, go to a hash set.
pub struct VoxelBits {
    lo: [i64; 3],
    /// Blocks along each side of the box (0: the box is too large, all keys go to `overflow`).
    blocks: usize,
    /// Per block of the box, 0 or 1 + its place in `bits`; allocated at the first key in the
    /// box (a set made for each chunk of a scan is mostly never entered).
    index: Vec<u32>,
    bits: Vec<[u64; 8]>,
    overflow: VoxelSet,
}

/// The most blocks [`VoxelBits`] indexes (a 4 MiB index): a cube of about 800 voxels a side.
const MAX_BLOCKS: usize = 1 << 20;

impl VoxelBits {
    /// An empty set over the voxels `lo..=hi`.
    pub fn new(lo: (i64, i64, i64), hi: (i64, i64, i64)) -> VoxelBits {
        let side = [
            hi.0.saturating_sub(lo.0),
            hi.1.saturating_sub(lo.1),
            hi.2.saturating_sub(lo.2),
        ]
        .iter()
        .map(|&d| d.saturating_add(1).clamp(1, i64::from(u32::MAX)) as usize)
        .max()
        .unwrap_or(1);
        let blocks = side.div_ceil(8);
        let fits = blocks.checked_pow(3).is_some_and(|n| n <= MAX_BLOCKS);
        VoxelBits {
            lo: [lo.0, lo.1, lo.2],
            blocks: if fits { blocks } else { 0 },
            index: Vec::new(),
            bits: Vec::new(),
            overflow: VoxelSet::default(),
        }
    }

    /// Adds `key`; whether it was not in the set.
    #[inline]
    pub fn insert(&mut self, key: (i64, i64, i64)) -> bool {
        let side = (self.blocks * 8) as i64;
        let rel = [
            key.0.wrapping_sub(self.lo[0]),
            key.1.wrapping_sub(self.lo[1]),
            key.2.wrapping_sub(self.lo[2]),
        ];
        if !rel.iter().all(|&r| (0..side).contains(&r)) {
            return self.overflow.insert(key);
        }
        let [x, y, z] = rel.map(|r| r as usize);
        let n = self.blocks;
        if self.index.is_empty() {
            self.index = vec![0; n * n * n];
        }
        let block = ((z >> 3) * n + (y >> 3)) * n + (x >> 3);
        let slot = match self.index[block] {
            0 => {
                self.bits.push([0; 8]);
                self.index[block] = self.bits.len() as u32;
                self.bits.len() - 1
            }
            s => s as usize - 1,
        };
        let bit = ((z & 7) << 6) | ((y & 7) << 3) | (x & 7);
        let (word, mask) = (&mut self.bits[slot][bit >> 6], 1u64 << (bit & 63));
        let new = *word & mask == 0;
        *word |= mask;
        new
    }
}

/// A set of voxel keys.
pub type VoxelSet = std::collections::HashSet<(i64, i64, i64), std::hash::BuildHasherDefault<VoxelHasher>>;

/// A hasher for voxel keys: one multiply-rotate per coordinate (the Fx hash of rustc). The std
/// SipHash resists hash flooding, which no point cloud attempts on a set that lives for one call,
/// and cost more than the rest of the subsampling.
#[derive(Default)]
pub struct VoxelHasher(u64);

impl std::hash::Hasher for VoxelHasher {
    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut b = [0u8; 8];
            b[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(b));
        }
    }

    #[inline]
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }

    #[inline]
    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }

    #[inline]
    fn finish(&self) -> u64 {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    /// 3000 points spread over a 2 x 1 x 0.3 m box.
    fn random_points(rng: &mut rand_chacha::ChaCha8Rng) -> Vec<Point3<f64>> {
        (0..3000)
            .map(|_| {
                Point3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-0.5..0.5),
                    rng.random_range(0.0..0.3),
                )
            })
            .collect()
    }

    #[test]
    fn radius_queries_match_brute_force() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let pts = random_points(&mut rng);
        let grid = Grid::new(&pts, 0.05);
        for _ in 0..200 {
            let c = Point3::new(
                rng.random_range(-1.2..1.2),
                rng.random_range(-0.6..0.6),
                rng.random_range(-0.1..0.4),
            );
            let r = rng.random_range(0.01..0.2);
            let mut got = grid.within(&pts, &c, r);
            got.sort();
            let want: Vec<usize> = (0..pts.len()).filter(|&i| (pts[i] - c).norm() <= r).collect();
            assert_eq!(got, want);
        }
    }

    /// A box query gives every point of the sphere inside the box, in the sphere query's order.
    #[test]
    fn box_queries_keep_the_points_in_the_box_in_order() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let pts = random_points(&mut rng);
        let grid = Grid::new(&pts, 0.05);
        for _ in 0..200 {
            let c = Point3::new(rng.random_range(-1.0..1.0), rng.random_range(-0.5..0.5), 0.15);
            let r = rng.random_range(0.05..0.3);
            let half = nalgebra::Vector3::new(
                rng.random_range(0.0..0.3),
                rng.random_range(0.0..0.3),
                rng.random_range(0.0..0.3),
            );
            let inside = |i: usize| (0..3).all(|k| (pts[i][k] - c[k]).abs() <= half[k]);
            let mut got = Vec::new();
            grid.for_each_within_box(&pts, &c, r, &half, |i| {
                if inside(i) {
                    got.push(i)
                }
            });
            let want: Vec<usize> = grid.within(&pts, &c, r).into_iter().filter(|&i| inside(i)).collect();
            assert_eq!(got, want);
        }
    }

    /// The bit blocks say what a hash set says of every key: inside the box, across its
    /// blocks' edges, outside it (either side, far off), and for a box too large to index.
    #[test]
    fn voxel_bits_agree_with_a_hash_set() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        for (lo, hi) in [
            ((-20, 5, -3), (20, 30, 9)),
            ((0, 0, 0), (0, 0, 0)),
            ((-1 << 40, 0, 0), (1 << 40, 1, 1)),
            ((i64::MIN + 5, 0, 0), (i64::MAX - 5, 1, 1)),
        ] {
            let mut bits = VoxelBits::new(lo, hi);
            let mut set = VoxelSet::default();
            for _ in 0..20_000 {
                let key = if rng.random_range(0..10) == 0 {
                    (rng.random_range(i64::MIN..i64::MAX), rng.random_range(-40..40), 7)
                } else {
                    (
                        rng.random_range(-25..25),
                        rng.random_range(0..35),
                        rng.random_range(-5..12),
                    )
                };
                assert_eq!(bits.insert(key), set.insert(key), "{key:?} in {lo:?}..{hi:?}");
            }
        }
    }

    #[test]
    fn subsampling_keeps_one_point_per_voxel() {
        let pts: Vec<Point3<f64>> = (0..100).map(|i| Point3::new(i as f64 * 0.001, 0.0, 0.0)).collect();
        assert_eq!(voxel_subsample(&pts, 0.01).len(), 10);
    }
}
