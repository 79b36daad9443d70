//! One sweep with real devices: drive the PTU through the tilt range while reading profiles,
//! then [`assemble`] them.
//!
//! The order of events:
//!
//! 1. move to the start (`tilt_from_rad` at `pan_rad`) and wait for the move to end;
//! 2. one position sample (it brackets the first profiles: none is exposed before it);
//! 3. `START` to the sensor;
//! 4. the sweep move, tracked with every position sample kept, while profiles are read
//!    concurrently (one task: `select!` over the move and the next profile);
//! 5. when the move has ended, `STOP`, then the frames still on the line are read until it has
//!    been quiet for [`SweepSettings::grace`];
//! 6. one more position sample (it brackets the last profiles: all were exposed before it).
//!
//! Any device error ends the sweep with an error naming the device; the other device is left
//! quiet on a best-effort basis (the PTU halted after a sensor failure, the sensor stopped after
//! a PTU failure). Back-and-forth sweeping is calling this with the tilts swapped
//! ([`SweepSettings::reversed`]); frames left on the line from an earlier sweep were exposed
//! before step 2 and are dropped as outside the samples' span.

use std::time::Duration;

use sqscan_drivers::sensor::{ProfileSource, ReceivedProfile};
use sqscan_drivers::{Goal, PanTilt, PositionSample};

use super::{Sweep, SweepError, SweepSettings, assemble};
use crate::calibration::Calibration;

/// How far short of the goal tilt the PTU may report the sweep move ended (rad).
const GOAL_SLACK_RAD: f64 = 0.01;

/// Runs one sweep and assembles it. See the module docs for the order of events. Any PTU
/// driver and any profile sensor will do: the sweep only needs [`PanTilt`] and
/// [`ProfileSource`].
pub async fn acquire<P: PanTilt, R: ProfileSource>(
    ptu: &mut P,
    sensor: &mut R,
    calib: &Calibration,
    settings: &SweepSettings,
) -> Result<Sweep, SweepError> {
    acquire_live(ptu, sensor, calib, settings, |_| {}).await
}

/// [`acquire`], handing `live` every position sample of the sweep as it is read (those of
/// steps 2, 4 and 6, in time order): the joint angles while the sweep is still going, for a
/// joint-state publisher.
pub async fn acquire_live<P: PanTilt, R: ProfileSource>(
    ptu: &mut P,
    sensor: &mut R,
    calib: &Calibration,
    settings: &SweepSettings,
    mut live: impl FnMut(&PositionSample) + Send,
) -> Result<Sweep, SweepError> {
    settings.validate()?;
    let approach = Goal {
        pan_rad: settings.pan_rad,
        tilt_rad: settings.tilt_from_rad,
        speed_rad_s: settings.approach_speed_rad_s,
    };
    let sweep_goal = Goal {
        tilt_rad: settings.tilt_to_rad,
        speed_rad_s: settings.speed_rad_s,
        ..approach
    };
    // Refuse an out-of-range sweep before moving at all.
    let limits = ptu.limits();
    limits.check(&approach).map_err(SweepError::Ptu)?;
    limits.check(&sweep_goal).map_err(SweepError::Ptu)?;

    // 1. To the start. Worst case from anywhere in the limits at the approach speed.
    let span = (limits.tilt_rad.1 - limits.tilt_rad.0).max(limits.pan_rad.1 - limits.pan_rad.0);
    let approach_time = secs(span.abs() / settings.approach_speed_rad_s).saturating_add(settings.timeout);
    ptu.move_and_track(approach, None, approach_time)
        .await
        .map_err(SweepError::Ptu)?;

    // 2. The sample before the first exposure.
    let mut samples: Vec<PositionSample> = vec![ptu.position().await.map_err(SweepError::Ptu)?];
    live(&samples[0]);

    // 3. Acquisition on.
    sensor.start().await.map_err(SweepError::Sensor)?;
    let started = std::time::Instant::now();

    // 4. The move, reading profiles meanwhile.
    let mut profiles: Vec<ReceivedProfile> = Vec::new();
    let last = sweep_reading(
        ptu,
        sensor,
        sweep_goal,
        settings,
        &mut samples,
        &mut profiles,
        &mut live,
    )
    .await?;

    // 5. Acquisition off; what is still on the line was exposed during the move.
    drain_after_stop(sensor, settings, &mut profiles).await?;

    // A sensor that sent nothing at all failed, whatever the PTU did.
    if profiles.is_empty() {
        return Err(SweepError::Sensor(sqscan_drivers::Error::Timeout {
            waiting_for: "a profile during the sweep",
            after: started.elapsed(),
        }));
    }

    // A move that "ended" short of the goal was halted: a cut-short sweep.
    if (last.tilt_rad - settings.tilt_to_rad).abs() > GOAL_SLACK_RAD {
        return Err(SweepError::PtuStopped {
            tilt_rad: last.tilt_rad,
            goal_rad: settings.tilt_to_rad,
        });
    }

    // 6. The sample after the last exposure.
    let after = ptu.position().await.map_err(SweepError::Ptu)?;
    live(&after);
    samples.push(after);

    let sweep = assemble(&samples, &profiles, calib, settings.sensor_latency_s)?;
    tracing::debug!(report = ?sweep.report, "sweep assembled");
    sweep.require_profiles(settings.min_profiles)
}

