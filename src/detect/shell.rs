//! Where a compound's further part is looked for around a placement of the part it connects
//! to: where the model puts it, at every spin of that placement about its axis (its fit does
//! not fix the spin), and the shell the connection leaves around it, where the part's RANSAC
//! trials seed. Used by [`super::compound::combinations`].

use super::fit::Fit;
use super::plane_check::PlaneCheck;
use super::space::{MIN_SAMPLE, SearchSpace, consensus, refine_band};
use crate::geometry::{PlacedKernel, PlacedSuperquadric};
use crate::model::{Connection, Model};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

/// Subsampled points in the shell around a parent placement where the part's surface can be
/// (its connection's distance, give or take the part's reach), that are not on the parent's own
/// surface: where the part's RANSAC trials seed.
pub(super) fn shell_seeds(
    space: &SearchSpace<'_>,
    conn: &Connection,
    shape: &crate::geometry::Superquadric,
    parent: &PlacedSuperquadric,
) -> Vec<usize> {
    let pc = Point3::from(parent.pose.translation.vector);
    let reach = shape.bounding_radius();
    let band = refine_band(&parent.shape, space.noise.at(&pc));
    let kernel = PlacedKernel::new(parent);
    let mut seeds = Vec::new();
    space
        .sub_grid
        .for_each_within(space.sub, &pc, conn.distance + reach, |i| {
            let p = &space.sub[i];
            // Outside the parent's box grown by the band, a point is off its surface.
            if (p - pc).norm() >= conn.distance - reach
                && kernel.surface_distance_near(p, band).is_none_or(|d| d.abs() > band)
            {
                seeds.push(i);
            }
        });
    seeds
}

/// Bounds on the steps of the spin about the parent's axis at which the part is tried where the
/// model puts it.
const SPIN_STEPS: (usize, usize) = (16, 180);
/// Placements kept per parent placement: the best local maxima of the support over the spin.
const SPIN_KEPT: usize = 3;

/// The part where the model puts it against its parent's placement, at every spin of the parent
/// about its own axis (and turned over, when the parent's fit cannot tell its ends apart): a
/// parent's fit fixes its axis but often not its spin, which is what places the other part. The
/// best local maxima of the support (subsampled points within the band of the part's surface)
/// come back as fits, to be refined.
pub(super) fn spun_placements(
    space: &SearchSpace<'_>,
    model: &Model,
    parent: usize,
    part: usize,
    parent_placed: &PlacedSuperquadric,
    check: &PlaneCheck,
) -> Vec<(usize, Fit)> {
    let rel = model.parts[parent].pose_in_object.inverse() * model.parts[part].pose_in_object;
    let shape = model.parts[part].shape;
    let centre = Point3::from(parent_placed.pose.translation.vector);
    let band = refine_band(&shape, space.noise.at(&centre));
    let turned_over = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let flips: &[f64] = if model.parts[parent].shape.is_tapered() || same_when_turned_over(&rel, &shape, &turned_over) {
        &[0.0]
    } else {
        &[0.0, std::f64::consts::PI]
    };
    // Steps no longer along the arc than the part's thinnest half-size, so that the support's
    // peak cannot fall between two of them.
    let arc = rel.translation.vector.xy().norm() * std::f64::consts::TAU;
    let thinnest = shape.a.iter().copied().fold(f64::INFINITY, f64::min);
    let steps = ((arc / thinnest).ceil() as usize).clamp(SPIN_STEPS.0, SPIN_STEPS.1);
    let mut out: Vec<(usize, Fit)> = Vec::new();
    for &flip in flips {
        let turn = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), flip);
        let placed: Vec<PlacedSuperquadric> = (0..steps)
            .map(|k| {
                let spin = UnitQuaternion::from_axis_angle(
                    &Vector3::z_axis(),
                    std::f64::consts::TAU * k as f64 / steps as f64,
                );
                let pose = parent_placed.pose * Isometry3::from_parts(Translation3::identity(), turn * spin) * rel;
                PlacedSuperquadric::new(shape, pose)
            })
            .collect();
        let support: Vec<usize> = placed
            .iter()
            .map(|q| {
                if check.allows(space, q) {
                    consensus(space, q, band)
                } else {
                    0
                }
            })
            .collect();
        for k in 0..steps {
            let (prev, next) = (support[(k + steps - 1) % steps], support[(k + 1) % steps]);
            // A plateau's first step stands for it.
            if support[k] >= MIN_SAMPLE && support[k] > prev && support[k] >= next {
                out.push((
                    support[k],
                    Fit {
                        placed: placed[k],
                        m: f64::INFINITY,
                        iterations: 0,
                    },
                ));
            }
        }
    }
    out.sort_by_key(|o| std::cmp::Reverse(o.0));
    out.truncate(SPIN_KEPT);
    out
}

/// Whether turning the parent over (half a turn about its x axis) puts the part, placed at `rel`
/// in the parent's frame, where some spin about the parent's axis already puts it: when the part
/// sits in the parent's middle plane and the turn is one of the part's own symmetries there (a
/// mallet's shaft, a cup's handle). Then the turned-over spins repeat the others.
fn same_when_turned_over(
    rel: &Isometry3<f64>,
    shape: &crate::geometry::Superquadric,
    turned_over: &UnitQuaternion<f64>,
) -> bool {
    // Turned over, then spun back by any angle: the part's pose in its own frame.
    let moved = rel.inverse() * Isometry3::from_parts(Translation3::identity(), *turned_over) * rel;
    if moved.translation.vector.norm() > 1e-6 {
        return false;
    }
    let half = |axis: nalgebra::Unit<Vector3<f64>>| UnitQuaternion::from_axis_angle(&axis, std::f64::consts::PI);
    // The superquadric is even in x and y; untapered, also in z.
    let mut symmetries = vec![UnitQuaternion::identity(), half(Vector3::z_axis())];
    if !shape.is_tapered() {
        symmetries.extend([half(Vector3::x_axis()), half(Vector3::y_axis())]);
    }
    symmetries.iter().any(|s| s.angle_to(&moved.rotation) < 1e-6)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Superquadric;
    use std::path::Path;

    fn rel(model: &Model, parent: usize, part: usize) -> Isometry3<f64> {
        model.parts[parent].pose_in_object.inverse() * model.parts[part].pose_in_object
    }

    #[test]
    fn turning_the_parent_over_repeats_a_part_in_its_middle_plane_only() {
        let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
        let over = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        // A mallet's shaft and a cup's handle sit in the middle plane of the head and the body.
        for name in ["mallet", "cup"] {
            let m = Model::load(name, &models).unwrap();
            assert!(
                same_when_turned_over(&rel(&m, 0, 1), &m.parts[1].shape, &over),
                "{name}"
            );
        }
        // Off that plane (a handle 2 cm up), turned over is elsewhere.
        let shape = Superquadric::new([0.03, 0.023, 0.008], 0.5, 1.0, 0.0, 0.0).unwrap();
        let up = Isometry3::translation(0.05, 0.0, 0.02);
        assert!(!same_when_turned_over(&up, &shape, &over));
        // In the plane but tapered along an axis the turn reverses: not the same surface.
        let tapered = Superquadric::new([0.03, 0.03, 0.05], 0.5, 1.0, 0.3, 0.3).unwrap();
        let flat = Isometry3::translation(0.05, 0.0, 0.0);
        assert!(!same_when_turned_over(&flat, &tapered, &over));
    }
}
