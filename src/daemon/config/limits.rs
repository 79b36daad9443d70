//! The documented ranges of the numbers in the file: past them a setting is a mistake (a
//! unit slip, a typo of exponent), and some would kill a task at start (a sweep that never ends,
//! a duration no clock holds, a pool of 2^62 threads).

/// Clients at once (each holds a file descriptor).
pub const MAX_CLIENTS: (usize, usize) = (1, 65_536);
/// Messages queued for one client.
pub const CLIENT_QUEUE: (usize, usize) = (4, 65_536);
/// How long a client may sit idle (s): a day at most.
pub const IDLE_TIMEOUT_S: (f64, f64) = (0.1, 86_400.0);
/// A Foxglove viewer's queue of unsent messages (MB).
pub const VIEW_BACKLOG_MB: (usize, usize) = (1, 1024);
/// Detections run at once.
pub const WORKERS: (usize, usize) = (1, 256);
/// Profiles a sweep needs at least.
pub const MIN_PROFILES: (usize, usize) = (2, 100_000);
/// Recordings kept (0: all).
pub const RECORD_KEEP: (usize, usize) = (0, 1_000_000);
/// Pan and tilt angles (rad): one turn either way.
pub const ANGLE_RAD: (f64, f64) = (-std::f64::consts::TAU, std::f64::consts::TAU);
/// Sweep speed (rad/s).
pub const SPEED_RAD_S: (f64, f64) = (1e-3, 10.0);
/// Pause between sweeps (s).
pub const PAUSE_S: (f64, f64) = (0.0, 3600.0);
/// Slack beyond a move's nominal duration, and the longest silence of the sensor (s).
pub const TIMEOUT_S: (f64, f64) = (0.01, 3600.0);
/// The longest a sweep's tilt range may take at its speed (s).
pub const SWEEP_S: f64 = 3600.0;
/// Replay speed against the recorded pace (0: as fast as asked).
pub const REPLAY_SPEED: (f64, f64) = (0.0, 1000.0);
/// Range cut of the detector (m).
pub const MAX_RANGE_M: (f64, f64) = (0.01, 1000.0);
/// The largest DDS domain id whose ports stay below 65 536.
pub const ROS_DOMAIN_ID: u16 = 232;
/// A ROS 2 topic's keep-last depth. The writer keeps that many clouds for subscribers that
/// are behind, each a whole sweep (0.8 MB at 256 columns, 10 MB at 4096): 20 is ample for a
/// topic that changes every few seconds, and bounds that memory.
pub const ROS_DEPTH: (usize, usize) = (1, 20);
/// The largest DDS sample the node reassembles from fragments (KiB). It receives only
/// discovery data, a few KB a participant; the patched RustDDS holds 16 times this at most
/// in all incomplete samples, so 64 MiB bounds that at 1 GiB.
pub const ROS_MAX_RECEIVED_SAMPLE_KIB: (usize, usize) = (64, 65_536);
