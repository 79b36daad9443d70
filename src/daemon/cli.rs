//! `sqscand`'s command line, in the library so that `sqscan completions` and `sqscan man` can
//! describe the daemon too.

use std::path::PathBuf;

use clap::Parser;

#[derive(Parser)]
#[command(
    name = "sqscand",
    version,
    about = "Scan the table and answer \"where is the cup?\" over a local socket",
    long_about = "Scan the table and answer \"where is the cup?\" over a local socket.\n\n\
        Reads its configuration from --config, else /etc/sqscan/sqscand.toml when that exists, \
        else runs the embedded default: the simulated scanner on scenes/fig3_table.toml with the \
        socket at $XDG_RUNTIME_DIR/sqscand.sock (or ./sqscand.sock). Ask it with `sqscan find cup`, \
        `sqscan status`, `sqscan watch cup`, `sqscan scan`. SIGHUP re-reads the configuration and \
        the models without dropping clients. Logs go to stderr; SQSCAN_LOG=debug shows more."
)]
pub struct DaemonCli {
    /// Configuration file [default: /etc/sqscan/sqscand.toml if it exists, else the embedded
    /// simulator configuration]
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Unix socket to listen on (overrides the file's server.socket)
    #[arg(long, value_name = "PATH")]
    pub socket: Option<PathBuf>,
    /// Directory of object models (overrides the file's server.models_dir) [default:
    /// $SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models,
    /// /usr/share/sqscan/models that exists]
    #[arg(long, value_name = "DIR")]
    pub models_dir: Option<PathBuf>,
    /// Serve the recorded sweeps in DIR instead of scanning (overrides the file's backend): the
    /// daemon's recordings (sweep-*.json and .pcd) and other organized PCD files with a viewpoint
    /// (and, in a build with the mcap feature, MCAP files with a ROS 2 PointCloud2)
    #[arg(long, value_name = "DIR")]
    pub replay: Option<PathBuf>,
    /// With --replay: 1 replays at the recorded pace, 2 twice as fast, 0 as fast as asked
    #[arg(long, value_name = "FACTOR", default_value_t = 1.0, requires = "replay")]
    pub replay_speed: f64,
    /// With --replay: start again after the last sweep instead of stopping there
    #[arg(long, requires = "replay")]
    pub replay_loop: bool,
    /// With --replay: serve one recorded sweep a request, the next each time a client asks for a
    /// fresh one (`sqscan scan`, or a `find` whose newest sweep is too old), at once; the file's
    /// acquisition mode becomes on_demand
    #[arg(long, requires = "replay", conflicts_with = "replay_speed")]
    pub replay_step: bool,
    /// Run every start-up check (configuration, models, scene or calibration, serial devices) and exit
    #[arg(long)]
    pub check: bool,
    /// With --check: also open the configured PTU and sensor and say what they report (the PTU
    /// is not homed or moved; an SQPF sensor is started for one profile); fails naming the device
    /// that does not answer
    #[arg(long, requires = "check")]
    pub probe: bool,
}
