//! Diagnostics of both binaries: `tracing` to stderr (stdout stays the command's output), at the
//! level `SQSCAN_LOG` names (`error`, `warn`, `info`, `debug`, `trace`) or the binary's default.

/// Installs the stderr subscriber; call once at start-up.
pub fn init(default: tracing::Level) {
    let level = std::env::var("SQSCAN_LOG")
        .ok()
        .and_then(|l| l.parse().ok())
        .unwrap_or(default);
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_max_level(level)
        .with_target(false)
        .init();
}
