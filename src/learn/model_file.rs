//! The learned model as a model file (`model::ModelFile`) that `sqscan detect` takes as it is.

use super::Learned;
use super::family::snap_revolution;
use crate::geometry::Superquadric;
use crate::model::{ConnectionFile, ModelFile, PartFile};
use crate::pose::PoseSpec;
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};

/// Provenance written into the model file's comment block.
#[derive(Debug, Clone, Default)]
pub struct Provenance {
    pub input: String,
    pub selection: String,
    pub command: String,
}

/// A model file for a learned object, in the object frame of its first part (the part's
/// centre, z along its axis); the fit's account and the provenance as comments.
pub fn model_toml(name: &str, learned: &Learned, prov: &Provenance) -> String {
    let mut comments = vec![format!("Learned by `sqscan learn` from {}", prov.input)];
    if !prov.selection.is_empty() {
        comments.push(format!("points: {}", prov.selection));
    }
    comments.push(format!(
        "object points {}; plane {}",
        learned.object_points,
        match &learned.segmentation.plane {
            Some(p) => format!(
                "n = ({:.4}, {:.4}, {:.4}), d = {:.4}",
                p.normal.x, p.normal.y, p.normal.z, p.d
            ),
            None => "none".into(),
        }
    ));
    if let Some(r) = &learned.support {
        comments.push(format!(
            "stands on a level surface {:.1} mm over the plane ({} points beside its foot), where it was fitted resting",
            1e3 * r.height,
            r.points
        ));
    }
    comments.extend(fit_comments(learned));
    let written = written_shapes(learned);
    comments.extend(sizes_comments(learned, &written));
    if !prov.command.is_empty() {
        comments.push(format!("command: {}", prov.command));
    }
    for r in &learned.parts {
        if snap_revolution(&r.placed.shape).is_some() {
            let f = &r.placed.shape;
            comments.push(format!(
                "fitted a = ({:.4}, {:.4}, {:.4}), e2 = {:.3}, kx = {:.3}, ky = {:.3}: taken as a body of revolution",
                f.a[0], f.a[1], f.a[2], f.e2, f.kx, f.ky
            ));
        }
    }
    comments.extend(learned.colour.as_ref().map(|_| colour_comment()));
    // The object frame is the first part's frame; further parts are posed in it and connected
    // to it (the detector votes on the angle between the z axes and the centre distance).
    let base = object_frame(learned, &written);
    let (t, q) = (base.translation.vector, base.rotation.coords);
    comments.push(format!(
        "model frame in the cloud: position [{:.5}, {:.5}, {:.5}], orientation [{:.6}, {:.6}, {:.6}, {:.6}]",
        t.x, t.y, t.z, q.x, q.y, q.z, q.w
    ));
    let part = learned
        .parts
        .iter()
        .zip(&written)
        .enumerate()
        .map(|(i, (r, shape))| {
            let name = if i == 0 { "body".to_string() } else { format!("part{i}") };
            let pose = (i > 0).then(|| base.inverse() * r.placed.pose);
            part_file(&name, shape, r.open && i == 0, pose.as_ref())
        })
        .collect();
    let connection = learned
        .parts
        .iter()
        .enumerate()
        .skip(1)
        .map(|(i, r)| {
            let za = base.rotation * Vector3::z();
            let zb = r.placed.pose.rotation * Vector3::z();
            let signed = written[0].is_tapered() && written[i].is_tapered();
            let angle = crate::model::axis_angle(&za, &zb, signed);
            let distance = (r.placed.pose.translation.vector - base.translation.vector).norm();
            ConnectionFile {
                parts: ["body".into(), format!("part{i}")],
                angle_rad: None,
                angle_deg: Some(round(angle.to_degrees(), 3)),
                distance: round(distance, 5),
            }
        })
        .collect();
    let file = ModelFile {
        name: Some(name.into()),
        description: format!("Learned from {}", prov.input),
        held: false,
        part,
        connection,
        colour: learned
            .colour
            .as_ref()
            .map(|h| h.iter().map(|v| round(*v, 5)).collect()),
    };
    file.to_toml(&comments)
        .expect("a model file of numbers and strings serializes")
}

