//! The socket protocol (`docs/PROTOCOL.md`): one JSON object a line each way, every reply with a
//! `class`. This module parses requests into [`Request`] with messages that name what was wrong;
//! the replies are the types of [`super::reply`].

use serde_json::{Map, Value};

use super::reply::{ErrorCode, Reply};

/// Defaults of `find`.
pub const DEFAULT_MAX_AGE_S: f64 = 2.0;
pub const DEFAULT_TIMEOUT_S: f64 = 10.0;
/// Longest wait a client may ask for (s): keeps a typo from parking a request for a year.
pub const MAX_TIMEOUT_S: f64 = 3600.0;

#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// Where is `object`: from a sweep no older than `max_age_s`, or the next one.
    Find {
        object: String,
        max_age_s: f64,
        timeout_s: f64,
        all: bool,
        /// Grasps to give each found instance (0: none).
        grasps: usize,
    },
    /// A sweep now; the reply comes when it is complete.
    Scan {
        timeout_s: f64,
    },
    /// The points of a sweep no older than `max_age_s` (or the next), as a binary PCD payload
    /// after the reply line.
    Cloud {
        max_age_s: f64,
        timeout_s: f64,
    },
    Status,
    Models,
    /// Detections of these objects on every sweep until the client leaves or unwatches.
    Watch {
        objects: Vec<String>,
        /// Grasps to give each found instance (0: none).
        grasps: usize,
    },
    Unwatch,
}

/// A parsed request; `id` (any JSON value) is echoed in every reply to it, so a client can have
/// several requests in flight on one connection.
#[derive(Debug, Clone, PartialEq)]
pub struct Request {
    pub id: Option<Value>,
    pub command: Command,
}

/// A request that could not be taken: the message for the error reply, and the id if one could
/// be read.
#[derive(Debug, Clone, PartialEq)]
pub struct RequestError {
    pub id: Option<Value>,
    pub message: String,
}

fn err(id: &Option<Value>, message: impl Into<String>) -> RequestError {
    RequestError {
        id: id.clone(),
        message: message.into(),
    }
}

fn number(obj: &Map<String, Value>, key: &str, default: f64, id: &Option<Value>) -> Result<f64, RequestError> {
    match obj.get(key) {
        None | Some(Value::Null) => Ok(default),
        Some(Value::Number(n)) => {
            let x = n.as_f64().unwrap_or(f64::NAN);
            if (0.0..=MAX_TIMEOUT_S).contains(&x) {
                Ok(x)
            } else {
                Err(err(
                    id,
                    format!("\"{key}\": {n} is out of range: give seconds in [0, {MAX_TIMEOUT_S}]"),
                ))
            }
        }
        Some(other) => Err(err(id, format!("\"{key}\": expected a number of seconds, got {other}"))),
    }
}

fn object_name(v: &Value, key: &str, id: &Option<Value>) -> Result<String, RequestError> {
    match v {
        Value::String(s) if !s.is_empty() && s.len() <= 256 => Ok(s.clone()),
        other => Err(err(id, format!("\"{key}\": expected an object name, got {other}"))),
    }
}

fn check_keys(obj: &Map<String, Value>, allowed: &[&str], cmd: &str, id: &Option<Value>) -> Result<(), RequestError> {
    for k in obj.keys() {
        if k != "cmd" && k != "id" && !allowed.contains(&k.as_str()) {
            let known = if allowed.is_empty() {
                "it takes none".to_string()
            } else {
                format!("it takes {}", allowed.join(", "))
            };
            return Err(err(id, format!("\"{cmd}\": unknown field \"{k}\"; {known}")));
        }
    }
    Ok(())
}

/// The longest `id` (as JSON) a request may carry: it is echoed in every reply and update.
pub const MAX_ID_BYTES: usize = 256;

