//! `sqscan detect`: find an object in a point-cloud file.

use crate::write_atomic;
use anyhow::{Context, Result, bail};
use clap::Args;
use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion};
use sqscan::cloud::{self, Field, FieldData, PlyFormat, PointCloud};
use sqscan::detect::{self, Params};
use sqscan::grasp::Gripper;
use sqscan::model::Model;
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct DetectArgs {
    #[command(flatten)]
    pub models: crate::ModelsDirArg,
    /// Model name (looked up in the models directory) or model file
    #[arg(long)]
    model: String,
    /// Point cloud file (.pcd, .ply, text with x y z per line, or .mcap in a build with the mcap
    /// feature)
    #[arg(long)]
    cloud: PathBuf,
    /// Seed of every random choice of the search
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Report every accepted instance that does not overlap a better one
    #[arg(long)]
    all: bool,
    /// Write the input cloud with the detected surfaces added in colour (PLY)
    #[arg(long, value_name = "DETECTED.ply")]
    out: Option<PathBuf>,
    /// Ignore points farther than this from the viewpoint (m), e.g. a wall behind the table
    #[arg(long, value_name = "M")]
    max_range: Option<f64>,
    /// Sensor position "x,y,z" in the cloud's frame [default: the file's VIEWPOINT, else the origin]
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point)]
    viewpoint: Option<Point3<f64>>,
    /// Hypotheses for the (largest) part [default: the model's m, else from the scene's extent]
    #[arg(long, value_name = "M")]
    hypotheses: Option<usize>,
    /// RANSAC trials per hypothesis
    #[arg(long, default_value_t = 10)]
    trials: usize,
    /// Keep the dominant plane instead of removing it
    #[arg(long)]
    keep_plane: bool,
    /// Do not check a found object's colours against the model's (where both have colours)
    #[arg(long)]
    ignore_colour: bool,
    /// Run the detection N times on the cloud in this process and report the fastest run, for
    /// benchmarks: the runs after the first are warm, as in the daemon. Every run must give the
    /// same answer
    #[arg(long, value_name = "N", default_value_t = 1)]
    repeat: usize,
    /// Give every found object up to N grasps of a parallel gripper, best first, checked
    /// against the cloud (docs/GRASPS.md)
    #[arg(long, value_name = "N", default_value_t = 0)]
    grasps: usize,
    /// The gripper's settings: a TOML file of the [gripper] table's keys [default: a Robotiq
    /// 2F-85-class gripper]
    #[arg(long, value_name = "GRIPPER.toml")]
    gripper: Option<PathBuf>,
}

/// Runs of one detection at most with `--repeat`.
const MAX_REPEAT: usize = 1000;
/// Grasps of one object at most with `--grasps`.
const MAX_GRASPS: usize = 100;

/// A gripper's settings from a TOML file of the `[gripper]` table's keys, checked.
pub fn read_gripper(path: &Path) -> Result<Gripper> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let g: Gripper = toml::from_str(&text).with_context(|| format!("{}: not a gripper's settings", path.display()))?;
    g.validate().with_context(|| path.display().to_string())?;
    Ok(g)
}

/// Comma-separated numbers ("1, -2.5,3").
fn parse_numbers(s: &str) -> Result<Vec<f64>, String> {
    s.split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{s:?}: {e}"))
}

pub fn parse_point(s: &str) -> Result<Point3<f64>, String> {
    let v = parse_numbers(s)?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Point3::new(*x, *y, *z)),
        _ => Err(format!("{s:?}: give three finite numbers x,y,z")),
    }
}

/// "x,y,z,qx,qy,qz,qw" as a pose (the quaternion normalised; it must not be zero).
pub fn parse_pose(s: &str) -> Result<Isometry3<f64>, String> {
    let v = parse_numbers(s)?;
    let [x, y, z, qx, qy, qz, qw] = v.as_slice() else {
        return Err(format!("{s:?}: give seven numbers x,y,z,qx,qy,qz,qw"));
    };
    if !v.iter().all(|c| c.is_finite()) {
        return Err(format!("{s:?}: not finite"));
    }
    let q = Quaternion::new(*qw, *qx, *qy, *qz);
    if q.norm() < 1e-9 {
        return Err(format!("{s:?}: the quaternion is zero"));
    }
    Ok(Isometry3::from_parts(
        Translation3::new(*x, *y, *z),
        UnitQuaternion::from_quaternion(q),
    ))
}

/// Detector parameters from the common flags and the cloud's own viewpoint.
pub fn params_for(cloud: &PointCloud, seed: u64, viewpoint: Option<Point3<f64>>) -> Params {
    let file_viewpoint = cloud.viewpoint_position();
    Params {
        seed,
        viewpoint: viewpoint.or(file_viewpoint).or(Some(Point3::origin())),
        ..Params::default()
    }
}

