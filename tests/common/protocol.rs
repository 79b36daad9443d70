//! Checks a message of the daemon against the protocol: the JSON Schema kept in
//! `docs/protocol.schema.json`, and the reply types, which must read it and write it back unchanged
//! (so a field the types do not know, which the schema would let through, is caught too).

use std::sync::OnceLock;

use serde_json::Value;
use sqscan::daemon::reply::Reply;

fn validator() -> &'static jsonschema::Validator {
    static V: OnceLock<jsonschema::Validator> = OnceLock::new();
    V.get_or_init(|| {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/protocol.schema.json");
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let schema: Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        jsonschema::validator_for(&schema).unwrap_or_else(|e| panic!("{}: not a JSON Schema: {e}", path.display()))
    })
}

/// Numbers as f64, so `10` and `10.0` compare equal.
fn normalized(v: &Value) -> Value {
    match v {
        Value::Number(n) => n.as_f64().map(Value::from).unwrap_or(Value::Null),
        Value::Array(a) => Value::Array(a.iter().map(normalized).collect()),
        Value::Object(o) => Value::Object(o.iter().map(|(k, v)| (k.clone(), normalized(v))).collect()),
        other => other.clone(),
    }
}

/// What is wrong with `v` as a message of the daemon, if anything.
pub fn problems(v: &Value) -> Option<String> {
    let errors: Vec<String> = validator()
        .iter_errors(v)
        .map(|e| format!("{} at {}", e, e.instance_path()))
        .collect();
    if !errors.is_empty() {
        return Some(format!("schema: {}", errors.join("; ")));
    }
    let typed: Reply = match serde_json::from_value(v.clone()) {
        Ok(r) => r,
        Err(e) => return Some(format!("types: {e}")),
    };
    let back = serde_json::to_value(&typed).unwrap();
    if normalized(&back) != normalized(v) {
        return Some(format!("types: written back as {back}"));
    }
    None
}

/// Panics, naming the message and what is wrong, unless `v` is a message of the daemon.
pub fn check_reply(v: &Value) {
    if let Some(p) = problems(v) {
        panic!("not a reply of the protocol ({p}):\n{v}");
    }
}
