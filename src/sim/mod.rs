//! The simulated scanner: scene files and a ray-cast model of the laser triangulation sensor.
//!
//! For each profile the PTU's tilt at that instant places the laser plane. Each column's laser
//! ray is cast to its first surface (so whatever the laser cannot reach lies in a laser shadow);
//! the lit spot is returned only when the camera, `baseline` off the laser plane, sees it
//! unobstructed (camera shadow), when neither the laser nor the camera meets the surface more
//! obliquely than `max_incidence`, and when it lies in the depth window. The row where the spot
//! appears gets Gaussian noise (so depth noise grows with depth squared) and is quantized to the
//! sensor's sub-pixel resolution; random dropout removes a share of the rest. The sweep is then
//! assembled exactly as a real one would be: rows back to depth through the sensor model, and
//! into the base frame through the rig's kinematic chain at each profile's tilt.

mod scene;
mod sensor;

pub use scene::*;
pub use sensor::*;

use crate::cloud::{Field, FieldData, PointCloud};
use crate::geometry::PlacedSuperquadric;
use crate::numeric::stream_seed;
use crate::sweep::{Sweep, SweepReport};
use nalgebra::{Isometry3, Point3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

/// Point labels: 0 no return, 1 table, 2 floor, then `20 + 10 k + part` for object `k`
/// (see [`Scene::labelled_parts`]).
pub const LABEL_NONE: u32 = 0;
pub const LABEL_TABLE: u32 = 1;
pub const LABEL_FLOOR: u32 = 2;

/// Albedo used for the simulated intensity (a matte, light surface).
const ALBEDO: f64 = 0.9;
/// The shadow ray starts this far off the lit surface so it does not hit that surface at its
/// own start (m).
const SHADOW_EPSILON: f64 = 1e-5;

/// What the sensor reports for one profile: one value per column.
#[derive(Debug, Clone, PartialEq)]
pub struct RawProfile {
    /// Fixed-point sub-pixel rows (0 = no return).
    pub rows: Vec<u16>,
    /// Reflected intensity 0-255 (0 where there was no return).
    pub intensity: Vec<u8>,
    /// What each column hit (the simulator's ground truth, not part of a real sensor's output).
    pub labels: Vec<u32>,
}

struct Caster<'a> {
    scene: &'a Scene,
    /// Label, placement, bounding sphere centre and radius, and whether the part is open.
    parts: Vec<(u32, PlacedSuperquadric, Point3<f64>, f64, bool)>,
}

impl<'a> Caster<'a> {
    fn new(scene: &'a Scene) -> Self {
        let parts = scene
            .labelled_parts()
            .into_iter()
            .map(|(l, p, open)| {
                let c = Point3::from(p.pose.translation.vector);
                (l, p, c, p.shape.bounding_radius() * 1.001, open)
            })
            .collect();
        Caster { scene, parts }
    }

    /// First hit along `origin + t dir` (unit `dir`) for `t` in `(0, t_max]`, considering the
    /// parts in `candidates`: `(t, label, outward unit normal)`.
    fn first_hit(
        &self,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        t_max: f64,
        candidates: &[usize],
    ) -> Option<(f64, u32, Vector3<f64>)> {
        let mut best: Option<(f64, u32, Vector3<f64>)> = None;
        let mut limit = t_max;
        if let Some(t) = &self.scene.table
            && let Some(s) = plane_hit(origin, dir, t.height, limit)
        {
            let p = origin + dir * s;
            if t.contains_xy(p.x, p.y) {
                best = Some((s, LABEL_TABLE, Vector3::z()));
                limit = s;
            }
        }
        if self.scene.floor
            && let Some(s) = plane_hit(origin, dir, 0.0, limit)
        {
            best = Some((s, LABEL_FLOOR, Vector3::z()));
            limit = s;
        }
        for &i in candidates {
            let (label, part, centre, radius, open) = &self.parts[i];
            // Skip parts whose bounding sphere the ray misses or meets only beyond the best hit.
            let oc = centre - origin;
            let along = oc.dot(dir);
            let d2 = oc.norm_squared() - along * along;
            if d2 > radius * radius || along - radius > limit || along + radius < 0.0 {
                continue;
            }
            if let Some(s) = part.ray_hit(origin, dir, limit)
                && s < limit
            {
                let local = part.to_local(&(origin + dir * s));
                let g = part.shape.residual_grad(&local).grad;
                let (s, g) = if *open && crate::model::is_lid(&g) {
                    // An open container has no lid: the ray goes in through the opening and
                    // meets the inside of the wall or the bottom (a zero-thickness wall: the
                    // same surface seen from within), unless it leaves through the opening
                    // again.
                    match inner_hit(part, origin, dir, s, *radius) {
                        Some((s_in, g_in)) if s_in < limit => (s_in, -g_in),
                        _ => continue,
                    }
                } else {
                    (s, g)
                };
                let n = (part.pose.rotation * g).try_normalize(1e-300).unwrap_or(-dir);
                best = Some((s, *label, n));
                limit = s;
            }
        }
        best
    }

