//! Object models: one to three tapered superquadric parts, loaded from `models/*.toml`.
//!
//! The format is documented in `models/README.md`. A compound object gives every part's pose in
//! the object frame (what the simulator renders and what "the object's pose" means) and the
//! connectivity the detector votes on (paper Fig. 2: the angle between the part z axes and the
//! distance between the part centres). The two are redundant on purpose: loading checks that they
//! agree, which catches a mistyped model before it silently detects the wrong thing.

use crate::geometry::{PlacedSuperquadric, Superquadric};
use crate::pose::PoseSpec;
use crate::spec::{SpecError, read_toml};
use nalgebra::{Isometry3, Vector3};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Connectivity given in a file must match the part poses to this much.
const ANGLE_TOLERANCE_RAD: f64 = 1.0 * std::f64::consts::PI / 180.0;
const DISTANCE_TOLERANCE_M: f64 = 0.001;

/// A model file as written (`models/README.md`): what [`Model::from_file`] reads and validates,
/// and what `sqscan learn` writes.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ModelFile {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub held: bool,
    #[serde(default)]
    pub part: Vec<PartFile>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub connection: Vec<ConnectionFile>,
    /// The colours of the object's points, as [`crate::appearance::histogram`] gives them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub colour: Option<Vec<f64>>,
}

/// One `[[part]]` table.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PartFile {
    pub name: String,
    pub a: [f64; 3],
    pub e1: f64,
    pub e2: f64,
    #[serde(default)]
    pub kx: f64,
    #[serde(default)]
    pub ky: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub m: Option<u32>,
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub open: bool,
    #[serde(default, skip_serializing_if = "PoseSpec::is_identity")]
    pub pose: PoseSpec,
}

/// One `[[connection]]` table.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ConnectionFile {
    pub parts: [String; 2],
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angle_rad: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angle_deg: Option<f64>,
    pub distance: f64,
}

impl ModelFile {
    /// The file's text: `comments` as `#` lines, then the tables.
    pub fn to_toml(&self, comments: &[String]) -> Result<String, toml::ser::Error> {
        let mut text: String = comments
            .iter()
            .flat_map(|c| c.lines())
            .map(|l| format!("# {l}\n"))
            .collect();
        text.push_str(&toml::to_string(self)?);
        Ok(text)
    }
}

/// One superquadric part of a model.
#[derive(Debug, Clone, PartialEq)]
pub struct Part {
    pub name: String,
    pub shape: Superquadric,
    /// The part's pose in the object frame.
    pub pose_in_object: Isometry3<f64>,
    /// Hypotheses to search for this part (paper's m); `None` lets the detector derive it from
    /// the ratio of part size to scene extent.
    pub hypotheses: Option<u32>,
    /// An open container (a mug, a bowl): its top (+z) is an opening, not a surface. A sensor
    /// looking in sees the inside, which a solid model would count as interior points, and sees
    /// nothing where a lid would be.
    pub open: bool,
}

/// The lid of an open part: where the outward normal in the part frame has a z component above
/// this. The superquadric's top cap; its side wall stays a surface.
pub const LID_NORMAL_Z: f64 = 0.7;

impl Part {
    /// Whether a local surface normal (any length) lies on the lid of an open part.
    pub fn on_lid(&self, local_normal: &Vector3<f64>) -> bool {
        self.open && is_lid(local_normal)
    }
}

/// Whether a local surface normal (any length) points into the lid region.
pub fn is_lid(local_normal: &Vector3<f64>) -> bool {
    let n = local_normal.norm();
    n > 0.0 && local_normal.z / n > LID_NORMAL_Z
}

/// The relation of two parts (paper eq. 6, 7).
#[derive(Debug, Clone, PartialEq)]
pub struct Connection {
    /// Indices into [`Model::parts`].
    pub parts: [usize; 2],
    /// Angle between the part z axes (rad).
    pub angle: f64,
    /// Distance between the part centres (m).
    pub distance: f64,
}

