//! Surface sampling close to uniform over the surface area (not over the parameter angles).
//!
//! The classic parametrisation `x = a1 cos^e1(eta) cos^e2(omega)` crowds points at the edges of
//! box-like shapes (for e = 0.1 nearly all of a flat face maps to a sliver of parameter space).
//! Instead, directions from the centre are laid out on the six faces of a cube; each direction
//! meets the surface at one point (a superellipsoid is star-shaped about its centre). A quadtree
//! over every cube face is refined until a cell's surface patch is smaller than half a sample's
//! share of area, and the cells are walked in quadtree order with error diffusion of area: a
//! point is emitted each time another `spacing^2` of area has been passed. That gives one point
//! per `spacing^2` of surface, spread evenly, deterministically.

use super::Superquadric;
use super::kernel::Kernel;
use super::superquadric::PlacedSuperquadric;
use crate::numeric::lanes::{Lanes, widened};
use nalgebra::{Point3, Vector3};

/// Depth of the first uniform split of every cube face (4^3 = 64 cells): deep enough that the
/// four-triangle area estimate of a cell is good before the adaptive refinement starts.
const MIN_DEPTH: u32 = 3;
/// Cells stop splitting here whatever their area (4^12 cells a face is far below any spacing
/// that makes sense for objects a robot picks up).
const MAX_DEPTH: u32 = 12;

impl Kernel {
    /// The surface point in the direction of the cube-face point `(u, v)` of face `face`.
    fn cube_surface_point(&self, face: usize, u: f64, v: f64) -> Vector3<f64> {
        let [x, y, z] = self.cube_surface_points(face, Lanes([u]), Lanes([v]));
        Vector3::new(x.0[0], y.0[0], z.0[0])
    }

    /// [`Self::cube_surface_point`] of `L` points of one face at once, the same to the bit.
    #[inline(always)]
    fn cube_surface_points<const L: usize>(&self, face: usize, u: Lanes<L>, v: Lanes<L>) -> [Lanes<L>; 3] {
        let (one, mone) = (Lanes::splat(1.0), Lanes::splat(-1.0));
        let d = match face {
            0 => [one, u, v],
            1 => [mone, -u, v],
            2 => [u, one, v],
            3 => [-u, mone, v],
            4 => [u, v, one],
            _ => [u, -v, mone],
        };
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        self.taper_lanes(self.untapered_surface_along_lanes(d.map(|c| c / n)))
    }
}

widened! {
/// Four points of one face, as vectors.
fn four_points(kernel: &Kernel, face: usize, uv: [(f64, f64); 4]) -> [Vector3<f64>; 4] {
    let [x, y, z] = kernel.cube_surface_points(face, Lanes(uv.map(|p| p.0)), Lanes(uv.map(|p| p.1)));
    std::array::from_fn(|i| Vector3::new(x.0[i], y.0[i], z.0[i]))
}
}

impl Superquadric {
    /// Points on the surface, in the local frame, about `spacing` metres apart.
    ///
    /// Returns an empty set for a non-positive or non-finite spacing.
    pub fn sample_surface(&self, spacing: f64) -> Vec<Vector3<f64>> {
        let mut out = Vec::new();
        if !(spacing.is_finite() && spacing > 0.0) {
            return out;
        }
        let kernel = Kernel::new(self);
        let mut walk = Walk {
            sq: &kernel,
            share: spacing * spacing,
            acc: 0.0,
            out: &mut out,
        };
        for face in 0..6 {
            walk.cell(face, -1.0, -1.0, 2.0, 0, None);
        }
        out
    }
}

struct Walk<'a> {
    sq: &'a Kernel,
    share: f64,
    acc: f64,
    out: &'a mut Vec<Vector3<f64>>,
}

