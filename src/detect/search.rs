//! Hypothesis generation (paper III-B-1): RANSAC trials on subsampled data, each a
//! Levenberg-Marquardt pose fit to about 30 points around a random seed point, started with the
//! part's z axis along each of the sample's three central-moment directions; the best trial of
//! every hypothesis is refined on the points near it (subsampled to a twelfth of the smallest
//! size) until M stops improving.
//!
//! Beyond the paper, every start is placed where the superquadric would touch the sampled patch
//! (its centre one half-size behind the patch, away from the viewpoint) instead of at the patch
//! centroid, so a fit needs a few iterations instead of twenty; starts that would reach deep
//! through the support plane are not fitted, and the rest are screened by successive halving
//! and only the best continues. Hypotheses that meet in the coarse rounds of
//! the refinement are refined, scored and voted on once.
//!
//! [`region_fits`] runs the m hypotheses of one part in parallel, each over its own compact region
//! of the scene and from its own random stream; [`distinct`] keeps the fits that are not copies,
//! for [`refine_fits`](super::refine::refine_fits).

use super::fit::{Fit, fit_pose_tol, measure_of_fit};
use super::plane_check::PlaneCheck;
use super::space::{MIN_SAMPLE, SearchSettings, SearchSpace, consensus, refine_band, same_pose, sample_radius};
use crate::geometry::{NearBatch, PlacedKernel, PlacedSuperquadric, Superquadric};
use crate::numeric::stream_seed;
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Iterations of the short fit every start gets before the best one continues.
const SCREEN_ITERATIONS: usize = 4;
/// A trial whose fit reaches through the support plane is set on it where its sample's RMS
/// distance from the fit is at most this many noise sigmas: the sample of about 30 points then
/// lies on the fit as the sensor's noise allows (its RMS spreads by about an eighth of a sigma),
/// with room for the model approximating the object.
const LIFT_NOISE: f64 = 1.5;
/// Initial poses for a patch: z along each central-moment axis (both signs when the taper makes
/// the sign observable, both spins of the x axis when the cross-section is not round), the
/// centre one half-size behind the patch along its normal (on both sides when no viewpoint says
/// which side faces the sensor). With a `rest_axis` (an open container on a plane), z lies along
/// it, both ways.
pub fn initial_poses(
    shape: &Superquadric,
    sample: &[Point3<f64>],
    viewpoint: Option<Point3<f64>>,
    rest_axis: Option<Vector3<f64>>,
) -> Vec<Isometry3<f64>> {
    // Axes sorted by variance: e[0] the smallest (the patch normal).
    let (c, e) = crate::geometry::principal_axes(sample);
    let axes: Vec<(Vector3<f64>, Vector3<f64>)> = match rest_axis {
        // x along the patch's longest direction across the axis (any will do for a round part).
        // An untapered shape is the same turned over (F depends on |z|): one direction does.
        Some(n) => [n, -n][..if shape.is_tapered() { 2 } else { 1 }]
            .iter()
            .copied()
            .map(|z| {
                let x0 = if (e[2] - z * z.dot(&e[2])).norm() > 0.3 {
                    e[2]
                } else {
                    e[1]
                };
                (z, x0)
            })
            .collect(),
        None => {
            let round = shape.is_revolution();
            let mut v = Vec::with_capacity(6);
            for k in 0..3 {
                let spins: &[usize] = if round { &[1] } else { &[1, 2] };
                for &s in spins {
                    v.push((e[k], e[(k + s) % 3]));
                }
            }
            v
        }
    };
    let normal = e[0];
    let outward: Vec<Vector3<f64>> = match viewpoint {
        // An open container is seen from inside as much as from outside: a patch of its inner
        // wall or bottom faces the sensor with the model's inward side, and its centre lies on
        // the sensor's side of the patch.
        Some(v) if rest_axis.is_none() => {
            let to_view = v.coords - c;
            vec![if normal.dot(&to_view) >= 0.0 { normal } else { -normal }]
        }
        _ => vec![normal, -normal],
    };
    let mut out = Vec::with_capacity(24);
    for (z, x0) in axes {
        let x = (x0 - z * z.dot(&x0)).normalize();
        let y = z.cross(&x);
        let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
        let mut rots = vec![r];
        if shape.is_tapered() && rest_axis.is_none() {
            // Half a turn about x flips z (and y), keeping the frame right-handed.
            rots.push(r * Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI));
        }
        for r in rots {
            // The half-size along the patch normal: how far behind the patch the centre lies.
            let depth = depth_behind(shape, &(r.inverse() * normal));
            for o in &outward {
                let centre = c - o * depth;
                out.push(Isometry3::from_parts(
                    centre.into(),
                    UnitQuaternion::from_rotation_matrix(&r),
                ));
            }
        }
    }
    out
}

