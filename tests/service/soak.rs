//! The soak run of `benches/soak.sh` for two minutes with a fault every 20 s (a burst of hostile
//! clients, the rig unplugged and replugged, a SIGHUP, a stalled rig, a rig sending garbage):
//! no honest `find` loses its answer, every fault is recovered from, and the daemon's
//! descriptors and memory are where they were after the warm-up. The 60-minute run is in
//! BENCHMARKS.md.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

use crate::common::{root, tmpdir};

#[test]
fn a_two_minute_soak_on_the_mock_rig_loses_no_answer_and_recovers_from_every_fault() {
    if Command::new("python3").arg("--version").output().is_err() {
        eprintln!("SKIPPED: no python3 to run benches/soak.py");
        return;
    }
    let bin = Path::new(env!("CARGO_BIN_EXE_sqscand")).parent().unwrap();
    assert!(bin.join("sqscan").is_file(), "{}", bin.display());
    let work = tmpdir("soak");
    let out = Command::new("python3")
        .arg(root().join("benches/soak.py"))
        .arg("--bin")
        .arg(bin)
        .args(["--minutes", "2", "--fault-every", "20", "--work"])
        .arg(&work)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let log = || std::fs::read_to_string(work.join("sqscand.log")).unwrap_or_default();
    let r: Value =
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}: {text}\n{}", String::from_utf8_lossy(&out.stderr)));
    assert!(out.status.success(), "{:#}\n{}", r["failures"], log());
    assert_eq!(r["lost"], 0, "{r:#}");
    assert_eq!(r["recovered"], 5, "{r:#}");
    assert!(r["found"].as_u64().unwrap() > 10, "{r:#}");
    let kinds: Vec<&str> = r["faults"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds, ["hostile", "unplug", "sighup", "stall", "garbage"]);
    let _ = std::fs::remove_dir_all(&work);
}