/// The sweep's move to `goal`, reading profiles into `profiles` and position samples into
/// `samples` (each handed to `live`) meanwhile; the move's last sample. Where the move fails the
/// sensor is stopped, where the sensor fails the unit is halted.
async fn sweep_reading<P: PanTilt, R: ProfileSource>(
    ptu: &mut P,
    sensor: &mut R,
    goal: Goal,
    settings: &SweepSettings,
    samples: &mut Vec<PositionSample>,
    profiles: &mut Vec<ReceivedProfile>,
    live: &mut (impl FnMut(&PositionSample) + Send),
) -> Result<PositionSample, SweepError> {
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel();
    let track_time = secs(settings.nominal_duration_s()).saturating_add(settings.timeout);
    let moved = {
        let mut sweep = Box::pin(ptu.move_and_track(goal, Some(&tx), track_time));
        loop {
            tokio::select! {
                r = &mut sweep => break Ok(r),
                Some(s) = rx.recv() => {
                    live(&s);
                    samples.push(s);
                }
                r = sensor.next_profile(settings.timeout) => match r {
                    Ok(p) => profiles.push(p),
                    Err(e) => break Err(e),
                },
            }
        }
    };
    drop(tx);
    while let Ok(s) = rx.try_recv() {
        live(&s);
        samples.push(s);
    }
    match moved {
        Ok(Ok(last)) => Ok(last),
        Ok(Err(e)) => {
            let _ = sensor.stop().await;
            Err(SweepError::Ptu(e))
        }
        Err(e) => {
            let _ = ptu.halt().await;
            Err(SweepError::Sensor(e))
        }
    }
}

/// Stops the acquisition and reads what is still on the line (exposed during the move) into
/// `profiles`, until the line has been quiet for three profile periods or `settings.timeout`.
async fn drain_after_stop<R: ProfileSource>(
    sensor: &mut R,
    settings: &SweepSettings,
    profiles: &mut Vec<ReceivedProfile>,
) -> Result<(), SweepError> {
    let stopped = sensor.stop().await;
    if let Err(e) = stopped {
        return Err(SweepError::Sensor(e));
    }
    // Bounded even if the sensor ignored STOP.
    let drain_until = std::time::Instant::now()
        .checked_add(settings.timeout)
        .unwrap_or_else(std::time::Instant::now);
    // A frame still on its way arrives within about one profile period of the last: wait three
    // observed periods (bounded by `grace`) rather than always the whole grace, which would add
    // to every sweep's latency.
    let quiet = drain_quiet(profiles, settings.grace);
    while std::time::Instant::now() < drain_until {
        match sensor.next_profile(quiet).await {
            Ok(p) => profiles.push(p),
            Err(sqscan_drivers::Error::Timeout { .. }) => break,
            Err(e) => return Err(SweepError::Sensor(e)),
        }
    }
    Ok(())
}

fn secs(s: f64) -> Duration {
    Duration::try_from_secs_f64(s).unwrap_or(Duration::MAX)
}

/// How long the line must stay quiet after STOP: three median inter-arrival periods of the
/// profiles so far, at least 10 ms, at most `grace` (all of `grace` when there are too few
/// profiles to tell the rate).
fn drain_quiet(profiles: &[ReceivedProfile], grace: Duration) -> Duration {
    let mut gaps: Vec<Duration> = profiles
        .windows(2)
        .map(|w| w[1].received.saturating_duration_since(w[0].received))
        .collect();
    if gaps.len() < 8 {
        return grace;
    }
    gaps.sort_unstable();
    (gaps[gaps.len() / 2] * 3).clamp(Duration::from_millis(10), grace)
}