/// The half-size of `shape` along the patch normal `n` (in the start's frame): how far behind
/// the patch a start's centre lies.
fn depth_behind(shape: &Superquadric, n: &Vector3<f64>) -> f64 {
    (n.x * shape.a[0])
        .abs()
        .max((n.y * shape.a[1]).abs())
        .max((n.z * shape.a[2]).abs())
}

/// The starts turned so that the part's axis nearest the support plane's normal lies along it,
/// where it was more than a few degrees off: objects rest on the table or on something parallel
/// to it, and a patch across an edge of a box lying there (its front and its top) has central
/// moments at 45 degrees to the box's faces, a basin the fit does not leave. Each is placed one
/// half-size behind the patch, as in [`initial_poses`].
fn level_starts(
    shape: &Superquadric,
    sample: &[Point3<f64>],
    starts: &[Isometry3<f64>],
    normal: &Vector3<f64>,
) -> Vec<Isometry3<f64>> {
    const MIN_TILT: f64 = 0.15;
    if shape.is_revolution() {
        return Vec::new();
    }
    let (c, e) = crate::geometry::principal_axes(sample);
    let patch_normal = e[0];
    let mut out = Vec::new();
    for s in starts {
        let r = s.rotation;
        let Some((k, cos)) = (0..3)
            .map(|k| (k, (r * Vector3::ith(k, 1.0)).dot(normal)))
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        else {
            continue;
        };
        let axis = r * Vector3::ith(k, 1.0);
        let target = if cos >= 0.0 { *normal } else { -normal };
        if axis.dot(&target).clamp(-1.0, 1.0).acos() < MIN_TILT {
            continue;
        }
        let Some(turn) = UnitQuaternion::rotation_between(&axis, &target) else {
            continue;
        };
        let q = turn * r;
        let depth = depth_behind(shape, &(q.inverse() * patch_normal));
        // The same side of the patch as the start it came from.
        let side = (s.translation.vector - c).try_normalize(1e-12).unwrap_or(-patch_normal);
        let start = Isometry3::from_parts((c + side * depth).into(), q);
        // Starts a turn of the patch apart level to the same pose (the box across its edge).
        let repeats = |o: &Isometry3<f64>| {
            o.rotation.angle_to(&q) < MIN_TILT
                && (o.translation.vector - start.translation.vector).norm() < 0.25 * depth
        };
        if !out.iter().any(repeats) {
            out.push(start);
        }
    }
    out
}

