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
