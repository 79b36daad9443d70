//! `[hardware.sensor]`: an SQPF stream on a serial line or TCP, or a GigE Vision camera with
//! the features to set by name.

use std::path::{Path, PathBuf};

use serde::Deserialize;
use sqscan_drivers::gige::FeatureValue;

use super::checks::one_of;
use crate::spec::SpecError;

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SensorFile {
    /// `"sqpf"` (default): SQPF frames on `path` or `tcp`; `"gige"`: a GigE Vision camera.
    kind: Option<String>,
    /// Serial device of the sensor, or:
    path: Option<PathBuf>,
    /// `host:port` of a sensor that streams over TCP.
    tcp: Option<String>,
    pub(super) baud: Option<u32>,
    /// The GigE Vision camera's IP address.
    address: Option<String>,
    /// GenICam features set in this order after opening.
    features: Option<Vec<FeatureFile>>,
    /// Profiles a block (the camera's `Height`).
    rows_per_frame: Option<u32>,
    /// `"first_row"` (default) or `"last_row"`: the row a block's timestamp belongs to.
    stamp: Option<String>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct FeatureFile {
    name: String,
    value: toml::Value,
}

#[derive(Debug, Clone, PartialEq)]
pub enum SensorEndpoint {
    Serial(PathBuf),
    Tcp(String),
    /// A GigE Vision line-profile camera.
    Gige(GigeEndpoint),
}

/// A GigE Vision camera as configured (`[hardware.sensor] kind = "gige"`).
#[derive(Debug, Clone, PartialEq)]
pub struct GigeEndpoint {
    pub address: String,
    pub features: Vec<(String, FeatureValue)>,
    pub rows_per_frame: Option<u32>,
    /// The block's timestamp is its last row's (else its first's).
    pub stamp_last_row: bool,
}

impl std::fmt::Display for SensorEndpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SensorEndpoint::Serial(p) => write!(f, "{}", p.display()),
            SensorEndpoint::Tcp(a) => write!(f, "tcp://{a}"),
            SensorEndpoint::Gige(g) => write!(f, "gige://{}", g.address),
        }
    }
}

/// Profiles a GigE Vision block at most.
pub const MAX_ROWS_PER_FRAME: u32 = 65_535;

fn gige(path: &Path, s: &SensorFile) -> Result<SensorEndpoint, SpecError> {
    let field = |f: &str| format!("hardware.sensor.{f}");
    refuse(
        path,
        &[
            ("path", s.path.is_some()),
            ("tcp", s.tcp.is_some()),
            ("baud", s.baud.is_some()),
        ],
        "not for a GigE Vision camera (kind = \"gige\"): give address",
    )?;
    if !cfg!(feature = "gige") {
        return Err(SpecError::invalid(
            path,
            "hardware.sensor.kind",
            "\"gige\": this sqscand was built without GigE Vision support (cargo feature gige)",
        ));
    }
    let address = match s.address.as_deref().map(str::trim) {
        Some(a) if !a.is_empty() => a.to_string(),
        _ => {
            return Err(SpecError::invalid(
                path,
                field("address"),
                "give the camera's IP address",
            ));
        }
    };
    let mut features = Vec::new();
    for (i, f) in s.features.iter().flatten().enumerate() {
        let at = format!("hardware.sensor.features[{i}]");
        if f.name.trim().is_empty() || f.name.chars().any(|c| !(c.is_ascii_alphanumeric() || c == '_')) {
            return Err(SpecError::invalid(
                path,
                &at,
                format!("name {:?}: give a GenICam feature name", f.name),
            ));
        }
        let value = match &f.value {
            toml::Value::Boolean(b) => FeatureValue::Bool(*b),
            toml::Value::Integer(n) => FeatureValue::Int(*n),
            toml::Value::Float(x) if x.is_finite() => FeatureValue::Float(*x),
            toml::Value::String(t) => FeatureValue::Str(t.clone()),
            other => {
                return Err(SpecError::invalid(
                    path,
                    &at,
                    format!("{}: {other}: give a boolean, integer, finite number or string", f.name),
                ));
            }
        };
        features.push((f.name.clone(), value));
    }
    if let Some(n) = s.rows_per_frame
        && !(1..=MAX_ROWS_PER_FRAME).contains(&n)
    {
        return Err(SpecError::invalid(
            path,
            field("rows_per_frame"),
            format!("{n}: give 1 to {MAX_ROWS_PER_FRAME}"),
        ));
    }
    let stamp_last_row = one_of(
        path,
        &field("stamp"),
        s.stamp.as_deref(),
        &[("first_row", false), ("last_row", true)],
    )?;
    Ok(SensorEndpoint::Gige(GigeEndpoint {
        address,
        features,
        rows_per_frame: s.rows_per_frame,
        stamp_last_row,
    }))
}

/// The first of `fields` that is `given`, as an error saying `why` it does not belong.
fn refuse(path: &Path, fields: &[(&str, bool)], why: &str) -> Result<(), SpecError> {
    match fields.iter().find(|(_, given)| *given) {
        Some((name, _)) => Err(SpecError::invalid(path, format!("hardware.sensor.{name}"), why)),
        None => Ok(()),
    }
}

/// The sensor a `[hardware.sensor]` table names; relative paths through `rel`.
pub(super) fn endpoint(
    path: &Path,
    s: &SensorFile,
    rel: impl Fn(&Path) -> PathBuf,
) -> Result<SensorEndpoint, SpecError> {
    match s.kind.as_deref() {
        Some("gige") => gige(path, s),
        None | Some("sqpf") => {
            refuse(
                path,
                &[
                    ("address", s.address.is_some()),
                    ("features", s.features.is_some()),
                    ("rows_per_frame", s.rows_per_frame.is_some()),
                    ("stamp", s.stamp.is_some()),
                ],
                "only for a GigE Vision camera (kind = \"gige\")",
            )?;
            match (&s.path, &s.tcp) {
                (Some(p), None) => Ok(SensorEndpoint::Serial(rel(p))),
                (None, Some(a)) => Ok(SensorEndpoint::Tcp(a.clone())),
                _ => Err(SpecError::invalid(
                    path,
                    "hardware.sensor",
                    "give exactly one of path or tcp",
                )),
            }
        }
        Some(other) => Err(SpecError::invalid(
            path,
            "hardware.sensor.kind",
            format!("{other:?}: give \"sqpf\" or \"gige\""),
        )),
    }
}