/// Parses one request line (without its newline).
pub fn parse_request(line: &[u8]) -> Result<Request, RequestError> {
    let v: Value = serde_json::from_slice(line)
        .map_err(|e| err(&None, format!("malformed JSON at column {}: {e}", e.column())))?;
    let Value::Object(obj) = v else {
        return Err(err(
            &None,
            format!("expected a JSON object like {{\"cmd\":\"status\"}}, got {v}"),
        ));
    };
    let id = request_id(&obj)?;
    let cmd = match obj.get("cmd") {
        Some(Value::String(s)) => s.as_str(),
        Some(other) => return Err(err(&id, format!("\"cmd\": expected a string, got {other}"))),
        None => {
            return Err(err(
                &id,
                "missing \"cmd\"; give one of find, scan, cloud, status, models, watch, unwatch",
            ));
        }
    };
    let command = match cmd {
        "find" => find_command(&obj, &id)?,
        "scan" => {
            check_keys(&obj, &["timeout_s"], cmd, &id)?;
            Command::Scan {
                timeout_s: number(&obj, "timeout_s", DEFAULT_TIMEOUT_S * 3.0, &id)?,
            }
        }
        "cloud" => {
            check_keys(&obj, &["max_age_s", "timeout_s"], cmd, &id)?;
            Command::Cloud {
                max_age_s: number(&obj, "max_age_s", DEFAULT_MAX_AGE_S, &id)?,
                timeout_s: number(&obj, "timeout_s", DEFAULT_TIMEOUT_S, &id)?,
            }
        }
        "status" => {
            check_keys(&obj, &[], cmd, &id)?;
            Command::Status
        }
        "models" => {
            check_keys(&obj, &[], cmd, &id)?;
            Command::Models
        }
        "watch" => watch_command(&obj, &id)?,
        "unwatch" => {
            check_keys(&obj, &[], cmd, &id)?;
            Command::Unwatch
        }
        other => {
            return Err(err(
                &id,
                format!("unknown command {other:?}; give one of find, scan, cloud, status, models, watch, unwatch"),
            ));
        }
    };
    Ok(Request { id, command })
}

/// The request's `id`, echoed in its replies: any JSON up to [`MAX_ID_BYTES`].
fn request_id(obj: &Map<String, Value>) -> Result<Option<Value>, RequestError> {
    let id = obj.get("id").cloned();
    if let Some(v) = &id {
        let n = v.to_string().len();
        if n > MAX_ID_BYTES {
            return Err(err(
                &None,
                format!("\"id\" of {n} bytes is over the limit of {MAX_ID_BYTES} bytes"),
            ));
        }
    }
    Ok(id)
}

/// `find`: the object, how old a sweep may be, how long to wait, and whether every instance.
fn find_command(obj: &Map<String, Value>, id: &Option<Value>) -> Result<Command, RequestError> {
    check_keys(obj, &["object", "max_age_s", "timeout_s", "all", "grasps"], "find", id)?;
    let object = match obj.get("object") {
        Some(v) => object_name(v, "object", id)?,
        None => {
            return Err(err(
                id,
                "\"find\": missing \"object\", e.g. {\"cmd\":\"find\",\"object\":\"cup\"}",
            ));
        }
    };
    let all = match obj.get("all") {
        None | Some(Value::Null) => false,
        Some(Value::Bool(b)) => *b,
        Some(other) => return Err(err(id, format!("\"all\": expected true or false, got {other}"))),
    };
    Ok(Command::Find {
        object,
        max_age_s: number(obj, "max_age_s", DEFAULT_MAX_AGE_S, id)?,
        timeout_s: number(obj, "timeout_s", DEFAULT_TIMEOUT_S, id)?,
        all,
        grasps: grasps(obj, id)?,
    })
}

/// Most grasps a request may ask for, per instance.
pub const MAX_GRASPS: usize = 100;

/// `"grasps"`: how many grasps each found instance gets (default none).
fn grasps(obj: &Map<String, Value>, id: &Option<Value>) -> Result<usize, RequestError> {
    match obj.get("grasps") {
        None | Some(Value::Null) => Ok(0),
        Some(Value::Number(n)) => match n.as_u64() {
            Some(k) if k <= MAX_GRASPS as u64 => Ok(k as usize),
            _ => Err(err(
                id,
                format!("\"grasps\": {n} is out of range: give a whole number from 0 to {MAX_GRASPS}"),
            )),
        },
        Some(other) => Err(err(id, format!("\"grasps\": expected a whole number, got {other}"))),
    }
}

/// `watch`: the objects, from `objects` (a list) and `object` (one name), each once.
fn watch_command(obj: &Map<String, Value>, id: &Option<Value>) -> Result<Command, RequestError> {
    check_keys(obj, &["objects", "object", "grasps"], "watch", id)?;
    let mut objects = Vec::new();
    if let Some(v) = obj.get("object") {
        objects.push(object_name(v, "object", id)?);
    }
    match obj.get("objects") {
        None => {}
        Some(Value::Array(a)) => {
            for v in a {
                objects.push(object_name(v, "objects", id)?);
            }
        }
        Some(other) => return Err(err(id, format!("\"objects\": expected a list of names, got {other}"))),
    }
    if objects.is_empty() {
        return Err(err(id, "\"watch\": give \"objects\": [names] or \"object\": name"));
    }
    objects.sort();
    objects.dedup();
    Ok(Command::Watch {
        objects,
        grasps: grasps(obj, id)?,
    })
}

