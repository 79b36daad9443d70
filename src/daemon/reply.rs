//! Every message the daemon sends, as types: the replies are built from these structs only, and
//! the protocol's JSON Schema (`docs/protocol.schema.json`, [`schema`]) is derived from them, so
//! a test can check the code, the schema and `docs/PROTOCOL.md` against each other.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::detect::output::ReportJson;
use crate::sweep::SweepReport;

/// Protocol version, sent in the `version` greeting. Minor bumps add fields or commands; a major
/// bump changes or removes them.
pub const PROTO_MAJOR: u32 = 2;
pub const PROTO_MINOR: u32 = 2;

/// One message from the daemon: an object with a `class`, and the `id` of the request it answers
/// (absent for the greeting, for errors to lines that could not be read, and for requests sent
/// without one).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "class", rename_all = "snake_case")]
pub enum Reply {
    Version(Version),
    Detection(Box<DetectionReply>),
    Sweep(Box<SweepReply>),
    Cloud(Box<CloudHeader>),
    Status(Box<Status>),
    Models(Models),
    Watch(Watch),
    Error(ErrorReply),
}

/// The request's `id`, copied as it came (any JSON value).
pub type Id = Option<Value>;

/// The greeting on connect.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Version {
    pub release: String,
    pub proto_major: u32,
    pub proto_minor: u32,
}

impl Version {
    pub fn now() -> Version {
        Version {
            release: env!("CARGO_PKG_VERSION").to_string(),
            proto_major: PROTO_MAJOR,
            proto_minor: PROTO_MINOR,
        }
    }
}

/// Where a replayed sweep came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RecordedJson {
    /// The sweep's id when it was recorded; `null` for a cloud that is not one of the daemon's
    /// recordings.
    pub id: Option<u64>,
    pub file: String,
}

/// The sweep a detection was made on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SweepRef {
    /// The sweep's number, counted from 1 since the daemon started.
    pub id: u64,
    /// Unix time of its completion (s).
    pub time: f64,
    /// Its age when the reply was made (s).
    pub age_s: f64,
    /// Points with a return.
    pub points: usize,
    /// `null` for a sweep made now.
    pub recorded: Option<RecordedJson>,
}

/// The answer to `find`, and each `watch` update.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct DetectionReply {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Id,
    #[serde(flatten)]
    pub report: ReportJson,
    /// The frame the poses and the plane are in.
    pub frame: String,
    pub sweep: SweepRef,
    /// From the sweep's last profile to the detection's end (ms).
    pub latency_ms: f64,
}

/// A completed sweep, as `scan` returns it and `status` shows the newest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SweepSummary {
    /// The sweep's number, counted from 1 since the daemon started.
    pub id: u64,
    /// Unix time of its completion (s).
    pub time: f64,
    pub age_s: f64,
    /// From its start to its completion (s).
    pub duration_s: f64,
    /// Rows of the range image.
    pub profiles: usize,
    /// Columns of the range image.
    pub columns: usize,
    /// Points with a return.
    pub points: usize,
    /// The assembler's account of the profiles (`docs/SWEEP.md`).
    pub report: SweepReport,
    pub recorded: Option<RecordedJson>,
}

/// The answer to `scan`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SweepReply {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Id,
    pub sweep: SweepSummary,
}

/// The answer to `cloud`: this line, then exactly `bytes` bytes of payload (the sweep as a PCD
/// file), then the protocol's lines go on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct CloudHeader {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Id,
    pub sweep: SweepRef,
    /// The frame the points are in.
    pub frame: String,
    /// Columns of the organized cloud (sensor columns).
    pub width: usize,
    /// Rows (profiles).
    pub height: usize,
    /// The PCD fields, in order: x, y, z (m, f32; NaN where there was no return), then the
    /// sweep's others (intensity u8 for a sensor that sends it; label u32 in simulation).
    pub fields: Vec<String>,
    /// How the payload is encoded: `pcd_binary`, a PCD file (header, VIEWPOINT the sensor's
    /// pose at mid-sweep, DATA binary, point-major, little-endian).
    pub format: String,
    /// Length of the payload that follows the line's newline.
    pub bytes: usize,
}