/// One line a part: how its fit went.
fn fit_comments(learned: &Learned) -> Vec<String> {
    learned.parts.iter().enumerate().map(|(i, r)| {
        let t = r.placed.pose.translation.vector;
        format!(
            "part {i}: {} points fitted, residual RMS {:.2} mm over {:.0} % inliers, median |r| {:.2} mm, start {}, centre in the cloud ({:.4}, {:.4}, {:.4})",
            r.fitted_points,
            r.rms * 1e3,
            r.inlier_share * 100.0,
            r.median_abs * 1e3,
            r.start,
            t.x,
            t.y,
            t.z
        )
    }).collect()
}

/// What the `colour` line holds.
fn colour_comment() -> String {
    use crate::appearance::{BINS, MIN_SIMILARITY, RANGE};
    format!(
        "colour: the share of the object's points in each cell of chromaticity r = R/(R+G+B) (rows) by \
         g = G/(R+G+B) (columns), {BINS} cells of {w:.3} from 0 (the last to 1); a detection sharing less than \
         {MIN_SIMILARITY} of it is not the object",
        w = RANGE / BINS as f64
    )
}

/// For each part, what the view fixes of its sizes ([`super::allows`]), in the written shapes (a
/// body of revolution's two sizes made one: each bound moves with its size).
fn sizes_comments(learned: &Learned, written: &[Superquadric]) -> Vec<String> {
    learned
        .sizes
        .iter()
        .zip(written)
        .enumerate()
        .map(|(i, (s, shape))| {
            let e = super::allows::extents(shape);
            let list = |f: &dyn Fn(usize) -> String| (0..3).map(f).collect::<Vec<_>>().join(", ");
            format!(
                "part {i} extents along its x, y, z: {} mm; the points span {} (1-99 %); the scene allows up to {} \
                 (a side grown until it would cross space the sensor saw through, take in the seen surface or sink \
                 into the support; - where nothing in view stops it within {:.0} mm)",
                list(&|k| format!("{:.1}", 1e3 * e[k])),
                list(&|k| format!("{:.1}", 1e3 * s[k].seen)),
                list(&|k| s[k]
                    .at_most
                    .map_or_else(|| "-".into(), |m| format!("{:.1}", 1e3 * (m - s[k].size + e[k])))),
                1e3 * super::REACH
            )
        })
        .collect()
}

/// `x` rounded to `decimals` places: a model file carries what one view can tell (0.1 mm, a
/// thousandth of an exponent), not the fit's last digits.
fn round(x: f64, decimals: i32) -> f64 {
    let s = 10f64.powi(decimals);
    (x * s).round() / s
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

/// An exponent for the file: to 3 decimals, but one whose `2/e` is whole (1/3, 2/11) to 12,
/// so that it stays whole when read back: the detector evaluates such shapes without
/// logarithms.
fn exponent(e: f64) -> f64 {
    let n = (2.0 / e).round();
    if n >= 1.0 && (2.0 / e - n).abs() < 1e-9 {
        round(2.0 / n, 12)
    } else {
        round(e, 3)
    }
}

/// One `[[part]]` table.
pub(super) fn part_file(name: &str, sq: &Superquadric, open: bool, pose: Option<&Isometry3<f64>>) -> PartFile {
    PartFile {
        name: name.into(),
        a: sq.a.map(|v| round(v, 4)),
        e1: exponent(sq.e1),
        e2: exponent(sq.e2),
        kx: round(sq.kx, 3),
        ky: round(sq.ky, 3),
        m: None,
        open,
        pose: pose.map_or_else(PoseSpec::default, |p| {
            let j = crate::pose::PoseJson::from(p);
            PoseSpec {
                position: j.position.map(|v| round(v, 5)),
                orientation: Some(j.orientation.map(|v| round(v, 6))),
                ..PoseSpec::default()
            }
        }),
    }
}

#[cfg(test)]
mod tests {
    /// The comment gives the cell width as a person writes it, not as a float prints.
    #[test]
    fn the_colour_comment_gives_the_cell_width_rounded() {
        let c = super::colour_comment();
        assert!(c.contains("10 cells of 0.070 from 0"), "{c}");
        assert!(!c.contains("0.0699"), "{c}");
    }
}
