//! The protocol's three descriptions agree: the reply types (`src/daemon/reply.rs`), the JSON
//! Schema generated from them (`docs/protocol.schema.json`), and `docs/PROTOCOL.md`'s examples,
//! requests and error codes. Regenerate the schema file after changing the types with
//! `SQSCAN_BLESS=1 cargo test --test service protocol::`.

use crate::common::root;
use serde_json::Value;
use sqscan::daemon::protocol::parse_request;
use sqscan::daemon::reply::{ErrorCode, PROTO_MAJOR, PROTO_MINOR, Reply, schema};

fn protocol_md() -> String {
    std::fs::read_to_string(root().join("docs/PROTOCOL.md")).unwrap()
}

/// The ```json blocks of a Markdown text, each parsed as one JSON value.
fn json_blocks(md: &str) -> Vec<Value> {
    let mut out = Vec::new();
    let mut rest = md;
    while let Some(i) = rest.find("```json\n") {
        let body = &rest[i + 8..];
        let j = body.find("```").expect("an unclosed ```json block");
        out.push(serde_json::from_str(&body[..j]).unwrap_or_else(|e| panic!("{e}: not JSON:\n{}", &body[..j])));
        rest = &body[j + 3..];
    }
    out
}

#[test]
fn the_schema_file_is_what_the_code_generates() {
    let path = root().join("docs/protocol.schema.json");
    let generated = serde_json::to_string_pretty(&schema()).unwrap() + "\n";
    if std::env::var_os("SQSCAN_BLESS").is_some() {
        std::fs::write(&path, &generated).unwrap();
    }
    let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        on_disk == generated,
        "{} differs from the schema of src/daemon/reply.rs: regenerate it with \
         SQSCAN_BLESS=1 cargo test --test service protocol::",
        path.display()
    );
}

#[test]
fn every_example_in_protocol_md_is_a_valid_reply_of_this_version() {
    let md = protocol_md();
    let examples = json_blocks(&md);
    assert!(examples.len() >= 7, "{} examples", examples.len());
    let mut classes = std::collections::BTreeSet::new();
    for v in &examples {
        crate::common::protocol::check_reply(v);
        classes.insert(v["class"].as_str().unwrap().to_string());
        if v["class"] == "version" {
            assert_eq!(
                (v["proto_major"].as_u64(), v["proto_minor"].as_u64()),
                (Some(PROTO_MAJOR as u64), Some(PROTO_MINOR as u64))
            );
        }
    }
    // Every class the daemon sends has an example.
    for class in [
        "version",
        "detection",
        "sweep",
        "cloud",
        "status",
        "models",
        "watch",
        "error",
    ] {
        assert!(classes.contains(class), "no example of {class:?} in PROTOCOL.md");
    }
    assert!(md.contains(&format!(
        "Version {PROTO_MAJOR}.{PROTO_MINOR} (`proto_major` {PROTO_MAJOR}"
    )));
}

#[test]
fn every_request_in_protocol_md_parses() {
    let md = protocol_md();
    let requests: Vec<&str> = md
        .lines()
        .filter_map(|l| l.strip_prefix("| `{\"cmd\""))
        .map(|l| &l[..l.find("}`").expect("a request cell") + 1])
        .collect();
    assert!(requests.len() >= 6, "{requests:?}");
    for r in requests {
        let line = format!("{{\"cmd\"{r}");
        parse_request(line.as_bytes()).unwrap_or_else(|e| panic!("{line}: {}", e.message));
    }
}

#[test]
fn protocol_md_lists_every_error_code_and_no_other() {
    let md = protocol_md();
    let listed: Vec<&str> = md
        .lines()
        .filter_map(|l| l.strip_prefix("| `"))
        .filter_map(|l| l.split_once("` |").map(|(c, _)| c))
        .filter(|c| !c.starts_with('{'))
        .collect();
    let codes: Vec<&str> = ErrorCode::ALL.iter().map(|c| c.as_str()).collect();
    assert_eq!(listed, codes);
}

/// The checks are not vacuous: what the schema or the types do not allow is refused.
#[test]
fn replies_that_break_the_protocol_are_refused() {
    let ok: Value = serde_json::from_str(r#"{"class":"watch","objects":["cup"],"enable":true}"#).unwrap();
    crate::common::protocol::check_reply(&ok);
    for bad in [
        r#"{"class":"watch","objects":["cup"]}"#,
        r#"{"class":"watch","objects":"cup","enable":true}"#,
        r#"{"class":"error","message":"no code"}"#,
        r#"{"class":"error","code":"teapot","message":"an unknown code"}"#,
        r#"{"class":"sweep","id":13,"time":1.0,"age_s":0.0}"#,
        r#"{"class":"gossip"}"#,
    ] {
        let v: Value = serde_json::from_str(bad).unwrap();
        assert!(crate::common::protocol::problems(&v).is_some(), "accepted {bad}");
    }
    // A field the types do not know is an undocumented field: refused here, though a client
    // would ignore it.
    let extra: Value = serde_json::from_str(r#"{"class":"watch","objects":[],"enable":false,"colour":1}"#).unwrap();
    assert!(crate::common::protocol::problems(&extra).is_some());
    let r: Reply = serde_json::from_value(ok).unwrap();
    assert!(!r.is_error());
}
