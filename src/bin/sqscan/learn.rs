//! `sqscan learn`: learn a model by showing the object: recover its superquadric(s)
//! from one scan and write a model file that `sqscan detect` takes as it is.

use crate::detect::parse_point;
use crate::write_atomic;
use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use nalgebra::Point3;
use serde_json::json;
use sqscan::cloud::plane::remove_dominant_plane;
use sqscan::cloud::{self, FieldData};
use sqscan::learn::{self, Cost, LearnParams, Provenance, Segmentation, ShapeFamily};
use sqscan::model::Model;
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, ValueEnum)]
pub enum CostArg {
    /// Radial Euclidean distance (m)
    Radial,
    /// Paper eq. 2 with Solina's volume factor sqrt(a1 a2 a3)
    Solina,
    /// First-order geometric distance along the surface normal (m)
    Normal,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum ShapeArg {
    /// A body of revolution unless the general shape fits the view clearly (5 %) better
    Auto,
    /// Any superquadric
    General,
    /// A body of revolution (for a round object whose view does not tell: a segmented can)
    Revolution,
}

#[derive(Args)]
pub struct LearnArgs {
    #[command(flatten)]
    pub models: crate::ModelsDirArg,
    /// Point cloud file (.pcd, .ply, or text with x y z per line); several files are sweeps of
    /// one view (organized clouds of the same size, the scene and the sensor still), learned from
    /// their per-pixel median, which cuts the noise by about the square root of their number
    #[arg(long, num_args = 1.., required_unless_present = "simulate")]
    cloud: Vec<PathBuf>,
    /// Name of the learned model
    #[arg(long, required_unless_present = "simulate")]
    name: Option<String>,
    /// Superquadric parts (1, 2 or 3)
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=3))]
    parts: u8,
    /// Model file to write [default: MODELS_DIR/NAME.toml, unless that is the package's /usr/share/sqscan/models]
    #[arg(long, value_name = "FILE.toml")]
    out: Option<PathBuf>,
    /// Replace an existing model file
    #[arg(long)]
    force: bool,
    /// Use the points labelled as object N (mOSD labels: label >= 20 and label / 10 == N); the
    /// table is fitted to the points labelled 1-9
    #[arg(long, value_name = "N", conflicts_with_all = ["at", "within", "segmented"])]
    label: Option<u32>,
    /// Learn the object shown by a point "x,y,z" of the cloud's frame: the connected points clear
    /// of the supporting plane (over twice its noise band) nearest to it (within 5 cm), cut from
    /// what touches it where the two meet in a concave crease
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point, allow_hyphen_values = true,
          conflicts_with_all = ["within", "segmented"])]
    at: Option<Point3<f64>>,
    /// Learn the points clear of the supporting plane (over twice its noise band) inside the box
    /// "x0,y0,z0,x1,y1,z1" (its opposite corners, in the cloud's frame)
    #[arg(id = "within", long = "box", value_name = "MIN,MAX", value_parser = parse_box,
          allow_hyphen_values = true, conflicts_with = "segmented")]
    within: Option<(Point3<f64>, Point3<f64>)>,
    /// The cloud holds the object only (already segmented): no plane removal, no clustering;
    /// with --up it stands on the plane across up at its lowest points
    #[arg(long)]
    segmented: bool,
    /// Sensor position "x,y,z" [default: the file's VIEWPOINT, else the origin]
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point)]
    viewpoint: Option<Point3<f64>>,
    /// Up direction "x,y,z" when there is no supporting plane in the cloud
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point)]
    up: Option<Point3<f64>>,
    /// Ignore points farther than this from the viewpoint (m)
    #[arg(long, value_name = "M")]
    max_range: Option<f64>,
    /// Do not add the visible points mirrored through the vertical axis
    #[arg(long)]
    no_mirror: bool,
    /// Free space just outside the points' silhouette seen from the viewpoint (segmented clouds
    /// from a camera with a known position)
    #[arg(long)]
    silhouette: bool,
    /// Residual minimised
    #[arg(long, value_enum, default_value = "radial")]
    cost: CostArg,
    /// Fit the distance to the nearest surface in the final stages, not the distance along the
    /// sensor's ray through each point (for a cloud whose viewpoint is not known)
    #[arg(long)]
    no_rays: bool,
    /// Shapes to choose from
    #[arg(long, value_enum, default_value = "auto")]
    shape: ShapeArg,
    /// Instead of a cloud: simulate the named shipped model alone on the table (fig3 rig, 2 mm
    /// noise), learn it and print the errors against the truth as JSON
    #[arg(long, value_name = "MODEL")]
    simulate: Option<String>,
    /// Noise seed of --simulate
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Sweeps of the one view --simulate takes, learned from their per-pixel median
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=256))]
    sweeps: u32,
    /// How --simulate sets the model on the table, "roll,pitch,yaw" in degrees [default: slender
    /// parts on their side at yaw 30, the others upright at yaw 25]
    #[arg(long, value_name = "R,P,Y", value_parser = parse_point, allow_hyphen_values = true)]
    rpy: Option<Point3<f64>>,
}

