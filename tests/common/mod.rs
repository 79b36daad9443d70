//! Where the integration tests find real data.
//!
//! The repository carries the few real scans its tests read (`tests/data/real`, see its
//! SOURCES.md). The development workplace keeps larger shared sets beside the repository
//! (`../shared/data/...`); a test that needs one of those says that it skipped and returns where
//! the set is absent, so that `cargo test` passes on any clone.

// Each test binary compiles this module and uses only some of it.
#![allow(dead_code)]

pub mod protocol;

use std::io::Write;
use std::path::{Path, PathBuf};

/// A real scan the repository carries.
pub fn real_data(name: &str) -> PathBuf {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/real").join(name);
    assert!(
        path.is_file(),
        "{} is missing: the repository carries it (tests/data/real/SOURCES.md)",
        path.display()
    );
    path
}

/// `rel` (e.g. `data/real/test11.pcd`) in the shared development set beside the repository, or
/// None after saying that `test` skipped what needs it.
pub fn shared_data(rel: &str, test: &str) -> Option<PathBuf> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared").join(rel);
    if path.exists() {
        return Some(path);
    }
    // Straight to stderr: the test harness captures `eprintln!` of passing tests, and a skip
    // must be seen.
    let _ = writeln!(
        std::io::stderr(),
        "{test}: skipped: ../shared/{rel} not found (the shared development set beside the repository); this part needs it"
    );
    None
}

/// A child process killed when the test ends, however it ends.
pub struct Proc(pub std::process::Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Polls `ok` every 50 ms; fails the test after `timeout`, naming `what` it waited for.
pub fn wait_for(what: &str, timeout: std::time::Duration, mut ok: impl FnMut() -> bool) {
    let t0 = std::time::Instant::now();
    while !ok() {
        assert!(t0.elapsed() < timeout, "timed out waiting for {what}");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// The repository's root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The Python `scripts/test.sh` prepares (`SQSCAN_PYTHON`) if it imports `modules`, else `None`:
/// the test then says it skipped, or fails where `SQSCAN_REQUIRE_PYTHON_TOOLS` is set (as
/// `scripts/test.sh` sets it).
pub fn python(modules: &[&str]) -> Option<PathBuf> {
    let import = format!("import {}", modules.join(", "));
    let found = std::env::var_os("SQSCAN_PYTHON").map(PathBuf::from).filter(|p| {
        std::process::Command::new(p)
            .args(["-c", &import])
            .status()
            .is_ok_and(|s| s.success())
    });
    if found.is_none() {
        assert!(
            std::env::var_os("SQSCAN_REQUIRE_PYTHON_TOOLS").is_none(),
            "SQSCAN_PYTHON must name a Python that can `{import}`"
        );
        eprintln!("SKIPPED: no Python that can `{import}` (set SQSCAN_PYTHON; scripts/test.sh makes one)");
    }
    found
}

/// The `node_modules` of the npm test clients (`tests/js/package-lock.json`, which
/// `scripts/test.sh` installs under `target/`) and a `node` to run them, or `None` (the test says
/// it skipped) where either is missing, unless `SQSCAN_REQUIRE_NODE_TOOLS` is set.
pub fn node_modules() -> Option<PathBuf> {
    let modules = std::env::var_os("SQSCAN_NODE_MODULES")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("target/js-clients/node_modules"));
    let node_runs = std::process::Command::new("node")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    let found = (node_runs && modules.join("@foxglove/ws-protocol/package.json").is_file()).then_some(modules);
    if found.is_none() {
        assert!(
            std::env::var_os("SQSCAN_REQUIRE_NODE_TOOLS").is_none(),
            "SQSCAN_NODE_MODULES must name the installed tests/js clients' node_modules, and node must run"
        );
        eprintln!("SKIPPED: no node, or no tests/js clients installed (scripts/test.sh installs them)");
    }
    found
}

/// `sqscand` on `dir/NAME.toml`, its socket `dir/NAME.sock`, its log `dir/NAME.log`, with
/// `args` more; returns once the socket answers.
pub fn sqscand(dir: &Path, name: &str, args: &[&std::ffi::OsStr]) -> Proc {
    use std::process::{Command, Stdio};
    let socket = dir.join(format!("{name}.sock"));
    let p = Proc(
        Command::new(env!("CARGO_BIN_EXE_sqscand"))
            .arg("--config")
            .arg(dir.join(format!("{name}.toml")))
            .arg("--socket")
            .arg(&socket)
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(dir.join(format!("{name}.log"))).unwrap())
            .env_remove("NOTIFY_SOCKET")
            .env("SQSCAN_MODELS_DIR", root().join("models"))
            .spawn()
            .unwrap(),
    );
    wait_for("the daemon's socket", std::time::Duration::from_secs(30), || {
        std::os::unix::net::UnixStream::connect(&socket).is_ok()
    });
    p
}

/// One request on a new connection to `socket`, and its reply.
pub fn ask(socket: &Path, request: serde_json::Value) -> serde_json::Value {
    use std::io::BufRead;
    let s = std::os::unix::net::UnixStream::connect(socket).unwrap();
    s.set_read_timeout(Some(std::time::Duration::from_secs(90))).unwrap();
    let mut w = s.try_clone().unwrap();
    let mut r = std::io::BufReader::new(s);
    let mut line = String::new();
    r.read_line(&mut line).unwrap(); // the version greeting
    w.write_all(format!("{request}\n").as_bytes()).unwrap();
    line.clear();
    r.read_line(&mut line).unwrap();
    serde_json::from_str(&line).unwrap()
}

/// A fresh directory for one test's files, named after the test and the process.
pub fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sqscan-e2e-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A TCP port on loopback that was free a moment ago.
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A process's resident memory (bytes), from /proc.
#[allow(dead_code)]
pub fn rss(pid: u32) -> u64 {
    try_rss(pid).unwrap()
}

/// A process's resident memory (bytes), from /proc; none once it has gone.
#[allow(dead_code)]
pub fn try_rss(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let kb: u64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())?;
    Some(kb * 1024)
}