    /// Whether the segment from `from` to `to` is free of every surface.
    fn segment_clear(&self, from: &Point3<f64>, to: &Point3<f64>) -> bool {
        let v = to - from;
        let len = v.norm();
        if len <= SHADOW_EPSILON {
            return true;
        }
        let dir = v / len;
        let start = from + dir * SHADOW_EPSILON;
        let t_max = len - SHADOW_EPSILON;
        if let Some(t) = &self.scene.table
            && let Some(s) = plane_hit(&start, &dir, t.height, t_max)
        {
            let p = start + dir * s;
            if s > SHADOW_EPSILON && t.contains_xy(p.x, p.y) {
                return false;
            }
        }
        for (_, part, centre, radius, open) in &self.parts {
            let oc = centre - start;
            let along = oc.dot(&dir).clamp(0.0, t_max);
            if (centre - (start + dir * along)).norm_squared() > radius * radius {
                continue;
            }
            let Some(t_in) = part.ray_hit(&start, &dir, t_max) else {
                continue;
            };
            if !open || !open_crossings_clear(part, &start, &dir, t_in, t_max) {
                return false;
            }
        }
        true
    }
}

/// The outward local normal direction (unnormalised) at a frame point on `part`.
fn local_normal(part: &PlacedSuperquadric, p: &Point3<f64>) -> Vector3<f64> {
    part.shape.residual_grad(&part.to_local(p)).grad
}

/// Where a ray that entered an open part through its opening at `s_entry` meets the part from
/// inside: the far crossing of the (convex) solid, found by casting back from beyond it. `None`
/// when the ray leaves through the opening again. Returns the distance and the outward local
/// normal there.
fn inner_hit(
    part: &PlacedSuperquadric,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    s_entry: f64,
    radius: f64,
) -> Option<(f64, Vector3<f64>)> {
    let span = 2.0 * radius;
    let far = origin + dir * (s_entry + span);
    let back = part.ray_hit(&far, &(-dir), span)?;
    let s_exit = s_entry + span - back;
    if s_exit <= s_entry + SHADOW_EPSILON {
        return None;
    }
    let g = local_normal(part, &(origin + dir * s_exit));
    (!crate::model::is_lid(&g)).then_some((s_exit, g))
}

/// A segment `start + t dir`, `t` in `[0, t_max]`, that is inside an open part from `t_in` on:
/// clear of it when every crossing of its surface is through the opening (the camera looking
/// into a mug at its inner wall).
fn open_crossings_clear(
    part: &PlacedSuperquadric,
    start: &Point3<f64>,
    dir: &Vector3<f64>,
    t_in: f64,
    t_max: f64,
) -> bool {
    if t_in > 0.0 && !crate::model::is_lid(&local_normal(part, &(start + dir * t_in))) {
        return false;
    }
    let end = start + dir * t_max;
    match part.ray_hit(&end, &(-dir), t_max) {
        // The segment ends inside the part: it does not cross the surface again.
        Some(0.0) => true,
        Some(back) => crate::model::is_lid(&local_normal(part, &(start + dir * (t_max - back)))),
        None => true,
    }
}

