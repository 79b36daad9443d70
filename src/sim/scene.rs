//! Scene files (`scenes/*.toml`, format in `scenes/README.md`): a table, objects placed by model
//! and pose, free superquadric parts for clutter, and the scanning rig.

use crate::calibration::{self, Calibration};
use crate::geometry::{PlacedSuperquadric, Superquadric};
use crate::model::{Model, resolve};
use crate::pose::PoseSpec;
use crate::spec::{SpecError, read_toml};
use nalgebra::{Isometry3, Translation3};
use serde::Deserialize;
use std::path::{Path, PathBuf};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    #[serde(default)]
    description: String,
    table: Option<TableFile>,
    #[serde(default)]
    floor: bool,
    rig: RigFile,
    #[serde(default)]
    object: Vec<ObjectFile>,
    #[serde(default)]
    part: Vec<FreePartFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TableFile {
    height: f64,
    center: [f64; 2],
    size: [f64; 2],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectFile {
    name: Option<String>,
    model: String,
    pose: PoseSpec,
    #[serde(default = "yes")]
    on_table: bool,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FreePartFile {
    name: String,
    a: [f64; 3],
    e1: f64,
    e2: f64,
    #[serde(default)]
    kx: f64,
    #[serde(default)]
    ky: f64,
    pose: PoseSpec,
    #[serde(default = "yes")]
    on_table: bool,
}

fn yes() -> bool {
    true
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RigFile {
    ptu: PoseSpec,
    #[serde(default)]
    sensor_mount: PoseSpec,
    #[serde(default)]
    pan: f64,
    #[serde(default = "default_profiles")]
    profiles: usize,
    tilt_start: f64,
    tilt_end: f64,
    tilt_speed: f64,
    #[serde(default = "default_columns")]
    columns: usize,
    fov_deg: f64,
    baseline: f64,
    range_min: f64,
    range_max: f64,
    #[serde(default = "default_noise")]
    noise_sigma_at_1m: f64,
    #[serde(default)]
    dropout: f64,
    #[serde(default = "default_incidence")]
    max_incidence_deg: f64,
    #[serde(default = "default_fraction_bits")]
    fraction_bits: u8,
}

fn default_profiles() -> usize {
    150
}
fn default_columns() -> usize {
    1536
}
fn default_noise() -> f64 {
    0.002
}
fn default_incidence() -> f64 {
    80.0
}
fn default_fraction_bits() -> u8 {
    4
}

/// The table top: a horizontal rectangle in the base frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// Height of the top above the base frame origin (m).
    pub height: f64,
    pub center: [f64; 2],
    pub size: [f64; 2],
}

impl Table {
    pub fn contains_xy(&self, x: f64, y: f64) -> bool {
        (x - self.center[0]).abs() <= 0.5 * self.size[0] && (y - self.center[1]).abs() <= 0.5 * self.size[1]
    }
}

/// An object in a scene: a model at a pose in the base frame.
#[derive(Debug, Clone)]
pub struct SceneObject {
    pub name: String,
    pub model: Model,
    pub pose: Isometry3<f64>,
}

/// A free superquadric (clutter that is no model).
#[derive(Debug, Clone)]
pub struct FreePart {
    pub name: String,
    pub placed: PlacedSuperquadric,
}

/// The scanning rig: the PTU on the base, the sensor on the PTU and the triangulation sensor.
///
/// Frames: `base` (REP-103), the PTU frame at the pan/tilt axes' intersection (`ptu` pose in the
/// base frame), pan about the PTU's z, then tilt about the panned y (positive tilt pitches the
/// sensor down), then the sensor mount. In the sensor frame the laser leaves the origin and its
/// fan spans the x-y plane (x forward along the central ray, y left); the camera sits `baseline`
/// metres above it on +z and looks along +x, parallel to the laser plane, so each sensor column
/// sees along one fixed direction of the fan and the row where the line appears encodes depth.
#[derive(Debug, Clone, PartialEq)]
pub struct Rig {
    pub ptu_in_base: Isometry3<f64>,
    pub sensor_in_tilt: Isometry3<f64>,
    pub pan: f64,
    pub profiles: usize,
    pub tilt_start: f64,
    pub tilt_end: f64,
    pub tilt_speed: f64,
    pub sensor: super::SensorModel,
}

impl Rig {
    /// The rig's exact calibration: calibrated raw rows give the simulator's own points
    /// (`calibration/sim_rig.toml` is this, written out).
    pub fn calibration(&self) -> Calibration {
        Calibration::from_homography(
            self.sensor.columns,
            self.sensor.fraction_bits,
            self.sensor.homography(),
            self.sensor_in_tilt,
            self.ptu_in_base,
        )
    }

    /// The sensor frame in the base frame at the given joint angles.
    pub fn sensor_in_base(&self, pan: f64, tilt: f64) -> Isometry3<f64> {
        self.ptu_in_base * calibration::pan_link(pan) * calibration::tilt_link(tilt) * self.sensor_in_tilt
    }

    /// Duration of one sweep (s).
    pub fn sweep_duration(&self) -> f64 {
        (self.tilt_end - self.tilt_start).abs() / self.tilt_speed
    }

    /// Time of profile `i` from the start of the sweep (s) and the tilt then (rad): the tilt moves
    /// at constant speed and profiles are exposed at a constant rate from end to end.
    pub fn profile_time_and_tilt(&self, i: usize) -> (f64, f64) {
        let f = if self.profiles > 1 {
            i as f64 / (self.profiles - 1) as f64
        } else {
            0.0
        };
        (
            f * self.sweep_duration(),
            self.tilt_start + f * (self.tilt_end - self.tilt_start),
        )
    }
}

/// A validated scene.
#[derive(Debug, Clone)]
pub struct Scene {
    pub description: String,
    pub table: Option<Table>,
    /// A floor plane at z = 0 of the base frame.
    pub floor: bool,
    pub objects: Vec<SceneObject>,
    pub free_parts: Vec<FreePart>,
    pub rig: Rig,
    pub source: PathBuf,
}

impl Scene {
    /// Load a scene file; models named in it are looked up in `models_dir`.
    pub fn from_file(path: &Path, models_dir: &Path) -> Result<Scene, SpecError> {
        let file: SceneFile = read_toml(path)?;
        Self::validate(file, path, models_dir)
    }

    /// Parse scene TOML text (`path` names it in messages).
    pub fn from_toml_str(text: &str, path: &Path, models_dir: &Path) -> Result<Scene, SpecError> {
        let file: SceneFile = crate::spec::parse_toml(text, path)?;
        Self::validate(file, path, models_dir)
    }

    fn validate(file: SceneFile, path: &Path, models_dir: &Path) -> Result<Scene, SpecError> {
        let bad = |field: String, msg: String| SpecError::invalid(path, field, msg);
        let table = match file.table {
            Some(t) => {
                if !t.height.is_finite() || t.center.iter().any(|v| !v.is_finite()) {
                    return Err(bad("table".into(), "height and center must be finite".into()));
                }
                if !(t.size.iter().all(|s| s.is_finite() && *s > 0.0)) {
                    return Err(bad(
                        "table.size".into(),
                        format!("{:?} must be two positive lengths (m)", t.size),
                    ));
                }
                Some(Table {
                    height: t.height,
                    center: t.center,
                    size: t.size,
                })
            }
            None => None,
        };
        let rig = validate_rig(&file.rig, path)?;
        let rest_on_table = |field: String, pose: Isometry3<f64>, lowest: f64| -> Result<Isometry3<f64>, SpecError> {
            let Some(t) = &table else {
                return Err(bad(field, "on_table = true but the scene has no [table]".into()));
            };
            // The given z is the gap between the object's lowest point and the table top.
            let z = t.height + pose.translation.vector.z - lowest;
            let mut p = pose;
            p.translation = Translation3::new(p.translation.vector.x, p.translation.vector.y, z);
            Ok(p)
        };
        let mut objects = Vec::new();
        for (i, o) in file.object.into_iter().enumerate() {
            let field = |f: &str| format!("object[{i}].{f}");
            let model_path = resolve(&o.model, models_dir);
            // A model path relative to the scene file is looked up next to it first.
            let model_path = if model_path.is_relative() && !model_path.exists() {
                path.parent()
                    .map(|d| d.join(&model_path))
                    .filter(|p| p.exists())
                    .unwrap_or(model_path)
            } else {
                model_path
            };
            let model = Model::from_file(&model_path).map_err(|e| bad(field("model"), e.with_causes()))?;
            let mut pose = o.pose.to_isometry().map_err(|m| bad(field("pose"), m))?;
            if o.on_table {
                let lowest = model
                    .placed_parts(&Isometry3::from_parts(Translation3::identity(), pose.rotation))
                    .iter()
                    .map(|p| p.lowest_z())
                    .fold(f64::INFINITY, f64::min);
                pose = rest_on_table(field("on_table"), pose, lowest)?;
            }
            let name = o.name.unwrap_or_else(|| model.name.clone());
            if objects.iter().any(|x: &SceneObject| x.name == name) {
                return Err(bad(field("name"), format!("{name:?} is used twice; name the objects")));
            }
            objects.push(SceneObject { name, model, pose });
        }
        let mut free_parts = Vec::new();
        for (i, p) in file.part.into_iter().enumerate() {
            let field = |f: &str| format!("part[{i}] ({}).{f}", p.name);
            let shape =
                Superquadric::new(p.a, p.e1, p.e2, p.kx, p.ky).map_err(|e| bad(field("shape"), e.to_string()))?;
            let mut pose = p.pose.to_isometry().map_err(|m| bad(field("pose"), m))?;
            if p.on_table {
                let rotated =
                    PlacedSuperquadric::new(shape, Isometry3::from_parts(Translation3::identity(), pose.rotation));
                let lowest = rotated.lowest_z();
                pose = rest_on_table(field("on_table"), pose, lowest)?;
            }
            free_parts.push(FreePart {
                name: p.name,
                placed: PlacedSuperquadric::new(shape, pose),
            });
        }
        Ok(Scene {
            description: file.description,
            table,
            floor: file.floor,
            objects,
            free_parts,
            rig,
            source: path.to_owned(),
        })
    }

    /// Every superquadric in the scene in the base frame, with its point label
    /// (`20 + 10 k + part` for part `part` of object `k`, continuing for free parts), following
    /// the mOSD convention that `label / 10 - 2` is the object index.
    /// Whether each part is open (see [`crate::model::Part::open`]) comes third.
    pub fn labelled_parts(&self) -> Vec<(u32, PlacedSuperquadric, bool)> {
        let mut out = Vec::new();
        for (k, o) in self.objects.iter().enumerate() {
            for (j, p) in o.model.placed_parts(&o.pose).into_iter().enumerate() {
                out.push((20 + 10 * k as u32 + j as u32, p, o.model.parts[j].open));
            }
        }
        let base = 20 + 10 * self.objects.len() as u32;
        for (j, p) in self.free_parts.iter().enumerate() {
            out.push((base + 10 * j as u32, p.placed, false));
        }
        out
    }

    /// The scene without the named object (for "is it absent?" trials).
    pub fn without_object(&self, name: &str) -> Scene {
        let mut s = self.clone();
        s.objects.retain(|o| o.name != name && o.model.name != name);
        s
    }
}

/// Pixels (profiles x columns) a simulated sweep may have.
pub const MAX_SWEEP_PIXELS: usize = 4 << 20;

fn validate_rig(r: &RigFile, path: &Path) -> Result<Rig, SpecError> {
    let bad = |field: &str, msg: String| SpecError::invalid(path, format!("rig.{field}"), msg);
    let ptu_in_base = r.ptu.to_isometry().map_err(|m| bad("ptu", m))?;
    let sensor_in_tilt = r.sensor_mount.to_isometry().map_err(|m| bad("sensor_mount", m))?;
    if !(1..=100_000).contains(&r.profiles) {
        return Err(bad("profiles", format!("{} profiles: give 1 to 100000", r.profiles)));
    }
    // A simulated sweep holds a few tens of bytes a pixel (point, range, stamps, the range
    // image): this many pixels is about 200 MB, 18 times a real 150 x 1536 sweep.
    if r.profiles.saturating_mul(r.columns) > MAX_SWEEP_PIXELS {
        return Err(bad(
            "profiles",
            format!(
                "{} profiles x {} columns = {} pixels: at most {MAX_SWEEP_PIXELS} a sweep",
                r.profiles,
                r.columns,
                r.profiles.saturating_mul(r.columns)
            ),
        ));
    }
    for (f, v) in [("pan", r.pan), ("tilt_start", r.tilt_start), ("tilt_end", r.tilt_end)] {
        if !(v.is_finite() && v.abs() <= std::f64::consts::PI) {
            return Err(bad(f, format!("{v} rad is not an angle in [-pi, pi]")));
        }
    }
    if !(r.tilt_speed.is_finite() && r.tilt_speed > 0.0) {
        return Err(bad("tilt_speed", format!("{} rad/s must be > 0", r.tilt_speed)));
    }
    let sensor = super::SensorModel::new(
        r.columns,
        r.fov_deg.to_radians(),
        r.baseline,
        r.range_min,
        r.range_max,
        r.noise_sigma_at_1m,
        r.dropout,
        r.max_incidence_deg.to_radians(),
        r.fraction_bits,
    )
    .map_err(|(f, m)| bad(f, m))?;
    Ok(Rig {
        ptu_in_base,
        sensor_in_tilt,
        pan: r.pan,
        profiles: r.profiles,
        tilt_start: r.tilt_start,
        tilt_end: r.tilt_end,
        tilt_speed: r.tilt_speed,
        sensor,
    })
}
