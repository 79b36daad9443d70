//! The simulator backend: the ray-cast model of the rig on a scene file, paced like the real rig
//! unless told otherwise.

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};

use crate::numeric::stream_seed;
use crate::sim::{self, Scene};

use super::backend::{Backend, DeviceStatus, Devices, JointFeed, SweepFailure, Swept};
use super::config::SweepConfig;

/// The simulated scanner.
pub struct SimBackend {
    scene: Arc<Scene>,
    seed: u64,
    realtime: bool,
    index: u64,
}

impl SimBackend {
    /// Loads the scene; the `[sweep]` table, where given, moves the simulated rig as it would
    /// the real one.
    pub fn new(
        scene_path: &Path,
        models_dir: &Path,
        seed: u64,
        realtime: bool,
        sweep: &SweepConfig,
    ) -> Result<SimBackend> {
        let mut scene = Scene::from_file(scene_path, models_dir)
            .map_err(|e| anyhow::anyhow!(e.with_causes()))
            .context("loading the simulated scene")?;
        if let Some(p) = sweep.pan_rad {
            scene.rig.pan = p;
        }
        if let Some(t) = sweep.tilt_from_rad {
            scene.rig.tilt_start = t;
        }
        if let Some(t) = sweep.tilt_to_rad {
            scene.rig.tilt_end = t;
        }
        if let Some(v) = sweep.speed_rad_s {
            scene.rig.tilt_speed = v;
        }
        Ok(SimBackend {
            scene: Arc::new(scene),
            seed,
            realtime,
            index: 0,
        })
    }
}

impl Backend for SimBackend {
    fn name(&self) -> &'static str {
        "sim"
    }

    fn devices(&self) -> Vec<DeviceStatus> {
        let mut d = DeviceStatus::new(
            "simulator",
            self.scene.source.display().to_string(),
            "ray-cast scanner".into(),
        );
        d.connected = true;
        d.opens = 1;
        vec![d]
    }

    async fn sweep(&mut self, forward: bool, _devices: &Devices, joints: &JointFeed) -> Result<Swept, SweepFailure> {
        let started = Instant::now();
        let mut scene = (*self.scene).clone();
        if !forward {
            std::mem::swap(&mut scene.rig.tilt_start, &mut scene.rig.tilt_end);
        }
        let duration = Duration::from_secs_f64(scene.rig.sweep_duration());
        let seed = stream_seed(self.seed, self.index);
        self.index += 1;
        let sweep = tokio::task::spawn_blocking(move || sim::simulate(&scene, seed))
            .await
            .map_err(|e| SweepFailure {
                message: format!("simulator failed: {e}"),
            })?;
        let last_profile = if self.realtime {
            // The real rig takes the sweep's duration; pacing keeps sweep ages and rates honest,
            // and each profile's angles go out at its time, as a PTU's samples would.
            let at = |s: f64| {
                Duration::try_from_secs_f64(s)
                    .ok()
                    .and_then(|d| started.checked_add(d))
                    .unwrap_or(started)
            };
            for ((stamp, pan), tilt) in sweep.stamp_s.iter().zip(&sweep.pan_rad).zip(&sweep.tilt_rad) {
                tokio::time::sleep_until(at(*stamp).into()).await;
                joints.send(at(*stamp), *pan, *tilt);
            }
            tokio::time::sleep_until((started + duration).into()).await;
            at(sweep.stamp_s.last().copied().unwrap_or(0.0))
        } else {
            let now = Instant::now();
            joints.send_profiles(&sweep, now);
            now
        };
        Ok(Swept {
            sweep,
            started,
            last_profile,
            recorded: None,
        })
    }

    async fn stop(&mut self) {}

    fn mount(&self) -> Option<super::backend::Mount> {
        Some(super::backend::Mount {
            ptu_in_base: self.scene.rig.ptu_in_base,
            sensor_in_tilt: self.scene.rig.sensor_in_tilt,
        })
    }
}