impl RequestError {
    /// The error reply to the line.
    pub fn reply(&self) -> Reply {
        Reply::error(self.id.clone(), ErrorCode::BadRequest, &self.message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn ok(s: &str) -> Request {
        parse_request(s.as_bytes()).unwrap_or_else(|e| panic!("{s}: {}", e.message))
    }
    fn bad(s: &str) -> String {
        parse_request(s.as_bytes()).unwrap_err().message
    }

    #[test]
    fn grasps_out_of_range_or_not_a_count_are_refused_by_name() {
        for g in ["-1", "101", "1.5", "\"3\"", "true", "1e300", "18446744073709551616"] {
            for cmd in [r#""find","object":"cup""#, r#""watch","object":"cup""#] {
                let e = bad(&format!(r#"{{"cmd":{cmd},"grasps":{g}}}"#));
                assert!(e.contains("\"grasps\""), "{g}: {e}");
            }
        }
    }

    #[test]
    fn parses_the_documented_requests() {
        assert_eq!(
            ok(r#"{"cmd":"find","object":"cup","max_age_s":2.0,"timeout_s":10}"#).command,
            Command::Find {
                object: "cup".into(),
                max_age_s: 2.0,
                timeout_s: 10.0,
                all: false,
                grasps: 0
            }
        );
        assert!(matches!(
            ok(r#"{"cmd":"find","object":"cup","grasps":3}"#).command,
            Command::Find { grasps: 3, .. }
        ));
        let r = ok(r#"{"cmd":"find","object":"cup","id":7}"#);
        assert_eq!(r.id, Some(json!(7)));
        assert!(matches!(r.command, Command::Find { max_age_s, .. } if max_age_s == DEFAULT_MAX_AGE_S));
        assert_eq!(ok(r#"{"cmd":"status"}"#).command, Command::Status);
        assert_eq!(ok(r#"{"cmd":"models"}"#).command, Command::Models);
        assert_eq!(
            ok(r#"{"cmd":"watch","objects":["mug","cup","cup"]}"#).command,
            Command::Watch {
                objects: vec!["cup".into(), "mug".into()],
                grasps: 0
            }
        );
        assert!(matches!(
            ok(r#"{"cmd":"watch","object":"cup","grasps":100}"#).command,
            Command::Watch { grasps: 100, .. }
        ));
        assert!(matches!(ok(r#"{"cmd":"scan"}"#).command, Command::Scan { .. }));
        assert_eq!(
            ok(r#"{"cmd":"cloud","max_age_s":0}"#).command,
            Command::Cloud {
                max_age_s: 0.0,
                timeout_s: DEFAULT_TIMEOUT_S
            }
        );
    }

    #[test]
    fn errors_say_what_was_wrong() {
        assert!(bad("{\"cmd\":").contains("malformed JSON"));
        assert!(bad("[1,2]").contains("JSON object"));
        assert!(bad(r#"{"object":"cup"}"#).contains("missing \"cmd\""));
        assert!(bad(r#"{"cmd":"fnd"}"#).contains("unknown command \"fnd\""));
        assert!(bad(r#"{"cmd":"find"}"#).contains("missing \"object\""));
        assert!(bad(r#"{"cmd":"find","object":3}"#).contains("object name"));
        assert!(bad(r#"{"cmd":"find","object":"cup","max_age_s":-1}"#).contains("max_age_s"));
        assert!(bad(r#"{"cmd":"find","object":"cup","timeout_s":"soon"}"#).contains("timeout_s"));
        assert!(bad(r#"{"cmd":"status","verbose":true}"#).contains("unknown field \"verbose\""));
        assert!(bad(r#"{"cmd":"watch"}"#).contains("objects"));
        // An id is echoed in every reply and update: a long one is refused, not copied.
        let long = format!(r#"{{"cmd":"status","id":"{}"}}"#, "x".repeat(300));
        assert!(bad(&long).contains("over the limit of 256 bytes"));
        let at_limit = format!(r#"{{"cmd":"status","id":"{}"}}"#, "x".repeat(254));
        assert!(parse_request(at_limit.as_bytes()).is_ok());
        // The id survives an error once the JSON is readable.
        let e = parse_request(br#"{"cmd":"nope","id":"a"}"#).unwrap_err();
        assert_eq!(e.id, Some(json!("a")));
        let v = serde_json::to_value(e.reply()).unwrap();
        assert_eq!((&v["id"], &v["code"]), (&json!("a"), &json!("bad_request")));
    }
}
