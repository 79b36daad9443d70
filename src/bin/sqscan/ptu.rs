//! `sqscan ptu ...`: bring-up tool for a pan-tilt unit: status, home, move, sweep.

use anyhow::{Context, Result, bail};
use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Args, Subcommand};
use sqscan_drivers::{AxisConfig, AxisState, Goal, PanTilt, PositionSample, PtuKind, PtuSettings};
use std::path::PathBuf;
use std::time::Duration;

/// `--protocol`: the names of the PTU kind table, listed in the help with their descriptions.
pub fn ptu_kind_parser() -> impl TypedValueParser<Value = PtuKind> {
    PossibleValuesParser::new(PtuKind::ALL.map(|k| PossibleValue::new(k.name()).help(k.description())))
        .try_map(|s| s.parse::<PtuKind>())
}

#[derive(Args)]
pub struct PtuArgs {
    /// Serial port (or a mock's pty link)
    #[arg(long, value_name = "PATH")]
    device: PathBuf,
    /// The unit's protocol
    #[arg(long, value_parser = ptu_kind_parser())]
    protocol: PtuKind,
    /// Line speed [default: 38400 for powercube, 9600 for flir]
    #[arg(long)]
    baud: Option<u32>,
    /// PowerCube module id of the pan joint [default: 12]
    #[arg(long)]
    pan_module: Option<u8>,
    /// PowerCube module id of the tilt joint [default: 11]
    #[arg(long)]
    tilt_module: Option<u8>,
    /// Pan axis sign (+1 or -1): joint = sign * device + offset
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pan_sign: f64,
    /// Pan axis offset (rad): the joint angle at device angle 0
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_name = "RAD")]
    pan_offset: f64,
    /// Tilt axis sign (+1 or -1): joint = sign * device + offset (-1 for a PTU-D46 tilting down
    /// at negative positions)
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    tilt_sign: f64,
    /// Tilt axis offset (rad): the joint angle at device angle 0
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_name = "RAD")]
    tilt_offset: f64,
    /// Give up on a move after this many seconds
    #[arg(long, default_value_t = 60.0, value_name = "S")]
    timeout: f64,
    /// Print one JSON object (both joints' angles, state words and limits, and a sweep's
    /// samples summary) instead of lines of text
    #[arg(long)]
    json: bool,
    #[command(subcommand)]
    action: Action,
}

#[derive(Subcommand)]
enum Action {
    /// Print both joints' angles, state words and limits
    Status,
    /// Reset and home (PowerCube: wait for HOME_OK; PTU-D46: its recalibrating reset)
    Home,
    /// Move to an absolute pose (an axis not given stays where it is) and wait until reached
    Move {
        /// Pan joint angle to reach (rad)
        #[arg(long, allow_negative_numbers = true, value_name = "RAD")]
        pan: Option<f64>,
        /// Tilt joint angle to reach (rad)
        #[arg(long, allow_negative_numbers = true, value_name = "RAD")]
        tilt: Option<f64>,
        /// Joint speed (rad/s)
        #[arg(long, default_value_t = 0.5, value_name = "RAD_S")]
        speed: f64,
    },
    /// Tilt from one angle to another at a constant speed, sampling the position on the way
    Sweep {
        /// Tilt joint angle to start from (rad); the unit moves there first
        #[arg(long, allow_negative_numbers = true, value_name = "RAD")]
        from: f64,
        /// Tilt joint angle to end at (rad)
        #[arg(long, allow_negative_numbers = true, value_name = "RAD")]
        to: f64,
        /// Tilt speed during the sweep (rad/s)
        #[arg(long, value_name = "RAD_S")]
        speed: f64,
    },
}

pub fn run(a: PtuArgs) -> Result<()> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    let pan = AxisConfig::new(a.pan_sign, a.pan_offset).context("--pan-sign/--pan-offset")?;
    let tilt = AxisConfig::new(a.tilt_sign, a.tilt_offset).context("--tilt-sign/--tilt-offset")?;
    let timeout = Duration::try_from_secs_f64(a.timeout).context("--timeout: give a number of seconds >= 0")?;
    for (what, id) in [("pan", a.pan_module), ("tilt", a.tilt_module)] {
        if let Some(n) = id.filter(|n| !(1..=31).contains(n)) {
            bail!("--{what}-module {n}: give 1 to 31");
        }
    }
    let settings = PtuSettings {
        baud: a.baud,
        pan,
        tilt,
        pan_module: a.pan_module,
        tilt_module: a.tilt_module,
    };
    rt.block_on(async {
        let mut ptu = a
            .protocol
            .open(&a.device, &settings)
            .await
            .with_context(|| format!("no {} unit on {}", a.protocol.model(), a.device.display()))?;
        act(&mut ptu, &a.action, timeout, a.json).await
    })
}

