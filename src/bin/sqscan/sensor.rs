//! `sqscan sensor ...`: bring-up tool for a laser profile sensor.

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use sqscan_drivers::sensor::{ProfileSensor, ReceivedProfile, SensorConfig};
use std::path::PathBuf;
use std::time::Duration;

#[derive(Args)]
pub struct SensorArgs {
    /// Serial port (or a mock's pty link), or tcp://HOST:PORT for a networked sensor
    #[arg(long, value_name = "PATH")]
    device: PathBuf,
    /// Line speed
    #[arg(long, default_value_t = 921_600)]
    baud: u32,
    /// Give up when no profile arrives for this many seconds
    #[arg(long, default_value_t = 5.0, value_name = "S")]
    timeout: f64,
    #[command(subcommand)]
    action: Action,
}

#[derive(Subcommand)]
enum Action {
    /// Start acquisition, receive N profiles, stop, and print statistics
    Grab {
        #[arg(default_value_t = 100)]
        count: usize,
    },
}

pub fn run(a: SensorArgs) -> Result<()> {
    let wait = Duration::try_from_secs_f64(a.timeout).context("--timeout: give a number of seconds >= 0")?;
    let Action::Grab { count } = a.action;
    if count == 0 {
        bail!("grab: give a count of at least 1");
    }
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    let cfg = SensorConfig {
        baud: a.baud,
        ..SensorConfig::default()
    };
    let device = a.device.to_string_lossy().into_owned();
    rt.block_on(async {
        if let Some(addr) = device.strip_prefix("tcp://") {
            let sensor = ProfileSensor::connect_tcp(addr, cfg)
                .await
                .with_context(|| format!("cannot reach the sensor at {addr}"))?;
            grab(sensor, count, wait).await
        } else {
            let sensor =
                ProfileSensor::open(&a.device, cfg).with_context(|| format!("cannot open the sensor on {device}"))?;
            grab(sensor, count, wait).await
        }
    })
}

async fn grab<S: sqscan_drivers::Link>(mut sensor: ProfileSensor<S>, count: usize, wait: Duration) -> Result<()> {
    sensor.start().await.context("cannot start acquisition")?;
    let mut got: Vec<ReceivedProfile> = Vec::with_capacity(count.min(100_000));
    while got.len() < count {
        let r = sensor
            .next_profile(wait)
            .await
            .with_context(|| format!("after {} profiles", got.len()))?;
        got.push(r);
    }
    // Stopping is a courtesy to the next user; the profiles are in already.
    if let Err(e) = sensor.stop().await {
        eprintln!("sqscan: warning: cannot stop acquisition: {e}");
    }
    print_stats(&got, &sensor);
    Ok(())
}

fn print_stats<S: sqscan_drivers::Link>(got: &[ReceivedProfile], sensor: &ProfileSensor<S>) {
    let (Some(first), Some(last)) = (got.first(), got.last()) else {
        return;
    };
    let counts = sensor.counts();
    let decoder = sensor.decoder_stats();
    println!(
        "profiles: {}  seq {}..{}  dropped {}  duplicates {}  late {}  restarts {}  bad frames {}  skipped bytes {}",
        got.len(),
        first.profile.seq,
        last.profile.seq,
        counts.dropped,
        counts.duplicates,
        counts.late,
        counts.restarts,
        sensor.frame_errors(),
        decoder.skipped_bytes
    );
    let returns: Vec<usize> = got
        .iter()
        .map(|r| r.profile.rows.iter().filter(|&&v| v != 0).count())
        .collect();
    let columns = first.profile.columns();
    println!(
        "columns: {columns}  with a return: min {}  mean {:.1}  max {}",
        returns.iter().min().unwrap_or(&0),
        returns.iter().sum::<usize>() as f64 / got.len() as f64,
        returns.iter().max().unwrap_or(&0)
    );
    let rows: Vec<f64> = got
        .iter()
        .flat_map(|r| (0..r.profile.columns()).filter_map(|c| r.profile.row_px(c)))
        .collect();
    if rows.is_empty() {
        println!("rows: no returns");
    } else {
        let min = rows.iter().copied().fold(f64::INFINITY, f64::min);
        let max = rows.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        println!(
            "rows (px): min {min:.3}  mean {:.3}  max {max:.3}",
            rows.iter().sum::<f64>() / rows.len() as f64
        );
    }
    // Received profiles by the host clock; profiles the sensor made (sequence span, dropped ones
    // included) by its own clock.
    let host_s = (last.received - first.received).as_secs_f64();
    let sensor_s = last.profile.timestamp_ns.saturating_sub(first.profile.timestamp_ns) as f64 * 1e-9;
    let span = last.profile.seq.wrapping_sub(first.profile.seq) as f64;
    let per_s = |n: f64, s: f64| if s > 0.0 { n / s } else { 0.0 };
    println!(
        "rate: received {:.1} Hz (host clock), sensor {:.1} Hz (sequence span over the sensor clock)",
        per_s((got.len() - 1) as f64, host_s),
        per_s(span, sensor_s)
    );
}