/// A device's health.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct DeviceJson {
    /// `ptu`, `sensor`, `simulator`, `replay`.
    pub name: String,
    /// Device path, address, scene file or directory.
    pub path: String,
    pub kind: String,
    pub state: DeviceState,
    pub last_error: Option<String>,
    /// Unix time (s) of `last_error`.
    pub last_error_time: Option<f64>,
    /// Times the device was (re)opened.
    pub opens: u64,
    pub failures: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum DeviceState {
    /// Open and working.
    Ok,
    /// Failed; being reopened with backoff.
    Fault,
    /// Not opened yet.
    Closed,
    /// Nothing more to give: a replay that served every sweep.
    Finished,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SweepCounts {
    pub completed: u64,
    pub dropped: u64,
    /// Sweeps that were to be recorded but could not be (a full disk, a removed directory); each
    /// is a fault too, and none leaves a partial recording.
    pub not_recorded: u64,
    /// Median rate of the recent sweeps; `null` before two have completed.
    pub per_minute: Option<f64>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct DetectionCounts {
    pub count: u64,
    pub median_run_ms: Option<f64>,
    pub median_latency_ms: Option<f64>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ClientCounts {
    pub connected: usize,
    pub total: u64,
    pub requests: u64,
    pub errors: u64,
    pub watch_updates_skipped: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Fault {
    /// Unix time (s).
    pub time: f64,
    pub message: String,
}

/// The configuration in use, and its reloads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ConfigInfo {
    /// The file it was read from; `null` for the built-in defaults.
    pub file: Option<String>,
    /// Where the models were read from.
    pub models_dir: String,
    /// Unix time (s) the models and configuration were last (re)loaded.
    pub loaded: f64,
    /// Reloads taken (SIGHUP) since start.
    pub reloads: u64,
    /// Why the newest reload was refused (the old configuration stays in use); `null` when it
    /// was taken or none was asked.
    pub reload_error: Option<String>,
}

/// The answer to `status`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Status {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Id,
    pub release: String,
    /// `null` while the daemon's tasks run; else which died and why.
    pub failure: Option<String>,
    pub uptime_s: f64,
    /// `sim`, `hardware` or `replay`.
    pub backend: String,
    pub mode: Mode,
    pub devices: Vec<DeviceJson>,
    pub last_sweep: Option<SweepSummary>,
    pub sweeps: SweepCounts,
    pub detections: DetectionCounts,
    pub clients: ClientCounts,
    /// Objects detected on every sweep (by `watch` or the configuration).
    pub watched: Vec<String>,
    /// The newest 16 faults, newest last.
    pub faults: Vec<Fault>,
    pub config: ConfigInfo,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    Continuous,
    OnDemand,
}

/// A part of a model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ModelPart {
    pub name: String,
    /// Half-extents `[a1, a2, a3]` (m).
    pub size_m: [f64; 3],
    /// Shape exponents `[e1, e2]`.
    pub shape: [f64; 2],
    /// Taper `[kx, ky]`.
    pub taper: [f64; 2],
    /// An open part (a vessel: cup, bowl).
    pub open: bool,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ModelJson {
    pub name: String,
    pub parts: Vec<ModelPart>,
}

/// The answer to `models`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Models {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Id,
    pub models: Vec<ModelJson>,
}

/// The answer to `watch` and `unwatch`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Watch {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Id,
    /// Objects now watched on this connection (sorted; empty after `unwatch`).
    pub objects: Vec<String>,
    pub enable: bool,
}

/// What kind of error: stable names a client may act on (the message is for people).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ErrorCode {
    /// The line is not a request: malformed JSON, no or unknown `cmd`, an unknown field, a value
    /// of the wrong type or out of range, an over-long `id`.
    BadRequest,
    /// The line is longer than the limit; it was skipped.
    TooLarge,
    /// No model of that name is loaded.
    UnknownObject,
    /// No fresh sweep before the request's timeout, with the devices healthy.
    Timeout,
    /// No fresh sweep before the timeout because a device is failing (named in the message).
    Device,
    /// No fresh sweep will come: the replay served every recorded sweep.
    ReplayFinished,
    /// Every client slot is taken and none is idle; the connection is closed.
    Busy,
    /// The connection was idle too long, or its slot was given to a new client; it is closed.
    Idle,
    /// The daemon is stopping.
    Stopping,
    /// A fault of the daemon itself.
    Internal,
}

