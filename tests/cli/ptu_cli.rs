//! The new-user scenario, end to end with the real binaries: `sqscan mock ptu` in one process,
//! `sqscan ptu ... move --tilt 0.3` in another, talking over a pty through the mock's link.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};

const SQSCAN: &str = env!("CARGO_BIN_EXE_sqscan");
/// The models the mock rig's scene names, given by name rather than found from the working
/// directory.
const MODELS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/models");

/// Kills the mock when the test ends, however it ends.
struct Reaper(Child);

/// The fewest columns with a return in a profile, from `sqscan sensor grab`'s output.
fn min_returns(text: &str) -> usize {
    text.split("with a return: min ")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .expect("a returns line")
}

/// `sqscan sensor grab COUNT` from the mock camera on 127.0.0.1 in scan type `scan`.
#[cfg(feature = "gige")]
fn grab_from_camera(scan: &str, count: &str) -> std::process::Output {
    Command::new(SQSCAN)
        .env("SQSCAN_MODELS_DIR", MODELS)
        .args(["sensor", "--device", "gige://127.0.0.1", "--feature"])
        .arg(format!("DeviceScanType={scan}"))
        .args(["grab", count])
        .output()
        .unwrap()
}

/// `sqscan mock rig` on the Fig. 3 scene, a PowerCube at 100 profiles a second, with `extra`
/// arguments; its stdout piped.
fn mock_rig(ptu_link: &Path, sensor_link: &Path, extra: &[&str]) -> Reaper {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/fig3_table.toml");
    Reaper(
        Command::new(SQSCAN)
            .env("SQSCAN_MODELS_DIR", MODELS)
            .args(["mock", "rig", "--protocol", "powercube", "--rate", "100", "--scene"])
            .arg(&scene)
            .arg("--ptu-link")
            .arg(ptu_link)
            .arg("--sensor-link")
            .arg(sensor_link)
            .args(extra)
            .stdout(Stdio::piped())
            .spawn()
            .expect("sqscan mock runs"),
    )
}