/// Fit the best of several starts: every start gets a short fit on half the sample, the best
/// continues on all of it. A trial's pose only has to be good enough for the refinement to take
/// over, so its fit stops at a 0.1 % improvement.
pub fn fit_from_starts(
    shape: &Superquadric,
    starts: &[Isometry3<f64>],
    sample: &[Point3<f64>],
    iterations: usize,
) -> Option<Fit> {
    let five = shape.is_revolution();
    let half: Vec<Point3<f64>> = sample.iter().step_by(2).copied().collect();
    let screen_points = if half.len() >= MIN_SAMPLE { &half[..] } else { sample };
    // Successive halving: every start gets half the screening iterations, the better half of
    // them the rest. A start in the wrong basin (the axis along the wrong moment direction) is
    // plain after two steps.
    let first = (SCREEN_ITERATIONS / 2).min(iterations);
    let mut screened: Vec<Fit> = starts
        .iter()
        .map(|s| fit_pose_tol(&PlacedSuperquadric::new(*shape, *s), screen_points, first, five, 1e-3))
        .collect();
    screened.sort_by(|a, b| a.m.total_cmp(&b.m));
    screened.truncate(screened.len().div_ceil(2));
    let more = SCREEN_ITERATIONS.min(iterations) - first;
    let screened = screened
        .iter()
        .map(|f| {
            if more == 0 {
                return *f;
            }
            let g = fit_pose_tol(&f.placed, screen_points, more, five, 1e-3);
            Fit {
                iterations: f.iterations + g.iterations,
                ..g
            }
        })
        .min_by(|a, b| a.m.total_cmp(&b.m))?;
    let rest = iterations.saturating_sub(screened.iterations);
    if rest == 0 {
        return Some(screened);
    }
    Some(fit_pose_tol(&screened.placed, sample, rest, five, 1e-3))
}

/// The samples of one hypothesis' `settings.trials` RANSAC trials, seeded from `seeds` (indices
/// into `space.sub`): each a random subset of the points within the sample radius of a random
/// seed point. A seed with too few points around it gives no sample.
fn draw_samples(
    space: &SearchSpace<'_>,
    shape: &Superquadric,
    seeds: &[usize],
    settings: &SearchSettings,
    rng: &mut ChaCha8Rng,
) -> Vec<Vec<Point3<f64>>> {
    if seeds.is_empty() {
        return Vec::new();
    }
    let radius = sample_radius(shape);
    let mut near = Vec::new();
    let mut out = Vec::with_capacity(settings.trials);
    for _ in 0..settings.trials {
        let s = seeds[rng.random_range(0..seeds.len())];
        near.clear();
        space
            .sub_grid
            .for_each_within(space.sub, &space.sub[s], radius, |i| near.push(i));
        if near.len() < MIN_SAMPLE {
            continue;
        }
        // A random subset of the neighbourhood (partial Fisher-Yates).
        let k = settings.sample_points.min(near.len());
        for i in 0..k {
            let j = rng.random_range(i..near.len());
            near.swap(i, j);
        }
        out.push(near[..k].iter().map(|&i| space.sub[i]).collect());
    }
    out
}

/// One RANSAC trial: the pose fitted to `sample` from the starts [`initial_poses`] gives, with
/// its consensus in `band`; none where the support plane does not allow it.
///
/// The paper keeps the trial with the smallest M over its 30 points. That is an in-sample
/// measure: a small patch of anything is fitted well, so it favours whatever object fits its
/// patches best, not the object. Here a trial is judged by its consensus, as in classic RANSAC:
/// the subsampled points within the inlier band of the fitted surface, ties broken by M.
fn trial(
    space: &SearchSpace<'_>,
    shape: &Superquadric,
    sample: &[Point3<f64>],
    band: f64,
    settings: &SearchSettings,
    check: &PlaneCheck,
) -> Option<(usize, Fit)> {
    let radius = sample_radius(shape);
    let rest_axis = check.rest_axis(space);
    let mut starts = initial_poses(shape, sample, space.viewpoint, rest_axis);
    if rest_axis.is_none()
        && let Some(plane) = space.plane
    {
        let level = level_starts(shape, sample, &starts, &plane.normal);
        starts.extend(level);
    }
    // A start turned so that the part reaches through the support plane further than the
    // sample spans is turned the wrong way for this patch (a flat part set on its edge
    // beside a patch near the table): fitted, it ends where the plane does not allow it,
    // and the part's right way round for the patch is among the other starts.
    starts.retain(|s| check.may_start(space, &PlacedSuperquadric::new(*shape, *s), radius));
    if starts.is_empty() {
        return None;
    }
    let mut f = fit_from_starts(shape, &starts, sample, settings.fit_iterations)?;
    if !check.allows(space, &f.placed) {
        // A patch on an object's top says little about where its bottom is: a model a few
        // millimetres taller than the object (learned from a view where its rim or handles
        // stood higher) or leaning a few degrees, fitted to the patch, reaches through the table
        // the object stands on. Where the patch lies on the fit to within the sensor's noise,
        // the fit is right for what was seen, and set on the plane (by no more than the plane's
        // own tolerance again) it is where the object is. A fit that misses its own patch by
        // more, or reaches deeper, is another shape's (a cup sunk into a bowl), and is dropped.
        let plane = space.plane.as_ref()?;
        let centre = Point3::from(f.placed.pose.translation.vector);
        if !check.stands(&f.placed, plane)
            || rms_distance(&f.placed, sample, band) > LIFT_NOISE * space.noise.at(&centre)
        {
            return None;
        }
        let (lifted, excess) = check.lifted(&f.placed, plane)?;
        if excess > check.tolerance {
            return None;
        }
        f.placed = lifted;
        f.m = measure_of_fit(&lifted, sample);
    }
    Some((consensus(space, &f.placed, band), f))
}