pub fn run(a: LearnArgs, models_dir: &Path) -> Result<()> {
    let mut params = learn_params(&a);
    if let Some(m) = &a.simulate {
        let rpy = a.rpy.map(|p| [p.x, p.y, p.z]);
        return simulate(m, rpy, a.seed, a.sweeps as usize, &params, models_dir);
    }
    let (false, Some(name)) = (a.cloud.is_empty(), a.name.as_ref()) else {
        bail!("give --cloud and --name");
    };
    if name.is_empty() || name.chars().any(|c| c.is_whitespace()) {
        bail!("--name {name:?}: give one word");
    }
    let out = output_path(&a, name, models_dir)?;
    let (cloud, input) = read_view(&a.cloud)?;
    params.viewpoint = a.viewpoint.or(cloud.viewpoint_position()).or(Some(Point3::origin()));
    let view = View::of(&cloud, a.max_range, params.viewpoint.unwrap());
    let (mut learned, selection) = select_and_learn(&a, &view, &mut params)?;
    if let Some(c) = &view.colours {
        learned.colour = sqscan::appearance::histogram(learned.segmentation.object.iter().map(|&i| c[i]));
    }
    if learned.parts.len() < a.parts as usize {
        eprintln!(
            "sqscan learn: only {} part(s): nothing else left that the first explains badly",
            learned.parts.len()
        );
    }
    let command: Vec<String> = std::env::args().collect();
    let prov = Provenance {
        input,
        selection,
        command: command.join(" "),
    };
    let text = learn::model_toml(name, &learned, &prov);
    // What we write must load.
    let model = Model::from_toml_str(&text, &out).context("the learned model does not load")?;
    write_atomic(&out, |w| {
        use std::io::Write;
        w.write_all(text.as_bytes())?;
        Ok(())
    })?;
    println!("{}", summary(&model, &out, &learned));
    Ok(())
}

/// The learner's options from the command line.
fn learn_params(a: &LearnArgs) -> LearnParams {
    LearnParams {
        mirror: !a.no_mirror,
        silhouette: a.silhouette,
        cost: match a.cost {
            CostArg::Radial => Cost::Radial,
            CostArg::Solina => Cost::Solina,
            CostArg::Normal => Cost::Normal,
        },
        along_rays: !a.no_rays,
        up: a.up.map(|p| p.coords),
        max_range: a.max_range,
        shape: match a.shape {
            ShapeArg::Auto => ShapeFamily::Auto,
            ShapeArg::General => ShapeFamily::General,
            ShapeArg::Revolution => ShapeFamily::Revolution,
        },
        ..LearnParams::default()
    }
}

/// Where the model goes: `--out`, or the models directory unless that belongs to the package;
/// an existing file only with `--force`.
fn output_path(a: &LearnArgs, name: &str, models_dir: &Path) -> Result<PathBuf> {
    let out = match &a.out {
        Some(o) => o.clone(),
        // The package's directory belongs to dpkg: an upgrade would remove a model written there.
        None if models_dir.starts_with("/usr") => bail!(
            "the models directory {} belongs to the package: give --out FILE, or --models-dir DIR \
             (e.g. /etc/sqscan/models, which the daemon then reads instead)",
            models_dir.display()
        ),
        None => models_dir.join(format!("{name}.toml")),
    };
    if out.exists() && !a.force {
        bail!("{} exists; give --force to replace it", out.display());
    }
    Ok(out)
}

/// The view to learn from (one cloud, or the per-pixel median of several sweeps of it) and how
/// the model file names it.
fn read_view(paths: &[PathBuf]) -> Result<(cloud::PointCloud, String)> {
    if let [one] = paths {
        return Ok((cloud::read_cloud(one)?, one.display().to_string()));
    }
    let sweeps = paths
        .iter()
        .map(|p| cloud::read_cloud(p).with_context(|| format!("sweep {}", p.display())))
        .collect::<Result<Vec<_>>>()?;
    let names: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
    Ok((
        cloud::PointCloud::median_of_sweeps(&sweeps).map_err(|e| anyhow::anyhow!("--cloud: {e}"))?,
        format!("the per-pixel median of {} sweeps: {}", paths.len(), names.join(", ")),
    ))
}