/// Distance along a unit ray to the horizontal plane `z = height`, if within `(0, t_max]`.
fn plane_hit(origin: &Point3<f64>, dir: &Vector3<f64>, height: f64, t_max: f64) -> Option<f64> {
    if dir.z.abs() < 1e-12 {
        return None;
    }
    let s = (height - origin.z) / dir.z;
    (s > 0.0 && s <= t_max).then_some(s)
}

/// Render what the sensor reports for one profile with the sensor at `sensor_in_base`.
pub fn render_profile(scene: &Scene, sensor_in_base: &Isometry3<f64>, rng: &mut ChaCha8Rng) -> RawProfile {
    render_with(&Caster::new(scene), sensor_in_base, rng)
}

fn render_with(caster: &Caster<'_>, sensor_in_base: &Isometry3<f64>, rng: &mut ChaCha8Rng) -> RawProfile {
    let sensor = &caster.scene.rig.sensor;
    let n = sensor.columns;
    let mut out = RawProfile {
        rows: vec![0; n],
        intensity: vec![0; n],
        labels: vec![LABEL_NONE; n],
    };
    let origin = Point3::from(sensor_in_base.translation.vector);
    let camera = sensor_in_base.transform_point(&Point3::new(0.0, 0.0, sensor.baseline));
    let plane_normal = sensor_in_base.rotation * Vector3::z();
    // Only parts whose bounding sphere reaches the laser plane can be lit in this profile.
    let candidates: Vec<usize> = caster
        .parts
        .iter()
        .enumerate()
        .filter(|(_, (_, _, c, r, _))| (c - origin).dot(&plane_normal).abs() <= *r)
        .map(|(i, _)| i)
        .collect();
    let cos_max = sensor.max_incidence.cos();
    let row_sigma = sensor.row_sigma_px();
    for col in 0..n {
        let dir = sensor_in_base.rotation * sensor.column_direction(col);
        let cos_psi = 1.0 / (1.0 + sensor.column_tan(col).powi(2)).sqrt();
        // Nothing beyond the far depth limit can be reported; the laser may still reach it.
        let t_max = sensor.range_max / cos_psi;
        let Some((t, label, normal)) = caster.first_hit(&origin, &dir, t_max, &candidates) else {
            continue;
        };
        let depth = t * cos_psi;
        if depth < sensor.range_min {
            continue;
        }
        let lit = origin + dir * t;
        let cos_laser = normal.dot(&dir).abs();
        let to_camera = (camera - lit).normalize();
        let cos_camera = normal.dot(&to_camera);
        // The camera must see the lit side of the surface (for a closed surface a back face
        // would also fail the shadow ray; for a one-sided plane only this test catches it).
        let lit_side = -normal.dot(&dir).signum();
        if cos_laser < cos_max || cos_camera * lit_side < cos_max {
            continue;
        }
        // Draw the noise before the remaining tests so each column uses the same number of
        // draws whatever happens to its neighbours.
        let noise: f64 = StandardNormal.sample(rng);
        let drop = rng.random::<f64>() < sensor.dropout;
        if drop || !caster.segment_clear(&lit, &camera) {
            continue;
        }
        let row = sensor.row_of_depth(depth) + noise * row_sigma;
        let value = sensor.encode_row(row);
        if value == 0 {
            continue;
        }
        out.rows[col] = value;
        out.intensity[col] = (255.0 * ALBEDO * cos_laser).round().clamp(1.0, 255.0) as u8;
        out.labels[col] = label;
    }
    out
}

