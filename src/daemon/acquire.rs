//! The acquisition loop: sweeps continuously or on demand, publishes each completed sweep, keeps
//! the watched objects' detections warm, records, and survives device faults (a failed sweep is
//! dropped and counted, the device reopened with backoff).

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};

use crate::cloud::PointCloud;
use crate::sim::{self, Scene};
use crate::sweep::SweepReport;

use super::config::{Backend, Config};
use super::hardware::HardwareBackend;
use super::record;
use super::state::{DeviceStatus, Shared, SweepEntry, lock, stopped};

/// A sweep as a backend delivers it.
pub struct SweepData {
    pub started: Instant,
    /// When the last profile was exposed (hardware) or the sweep rendered (simulator): where
    /// sweep-to-answer latency starts.
    pub last_profile: Instant,
    /// Organized, base frame, NaN = no return; `viewpoint` set to the sensor at mid-sweep.
    pub cloud: PointCloud,
    pub profiles: usize,
    pub columns: usize,
    pub report: serde_json::Value,
}

/// Why a sweep failed, and whether the backend has already waited its backoff.
pub struct SweepFailure {
    pub message: String,
}

/// The simulated scanner: the ray-cast model of the rig on a scene file.
pub struct SimBackend {
    scene: Arc<Scene>,
    seed: u64,
    realtime: bool,
    index: u64,
}

impl SimBackend {
    pub fn new(scene_path: &std::path::Path, seed: u64, realtime: bool, config: &Config) -> Result<SimBackend> {
        let mut scene = Scene::from_file(scene_path, &config.models_dir)
            .map_err(|e| anyhow::anyhow!(e.with_causes()))
            .context("loading the simulated scene")?;
        // The [sweep] table, where given, moves the simulated rig as it would the real one.
        let s = &config.sweep;
        if let Some(p) = s.pan_rad {
            scene.rig.pan = p;
        }
        if let Some(t) = s.tilt_from_rad {
            scene.rig.tilt_start = t;
        }
        if let Some(t) = s.tilt_to_rad {
            scene.rig.tilt_end = t;
        }
        if let Some(v) = s.speed_rad_s {
            scene.rig.tilt_speed = v;
        }
        Ok(SimBackend {
            scene: Arc::new(scene),
            seed,
            realtime,
            index: 0,
        })
    }

    pub fn device(&self) -> DeviceStatus {
        let mut d = DeviceStatus::new(
            "simulator",
            self.scene.source.display().to_string(),
            "ray-cast scanner".into(),
        );
        d.connected = true;
        d.opens = 1;
        d
    }

    async fn sweep(&mut self, forward: bool) -> Result<SweepData, SweepFailure> {
        let started = Instant::now();
        let mut scene = (*self.scene).clone();
        if !forward {
            std::mem::swap(&mut scene.rig.tilt_start, &mut scene.rig.tilt_end);
        }
        let duration = Duration::from_secs_f64(scene.rig.sweep_duration());
        let seed = sim::stream_seed(self.seed, self.index);
        self.index += 1;
        let sweep = tokio::task::spawn_blocking(move || sim::simulate(&scene, seed))
            .await
            .map_err(|e| SweepFailure {
                message: format!("simulator failed: {e}"),
            })?;
        if self.realtime {
            // The real rig takes the sweep's duration; pacing keeps sweep ages and rates honest.
            tokio::time::sleep_until((started + duration).into()).await;
        }
        // The same account as an assembled hardware sweep gives: every rendered profile kept.
        let report = SweepReport {
            received: sweep.profiles,
            kept: sweep.profiles,
            points: sweep.finite_points(),
            duration_s: sweep.stamp_s.last().copied().unwrap_or(0.0),
            ..SweepReport::default()
        };
        Ok(SweepData {
            started,
            last_profile: Instant::now(),
            profiles: sweep.profiles,
            columns: sweep.columns,
            cloud: sweep.cloud,
            report: serde_json::to_value(&report).unwrap_or_default(),
        })
    }
}

pub enum AnyBackend {
    Sim(SimBackend),
    Hardware(Box<HardwareBackend>),
}