/// A validated object model.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    pub name: String,
    pub description: String,
    pub parts: Vec<Part>,
    pub connections: Vec<Connection>,
    /// The model is of a part of a larger object, which may hold it off whatever it lies on
    /// (the paper's mallet shaft searched alone, held above the table by the head): it need not
    /// rest on anything. A whole object does not float.
    pub held: bool,
    /// The colours of the object's points where it was shown ([`crate::appearance`]): a
    /// chromaticity histogram, `BINS * BINS` shares summing to 1. `None`: its colours are not
    /// known, and nothing is checked.
    pub colour: Option<Vec<f64>>,
    /// Where the model was read from (for messages and provenance).
    pub source: PathBuf,
}

/// The angle between two z axes, folded to `[0, pi/2]` when either axis has no sign (an
/// untapered part is symmetric under `z -> -z`).
pub fn axis_angle(za: &Vector3<f64>, zb: &Vector3<f64>, signed: bool) -> f64 {
    let c = (za.dot(zb) / (za.norm() * zb.norm())).clamp(-1.0, 1.0);
    let angle = c.acos();
    if signed {
        angle
    } else {
        angle.min(std::f64::consts::PI - angle)
    }
}

impl Model {
    /// Load a model given by name (looked up as `NAME.toml` in `models_dir`) or by file path.
    pub fn load(name_or_path: &str, models_dir: &Path) -> Result<Model, SpecError> {
        Self::from_file(&resolve(name_or_path, models_dir))
    }

    /// Load and validate a model file.
    pub fn from_file(path: &Path) -> Result<Model, SpecError> {
        let file: ModelFile = read_toml(path)?;
        Self::validate(file, path)
    }

    /// Parse and validate model TOML text (`path` names it in messages).
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Model, SpecError> {
        let file: ModelFile = crate::spec::parse_toml(text, path)?;
        Self::validate(file, path)
    }

    fn validate(file: ModelFile, path: &Path) -> Result<Model, SpecError> {
        let bad = |field: String, msg: String| SpecError::invalid(path, field, msg);
        let name = match file.name {
            Some(n) => n,
            None => path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
        };
        if name.is_empty() || name.chars().any(|c| c.is_whitespace()) {
            return Err(bad("name".into(), format!("{name:?} must be a non-empty word")));
        }
        if file.part.is_empty() || file.part.len() > 3 {
            return Err(bad(
                "part".into(),
                format!("{} parts given; a model has 1 to 3", file.part.len()),
            ));
        }
        let mut parts: Vec<Part> = Vec::with_capacity(file.part.len());
        for (i, p) in file.part.into_iter().enumerate() {
            let part = Self::part_from_file(i, p, &parts, path)?;
            parts.push(part);
        }
        let mut connections = Vec::new();
        for (i, c) in file.connection.into_iter().enumerate() {
            let connection = Self::connection_from_file(i, c, &parts, &connections, path)?;
            connections.push(connection);
        }
        Self::check_tree(&parts, &connections, path)?;
        if let Some(c) = &file.colour {
            Self::check_colour(c).map_err(|m| bad("colour".into(), m))?;
        }
        Ok(Model {
            name,
            description: file.description,
            parts,
            connections,
            held: file.held,
            colour: file.colour,
            source: path.to_owned(),
        })
    }

    /// A colour histogram: its length, and shares that are shares.
    fn check_colour(c: &[f64]) -> Result<(), String> {
        let bins = crate::appearance::BINS * crate::appearance::BINS;
        if c.len() != bins {
            return Err(format!("{} values given; the histogram has {bins}", c.len()));
        }
        if let Some(i) = c.iter().position(|v| !(v.is_finite() && (0.0..=1.0).contains(v))) {
            return Err(format!("value {i} is {}; give shares from 0 to 1", c[i]));
        }
        let sum: f64 = c.iter().sum();
        if (sum - 1.0).abs() > 0.01 {
            return Err(format!("the shares sum to {sum}, not 1"));
        }
        Ok(())
    }

