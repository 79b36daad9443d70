//! The new-user scenario, end to end with the real binaries: `sqscan mock ptu` in one process,
//! `sqscan ptu ... move --tilt 0.3` in another, talking over a pty through the mock's link.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};

const SQSCAN: &str = env!("CARGO_BIN_EXE_sqscan");

/// Kills the mock when the test ends, however it ends.
struct Reaper(Child);

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
    let tilt = out
        .lines()
        .find(|l| l.starts_with("tilt"))
        .expect("a tilt line");
    assert!(
        tilt.contains("+0.3000 rad") && tilt.contains("RAMP_END"),
        "{out}"
    );

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
    let (ok, out, err) = ptu_with(&link, "flir", &["sweep", "--from", "-0.15", "--to", "0.1", "--speed", "0.2"]);
    assert!(ok && out.contains("sweep: ") && out.contains("tilt +0.1001 rad"), "{out}{err}");
    let (ok, _, err) = ptu_with(&link, "flir", &["move", "--tilt", "0.3"]);
    assert!(!ok && err.contains("tilt (rad) = 0.3 outside"), "{err}");
    let (ok, out, err) = ptu_with(&link, "flir", &["home"]);
    assert!(ok && out.contains("pan  +0.0000 rad  0 steps"), "{out}{err}");

    drop(mock);
    let _ = std::fs::remove_dir_all(&dir);
}