pub fn detect(a: DetectArgs, models_dir: &Path) -> Result<()> {
    if a.max_range.is_some_and(|r| !(r.is_finite() && r > 0.0)) {
        bail!("--max-range: give a distance > 0 m");
    }
    if a.trials == 0 || a.hypotheses == Some(0) {
        bail!("--trials and --hypotheses must be at least 1");
    }
    if !(1..=MAX_REPEAT).contains(&a.repeat) {
        bail!("--repeat: give 1 to {MAX_REPEAT} runs");
    }
    let model = Model::load(&a.model, models_dir)?;
    let cloud = cloud::read_cloud(&a.cloud)?;
    let mut params = params_for(&cloud, a.seed, a.viewpoint);
    params.all = a.all;
    params.max_range = a.max_range;
    params.hypotheses = a.hypotheses;
    params.trials = a.trials;
    params.remove_plane = !a.keep_plane;
    let gripper = match &a.gripper {
        Some(path) => read_gripper(path)?,
        None => Gripper::default(),
    };
    if a.grasps > MAX_GRASPS {
        bail!("--grasps: give at most {MAX_GRASPS}");
    }
    let report = fastest_of(
        a.repeat,
        || {
            if a.ignore_colour {
                detect::detect(&cloud.points, &model, &params)
            } else {
                detect::detect_checked(&cloud, &model, &params)
            }
        },
        a.all,
    )?;
    let mut json = detect::output::report_json(&report, a.all);
    if a.grasps > 0 {
        detect::output::add_grasps(
            &mut json,
            &report,
            &model,
            &cloud.points,
            params.viewpoint,
            &gripper,
            a.grasps,
        );
    }
    println!("{}", serde_json::to_string(&json)?);
    if let Some(out) = &a.out {
        let shown: Vec<&detect::Detection> = if a.all {
            report.detections.iter().collect()
        } else {
            report.detections.iter().take(1).collect()
        };
        let coloured = with_detections(&cloud, &shown);
        write_atomic(out, |w| {
            Ok(cloud::write_ply(w, &coloured, PlyFormat::BinaryLittleEndian)?)
        })?;
    }
    Ok(())
}

/// The fastest of `runs` runs of `detect`, which must all give the same answer (the detector is
/// deterministic for a given input and seed; a difference is a bug worth stopping on).
fn fastest_of(runs: usize, detect: impl Fn() -> detect::Report, all: bool) -> Result<detect::Report> {
    let answer = |r: &detect::Report| {
        let mut json = detect::output::report_json(r, all);
        json.timing_ms = Default::default();
        json
    };
    let mut best = detect();
    let first = answer(&best);
    for run in 2..=runs {
        let report = detect();
        if answer(&report) != first {
            bail!("run {run} of --repeat answered differently from the first: the detector is not deterministic here");
        }
        if report.timing.total_ms < best.timing.total_ms {
            best = report;
        }
    }
    Ok(best)
}

/// The input's points in grey plus every detected part's surface (green when found, orange for
/// the most similar thing when not), as one PLY with red, green, blue.
fn with_detections(input: &PointCloud, detections: &[&detect::Detection]) -> PointCloud {
    let mut points: Vec<[f32; 3]> = input
        .points
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .copied()
        .collect();
    let mut rgb: Vec<[u8; 3]> = vec![[150, 150, 150]; points.len()];
    for d in detections {
        let colour = if d.found { [40, 220, 60] } else { [250, 140, 20] };
        for part in d.parts.iter().filter_map(|p| p.placed) {
            for q in part.sample_surface(part.shape.min_size() / 8.0) {
                points.push([q.x as f32, q.y as f32, q.z as f32]);
                rgb.push(colour);
            }
        }
    }
    let mut out = PointCloud::from_points(points);
    for (c, name) in ["red", "green", "blue"].iter().enumerate() {
        out.fields.push(Field {
            name: (*name).into(),
            count: 1,
            data: FieldData::U8(rgb.iter().map(|x| x[c]).collect()),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::parse_pose;

    #[test]
    fn a_pose_is_seven_numbers_with_a_nonzero_quaternion() {
        let p = parse_pose("0.1,-0.2,0.3,0,0,0.7071068,0.7071068").unwrap();
        assert!((p.translation.vector.y + 0.2).abs() < 1e-12);
        assert!((p.rotation.angle() - std::f64::consts::FRAC_PI_2).abs() < 1e-6);
        // Normalised.
        let q = parse_pose("0,0,0,0,0,0,2").unwrap();
        assert!(q.rotation.angle().abs() < 1e-12);
        assert!(parse_pose("1,2,3").unwrap_err().contains("seven numbers"));
        assert!(parse_pose("0,0,0,0,0,0,0").unwrap_err().contains("zero"));
        assert!(parse_pose("0,0,0,0,0,x,1").is_err());
        assert!(parse_pose("0,0,nan,0,0,0,1").unwrap_err().contains("not finite"));
    }
}