    /// One `[[part]]` table, checked against the parts before it.
    fn part_from_file(i: usize, p: PartFile, before: &[Part], path: &Path) -> Result<Part, SpecError> {
        let bad = |field: String, msg: String| SpecError::invalid(path, field, msg);
        let field = |f: &str| format!("part[{i}] ({}).{f}", p.name);
        if p.name.is_empty() {
            return Err(bad(format!("part[{i}].name"), "must not be empty".into()));
        }
        if before.iter().any(|q| q.name == p.name) {
            return Err(bad(field("name"), "two parts share this name".into()));
        }
        let shape = Superquadric::new(p.a, p.e1, p.e2, p.kx, p.ky).map_err(|e| {
            let f = match e {
                crate::geometry::ShapeError::Size { .. } => "a",
                crate::geometry::ShapeError::Exponent { name, .. } => name,
                crate::geometry::ShapeError::Taper { name, .. } => name,
            };
            bad(field(f), e.to_string())
        })?;
        if shape.max_size() > 2.0 {
            return Err(bad(
                field("a"),
                format!("{:?} m: sizes are half-sizes in metres; is this in mm?", p.a),
            ));
        }
        if let Some(m) = p.m
            && !(1..=1000).contains(&m)
        {
            return Err(bad(field("m"), format!("{m} hypotheses: give 1 to 1000")));
        }
        let pose_in_object = p.pose.to_isometry().map_err(|m| bad(field("pose"), m))?;
        Ok(Part {
            name: p.name,
            shape,
            pose_in_object,
            hypotheses: p.m,
            open: p.open,
        })
    }

    /// One `[[connection]]` table: its parts by name, its angle and distance as the part poses
    /// have them, not one given before.
    fn connection_from_file(
        i: usize,
        c: ConnectionFile,
        parts: &[Part],
        before: &[Connection],
        path: &Path,
    ) -> Result<Connection, SpecError> {
        let bad = |field: String, msg: String| SpecError::invalid(path, field, msg);
        let field = |f: &str| format!("connection[{i}].{f}");
        let mut idx = [0usize; 2];
        for (k, n) in c.parts.iter().enumerate() {
            idx[k] = parts
                .iter()
                .position(|p| &p.name == n)
                .ok_or_else(|| bad(field("parts"), format!("no part named {n:?}")))?;
        }
        if idx[0] == idx[1] {
            return Err(bad(field("parts"), "a part cannot connect to itself".into()));
        }
        let angle = match (c.angle_rad, c.angle_deg) {
            (Some(r), None) => r,
            (None, Some(d)) => d.to_radians(),
            _ => {
                return Err(bad(
                    field("angle_rad"),
                    "give exactly one of angle_rad, angle_deg".into(),
                ));
            }
        };
        if !(0.0..=std::f64::consts::PI + 1e-9).contains(&angle) {
            return Err(bad(field("angle_rad"), format!("{angle} rad is outside [0, pi]")));
        }
        if !(c.distance.is_finite() && c.distance >= 0.0 && c.distance < 2.0) {
            return Err(bad(
                field("distance"),
                format!("{} m is not a centre distance in metres", c.distance),
            ));
        }
        // The given connectivity must be the one the part poses have.
        let (pa, pb) = (&parts[idx[0]], &parts[idx[1]]);
        let signed = pa.shape.is_tapered() && pb.shape.is_tapered();
        let za = pa.pose_in_object.rotation * Vector3::z();
        let zb = pb.pose_in_object.rotation * Vector3::z();
        let posed_angle = axis_angle(&za, &zb, signed);
        let given_angle = if signed {
            angle
        } else {
            angle.min(std::f64::consts::PI - angle)
        };
        if (posed_angle - given_angle).abs() > ANGLE_TOLERANCE_RAD {
            return Err(bad(
                field("angle"),
                format!(
                    "{:.2} deg, but the part poses put the z axes {:.2} deg apart",
                    angle.to_degrees(),
                    posed_angle.to_degrees()
                ),
            ));
        }
        let posed_distance = (pa.pose_in_object.translation.vector - pb.pose_in_object.translation.vector).norm();
        if (posed_distance - c.distance).abs() > DISTANCE_TOLERANCE_M {
            return Err(bad(
                field("distance"),
                format!(
                    "{} m, but the part poses put the centres {posed_distance:.4} m apart",
                    c.distance
                ),
            ));
        }
        if before
            .iter()
            .any(|k: &Connection| (k.parts == idx) || (k.parts == [idx[1], idx[0]]))
        {
            return Err(bad(field("parts"), "these parts are already connected".into()));
        }
        Ok(Connection {
            parts: idx,
            angle,
            distance: c.distance,
        })
    }