/// The view's finite points within range, with their labels where the cloud has them.
struct View {
    points: Vec<Point3<f64>>,
    /// One a point, where the cloud has a `label` field of uint.
    labels: Option<Vec<u32>>,
    /// One a point, where the cloud has colours.
    colours: Option<Vec<[u8; 3]>>,
}

impl View {
    fn of(cloud: &cloud::PointCloud, max_range: Option<f64>, viewpoint: Point3<f64>) -> View {
        let label_field = match cloud.field("label").map(|f| &f.data) {
            Some(FieldData::U32(l)) => Some(l),
            _ => None,
        };
        let all_colours = cloud.colours();
        let mut points: Vec<Point3<f64>> = Vec::with_capacity(cloud.len());
        let mut labels: Vec<u32> = Vec::new();
        let mut colours: Vec<[u8; 3]> = Vec::new();
        for (i, p) in cloud.points.iter().enumerate() {
            if p.iter().all(|v| v.is_finite()) {
                let q = Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
                if let Some(r) = max_range
                    && (q - viewpoint).norm() > r
                {
                    continue;
                }
                points.push(q);
                if let Some(l) = label_field {
                    labels.push(l[i]);
                }
                if let Some(c) = &all_colours {
                    colours.push(c[i]);
                }
            }
        }
        View {
            points,
            labels: label_field.map(|_| labels),
            colours: all_colours.map(|_| colours),
        }
    }
}

/// The object's points as the command line selects them (`--label`, `--at`, `--box`,
/// `--segmented`, or the largest cluster on the plane), learned; and how the model file names
/// the selection.
fn select_and_learn(a: &LearnArgs, view: &View, params: &mut LearnParams) -> Result<(learn::Learned, String)> {
    let points = &view.points;
    let parts = a.parts as usize;
    if let Some(n) = a.label {
        let Some(labels) = &view.labels else {
            bail!("--label: {} has no uint label field", a.cloud[0].display());
        };
        let object: Vec<usize> = (0..points.len())
            .filter(|&i| labels[i] >= 20 && labels[i] / 10 == n)
            .collect();
        let table: Vec<Point3<f64>> = (0..points.len())
            .filter(|&i| (1..=9).contains(&labels[i]))
            .map(|i| points[i])
            .collect();
        let plane = remove_dominant_plane(&table, false, params.viewpoint).plane;
        let selection = format!(
            "the {} points labelled object {n} (label / 10 == {n}); plane from the {} points labelled 1-9",
            object.len(),
            table.len()
        );
        return Ok((
            learn::learn_parts(points, Segmentation { plane, object }, params, parts)?,
            selection,
        ));
    }
    if let Some(at) = &a.at {
        let segmentation = learn::segment_at(points, params, at)
            .map_err(|e| anyhow::anyhow!("--at {},{},{}: {e}", at.x, at.y, at.z))?;
        let selection = format!(
            "the {} points of the object nearest to ({}, {}, {}) off the supporting plane",
            segmentation.object.len(),
            at.x,
            at.y,
            at.z
        );
        return Ok((learn::learn_parts(points, segmentation, params, parts)?, selection));
    }
    if let Some((min, max)) = &a.within {
        let segmentation = learn::segment_box(points, params, min, max);
        if segmentation.object.len() < 10 {
            bail!(
                "--box: {} points off the supporting plane inside it; give a box around the object",
                segmentation.object.len()
            );
        }
        let selection = format!(
            "the {} points off the supporting plane in the box ({}, {}, {}) - ({}, {}, {})",
            segmentation.object.len(),
            min.x,
            min.y,
            min.z,
            max.x,
            max.y,
            max.z
        );
        return Ok((learn::learn_parts(points, segmentation, params, parts)?, selection));
    }
    if a.segmented {
        params.segment = false;
        let mut selection = format!("all {} finite points (segmented input)", points.len());
        let plane = learn::support_below(points, params.up.as_ref());
        if let Some(pl) = &plane {
            selection.push_str(&format!(
                ", standing on the plane across --up at {:.4} m (its lowest 1 %)",
                -pl.d
            ));
        }
        let segmentation = Segmentation {
            plane,
            object: (0..points.len()).collect(),
        };
        return Ok((learn::learn_parts(points, segmentation, params, parts)?, selection));
    }
    let segmentation = learn::segment(points, params);
    let selection = format!("{} finite points", points.len());
    // Segmenting takes the largest plane for the table and keeps one cluster standing on it: a
    // cloud of the object alone loses its largest face to that and leaves a sliver.
    let kept = segmentation.object.len();
    learn::learn_parts(points, segmentation, params, parts)
        .map(|l| (l, selection))
        .map_err(|e| match e {
            learn::LearnError::TooFewPoints(_) if kept * 4 < points.len() => anyhow::anyhow!(
                "{e}: segmentation kept {kept} of the cloud's {} points as the object on its support; \
                 if the cloud holds the object alone, give --segmented",
                points.len()
            ),
            e => e.into(),
        })
}