/// Whether a trial with `support` and fit `f` beats the best so far: more support, or as much
/// and a smaller M (the first of equals stays).
fn better(support: usize, f: &Fit, best: &Option<(usize, Fit)>) -> bool {
    best.as_ref()
        .is_none_or(|(s, b)| support > *s || (support == *s && f.m < b.m))
}

/// The RMS distance (m) of `points` from the placed surface, those farther than `reach` counted
/// at `reach`.
fn rms_distance(placed: &PlacedSuperquadric, points: &[Point3<f64>], reach: f64) -> f64 {
    if points.is_empty() {
        return f64::INFINITY;
    }
    let kernel = PlacedKernel::new(placed);
    let (mut sum, mut near) = (0.0, 0usize);
    let mut batch = NearBatch::new(&kernel, reach, |_, _, rg| {
        let d = PlacedSuperquadric::distance_from(rg).abs().min(reach);
        sum += d * d;
        near += 1;
    });
    for (i, p) in points.iter().enumerate() {
        batch.push(i, p);
    }
    batch.finish();
    ((sum + (points.len() - near) as f64 * reach * reach) / points.len() as f64).sqrt()
}

/// The best trial fit (with its consensus) of each of `m` compact regions of the seed points,
/// each region's trials drawn from its own stream; unrefined.
///
/// The draws (a grid query and a partial shuffle each) are made region by region; the trials'
/// fits, nearly all the cost, then run side by side over all the regions at once: the regions'
/// costs differ several times over (a region on the table's edge fits little, one on an object
/// every start), and ten regions shared by whole between two cores leave one idle.
pub fn region_fits(
    space: &SearchSpace<'_>,
    shape: &Superquadric,
    seeds: &[usize],
    m: usize,
    settings: &SearchSettings,
    check: &PlaneCheck,
    seed: u64,
) -> Vec<(usize, Fit)> {
    let regions = spatial_regions(space.sub_morton, seeds, m);
    let region = |h: usize| &regions[h % regions.len()];
    let draws: Vec<Vec<Vec<Point3<f64>>>> = (0..m)
        .into_par_iter()
        .map(|h| {
            let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(seed, h as u64));
            draw_samples(space, shape, region(h), settings, &mut rng)
        })
        .collect();
    // The region's seeds lie close together: the noise at the first holds for all.
    let bands: Vec<f64> = (0..m)
        .map(|h| {
            region(h)
                .first()
                .map_or(0.0, |&s| refine_band(shape, space.noise.at(&space.sub[s])))
        })
        .collect();
    let trials: Vec<(usize, &[Point3<f64>])> = draws
        .iter()
        .enumerate()
        .flat_map(|(h, d)| d.iter().map(move |sample| (h, &sample[..])))
        .collect();
    let fits: Vec<Option<(usize, Fit)>> = trials
        .par_iter()
        .map(|&(h, sample)| trial(space, shape, sample, bands[h], settings, check))
        .collect();
    let mut best: Vec<Option<(usize, Fit)>> = vec![None; m];
    for (&(h, _), fit) in trials.iter().zip(fits) {
        if let Some((support, f)) = fit
            && better(support, &f, &best[h])
        {
            best[h] = Some((support, f));
        }
    }
    best.into_iter().flatten().collect()
}