    /// The connections must tie all parts into one tree: the detector votes a compound over them.
    fn check_tree(parts: &[Part], connections: &[Connection], path: &Path) -> Result<(), SpecError> {
        let bad = |field: String, msg: String| SpecError::invalid(path, field, msg);
        if connections.len() != parts.len() - 1 {
            return Err(bad(
                "connection".into(),
                format!(
                    "{} parts need {} connections, {} given",
                    parts.len(),
                    parts.len() - 1,
                    connections.len()
                ),
            ));
        }
        let mut reached = vec![false; parts.len()];
        reached[0] = true;
        for _ in 0..parts.len() {
            for c in connections {
                if reached[c.parts[0]] || reached[c.parts[1]] {
                    reached[c.parts[0]] = true;
                    reached[c.parts[1]] = true;
                }
            }
        }
        if let Some(i) = reached.iter().position(|r| !r) {
            return Err(bad(
                "connection".into(),
                format!("part {:?} is not connected to the others", parts[i].name),
            ));
        }
        Ok(())
    }

    pub fn is_compound(&self) -> bool {
        self.parts.len() > 1
    }

    /// The parts placed in a frame, given the object's pose in that frame.
    pub fn placed_parts(&self, object_pose: &Isometry3<f64>) -> Vec<PlacedSuperquadric> {
        self.parts
            .iter()
            .map(|p| PlacedSuperquadric::new(p.shape, object_pose * p.pose_in_object))
            .collect()
    }

    /// Radius of a sphere about the object origin that contains every part.
    pub fn bounding_radius(&self) -> f64 {
        self.parts
            .iter()
            .map(|p| p.pose_in_object.translation.vector.norm() + p.shape.bounding_radius())
            .fold(0.0, f64::max)
    }
}

/// The file a model argument names: an existing path or anything ending in `.toml` is a path,
/// anything else a name in `models_dir`.
pub fn resolve(name_or_path: &str, models_dir: &Path) -> PathBuf {
    let p = Path::new(name_or_path);
    if name_or_path.ends_with(".toml") || p.components().count() > 1 || p.is_file() {
        p.to_owned()
    } else {
        models_dir.join(format!("{name_or_path}.toml"))
    }
}

/// Where models are looked for when no directory is given, after `$SQSCAN_MODELS_DIR`: the
/// working directory's `models` (a source checkout), the administrator's `/etc/sqscan/models`,
/// the package's `/usr/share/sqscan/models`.
pub const MODELS_SEARCH_PATH: [&str; 3] = ["models", "/etc/sqscan/models", "/usr/share/sqscan/models"];

/// The models directory when none is given on the command line: `$SQSCAN_MODELS_DIR` if set,
/// else the first directory of [`MODELS_SEARCH_PATH`] that exists, else the last of them (so
/// that the error of loading from it names where models were expected).
pub fn default_models_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("SQSCAN_MODELS_DIR").filter(|d| !d.is_empty()) {
        return PathBuf::from(d);
    }
    let found = MODELS_SEARCH_PATH.iter().map(PathBuf::from).find(|p| p.is_dir());
    found.unwrap_or_else(|| PathBuf::from(MODELS_SEARCH_PATH[MODELS_SEARCH_PATH.len() - 1]))
}

/// What to say when the models directory `dir` does not exist: where models are looked for.
pub fn missing_models_dir(dir: &Path) -> String {
    format!(
        "no models directory at {}: name one with --models-dir (or models_dir in the daemon's configuration) \
         or SQSCAN_MODELS_DIR, or install the models in one of {}",
        dir.display(),
        MODELS_SEARCH_PATH.join(", ")
    )
}