/// Simulate one sweep of the scene's rig. The same scene and seed give the same sweep. Every
/// rendered profile is kept, numbered by its index, at the rig's pan and exact tilt; the report
/// counts them as the assembler would (no position samples: the simulator needs none).
pub fn simulate(scene: &Scene, seed: u64) -> Sweep {
    let rig = &scene.rig;
    let sensor = &rig.sensor;
    let caster = Caster::new(scene);
    let (profiles, columns) = (rig.profiles, sensor.columns);
    let rendered: Vec<(f64, f64, RawProfile)> = (0..profiles)
        .into_par_iter()
        .map(|i| {
            let (stamp, tilt) = rig.profile_time_and_tilt(i);
            let pose = rig.sensor_in_base(rig.pan, tilt);
            let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(seed, i as u64));
            (stamp, tilt, render_with(&caster, &pose, &mut rng))
        })
        .collect();
    let total = profiles * columns;
    let mut range_m = vec![f32::NAN; total];
    let mut points = vec![[f32::NAN; 3]; total];
    let mut intensity = vec![0u8; total];
    let mut labels = vec![LABEL_NONE; total];
    let mut stamp_s = Vec::with_capacity(profiles);
    let mut tilt_rad = Vec::with_capacity(profiles);
    for (i, (stamp, tilt, raw)) in rendered.into_iter().enumerate() {
        let pose = rig.sensor_in_base(rig.pan, tilt);
        for col in 0..columns {
            let Some(row) = sensor.decode_row(raw.rows[col]) else {
                continue;
            };
            let p = sensor.point_in_sensor(col, row);
            let k = i * columns + col;
            range_m[k] = p.norm() as f32;
            let q = pose.transform_point(&Point3::from(p));
            points[k] = [q.x as f32, q.y as f32, q.z as f32];
            intensity[k] = raw.intensity[col];
            labels[k] = raw.labels[col];
        }
        stamp_s.push(stamp);
        tilt_rad.push(tilt);
    }
    let cloud = PointCloud {
        points,
        width: columns,
        height: profiles,
        fields: vec![
            Field {
                name: "intensity".into(),
                count: 1,
                data: FieldData::U8(intensity),
            },
            Field {
                name: "label".into(),
                count: 1,
                data: FieldData::U32(labels),
            },
        ],
        viewpoint: Some(viewpoint_of(rig)),
    };
    let report = SweepReport {
        received: profiles,
        kept: profiles,
        points: range_m.iter().filter(|r| r.is_finite()).count(),
        duration_s: stamp_s.last().copied().unwrap_or(0.0),
        ..SweepReport::default()
    };
    Sweep {
        profiles,
        columns,
        start: None,
        seq: (0..profiles).map(|i| u32::try_from(i).unwrap_or(u32::MAX)).collect(),
        pan_rad: vec![rig.pan; profiles],
        stamp_s,
        tilt_rad,
        range_m,
        cloud,
        report,
    }
}

/// The sensor pose at mid-sweep as a PCD viewpoint `[tx, ty, tz, qw, qx, qy, qz]`: the sensor
/// moves a few centimetres during a sweep, which does not matter for telling the front of a
/// surface from its back.
fn viewpoint_of(rig: &Rig) -> [f64; 7] {
    let pose = rig.sensor_in_base(rig.pan, 0.5 * (rig.tilt_start + rig.tilt_end));
    let t = pose.translation.vector;
    let q = pose.rotation.quaternion();
    [t.x, t.y, t.z, q.w, q.i, q.j, q.k]
}

/// Render the range image as 8-bit grey: near returns bright, far ones darker, no return black.
pub fn range_image_grey(sweep: &Sweep) -> Vec<u8> {
    let finite = sweep.range_m.iter().filter(|r| r.is_finite());
    let (lo, hi) = finite.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &r| {
        (lo.min(r), hi.max(r))
    });
    let span = (hi - lo).max(1e-6);
    sweep
        .range_m
        .iter()
        .map(|&r| {
            if r.is_finite() {
                (255.0 - 200.0 * (r - lo) / span).round() as u8
            } else {
                0
            }
        })
        .collect()
}

#[cfg(test)]
mod tests;
