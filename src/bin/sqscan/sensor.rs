//! `sqscan sensor ...`: bring-up tool for a laser profile sensor.

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use sqscan_drivers::profile::SeqCounts;
use sqscan_drivers::sensor::{ProfileSensor, ProfileSource, ReceivedProfile, SensorConfig};
use std::path::PathBuf;
use std::time::Duration;

#[derive(Args)]
pub struct SensorArgs {
    /// Serial port (or a mock's pty link), tcp://HOST:PORT for a networked sensor, or
    /// gige://ADDRESS for a GigE Vision line-profile camera (a build with the gige feature)
    #[arg(long, value_name = "PATH")]
    device: PathBuf,
    /// GigE Vision: set a GenICam feature before grabbing, NAME=VALUE (true/false, an integer, a
    /// number or an enumeration entry); repeat for more, set in the order given
    #[arg(long = "feature", value_name = "NAME=VALUE")]
    features: Vec<String>,
    /// GigE Vision: profiles a block (the camera's Height) [default: the camera's]
    #[arg(long, value_name = "N")]
    rows_per_frame: Option<u32>,
    /// GigE Vision: fixed-point fraction bits of the profiles (the calibration's)
    #[arg(long, value_name = "BITS", default_value_t = 4)]
    fraction_bits: u8,
    /// Line speed
    #[arg(long, default_value_t = 921_600)]
    baud: u32,
    /// Give up when no profile arrives for this many seconds
    #[arg(long, default_value_t = 5.0, value_name = "S")]
    timeout: f64,
    /// Print one JSON object (grab) or one a camera (discover) instead of text
    #[arg(long)]
    json: bool,
    #[command(subcommand)]
    action: Action,
}

#[derive(Subcommand)]
enum Action {
    /// Start acquisition, receive N profiles, stop, and print statistics
    Grab {
        /// Profiles to receive
        #[arg(default_value_t = 100)]
        count: usize,
    },
    /// List the GigE Vision cameras that answer a discovery broadcast on this host's networks
    /// (give --device gige://ANY; a build with the gige feature)
    Discover,
}

pub fn run(a: SensorArgs) -> Result<()> {
    let wait = Duration::try_from_secs_f64(a.timeout).context("--timeout: give a number of seconds >= 0")?;
    let count = match a.action {
        Action::Grab { count } => count,
        Action::Discover => return discover(a.json),
    };
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
    if let Some(addr) = device.strip_prefix("gige://") {
        return rt.block_on(grab_gige(&a, addr, count, wait));
    }
    if !a.features.is_empty() || a.rows_per_frame.is_some() {
        bail!("--feature and --rows-per-frame are for a GigE Vision camera (--device gige://ADDRESS)");
    }
    rt.block_on(async {
        if let Some(addr) = device.strip_prefix("tcp://") {
            let mut sensor = ProfileSensor::connect_tcp(addr, cfg)
                .await
                .with_context(|| format!("cannot reach the sensor at {addr}"))?;
            let got = grab(&mut sensor, count, wait).await?;
            report(&got, sensor.counts(), sqpf_stats(&sensor), a.json);
        } else {
            let mut sensor =
                ProfileSensor::open(&a.device, cfg).with_context(|| format!("cannot open the sensor on {device}"))?;
            let got = grab(&mut sensor, count, wait).await?;
            report(&got, sensor.counts(), sqpf_stats(&sensor), a.json);
        }
        Ok(())
    })
}

/// What an SQPF link knows beyond the profiles: frames it rejected, bytes it skipped.
fn sqpf_stats<S: sqscan_drivers::Link>(sensor: &ProfileSensor<S>) -> serde_json::Value {
    serde_json::json!({
        "bad_frames": sensor.frame_errors(),
        "skipped_bytes": sensor.decoder_stats().skipped_bytes,
    })
}

#[cfg(feature = "gige")]
fn discover(json: bool) -> Result<()> {
    let found = sqscan_drivers::gige::camera::discover();
    if found.is_empty() && !json {
        println!("no GigE Vision camera answered");
    }
    for d in found {
        if json {
            println!(
                "{}",
                serde_json::json!({"device": format!("gige://{}", d.address), "vendor": d.vendor, "model": d.model, "id": d.id})
            );
        } else {
            println!("gige://{}  {} {}  ({})", d.address, d.vendor, d.model, d.id);
        }
    }
    Ok(())
}

#[cfg(not(feature = "gige"))]
fn discover(_json: bool) -> Result<()> {
    bail!("discover: this sqscan was built without GigE Vision support (cargo feature gige)")
}