impl Walk<'_> {
    /// Visit a cell. `known` carries its corners `[p00, p10, p11, p01]` and centre when the parent
    /// already evaluated them (a split shares the parent's corners, edge midpoints and centre with
    /// its children, so each split costs 8 surface points instead of 20). The cell coordinates
    /// are dyadic, so a point reached through different parents is the same to the last bit.
    fn cell(
        &mut self,
        face: usize,
        u0: f64,
        v0: f64,
        size: f64,
        depth: u32,
        known: Option<([Vector3<f64>; 4], Vector3<f64>)>,
    ) {
        let sq = self.sq;
        let half = 0.5 * size;
        if depth < MIN_DEPTH {
            self.cell(face, u0, v0, half, depth + 1, None);
            self.cell(face, u0 + half, v0, half, depth + 1, None);
            self.cell(face, u0 + half, v0 + half, half, depth + 1, None);
            self.cell(face, u0, v0 + half, half, depth + 1, None);
            return;
        }
        let ([p00, p10, p11, p01], c) = known.unwrap_or_else(|| {
            (
                four_points(
                    sq,
                    face,
                    [(u0, v0), (u0 + size, v0), (u0 + size, v0 + size), (u0, v0 + size)],
                ),
                sq.cube_surface_point(face, u0 + half, v0 + half),
            )
        });
        // Four triangles fanned about the centre follow a curved patch better than two.
        let area = 0.5
            * ((p00 - c).cross(&(p10 - c)).norm()
                + (p10 - c).cross(&(p11 - c)).norm()
                + (p11 - c).cross(&(p01 - c)).norm()
                + (p01 - c).cross(&(p00 - c)).norm());
        if area > 0.5 * self.share && depth < MAX_DEPTH {
            // Serpentine order keeps consecutive cells adjacent, which spreads the diffused error.
            let q = 0.5 * half;
            // The four edge midpoints, then the four children's centres, four at a time.
            let [m0, m1, m2, m3] = four_points(
                sq,
                face,
                [
                    (u0 + half, v0),
                    (u0 + size, v0 + half),
                    (u0 + half, v0 + size),
                    (u0, v0 + half),
                ],
            );
            let [c0, c1, c2, c3] = four_points(
                sq,
                face,
                [
                    (u0 + q, v0 + q),
                    (u0 + half + q, v0 + q),
                    (u0 + half + q, v0 + half + q),
                    (u0 + q, v0 + half + q),
                ],
            );
            let d = depth + 1;
            self.cell(face, u0, v0, half, d, Some(([p00, m0, c, m3], c0)));
            self.cell(face, u0 + half, v0, half, d, Some(([m0, p10, m1, c], c1)));
            self.cell(face, u0 + half, v0 + half, half, d, Some(([c, m1, p11, m2], c2)));
            self.cell(face, u0, v0 + half, half, d, Some(([m3, c, m2, p01], c3)));
            return;
        }
        self.acc += area;
        if self.acc >= self.share {
            self.out.push(c);
            // Carry at most one share: a too-large leaf at MAX_DEPTH must not dump a burst of
            // points into the next cells.
            self.acc = (self.acc - self.share).min(self.share);
        }
    }
}

impl PlacedSuperquadric {
    /// The lowest `z` of the surface in the pose's frame (used to stand a shape on a table).
    ///
    /// A tapered superquadric has no closed form for it, so: a coarse grid over the six faces
    /// of the cube-map parameterisation, then a pattern search in `(u, v)` from the best few
    /// grid points, shrinking the step to 1e-7 of a face. Parameters are clamped to the face,
    /// so a minimum on a face border (an edge of a box) is reached from either side. A few
    /// thousand surface evaluations, where dense sampling fine enough for a slender part (a
    /// pen) took millions.
    pub fn lowest_z(&self) -> f64 {
        const GRID: usize = 24;
        let kernel = Kernel::new(&self.shape);
        let z = |face: usize, u: f64, v: f64| {
            let q = kernel.cube_surface_point(face, u.clamp(-1.0, 1.0), v.clamp(-1.0, 1.0));
            self.pose.transform_point(&Point3::from(q)).z
        };
        let mut seeds: Vec<(f64, usize, f64, f64)> = Vec::with_capacity(6 * (GRID + 1) * (GRID + 1));
        for face in 0..6 {
            for i in 0..=GRID {
                for j in 0..=GRID {
                    let (u, v) = (-1.0 + 2.0 * i as f64 / GRID as f64, -1.0 + 2.0 * j as f64 / GRID as f64);
                    seeds.push((z(face, u, v), face, u, v));
                }
            }
        }
        seeds.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut best = seeds.first().map_or(f64::INFINITY, |s| s.0);
        for &(z0, face, u0, v0) in seeds.iter().take(4) {
            let (mut u, mut v, mut zb) = (u0, v0, z0);
            let mut step = 2.0 / GRID as f64;
            while step > 1e-7 {
                let mut moved = false;
                for (du, dv) in [
                    (1.0, 0.0),
                    (-1.0, 0.0),
                    (0.0, 1.0),
                    (0.0, -1.0),
                    (1.0, 1.0),
                    (-1.0, -1.0),
                    (1.0, -1.0),
                    (-1.0, 1.0),
                ] {
                    let (un, vn) = ((u + du * step).clamp(-1.0, 1.0), (v + dv * step).clamp(-1.0, 1.0));
                    let zn = z(face, un, vn);
                    if zn < zb {
                        (u, v, zb) = (un, vn, zn);
                        moved = true;
                    }
                }
                if !moved {
                    step *= 0.5;
                }
            }
            best = best.min(zb);
        }
        best
    }

    /// Surface points in the pose's frame, about `spacing` metres apart.
    pub fn sample_surface(&self, spacing: f64) -> Vec<Point3<f64>> {
        self.shape
            .sample_surface(spacing)
            .into_iter()
            .map(|q| self.pose.transform_point(&Point3::from(q)))
            .collect()
    }
}