/// Raises this process's soft limit of open files to its hard one (for tests that open
/// thousands of connections); returns the limit now in force.
#[allow(dead_code)]
pub fn raise_open_files() -> u64 {
    let mut r = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit and setrlimit only read and write the struct given.
    unsafe {
        libc::getrlimit(libc::RLIMIT_NOFILE, &mut r);
        r.rlim_cur = r.rlim_max;
        libc::setrlimit(libc::RLIMIT_NOFILE, &r);
        libc::getrlimit(libc::RLIMIT_NOFILE, &mut r);
    }
    r.rlim_cur
}

/// `sqscan mock rig` (the `protocol` PTU and the SQPF sensor on ptys, rendering the Fig. 3
/// table) in its own process, with `extra` arguments, its log `dir/rig.log`; returns once both
/// links exist, with the PTU's and the sensor's link.
pub fn mock_rig(dir: &Path, protocol: &str, extra: &[&str]) -> (Proc, PathBuf, PathBuf) {
    use std::process::{Command, Stdio};
    let ptu = dir.join("ptu");
    let sensor = dir.join("sensor");
    let child = Command::new(env!("CARGO_BIN_EXE_sqscan"))
        .env("SQSCAN_MODELS_DIR", root().join("models"))
        .args(["mock", "rig", "--protocol", protocol, "--scene"])
        .arg(root().join("scenes/fig3_table.toml"))
        .arg("--ptu-link")
        .arg(&ptu)
        .arg("--sensor-link")
        .arg(&sensor)
        .args(extra)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(dir.join("rig.log")).unwrap())
        .spawn()
        .unwrap();
    let child = Proc(child);
    wait_for("the rig's links", std::time::Duration::from_secs(30), || {
        ptu.exists() && sensor.exists()
    });
    (child, ptu, sensor)
}

/// The `[hardware]` and `[sweep]` tables for a [`mock_rig`]: its links, the calibration
/// `calibration/CALIBRATION`, a sweep from 0.49 rad to `tilt_to` at 0.12 rad/s.
pub fn rig_config(ptu: &Path, sensor: &Path, protocol: &str, calibration: &str, tilt_to: f64) -> String {
    format!(
        r#"
[hardware]
calibration = "{}"
ptu = {{ path = "{}", protocol = "{protocol}" }}
sensor = {{ path = "{}" }}
[sweep]
tilt_from_rad = 0.49
tilt_to_rad = {tilt_to}
speed_rad_s = 0.12
timeout_s = 5.0
"#,
        root().join("calibration").join(calibration).display(),
        ptu.display(),
        sensor.display()
    )
}