#[cfg(feature = "gige")]
async fn grab_gige(a: &SensorArgs, addr: &str, count: usize, wait: Duration) -> Result<()> {
    use sqscan_drivers::gige::FeatureValue;
    use sqscan_drivers::gige::camera::{GigeConfig, GigeSensor};
    let mut cfg = GigeConfig::new(addr);
    for f in &a.features {
        let Some((name, value)) = f.split_once('=') else {
            bail!("--feature {f:?}: give NAME=VALUE");
        };
        let value = match value {
            "true" => FeatureValue::Bool(true),
            "false" => FeatureValue::Bool(false),
            v => match (v.parse::<i64>(), v.parse::<f64>()) {
                (Ok(i), _) => FeatureValue::Int(i),
                (_, Ok(x)) if x.is_finite() => FeatureValue::Float(x),
                _ => FeatureValue::Str(v.to_string()),
            },
        };
        cfg.features.push((name.trim().to_string(), value));
    }
    cfg.rows_per_frame = a.rows_per_frame;
    if a.fraction_bits > 15 {
        bail!("--fraction-bits {}: give 0 to 15", a.fraction_bits);
    }
    cfg.fraction_bits = a.fraction_bits;
    let mut camera = GigeSensor::open(cfg)
        .await
        .with_context(|| format!("cannot open the camera at {addr}"))?;
    let i = camera.info().clone();
    let camera_json = serde_json::json!({
        "device": format!("gige://{addr}"), "vendor": i.vendor, "model": i.model, "serial": i.serial,
        "columns": i.width, "rows_per_frame": i.rows_per_frame, "pixel_format": i.pixel_format,
        "line_rate_hz": i.line_rate_hz, "scale": i.encoding.scale, "offset": i.encoding.offset,
        "invalid": i.encoding.invalid,
    });
    if !a.json {
        println!(
            "camera: {} {} ({}) at {addr}: {} columns, {} profiles a block, {} at {} Hz, scale {} offset {} invalid {}",
            i.vendor,
            i.model,
            i.serial,
            i.width,
            i.rows_per_frame,
            i.pixel_format,
            i.line_rate_hz,
            i.encoding.scale,
            i.encoding.offset,
            i.encoding.invalid.map_or("none".to_string(), |v| v.to_string())
        );
    }
    let got = grab(&mut camera, count, wait).await;
    let counts = camera.counts();
    // Released before exiting, for whoever opens the camera next.
    camera.close();
    report(&got?, counts, serde_json::json!({ "camera": camera_json }), a.json);
    Ok(())
}

#[cfg(not(feature = "gige"))]
async fn grab_gige(_: &SensorArgs, addr: &str, _: usize, _: Duration) -> Result<()> {
    bail!("gige://{addr}: this sqscan was built without GigE Vision support (cargo feature gige)")
}

async fn grab<P: ProfileSource>(sensor: &mut P, count: usize, wait: Duration) -> Result<Vec<ReceivedProfile>> {
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
    Ok(got)
}

/// What the bring-up tool says of a grab, as text or one JSON object; `link` adds what the
/// link knows (SQPF: bad frames and skipped bytes; GigE Vision: the camera).
fn report(got: &[ReceivedProfile], counts: SeqCounts, link: serde_json::Value, json: bool) {
    let (Some(first), Some(last)) = (got.first(), got.last()) else {
        return;
    };
    let returns: Vec<usize> = got
        .iter()
        .map(|r| r.profile.rows.iter().filter(|&&v| v != 0).count())
        .collect();
    let columns = first.profile.columns();
    let (ret_min, ret_max) = (*returns.iter().min().unwrap_or(&0), *returns.iter().max().unwrap_or(&0));
    let ret_mean = returns.iter().sum::<usize>() as f64 / got.len() as f64;
    let rows: Vec<f64> = got
        .iter()
        .flat_map(|r| (0..r.profile.columns()).filter_map(|c| r.profile.row_px(c)))
        .collect();
    let row_stats = (!rows.is_empty()).then(|| {
        (
            rows.iter().copied().fold(f64::INFINITY, f64::min),
            rows.iter().sum::<f64>() / rows.len() as f64,
            rows.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        )
    });
    // Received profiles by the host clock; profiles the sensor made (sequence span, dropped ones
    // included) by its own clock.
    let host_s = (last.received - first.received).as_secs_f64();
    let sensor_s = last.profile.timestamp_ns.saturating_sub(first.profile.timestamp_ns) as f64 * 1e-9;
    let span = last.profile.seq.wrapping_sub(first.profile.seq) as f64;
    let per_s = |n: f64, s: f64| if s > 0.0 { n / s } else { 0.0 };
    let (received_hz, sensor_hz) = (per_s((got.len() - 1) as f64, host_s), per_s(span, sensor_s));
    if json {
        let mut v = serde_json::json!({
            "profiles": got.len(), "seq": [first.profile.seq, last.profile.seq],
            "dropped": counts.dropped, "duplicates": counts.duplicates, "late": counts.late,
            "restarts": counts.restarts, "columns": columns,
            "with_a_return": {"min": ret_min, "mean": ret_mean, "max": ret_max},
            "rows_px": row_stats.map(|(min, mean, max)| serde_json::json!({"min": min, "mean": mean, "max": max})),
            "rate_hz": {"received": received_hz, "sensor": sensor_hz},
        });
        if let (Some(o), serde_json::Value::Object(extra)) = (v.as_object_mut(), link) {
            o.extend(extra);
        }
        println!("{v}");
        return;
    }
    let extra = match &link {
        serde_json::Value::Object(o) if o.contains_key("bad_frames") => {
            format!("  bad frames {}  skipped bytes {}", o["bad_frames"], o["skipped_bytes"])
        }
        _ => String::new(),
    };
    println!(
        "profiles: {}  seq {}..{}  dropped {}  duplicates {}  late {}  restarts {}{extra}",
        got.len(),
        first.profile.seq,
        last.profile.seq,
        counts.dropped,
        counts.duplicates,
        counts.late,
        counts.restarts,
    );
    println!("columns: {columns}  with a return: min {ret_min}  mean {ret_mean:.1}  max {ret_max}");
    match row_stats {
        None => println!("rows: no returns"),
        Some((min, mean, max)) => println!("rows (px): min {min:.3}  mean {mean:.3}  max {max:.3}"),
    }
    println!(
        "rate: received {received_hz:.1} Hz (host clock), sensor {sensor_hz:.1} Hz (sequence span over the sensor clock)"
    );
}
