//! The learned model as a model file (`model::ModelFile`) that `sqscan detect` takes as it is.

use super::Learned;
use super::family::snap_revolution;
use crate::geometry::Superquadric;
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};

/// Provenance written into the model file's comment block.
#[derive(Debug, Clone, Default)]
pub struct Provenance {
    pub input: String,
    pub selection: String,
    pub command: String,
}

/// A model file for a learned single-part object, in the object frame of the part (the part's
/// centre, z along its axis).
pub fn model_toml(name: &str, learned: &Learned, prov: &Provenance) -> String {
    let mut s = String::new();
    s.push_str(&format!("# Learned by `sqscan learn` (issue #6) from {}\n", prov.input));
    if !prov.selection.is_empty() {
        s.push_str(&format!("# points: {}\n", prov.selection));
    }
    s.push_str(&format!(
        "# object points {}; plane {}\n",
        learned.object_points,
        match &learned.segmentation.plane {
            Some(p) => format!(
                "n = ({:.4}, {:.4}, {:.4}), d = {:.4}",
                p.normal.x, p.normal.y, p.normal.z, p.d
            ),
            None => "none".into(),
        }
    ));
    for (i, r) in learned.parts.iter().enumerate() {
        let t = r.placed.pose.translation.vector;
        s.push_str(&format!(
            "# part {i}: {} points fitted, residual RMS {:.2} mm over {:.0} % inliers, median |r| {:.2} mm, start {}, centre in the cloud ({:.4}, {:.4}, {:.4})\n",
            r.fitted_points,
            r.rms * 1e3,
            r.inlier_share * 100.0,
            r.median_abs * 1e3,
            r.start,
            t.x,
            t.y,
            t.z
        ));
    }
    if !prov.command.is_empty() {
        s.push_str(&format!("# command: {}\n", prov.command));
    }
    s.push_str(&format!("name = {name:?}\n"));
    s.push_str(&format!("description = {:?}\n", format!("Learned from {}", prov.input)));
    for r in &learned.parts {
        if snap_revolution(&r.placed.shape).is_some() {
            let f = &r.placed.shape;
            s.push_str(&format!(
                "# fitted a = ({:.4}, {:.4}, {:.4}), e2 = {:.3}, kx = {:.3}, ky = {:.3}: taken as a body of revolution\n",
                f.a[0], f.a[1], f.a[2], f.e2, f.kx, f.ky
            ));
        }
    }
    let written = written_shapes(learned);
    // The object frame is the first part's frame; further parts are posed in it and connected
    // to it (the detector votes on the angle between the z axes and the centre distance).
    let base = object_frame(learned, &written);
    let (t, q) = (base.translation.vector, base.rotation.coords);
    s.push_str(&format!(
        "# model frame in the cloud: position [{:.5}, {:.5}, {:.5}], orientation [{:.6}, {:.6}, {:.6}, {:.6}]\n",
        t.x, t.y, t.z, q.x, q.y, q.z, q.w
    ));
    for (i, (r, shape)) in learned.parts.iter().zip(&written).enumerate() {
        let name = if i == 0 { "body".to_string() } else { format!("part{i}") };
        let pose = (i > 0).then(|| base.inverse() * r.placed.pose);
        s.push_str(&part_toml(&name, shape, r.open && i == 0, pose.as_ref()));
    }
    for (i, r) in learned.parts.iter().enumerate().skip(1) {
        let za = base.rotation * Vector3::z();
        let zb = r.placed.pose.rotation * Vector3::z();
        let signed = written[0].is_tapered() && written[i].is_tapered();
        let angle = crate::model::axis_angle(&za, &zb, signed);
        let distance = (r.placed.pose.translation.vector - base.translation.vector).norm();
        s.push_str(&format!(
            "\n[[connection]]\nparts = [\"body\", \"part{i}\"]\nangle_deg = {:.3}\ndistance = {:.5}\n",
            angle.to_degrees(),
            distance
        ));
    }
    s
}

/// The shapes [`model_toml`] writes: bodies of revolution within what one view tells made
/// exact ([`snap_revolution`]), tapers below 0.05 (noise of one view) dropped so that an
/// untapered part keeps its z -> -z symmetry.
pub(super) fn written_shapes(learned: &Learned) -> Vec<Superquadric> {
    learned
        .parts
        .iter()
        .map(|r| {
            let mut shape = snap_revolution(&r.placed.shape).unwrap_or(r.placed.shape);
            if shape.kx.abs() < 0.05 && shape.ky.abs() < 0.05 {
                shape.kx = 0.0;
                shape.ky = 0.0;
            }
            shape
        })
        .collect()
}

/// Where the frame of the model [`model_toml`] writes lies in the learning cloud: with the
/// object's pose in that cloud it says where the model sits on the object (what `sqscan eval
/// --model-in-object` takes, so that a learned model is scored against its own frame).
pub fn model_pose(learned: &Learned) -> Isometry3<f64> {
    object_frame(learned, &written_shapes(learned))
}

/// The object frame of a learned model: the first part's frame, spun about its z axis so that
/// x points at the second part's centre when the first part is a body of revolution (its own
/// x is arbitrary then; the shipped cup has its handle along +x the same way, so a detected
/// pose means the same for both).
pub(super) fn object_frame(learned: &Learned, written: &[Superquadric]) -> Isometry3<f64> {
    let mut base = learned.parts[0].placed.pose;
    if let (Some(second), true) = (learned.parts.get(1), written[0].is_revolution()) {
        let d = base.inverse_transform_point(&Point3::from(second.placed.pose.translation.vector));
        if d.x.hypot(d.y) > 1e-6 {
            base.rotation *= UnitQuaternion::from_axis_angle(&Vector3::z_axis(), d.y.atan2(d.x));
        }
    }
    base
}

/// One `[[part]]` table.
pub fn part_toml(name: &str, sq: &Superquadric, open: bool, pose: Option<&Isometry3<f64>>) -> String {
    let mut s = format!(
        "\n[[part]]\nname = {name:?}\na = [{:.4}, {:.4}, {:.4}]\ne1 = {:.3}\ne2 = {:.3}\nkx = {:.3}\nky = {:.3}\n",
        sq.a[0], sq.a[1], sq.a[2], sq.e1, sq.e2, sq.kx, sq.ky
    );
    if open {
        s.push_str("open = true\n");
    }
    if let Some(p) = pose {
        let j = crate::pose::PoseJson::from(p);
        s.push_str(&format!(
            "pose = {{ position = [{:.5}, {:.5}, {:.5}], orientation = [{:.6}, {:.6}, {:.6}, {:.6}] }}\n",
            j.position[0],
            j.position[1],
            j.position[2],
            j.orientation[0],
            j.orientation[1],
            j.orientation[2],
            j.orientation[3]
        ));
    }
    s
}