impl AnyBackend {
    pub fn from_config(config: &Config) -> Result<AnyBackend> {
        Ok(match &config.backend {
            Backend::Sim { scene, seed, realtime } => {
                AnyBackend::Sim(SimBackend::new(scene, *seed, *realtime, config)?)
            }
            Backend::Hardware(h) => AnyBackend::Hardware(Box::new(HardwareBackend::new(h, &config.sweep)?)),
        })
    }

    pub fn devices(&self) -> Vec<DeviceStatus> {
        match self {
            AnyBackend::Sim(s) => vec![s.device()],
            AnyBackend::Hardware(h) => h.devices(),
        }
    }

    async fn sweep(&mut self, forward: bool, shared: &Shared) -> Result<SweepData, SweepFailure> {
        match self {
            AnyBackend::Sim(s) => s.sweep(forward).await,
            AnyBackend::Hardware(h) => h.sweep(forward, shared).await,
        }
    }

    async fn stop(&mut self) {
        if let AnyBackend::Hardware(h) = self {
            h.stop().await;
        }
    }
}

/// Runs until shutdown.
pub async fn run(shared: Arc<Shared>, mut backend: AnyBackend) {
    *lock(&shared.devices) = backend.devices();
    let mut shutdown = shared.shutdown.subscribe();
    let mut next_id = 1u64;
    let mut forward = true;
    let mut last_completed: Option<Instant> = None;
    loop {
        if shared.is_stopping() {
            break;
        }
        if !shared.config.continuous {
            tokio::select! {
                () = shared.sweep_wanted.notified() => {}
                () = stopped(&mut shutdown) => break,
            }
        }
        let result = tokio::select! {
            r = backend.sweep(forward, &shared) => r,
            () = stopped(&mut shutdown) => break,
        };
        match result {
            Ok(data) => {
                let entry = Arc::new(SweepEntry::new(next_id, data));
                next_id += 1;
                shared.stats.sweeps_completed.fetch_add(1, Ordering::Relaxed);
                if let Some(prev) = last_completed {
                    shared.stats.record_sweep_period(prev.elapsed().as_secs_f64());
                }
                last_completed = Some(entry.completed);
                tracing::info!(
                    "sweep {}: {} points, {} profiles",
                    entry.id,
                    entry.points,
                    entry.profiles
                );
                shared.latest.send_replace(Some(entry.clone()));
                warm_detections(&shared, &entry);
                if let Some(dir) = shared.config.record_dir.clone() {
                    let keep = shared.config.record_keep;
                    let e = entry.clone();
                    let s = shared.clone();
                    tokio::task::spawn_blocking(move || {
                        if let Err(err) = record::write_sweep(&dir, &e, keep) {
                            tracing::error!("recording sweep {}: {err:#}", e.id);
                            s.stats.record_fault(format!("recording sweep {}: {err:#}", e.id));
                        }
                    });
                }
                if shared.config.sweep.back_and_forth {
                    forward = !forward;
                }
                if !shared.config.sweep.pause.is_zero() {
                    tokio::select! {
                        () = tokio::time::sleep(shared.config.sweep.pause) => {}
                        () = stopped(&mut shutdown) => break,
                    }
                }
            }
            Err(f) => {
                shared.stats.sweeps_dropped.fetch_add(1, Ordering::Relaxed);
                tracing::warn!("sweep dropped: {}", f.message);
                shared.stats.record_fault(format!("sweep dropped: {}", f.message));
                // A failed sweep leaves the unit somewhere in the range: start the next one
                // from the configured start.
                forward = true;
                if !shared.config.continuous {
                    // Whoever asked is still waiting: try again.
                    shared.sweep_wanted.notify_one();
                }
            }
        }
    }
    backend.stop().await;
}

/// Starts the detections that someone is bound to want on a new sweep: the configured watch
/// list and the objects clients watch. They run once per sweep whoever asks first.
fn warm_detections(shared: &Arc<Shared>, entry: &Arc<SweepEntry>) {
    let mut objects: Vec<String> = shared.config.watch.clone();
    objects.extend(lock(&shared.watched).keys().cloned());
    objects.sort();
    objects.dedup();
    for name in objects {
        if let Ok(model) = shared.model(&name) {
            let (s, e) = (shared.clone(), entry.clone());
            tokio::spawn(async move {
                e.detection(&s, model, false).await;
            });
        }
    }
}