/// Every model in a directory, sorted by name; files that fail to load are returned as errors
/// beside the good ones so one broken file does not hide the rest.
pub fn load_dir(dir: &Path) -> Result<Vec<Result<Model, SpecError>>, SpecError> {
    let entries = std::fs::read_dir(dir).map_err(|source| SpecError::Io {
        path: dir.to_owned(),
        source,
    })?;
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    paths.sort();
    Ok(paths.iter().map(|p| Model::from_file(p)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    const PART: &str = "[[part]]\nname = \"body\"\na = [0.04, 0.04, 0.05]\ne1 = 0.3\ne2 = 1.0\n";
    const HANDLE: &str = "[[part]]\nname = \"handle\"\na = [0.01, 0.02, 0.03]\ne1 = 0.3\ne2 = 1.0\npose = { position = [0.06, 0.0, 0.0] }\n";

    /// The error a broken model file gives: its field and message.
    fn refused(text: &str) -> (String, String) {
        match Model::from_toml_str(text, Path::new("broken.toml")) {
            Err(SpecError::Invalid { field, message, .. }) => (field, message),
            other => panic!("{text}\n -> {other:?}"),
        }
    }

    #[test]
    fn broken_model_files_are_refused_naming_the_field() {
        let cases: [(String, &str, &str); 10] = [
            ("name = \"two words\"\n".to_owned() + PART, "name", "non-empty word"),
            ("name = \"x\"\n".to_owned(), "part", "0 parts given"),
            (format!("{PART}{PART}"), "part[1] (body).name", "share this name"),
            (PART.replace("0.3", "-1.0"), "part[0] (body).e1", ""),
            (PART.replace("0.05]", "50.0]"), "part[0] (body).a", "in mm?"),
            (format!("{PART}m = 0\n"), "part[0] (body).m", "give 1 to 1000"),
            (
                format!(
                    "{PART}{HANDLE}[[connection]]\nparts = [\"body\", \"body\"]\nangle_deg = 0.0\ndistance = 0.06\n"
                ),
                "connection[0].parts",
                "itself",
            ),
            (
                format!(
                    "{PART}{HANDLE}[[connection]]\nparts = [\"body\", \"lid\"]\nangle_deg = 0.0\ndistance = 0.06\n"
                ),
                "connection[0].parts",
                "no part named \"lid\"",
            ),
            (
                format!(
                    "{PART}{HANDLE}[[connection]]\nparts = [\"body\", \"handle\"]\nangle_deg = 0.0\ndistance = 0.08\n"
                ),
                "connection[0].distance",
                "0.0600 m apart",
            ),
            (
                format!("{PART}{HANDLE}"),
                "connection",
                "2 parts need 1 connections, 0 given",
            ),
        ];
        for (text, field, message) in &cases {
            let (f, m) = refused(text);
            assert_eq!(&f, field, "{text}");
            assert!(m.contains(message), "{f}: {m}");
        }
        // The same file with its connection right loads.
        let good =
            format!("{PART}{HANDLE}[[connection]]\nparts = [\"body\", \"handle\"]\nangle_deg = 0.0\ndistance = 0.06\n");
        let model = Model::from_toml_str(&good, Path::new("good.toml")).unwrap();
        assert_eq!((model.parts.len(), model.connections.len()), (2, 1));
    }

    /// A colour histogram must be one: its length, its shares between 0 and 1, summing to 1.
    #[test]
    fn a_broken_colour_histogram_is_refused_by_name() {
        let n = crate::appearance::BINS * crate::appearance::BINS;
        let list = |v: &[f64]| {
            format!(
                "colour = [{}]\n{PART}",
                v.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(", ")
            )
        };
        let mut one = vec![0.0; n];
        one[0] = 1.0;
        let good = Model::from_toml_str(&list(&one), Path::new("good.toml")).unwrap();
        assert_eq!(good.colour.as_deref(), Some(&one[..]));
        assert!(
            Model::from_toml_str(PART, Path::new("none.toml"))
                .unwrap()
                .colour
                .is_none()
        );
        let mut negative = one.clone();
        negative[1] = -0.5;
        let mut half = vec![0.0; n];
        half[3] = 0.5;
        for (v, message) in [
            (&one[..3], "3 values given"),
            (&negative[..], "value 1 is -0.5"),
            (&half[..], "sum to 0.5"),
        ] {
            let (f, m) = refused(&list(v));
            assert_eq!(f, "colour");
            assert!(m.contains(message), "{m}");
        }
    }

    /// A part of an object that the rest of it may hold up says so; a whole object is the
    /// default, and a `held` that is not a boolean is refused by name.
    #[test]
    fn held_is_false_unless_the_file_says_true() {
        let whole = Model::from_toml_str(PART, Path::new("whole.toml")).unwrap();
        assert!(!whole.held);
        let held = Model::from_toml_str(
            &format!(
                "held = true
{PART}"
            ),
            Path::new("held.toml"),
        )
        .unwrap();
        assert!(held.held);
        let err = Model::from_toml_str(&format!("held = \"yes\"\n{PART}"), Path::new("bad.toml")).unwrap_err();
        assert!(err.to_string().contains("held"), "{err}");
    }
}