async fn act(ptu: &mut impl PanTilt, action: &Action, timeout: Duration, json: bool) -> Result<()> {
    let mut sweep = None;
    match *action {
        Action::Status => {}
        Action::Home => {
            ptu.home().await.context("homing failed")?;
        }
        Action::Move { pan, tilt, speed } => {
            if pan.is_none() && tilt.is_none() {
                bail!("move: give --pan and/or --tilt");
            }
            let now = ptu.position().await?;
            let goal = Goal {
                pan_rad: pan.unwrap_or(now.pan_rad),
                tilt_rad: tilt.unwrap_or(now.tilt_rad),
                speed_rad_s: speed,
            };
            ptu.move_and_track(goal, None, timeout).await.context("move failed")?;
        }
        Action::Sweep { from, to, speed } => {
            let now = ptu.position().await?;
            let start = Goal {
                pan_rad: now.pan_rad,
                tilt_rad: from,
                speed_rad_s: speed.max(0.5),
            };
            ptu.move_and_track(start, None, timeout)
                .await
                .context("move to the sweep start failed")?;
            let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel();
            let goal = Goal {
                tilt_rad: to,
                speed_rad_s: speed,
                ..start
            };
            ptu.move_and_track(goal, Some(&tx), timeout)
                .await
                .context("sweep failed")?;
            drop(tx);
            let mut samples: Vec<PositionSample> = Vec::new();
            while let Some(s) = rx.recv().await {
                samples.push(s);
            }
            sweep = Some(sweep_summary(&samples));
        }
    }
    let state = ptu.state().await.context("cannot read the state")?;
    let limits = ptu.limits();
    if json {
        let axis = |s: &AxisState| serde_json::json!({"position_rad": s.position_rad, "detail": s.detail});
        println!(
            "{}",
            serde_json::json!({
                "pan": axis(&state.pan),
                "tilt": axis(&state.tilt),
                "limits": {"pan_rad": [limits.pan_rad.0, limits.pan_rad.1], "tilt_rad": [limits.tilt_rad.0, limits.tilt_rad.1]},
                "sweep": sweep,
            })
        );
        return Ok(());
    }
    if let Some(s) = &sweep {
        print_sweep(s);
    }
    println!(
        "pan  {}  limits [{:.4}, {:.4}]",
        axis_line(&state.pan),
        limits.pan_rad.0,
        limits.pan_rad.1
    );
    println!(
        "tilt {}  limits [{:.4}, {:.4}]",
        axis_line(&state.tilt),
        limits.tilt_rad.0,
        limits.tilt_rad.1
    );
    Ok(())
}

fn axis_line(s: &AxisState) -> String {
    format!("{:+.4} rad  {}", s.position_rad, s.detail)
}

/// What a sweep's position samples show: how many, over how long, from where to where, and the
/// fastest tilt between two samples; `null` without samples.
fn sweep_summary(samples: &[PositionSample]) -> serde_json::Value {
    let (Some(first), Some(last)) = (samples.first(), samples.last()) else {
        return serde_json::Value::Null;
    };
    let secs = (last.t - first.t).as_secs_f64();
    let max_speed = samples
        .windows(2)
        .map(|w| (w[1].tilt_rad - w[0].tilt_rad).abs() / (w[1].t - w[0].t).as_secs_f64().max(1e-9))
        .fold(0.0, f64::max);
    serde_json::json!({
        "samples": samples.len(),
        "duration_s": secs,
        "rate_hz": (samples.len().saturating_sub(1)) as f64 / secs.max(1e-9),
        "tilt_from_rad": first.tilt_rad,
        "tilt_to_rad": last.tilt_rad,
        "peak_speed_rad_s": max_speed,
    })
}

fn print_sweep(s: &serde_json::Value) {
    if s.is_null() {
        println!("sweep: no position samples");
        return;
    }
    let f = |k: &str| s[k].as_f64().unwrap_or(f64::NAN);
    println!(
        "sweep: {} samples over {:.3} s ({:.1} Hz), tilt {:+.4} -> {:+.4} rad, peak speed {:.3} rad/s",
        s["samples"],
        f("duration_s"),
        f("rate_hz"),
        f("tilt_from_rad"),
        f("tilt_to_rad"),
        f("peak_speed_rad_s")
    );
}