/// Split the seed points (indices into the points `morton` orders, each at most once) into `m`
/// spatially compact regions of equal size (consecutive runs in Morton order of 1 cm voxels),
/// one for each hypothesis.
///
/// The paper draws every hypothesis' trials from the whole scene and keeps each one's best fit,
/// so the hypotheses crowd onto the few objects that fit best and a lookalike can hide the
/// object from all m of them. Its m is chosen "to cover the whole scene": giving each hypothesis
/// its own part of the scene does exactly that.
fn spatial_regions(morton: &[u32], seeds: &[usize], m: usize) -> Vec<Vec<usize>> {
    if seeds.is_empty() || m <= 1 {
        return vec![seeds.to_vec()];
    }
    // The seeds in the points' order: all of them, or those marked.
    let order: Vec<usize> = if seeds.len() == morton.len() {
        morton.iter().map(|&i| i as usize).collect()
    } else {
        let mut marked = vec![false; morton.len()];
        for &i in seeds {
            marked[i] = true;
        }
        morton.iter().map(|&i| i as usize).filter(|&i| marked[i]).collect()
    };
    let m = m.min(order.len());
    (0..m)
        .map(|h| order[h * order.len() / m..(h + 1) * order.len() / m].to_vec())
        .collect()
}

/// Drop fits that repeat a better one or a `known` pose (the same place within half the sample
/// radius and the same axis within 30 degrees): many hypotheses land on the same object,
/// refinement brings such near copies to the same pose, and refining and verifying each copy
/// costs time and changes nothing.
pub fn distinct(mut fits: Vec<(usize, Fit)>, known: &[PlacedSuperquadric]) -> Vec<Fit> {
    // Best consensus first, then smallest M.
    fits.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.m.total_cmp(&b.1.m)));
    let mut kept: Vec<PlacedSuperquadric> = known.to_vec();
    let mut out: Vec<Fit> = Vec::with_capacity(fits.len());
    for (_, f) in fits {
        if !kept.iter().any(|k| same_pose(k, &f.placed)) {
            kept.push(f.placed);
            out.push(f);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::space::morton_order;

    #[test]
    fn regions_are_compact_runs_of_the_morton_order() {
        let corners = [(0.0, 0.0), (0.2, 0.0), (0.0, 0.2), (0.2, 0.2)];
        let points: Vec<Point3<f64>> = (0..400)
            .map(|k| {
                let (cx, cy) = corners[k % 4];
                let j = k / 4;
                Point3::new(cx + 0.003 * (j % 10) as f64, cy + 0.003 * (j / 10) as f64, 0.5)
            })
            .collect();
        let morton = morton_order(&points);
        let all: Vec<usize> = (0..points.len()).collect();
        let regions = spatial_regions(&morton, &all, 4);
        assert_eq!(regions.len(), 4);
        for r in &regions {
            assert_eq!(r.len(), 100);
            assert!(r.iter().all(|&i| i % 4 == r[0] % 4), "a region spans patches");
        }
        // A subset, given backwards: its regions are the runs of the same order.
        let subset: Vec<usize> = (0..points.len()).rev().filter(|i| i % 3 != 0).collect();
        let of_subset = spatial_regions(&morton, &subset, 4);
        let expected: Vec<usize> = morton.iter().map(|&i| i as usize).filter(|i| i % 3 != 0).collect();
        assert_eq!(of_subset.concat(), expected);
    }
}

#[cfg(test)]
mod level_start_tests {
    use super::*;

    /// A box lying on the plane z = 0: 52 mm high (its x), 180 mm deep (its y, along the world's
    /// y), 261 mm long (its z, along the world's x), as the Weetabix box lies under a stack.
    fn lying_box() -> (Superquadric, Isometry3<f64>) {
        let shape = Superquadric::new([0.026, 0.09, 0.1305], 0.1, 0.1, 0.0, 0.0).unwrap();
        let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[Vector3::z(), -Vector3::y(), Vector3::x()]));
        let pose = Isometry3::from_parts(
            Vector3::new(0.0, 0.0, 0.026).into(),
            UnitQuaternion::from_rotation_matrix(&r),
        );
        (shape, pose)
    }

    /// The points of its front face (y = -0.09) and its top (z = 0.052) within `radius` of the
    /// middle of the edge between them: the patch a seed on that edge draws.
    fn patch_across_the_edge(radius: f64) -> Vec<Point3<f64>> {
        let edge = Point3::new(0.0, -0.09, 0.052);
        let mut out = Vec::new();
        for i in -40..=40 {
            for j in 0..=40 {
                let u = 0.003 * i as f64;
                let w = 0.003 * j as f64;
                for p in [Point3::new(u, -0.09, 0.052 - w), Point3::new(u, -0.09 + w, 0.052)] {
                    if (p - edge).norm() <= radius && p.z >= 0.0 {
                        out.push(p);
                    }
                }
            }
        }
        out
    }

    /// Whether two box frames agree up to the box's symmetries: each axis along the same line.
    fn same_frame(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>, degrees: f64) -> bool {
        (0..3).all(|k| {
            let c = (a * Vector3::ith(k, 1.0)).dot(&(b * Vector3::ith(k, 1.0))).abs();
            c >= degrees.to_radians().cos()
        })
    }

    #[test]
    fn a_patch_across_a_lying_boxs_edge_gets_a_start_level_with_the_table() {
        let (shape, truth) = lying_box();
        let sample = patch_across_the_edge(sample_radius(&shape));
        let viewpoint = Some(Point3::new(0.0, -0.8, 0.6));
        let starts = initial_poses(&shape, &sample, viewpoint, None);
        // The patch's moments lie at 45 degrees to both faces: no start is the box's frame.
        assert!(!starts.iter().any(|s| same_frame(&s.rotation, &truth.rotation, 15.0)));
        let level = level_starts(&shape, &sample, &starts, &Vector3::z());
        assert!(!level.is_empty());
        for s in &level {
            let up = (0..3)
                .map(|k| (s.rotation * Vector3::ith(k, 1.0)).z.abs())
                .fold(0.0, f64::max);
            assert!(up > 1.0 - 1e-9, "a level start has an axis along the normal: {up}");
        }
        let right = level
            .iter()
            .filter(|s| same_frame(&s.rotation, &truth.rotation, 1.0))
            .count();
        assert!(right >= 1, "no level start in the box's frame");
        // Fitted from all of them, the box ends where it lies: its height and its depth behind
        // the front face (the patch does not show its ends: along its length it may slide).
        let all: Vec<Isometry3<f64>> = starts.iter().chain(&level).copied().collect();
        let fit = fit_from_starts(&shape, &all, &sample, 60).unwrap();
        let error = fit.placed.pose.translation.vector - truth.translation.vector;
        assert!(error.y.hypot(error.z) < 0.005, "fitted {error:?} m from the truth");
        assert!(same_frame(&fit.placed.pose.rotation, &truth.rotation, 3.0));
        // From the moment starts alone the fit stays in their basin.
        let alone = fit_from_starts(&shape, &starts, &sample, 60).unwrap();
        let error = alone.placed.pose.translation.vector - truth.translation.vector;
        assert!(
            error.y.hypot(error.z) > 0.01 || !same_frame(&alone.placed.pose.rotation, &truth.rotation, 3.0),
            "the moment starts alone found it: {error:?}"
        );
    }
}