impl Drop for Reaper {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn ptu(link: &Path, args: &[&str]) -> (bool, String, String) {
    ptu_with(link, "powercube", args)
}

fn ptu_with(link: &Path, protocol: &str, args: &[&str]) -> (bool, String, String) {
    let out = Command::new(SQSCAN)
        .env("SQSCAN_MODELS_DIR", MODELS)
        .args(["ptu", "--device"])
        .arg(link)
        .args(["--protocol", protocol])
        .args(args)
        .output()
        .expect("sqscan runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn mock_ptu_binary_moves_to_the_requested_tilt() {
    let dir = std::env::temp_dir().join(format!("sqscan-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("ptu");
    let mut mock = Reaper(
        Command::new(SQSCAN)
            .env("SQSCAN_MODELS_DIR", MODELS)
            .args(["mock", "ptu", "--protocol", "powercube", "--link"])
            .arg(&link)
            .stdout(Stdio::piped())
            .spawn()
            .expect("sqscan mock runs"),
    );
    // The mock prints its device once the pty and the link exist: no polling needed.
    let stdout = mock.0.stdout.take().unwrap();
    let mut first = String::new();
    BufReader::new(stdout).read_line(&mut first).unwrap();
    assert!(
        first.contains("/dev/pts/") && first.contains("tilt module 11"),
        "{first}"
    );
    assert!(
        std::fs::symlink_metadata(&link).is_ok(),
        "no link at {}",
        link.display()
    );

    let (ok, out, err) = ptu(&link, &["move", "--tilt", "0.3"]);
    assert!(ok, "{err}");
    let tilt = out.lines().find(|l| l.starts_with("tilt")).expect("a tilt line");
    assert!(tilt.contains("+0.3000 rad") && tilt.contains("RAMP_END"), "{out}");

    // A second run finds the unit where the first left it (the port reopens for a new client).
    let (ok, out, err) = ptu(&link, &["status"]);
    assert!(ok && out.contains("tilt +0.3000 rad"), "{out}{err}");

    // Out of limits: refused with a one-line error, nothing moves.
    let (ok, _, err) = ptu(&link, &["move", "--tilt", "3"]);
    assert!(!ok && err.contains("tilt (rad) = 3 outside"), "{err}");

    drop(mock);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn mock_flir_binary_moves_sweeps_and_refuses_out_of_range() {
    let dir = std::env::temp_dir().join(format!("sqscan-cli-flir-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("ptu");
    let mut mock = Reaper(
        Command::new(SQSCAN)
            .env("SQSCAN_MODELS_DIR", MODELS)
            .args(["mock", "ptu", "--protocol", "flir", "--link"])
            .arg(&link)
            .stdout(Stdio::piped())
            .spawn()
            .expect("sqscan mock runs"),
    );
    let stdout = mock.0.stdout.take().unwrap();
    let mut first = String::new();
    BufReader::new(stdout).read_line(&mut first).unwrap();
    assert!(first.contains("PTU-D46") && first.contains("/dev/pts/"), "{first}");

    let (ok, out, err) = ptu_with(&link, "flir", &["move", "--pan", "0.5", "--tilt", "-0.1"]);
    assert!(ok, "{err}");
    assert!(out.contains("pan  +0.5000 rad  557 steps"), "{out}");
    let (ok, out, err) = ptu_with(
        &link,
        "flir",
        &["sweep", "--from", "-0.15", "--to", "0.1", "--speed", "0.2"],
    );
    // 0.1 rad is 111.4 steps of 0.0514 deg: the unit ends on step 111.
    assert!(
        ok && out.contains("sweep: ") && out.contains("tilt +0.0996 rad  111 steps"),
        "{out}{err}"
    );
    // --json: one object with the joints, the limits and the sweep's samples.
    let (ok, out, err) = ptu_with(
        &link,
        "flir",
        &["--json", "sweep", "--from", "0.1", "--to", "-0.1", "--speed", "0.2"],
    );
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}"));
    assert!((v["tilt"]["position_rad"].as_f64().unwrap() + 0.1).abs() < 0.001, "{v}");
    assert!(v["sweep"]["samples"].as_u64().unwrap() > 5, "{v}");
    assert!(v["limits"]["tilt_rad"][0].as_f64().unwrap() < -0.1, "{v}");
    let (ok, _, err) = ptu_with(&link, "flir", &["move", "--tilt", "0.6"]);
    assert!(!ok && err.contains("tilt (rad) = 0.6 outside"), "{err}");
    let (ok, out, err) = ptu_with(&link, "flir", &["home"]);
    assert!(ok && out.contains("pan  +0.0000 rad  0 steps"), "{out}{err}");

    drop(mock);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn mock_rig_binary_serves_a_ptu_and_a_sensor_that_sees_the_table() {
    let dir = std::env::temp_dir().join(format!("sqscan-cli-rig-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (ptu_link, sensor_link) = (dir.join("ptu"), dir.join("sensor"));
    let mut mock = mock_rig(&ptu_link, &sensor_link, &[]);
    // Two lines once both ptys and links exist (loading the scene's models takes a while).
    let mut lines = BufReader::new(mock.0.stdout.take().unwrap()).lines();
    let first = lines.next().unwrap().unwrap();
    let second = lines.next().unwrap().unwrap();
    assert!(first.contains("PowerCube PTU on /dev/pts/"), "{first}");
    assert!(second.contains("sensor (256 columns, 100 Hz)"), "{second}");

    let (ok, _, err) = ptu(&ptu_link, &["move", "--tilt", "0.6"]);
    assert!(ok, "{err}");
    let out = Command::new(SQSCAN)
        .env("SQSCAN_MODELS_DIR", MODELS)
        .args(["sensor", "--device"])
        .arg(&sensor_link)
        .args(["grab", "20"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(text.starts_with("profiles: 20  seq 0..19  dropped 0"), "{text}");
    let out = Command::new(SQSCAN)
        .env("SQSCAN_MODELS_DIR", MODELS)
        .args(["sensor", "--json", "--device"])
        .arg(&sensor_link)
        .args(["grab", "5"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["profiles"], 5, "{v}");
    assert_eq!(v["columns"], 256, "{v}");
    assert_eq!(v["bad_frames"], 0, "{v}");
    assert!(v["with_a_return"]["min"].as_u64().unwrap() > 200, "{v}");
    // At tilt 0.6 nearly the whole fan sees the table or the objects on it.
    assert!(min_returns(&text) > 200, "{text}");

    drop(mock);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn mock_rig_binary_replugs_its_ptu_once_and_keeps_the_sensor_streaming() {
    let dir = std::env::temp_dir().join(format!("sqscan-cli-replug-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (ptu_link, sensor_link) = (dir.join("ptu"), dir.join("sensor"));
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/fig3_table.toml");
    let mut mock = Reaper(
        Command::new(SQSCAN)
            .env("SQSCAN_MODELS_DIR", MODELS)
            .args(["mock", "rig", "--protocol", "powercube", "--scene"])
            .arg(&scene)
            .arg("--ptu-link")
            .arg(&ptu_link)
            .arg("--sensor-link")
            .arg(&sensor_link)
            .args(["--disconnect-after", "3", "--ptu-replug-after", "0.2"])
            .stdout(Stdio::piped())
            .spawn()
            .expect("sqscan mock runs"),
    );
    let mut lines = BufReader::new(mock.0.stdout.take().unwrap()).lines();
    let first = lines.next().unwrap().unwrap();
    assert!(first.contains("PowerCube PTU on /dev/pts/"), "{first}");
    lines.next().unwrap().unwrap();

    // Unplugged after three replies: this session fails.
    let (ok, _, err) = ptu(&ptu_link, &["move", "--tilt", "0.6"]);
    assert!(!ok && err.contains("disconnected"), "{err}");
    let back = lines.next().unwrap().unwrap();
    assert!(back.contains("PTU plugged back in on /dev/pts/"), "{back}");
    let target = std::fs::read_link(&ptu_link).unwrap();
    assert!(
        back.contains(&target.display().to_string()),
        "{back} vs {}",
        target.display()
    );

    // Back behind the same link, for good: many more than three replies each.
    for tilt in ["0.6", "0.3"] {
        let (ok, out, err) = ptu(&ptu_link, &["move", "--tilt", tilt]);
        assert!(ok && out.contains(&format!("tilt +{tilt}000 rad")), "{out}{err}");
    }
    let out = Command::new(SQSCAN)
        .env("SQSCAN_MODELS_DIR", MODELS)
        .args(["sensor", "--device"])
        .arg(&sensor_link)
        .args(["grab", "5"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    // Without --disconnect-after there is nothing to replug.
    let out = Command::new(SQSCAN)
        .env("SQSCAN_MODELS_DIR", MODELS)
        .args(["mock", "rig", "--protocol", "powercube", "--scene"])
        .arg(&scene)
        .args(["--ptu-replug-after", "1"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--disconnect-after"));

    drop(mock);
    let _ = std::fs::remove_dir_all(&dir);
}

#[cfg(feature = "gige")]
#[test]
fn sensor_grab_from_a_gige_vision_camera_prints_what_it_prints_for_sqpf() {
    if !sqscan_drivers::mock::gige::in_private_network(
        "ptu_cli::sensor_grab_from_a_gige_vision_camera_prints_what_it_prints_for_sqpf",
    ) {
        return;
    }
    let dir = std::env::temp_dir().join(format!("sqscan-cli-gige-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (ptu_link, sensor_link) = (dir.join("ptu"), dir.join("sensor"));
    let mut mock = mock_rig(&ptu_link, &sensor_link, &["--sensor", "gige"]);
    let lines: Vec<String> = BufReader::new(mock.0.stdout.take().unwrap())
        .lines()
        .take(3)
        .map(|l| l.unwrap())
        .collect();
    assert!(
        lines[2].contains("GigE Vision camera SQ-LP-0001 (256 columns, 100 Hz, 10 profiles a block) on 127.0.0.1"),
        "{lines:?}"
    );
    let (ok, _, err) = ptu(&ptu_link, &["move", "--tilt", "0.6"]);
    assert!(ok, "{err}");
    let out = grab_from_camera("Linescan3D", "30");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        text.contains("256 columns, 10 profiles a block, Coord3D_C16 at 100 Hz"),
        "{text}"
    );
    assert!(text.contains("profiles: 30  seq "), "{text}");
    assert!(text.contains("dropped 0"), "{text}");
    assert!(min_returns(&text) > 200, "{text}");
    // Discovery (a broadcast, on loopback only here) finds it by its address.
    let out = Command::new(SQSCAN)
        .env("SQSCAN_MODELS_DIR", MODELS)
        .args(["sensor", "--device", "gige://any", "discover"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        text.contains("gige://127.0.0.1") && text.contains("SQ-LP-0001"),
        "{text}"
    );
    // Without the 3D mode the camera sends no range: a bring-up shows it.
    let out = grab_from_camera("Areascan", "10");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("with a return: min 0  mean 0.0  max 0"), "{text}");
    drop(mock);
    let _ = std::fs::remove_dir_all(&dir);
}