impl ErrorCode {
    /// Every code, in the order `docs/PROTOCOL.md` lists them.
    pub const ALL: [ErrorCode; 10] = [
        ErrorCode::BadRequest,
        ErrorCode::TooLarge,
        ErrorCode::UnknownObject,
        ErrorCode::Timeout,
        ErrorCode::Device,
        ErrorCode::ReplayFinished,
        ErrorCode::Busy,
        ErrorCode::Idle,
        ErrorCode::Stopping,
        ErrorCode::Internal,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            ErrorCode::BadRequest => "bad_request",
            ErrorCode::TooLarge => "too_large",
            ErrorCode::UnknownObject => "unknown_object",
            ErrorCode::Timeout => "timeout",
            ErrorCode::Device => "device",
            ErrorCode::ReplayFinished => "replay_finished",
            ErrorCode::Busy => "busy",
            ErrorCode::Idle => "idle",
            ErrorCode::Stopping => "stopping",
            ErrorCode::Internal => "internal",
        }
    }
}

/// An error: a stable `code` and a message that names what was wrong.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ErrorReply {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Id,
    pub code: ErrorCode,
    pub message: String,
}

impl Reply {
    pub fn error(id: Id, code: ErrorCode, message: impl Into<String>) -> Reply {
        Reply::Error(ErrorReply {
            id,
            code,
            message: message.into(),
        })
    }

    /// Sets the id of the request this answers (the greeting has none).
    pub fn with_id(mut self, new: Id) -> Reply {
        match &mut self {
            Reply::Version(_) => {}
            Reply::Detection(r) => r.id = new,
            Reply::Sweep(r) => r.id = new,
            Reply::Cloud(r) => r.id = new,
            Reply::Status(r) => r.id = new,
            Reply::Models(r) => r.id = new,
            Reply::Watch(r) => r.id = new,
            Reply::Error(r) => r.id = new,
        }
        self
    }

    pub fn is_error(&self) -> bool {
        matches!(self, Reply::Error(_))
    }

    /// The message as one line, newline included.
    pub fn line(&self) -> String {
        // Serializing these types cannot fail: every map key is a string.
        let mut s = serde_json::to_string(self).unwrap_or_else(|e| {
            format!(r#"{{"class":"error","code":"internal","message":"reply not serializable: {e}"}}"#)
        });
        s.push('\n');
        s
    }
}

/// The JSON Schema of every message the daemon sends (draft 2020-12), as kept in
/// `docs/protocol.schema.json`.
pub fn schema() -> Value {
    let mut s = serde_json::to_value(schemars::schema_for!(Reply)).unwrap_or(Value::Null);
    s["title"] = Value::from("sqscand reply");
    s["$comment"] = Value::from(format!(
        "Protocol {PROTO_MAJOR}.{PROTO_MINOR}, generated from src/daemon/reply.rs; see docs/PROTOCOL.md"
    ));
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_codes_are_spelled_as_serde_writes_them() {
        for c in ErrorCode::ALL {
            assert_eq!(serde_json::to_value(c).unwrap(), Value::from(c.as_str()));
        }
    }

    #[test]
    fn the_greeting_has_a_class_and_no_id() {
        let v: Value = serde_json::from_str(&Reply::Version(Version::now()).line()).unwrap();
        assert_eq!(v["class"], "version");
        assert_eq!(v["proto_major"], PROTO_MAJOR);
        assert!(v.get("id").is_none());
        let e = Reply::error(Some(Value::from("q")), ErrorCode::Busy, "x");
        let v: Value = serde_json::from_str(&e.line()).unwrap();
        assert_eq!(
            v,
            serde_json::json!({"class":"error","id":"q","code":"busy","message":"x"})
        );
    }
}
