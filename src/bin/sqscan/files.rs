//! Offline commands on files: simulate, show-model, info.

use crate::write_atomic;
use anyhow::{Context, Result, bail};
use clap::Args;
use serde_json::json;
use sqscan::cloud::{self, Field, FieldData, PcdData, PlyFormat, PointCloud};
use sqscan::model::Model;
use sqscan::pose::PoseJson;
use sqscan::sim::{self, Scene};
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct SimulateArgs {
    #[command(flatten)]
    pub models: crate::ModelsDirArg,
    /// Scene file (scenes/*.toml)
    scene: PathBuf,
    /// Output directory (created if missing)
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Seed of the sensor noise and dropout
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Override the scene's sensor columns (e.g. 1536 for a full-resolution sensor)
    #[arg(long)]
    columns: Option<usize>,
    /// Print one JSON object (the sweep's size and the files written) instead of a line of text
    #[arg(long)]
    json: bool,
}

pub fn simulate(a: SimulateArgs, models_dir: &Path) -> Result<()> {
    let mut scene = Scene::from_file(&a.scene, models_dir)?;
    if let Some(c) = a.columns {
        let s = &scene.rig.sensor;
        scene.rig.sensor = sim::SensorModel::new(
            c,
            2.0 * (s.cx / s.focal_px).atan(),
            s.baseline,
            s.range_min,
            s.range_max,
            s.noise_sigma_at_1m,
            s.dropout,
            s.max_incidence,
            s.fraction_bits,
        )
        .map_err(|(f, m)| anyhow::anyhow!("--columns: {f}: {m}"))?;
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?;
    let started = std::time::Instant::now();
    let sweep = sim::simulate(&scene, a.seed);
    let elapsed = started.elapsed();

    write_atomic(&a.out.join("cloud.ply"), |w| {
        Ok(cloud::write_ply(w, &sweep.cloud, PlyFormat::BinaryLittleEndian)?)
    })?;
    write_atomic(&a.out.join("cloud.pcd"), |w| {
        Ok(cloud::write_pcd(w, &sweep.cloud, PcdData::BinaryCompressed)?)
    })?;
    let grey = sim::range_image_grey(&sweep);
    write_atomic(&a.out.join("range.png"), |w| {
        let mut enc = png::Encoder::new(w, sweep.columns as u32, sweep.profiles as u32);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header()?;
        writer.write_image_data(&grey)?;
        writer.finish()?;
        Ok(())
    })?;
    let labels = match sweep.cloud.fields.iter().find(|f| f.name == "label").map(|f| &f.data) {
        Some(FieldData::U32(l)) => l.as_slice(),
        _ => bail!("internal: the simulated cloud has no label field"),
    };
    let objects: Vec<_> = scene
        .objects
        .iter()
        .enumerate()
        .map(|(k, o)| {
            let points = labels
                .iter()
                .filter(|&&l| l >= 20 && (l / 10 - 2) as usize == k)
                .count();
            json!({"name": o.name, "model": o.model.name, "pose": PoseJson::from(&o.pose), "points": points})
        })
        .collect();
    let truth = json!({
        "scene": a.scene.display().to_string(),
        "seed": a.seed,
        "frame": "base",
        "objects": objects,
        "points": sweep.finite_points(),
    });
    write_atomic(&a.out.join("truth.json"), |w| {
        serde_json::to_writer_pretty(&mut *w, &truth)?;
        Ok(())
    })?;
    if a.json {
        let files: Vec<String> = ["cloud.ply", "cloud.pcd", "range.png", "truth.json"]
            .iter()
            .map(|f| a.out.join(f).display().to_string())
            .collect();
        println!(
            "{}",
            json!({"scene": a.scene.display().to_string(), "seed": a.seed, "profiles": sweep.profiles,
                   "columns": sweep.columns, "points": sweep.finite_points(),
                   "simulate_ms": elapsed.as_secs_f64() * 1e3, "files": files})
        );
        return Ok(());
    }
    println!(
        "{}: {} profiles x {} columns, {} points, simulated in {:.1} ms; wrote cloud.ply, cloud.pcd, range.png, truth.json to {}",
        a.scene.display(),
        sweep.profiles,
        sweep.columns,
        sweep.finite_points(),
        elapsed.as_secs_f64() * 1e3,
        a.out.display()
    );
    Ok(())
}

#[derive(Args)]
pub struct ShowModelArgs {
    #[command(flatten)]
    pub models: crate::ModelsDirArg,
    /// Model name (looked up in the models directory) or model file
    model: String,
    /// Output PLY file
    #[arg(long, value_name = "FILE.ply")]
    out: PathBuf,
    /// Distance between surface samples (m)
    #[arg(long, default_value_t = 0.002)]
    spacing: f64,
    /// Print one JSON object (the model, its parts and the points written) instead of a line of text
    #[arg(long)]
    json: bool,
}

/// One colour a part: red, green, blue.
const PART_COLOURS: [[u8; 3]; 3] = [[230, 60, 50], [60, 190, 80], [60, 110, 230]];

pub fn show_model(a: ShowModelArgs, models_dir: &Path) -> Result<()> {
    if !(a.spacing.is_finite() && a.spacing >= 1e-4) {
        bail!("--spacing {}: give a sample distance of at least 0.0001 m", a.spacing);
    }
    let model = Model::load(&a.model, models_dir)?;
    let mut points = Vec::new();
    let mut rgb: [Vec<u8>; 3] = Default::default();
    for (i, part) in model.placed_parts(&nalgebra::Isometry3::identity()).iter().enumerate() {
        let samples = part.sample_surface(a.spacing);
        if samples.len() > 20_000_000 {
            bail!(
                "--spacing {} gives over 20 million points; choose a larger spacing",
                a.spacing
            );
        }
        for p in samples {
            points.push([p.x as f32, p.y as f32, p.z as f32]);
            for c in 0..3 {
                rgb[c].push(PART_COLOURS[i % 3][c]);
            }
        }
    }
    let n = points.len();
    let [r, g, b] = rgb;
    let mut cloud = PointCloud::from_points(points);
    for (name, data) in [("red", r), ("green", g), ("blue", b)] {
        cloud.fields.push(Field {
            name: name.into(),
            count: 1,
            data: FieldData::U8(data),
        });
    }
    write_atomic(&a.out, |w| {
        Ok(cloud::write_ply(w, &cloud, PlyFormat::BinaryLittleEndian)?)
    })?;
    if a.json {
        println!(
            "{}",
            json!({"model": model.name, "parts": model.parts.iter().map(|p| p.name.clone()).collect::<Vec<_>>(),
                   "points": n, "spacing_m": a.spacing, "out": a.out.display().to_string()})
        );
        return Ok(());
    }
    println!(
        "{}: {} parts, {n} points at {} m spacing -> {}",
        model.name,
        model.parts.len(),
        a.spacing,
        a.out.display()
    );
    Ok(())
}

#[derive(Args)]
pub struct InfoArgs {
    /// Point cloud file (.ply, .pcd, or text with x y z per line)
    file: PathBuf,
    /// Print one JSON object
    #[arg(long)]
    json: bool,
}

pub fn info(a: InfoArgs) -> Result<()> {
    let c = cloud::read_cloud(&a.file)?;
    let finite = c.finite_count();
    let bbox = c.bbox();
    if a.json {
        let (lo, hi) = match bbox {
            Some((lo, hi)) => (json!(lo), json!(hi)),
            None => (json!(null), json!(null)),
        };
        let fields: Vec<_> = c.fields.iter().map(|f| f.name.clone()).collect();
        println!(
            "{}",
            json!({"points": c.len(), "finite": finite, "width": c.width, "height": c.height,
                   "bbox_min": lo, "bbox_max": hi, "fields": fields})
        );
        return Ok(());
    }
    println!("{}", a.file.display());
    println!("  points     {}", c.len());
    println!("  finite     {finite}");
    if c.is_organized() {
        println!("  organized  {} x {}", c.width, c.height);
    } else {
        println!("  organized  no");
    }
    if !c.fields.is_empty() {
        println!(
            "  fields     x y z {}",
            c.fields.iter().map(|f| f.name.as_str()).collect::<Vec<_>>().join(" ")
        );
    }
    match bbox {
        Some((lo, hi)) => {
            println!("  bbox min   {:.4} {:.4} {:.4}", lo[0], lo[1], lo[2]);
            println!("  bbox max   {:.4} {:.4} {:.4}", hi[0], hi[1], hi[2]);
        }
        None => println!("  bbox       none (no finite point)"),
    }
    Ok(())
}