/// What `sqscan learn` prints: the model written, the plane, and each part's shape, pose and
/// fit, with what the data shows of each size.
fn summary(model: &Model, out: &Path, learned: &learn::Learned) -> serde_json::Value {
    let parts: Vec<serde_json::Value> = learned
        .parts
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let s = &r.placed.shape;
            let sizes = learned.sizes.get(i);
            json!({
                "a": s.a, "e1": s.e1, "e2": s.e2, "kx": s.kx, "ky": s.ky, "open": r.open,
                "pose": sqscan::pose::PoseJson::from(&r.placed.pose),
                // What the data shows of each size: a seen extent well below 2 a is a size the
                // fit inferred (a hidden back or foot).
                "seen_extent_m": sizes.map(|z| z.map(|z| z.seen)),
                // The shape's extents (taper included) and the largest the scene allows each to
                // grow to (null: nothing in view stops it within learn::REACH).
                "extent_m": sizes.map(|z| z.map(|z| z.size)),
                "allowed_extent_m": sizes.map(|z| z.map(|z| z.at_most)),
                "rms_m": r.rms, "median_abs_m": r.median_abs, "inlier_share": r.inlier_share,
                "fitted_points": r.fitted_points, "start": r.start,
            })
        })
        .collect();
    json!({
        "model": model.name,
        "out": out.display().to_string(),
        "object_points": learned.object_points,
        "plane": learned.segmentation.plane.map(|p| p.coefficients()),
        "support": learned.support.map(|r| r.plane.coefficients()),
        "model_pose": sqscan::pose::PoseJson::from(&learn::model_pose(learned)),
        // Whether the model keeps its object's colours (the cloud had them).
        "colour": model.colour.is_some(),
        "parts": parts,
    })
}

/// "x0,y0,z0,x1,y1,z1": two opposite corners of a box, as (min, max).
fn parse_box(s: &str) -> Result<(Point3<f64>, Point3<f64>), String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|c| c.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("{s:?}: give six numbers x0,y0,z0,x1,y1,z1"))?;
    let [x0, y0, z0, x1, y1, z1] = v.as_slice() else {
        return Err(format!("{s:?}: give six numbers x0,y0,z0,x1,y1,z1"));
    };
    if !v.iter().all(|c| c.is_finite()) {
        return Err(format!("{s:?}: not finite"));
    }
    let (a, b) = (Point3::new(*x0, *y0, *z0), Point3::new(*x1, *y1, *z1));
    let (min, max) = (a.inf(&b), a.sup(&b));
    if (0..3).any(|k| max[k] - min[k] <= 0.0) {
        return Err(format!("{s:?}: the box is empty along one axis"));
    }
    Ok((min, max))
}

fn simulate(
    model_name: &str,
    rpy_deg: Option<[f64; 3]>,
    seed: u64,
    sweeps: usize,
    params: &LearnParams,
    models_dir: &Path,
) -> Result<()> {
    let model = Model::load(model_name, models_dir)?;
    if model.parts.len() != 1 {
        bail!(
            "--simulate: {} has {} parts; give a single-part model",
            model.name,
            model.parts.len()
        );
    }
    let t = learn::simulated::learn_simulated(&model, rpy_deg, seed, sweeps, params)?;
    let r = &t.learned.parts[0];
    let sq = |s: &sqscan::geometry::Superquadric| json!({"a": s.a, "e1": s.e1, "e2": s.e2, "kx": s.kx, "ky": s.ky});
    println!(
        "{}",
        json!({
            "model": model.name,
            "seed": seed,
            "sweeps": sweeps,
            "truth": sq(&t.truth.shape),
            "learned": sq(&r.placed.shape),
            "open": r.open,
            "errors": t.errors,
            "max_size_error_m": t.errors.max_size_error(),
            "max_exponent_error": t.errors.max_exponent_error(),
            "within_tolerance": t.errors.max_size_error() < 0.005 && t.errors.max_exponent_error() < 0.1,
            "scan_points": t.points,
            "object_points": t.learned.object_points,
            "rms_m": r.rms,
            "seconds": t.seconds,
        })
    );
    Ok(())
}
