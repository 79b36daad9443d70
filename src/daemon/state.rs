//! What the daemon's tasks share: the newest sweep (with the detections made on it), the
//! devices' health, counters, and the set of objects clients watch.
//!
//! Sweeps are published through a `tokio::sync::watch` channel: acquisition never waits on a
//! reader, and a reader that falls behind simply sees the newest sweep. Detections are made at
//! most once per (sweep, object, all): every request for the same answer awaits one
//! `OnceCell`, so 200 clients asking "find cup" cost one detection.
//!
//! Over 600 lines on purpose: the shared state and the only methods that reach into it are one
//! wall, with the sweep entry whose detections run in its slots; split, the fields would have to
//! open again.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, RwLock};
use std::time::{Duration, Instant, SystemTime};

use nalgebra::Point3;
use tokio::sync::{Notify, OnceCell, Semaphore, watch};

use crate::detect::{self, Params, Report};
use crate::model::Model;
use crate::numeric::median;
use crate::sweep::Sweep;

use super::backend::{DeviceStatus, Devices, Recorded, Swept};
use super::config::Config;
use super::reply::{
    ClientCounts, ConfigInfo, DetectionCounts, Fault, Mode, RecordedJson, Status, SweepCounts, SweepRef, SweepSummary,
};
use super::shutdown::Shutdown;

/// Locks a std mutex, taking the data even if a panicking thread poisoned it: the data here are
/// counters and status texts, always consistent between statements.
pub fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// One completed sweep.
pub struct SweepEntry {
    pub id: u64,
    pub started: Instant,
    pub completed: Instant,
    /// The last profile's exposure (see [`Swept::last_profile`]).
    pub last_profile: Instant,
    pub completed_wall: SystemTime,
    pub sweep: Sweep,
    /// Where a replayed sweep was read from.
    pub recorded: Option<Recorded>,
    /// Points with a return in the cloud.
    pub points: usize,
    detections: Mutex<HashMap<DetectionKey, DetectionCell>>,
    /// The filtered cloud without its plane, by the load it was made under (the range cut is
    /// the configuration's); `None` where making it failed.
    scenes: Mutex<HashMap<u64, SceneCell>>,
}

/// One load's filtered scene, made by whoever asks first and awaited by the rest.
type SceneCell = Arc<OnceCell<Option<Arc<detect::Scene>>>>;

/// One detection of a sweep, made by whoever asks first and awaited by the rest.
type DetectionCell = Arc<OnceCell<Arc<Detected>>>;

/// A detection's key: the object, `all`, and the load it was made under.
type DetectionKey = (String, bool, u64);

/// A detection made on a sweep, and when it was done.
pub struct Detected {
    pub report: Report,
    /// From the sweep's last profile to this detection's end: what a client waiting on the
    /// sweep waits beyond the scan itself (assembly, queueing, detection).
    pub latency: Duration,
}

impl SweepEntry {
    /// The sweep a backend delivered, completed now.
    pub fn new(id: u64, swept: Swept) -> Self {
        SweepEntry {
            id,
            started: swept.started,
            completed: Instant::now(),
            last_profile: swept.last_profile,
            completed_wall: SystemTime::now(),
            points: swept.sweep.cloud.finite_count(),
            sweep: swept.sweep,
            recorded: swept.recorded,
            detections: Mutex::new(HashMap::new()),
            scenes: Mutex::new(HashMap::new()),
        }
    }

    pub fn age(&self) -> Duration {
        self.completed.elapsed()
    }

    /// Unix time of completion (s).
    pub fn time_s(&self) -> f64 {
        self.completed_wall
            .duration_since(SystemTime::UNIX_EPOCH)
            .map(|d| d.as_secs_f64())
            .unwrap_or(0.0)
    }

    /// The id the detector's seed comes from: the recorded sweep's for a replay (so the replay
    /// answers as the daemon that recorded it did), else this sweep's.
    pub fn seed_id(&self) -> u64 {
        self.recorded.as_ref().and_then(|r| r.id).unwrap_or(self.id)
    }

    /// Where a replayed sweep came from, as replies show it (`null` for a sweep made now).
    pub fn recorded_json(&self) -> Option<RecordedJson> {
        self.recorded.as_ref().map(|r| RecordedJson {
            id: r.id,
            file: r.file.display().to_string(),
        })
    }

    /// The sweep as a detection names it.
    pub fn reference(&self) -> SweepRef {
        SweepRef {
            id: self.id,
            time: self.time_s(),
            age_s: round3(self.age().as_secs_f64()),
            points: self.points,
            recorded: self.recorded_json(),
        }
    }

    /// The sensor position for the detector: the cloud's viewpoint.
    fn viewpoint(&self) -> Option<Point3<f64>> {
        self.sweep.cloud.viewpoint_position()
    }

    /// The detection of `model` on this sweep, made once however many ask; off the async
    /// worker threads, at most `detect_workers` at a time.
    pub async fn detection(self: &Arc<Self>, shared: &Shared, model: Arc<Model>, all: bool) -> Arc<Detected> {
        // Keyed by the load too: after a reload (a changed model, seed or range) the sweep's
        // detections are made anew.
        let loaded = shared.loaded();
        let model = loaded.models.get(&model.name).cloned().unwrap_or(model);
        let cell = lock(&self.detections)
            .entry((model.name.clone(), all, loaded.generation))
            .or_insert_with(|| Arc::new(OnceCell::new()))
            .clone();
        cell.get_or_init(|| async {
            // The semaphore is never closed, so acquire cannot fail; a detection then runs anyway.
            let _permit = shared.detection_slot().await;
            let entry = self.clone();
            let config = &loaded.config;
            let params = Params {
                seed: config.detect_seed ^ entry.seed_id(),
                viewpoint: entry.viewpoint(),
                max_range: config.max_range_m,
                all,
                ..Params::default()
            };
            let started = Instant::now();
            // The filtered cloud without its plane serves every object of this sweep and load:
            // made by the first detection, taken by the rest (on a 300 000-point sweep it is
            // a third of a detection).
            let scene_cell = lock(&self.scenes)
                .entry(loaded.generation)
                .or_insert_with(|| Arc::new(OnceCell::new()))
                .clone();
            let mut plane_ms = 0.0;
            let scene = scene_cell
                .get_or_init(|| async {
                    let (e, p) = (entry.clone(), params.clone());
                    let t = Instant::now();
                    let made = tokio::task::spawn_blocking(move || Arc::new(detect::scene(&e.sweep.cloud.points, &p)));
                    let scene = made.await.ok();
                    plane_ms = t.elapsed().as_secs_f64() * 1e3;
                    scene
                })
                .await
                .clone();
            let model_for_view = model.clone();
            let job = tokio::task::spawn_blocking(move || {
                scene.map(|scene| detect::detect_in(&scene, &model, &params, plane_ms))
            });
            let report = match job.await {
                Ok(Some(r)) => r,
                // A panic in the detector is a bug; answer "nothing found" rather than take the
                // daemon down, and say so in the log.
                failed => {
                    let e = failed
                        .err()
                        .map_or_else(|| "its scene could not be made".to_string(), |e| e.to_string());
                    tracing::error!("detector failed on sweep {}: {e}", self.id);
                    Report {
                        object: String::new(),
                        detections: Vec::new(),
                        plane: None,
                        points: 0,
                        scene_points: 0,
                        timing: Default::default(),
                    }
                }
            };
            let latency = self.last_profile.elapsed();
            shared.stats().record_detection(started.elapsed(), latency);
            let detected = Arc::new(Detected { latency, report });
            // Nobody listening (no live view) is no error.
            shared.announce((self.clone(), model_for_view, detected.clone()));
            detected
        })
        .await
        .clone()
    }

    /// The sweep as the `scan` reply and `status` show it.
    pub fn summary(&self) -> SweepSummary {
        SweepSummary {
            id: self.id,
            time: self.time_s(),
            age_s: round3(self.age().as_secs_f64()),
            duration_s: round3(self.completed.duration_since(self.started).as_secs_f64()),
            profiles: self.sweep.profiles,
            columns: self.sweep.columns,
            points: self.points,
            report: self.sweep.report.clone(),
            recorded: self.recorded_json(),
        }
    }
}

pub fn round3(x: f64) -> f64 {
    (x * 1e3).round() / 1e3
}

/// Running figures for `status`.
#[derive(Default)]
pub struct Stats {
    pub sweeps_completed: AtomicU64,
    pub sweeps_dropped: AtomicU64,
    /// Sweeps whose recording failed (and was removed).
    pub recordings_lost: AtomicU64,
    pub requests: AtomicU64,
    pub errors_sent: AtomicU64,
    pub watch_skipped: AtomicU64,
    pub clients: AtomicUsize,
    pub clients_total: AtomicU64,
    detections: Mutex<DetectionTimes>,
    /// The newest faults, newest last.
    pub faults: Mutex<VecDeque<(SystemTime, String)>>,
    sweep_periods: Mutex<VecDeque<f64>>,
}

#[derive(Default)]
struct DetectionTimes {
    count: u64,
    /// Recent detection run times and sweep-to-answer latencies (s).
    run: VecDeque<f64>,
    latency: VecDeque<f64>,
}

const RECENT: usize = 64;

fn push_recent(q: &mut VecDeque<f64>, x: f64) {
    if q.len() == RECENT {
        q.pop_front();
    }
    q.push_back(x);
}

/// The median of a window of recent values.
fn median_of(q: &VecDeque<f64>) -> Option<f64> {
    median(&mut q.iter().copied().collect::<Vec<f64>>())
}

impl Stats {
    pub fn record_detection(&self, run: Duration, latency: Duration) {
        let mut d = lock(&self.detections);
        d.count += 1;
        push_recent(&mut d.run, run.as_secs_f64());
        push_recent(&mut d.latency, latency.as_secs_f64());
    }

    pub fn record_fault(&self, message: String) {
        let mut f = lock(&self.faults);
        if f.len() == 16 {
            f.pop_front();
        }
        f.push_back((SystemTime::now(), message));
    }

    pub fn record_sweep_period(&self, period: f64) {
        push_recent(&mut lock(&self.sweep_periods), period);
    }
}

/// The newest (re)load of the configuration and models.
#[derive(Debug, Clone)]
pub struct Reload {
    pub loaded: SystemTime,
    /// Reloads taken.
    pub count: u64,
    /// Why the newest reload was refused, if it was.
    pub error: Option<String>,
}

/// The configuration and the models in use, swapped together by a reload.
pub struct Loaded {
    pub config: Arc<Config>,
    pub models: Arc<BTreeMap<String, Arc<Model>>>,
    /// Counts the loads (0 at start): a detection made under one is not served under another.
    pub generation: u64,
}

/// `cloud` payloads in memory at once, over all clients: each is held from its encoding until
/// the client's writer has written it (or given up on a client that does not read, after the
/// writer's timeout, `WRITE_TIMEOUT` of `outbox.rs`), so clients that ask for clouds and never
/// read cannot pile them up.
pub const CLOUD_SLOTS: usize = 4;

/// Everything the tasks share.
pub struct Shared {
    /// The configuration and the models in use: swapped whole by a reload (SIGHUP), so a task
    /// that took one sees a consistent set until it asks again.
    loaded: RwLock<Arc<Loaded>>,
    reload: Mutex<Reload>,
    /// The newest completed sweep.
    latest: watch::Sender<Option<Arc<SweepEntry>>>,
    /// Wakes an on-demand acquisition loop.
    sweep_wanted: Notify,
    /// What the backend calls itself (`status` shows it).
    backend: &'static str,
    /// The rig's fixed transforms, where the backend knows them (published and recorded as
    /// `/tf_static`).
    mount: Option<super::backend::Mount>,
    devices: Devices,
    stats: Stats,
    /// Objects watched by clients, with how many watch each.
    watched: Mutex<BTreeMap<String, usize>>,
    detect_slots: Semaphore,
    /// `cloud` payloads in memory at once ([`CLOUD_SLOTS`]).
    cloud_slots: Arc<Semaphore>,
    /// `cloud` requests waiting for one of those slots: while there are any, a transfer that
    /// makes no progress loses its slot sooner (`outbox::STALL_WHILE_WANTED`).
    cloud_waiting: std::sync::atomic::AtomicUsize,
    started: Instant,
    /// Thrown when the daemon is stopping.
    shutdown: Shutdown,
    /// Why a task the daemon cannot run without ended (a panic, or a return before shutdown):
    /// `status` reports it, the systemd watchdog stops, and `sqscand` exits with an error.
    failure: watch::Sender<Option<String>>,
    /// Every detection as it is made, for whoever shows them (the live view).
    detected: tokio::sync::broadcast::Sender<DetectedEvent>,
    /// The PTU's joint angles as the sweeps go (ROS 2 publishes them).
    joints: super::backend::JointFeed,
}

/// A detection made, on which sweep, of which model.
pub type DetectedEvent = (Arc<SweepEntry>, Arc<Model>, Arc<Detected>);

impl Shared {
    /// With the rig's fixed transforms.
    pub fn with_mount(mut self, mount: Option<super::backend::Mount>) -> Shared {
        self.mount = mount;
        self
    }

    pub fn new(config: Config, models: BTreeMap<String, Arc<Model>>, backend: &'static str) -> Shared {
        let workers = config.detect_workers;
        Shared {
            loaded: RwLock::new(Arc::new(Loaded {
                config: Arc::new(config),
                models: Arc::new(models),
                generation: 0,
            })),
            reload: Mutex::new(Reload {
                loaded: SystemTime::now(),
                count: 0,
                error: None,
            }),
            latest: watch::channel(None).0,
            failure: watch::channel(None).0,
            sweep_wanted: Notify::new(),
            backend,
            mount: None,
            devices: Devices::default(),
            stats: Stats::default(),
            watched: Mutex::new(BTreeMap::new()),
            detect_slots: Semaphore::new(workers),
            cloud_slots: Arc::new(Semaphore::new(CLOUD_SLOTS)),
            cloud_waiting: Default::default(),
            started: Instant::now(),
            shutdown: Shutdown::default(),
            // A viewer that falls this far behind misses detections (it is told it lagged).
            detected: tokio::sync::broadcast::channel(64).0,
            joints: Default::default(),
        }
    }

    /// The configuration in use.
    pub fn config(&self) -> Arc<Config> {
        self.loaded().config.clone()
    }

    /// The models in use.
    pub fn models(&self) -> Arc<BTreeMap<String, Arc<Model>>> {
        self.loaded().models.clone()
    }

    /// The configuration and the models in use, as one consistent pair.
    pub fn loaded(&self) -> Arc<Loaded> {
        self.loaded.read().unwrap_or_else(|p| p.into_inner()).clone()
    }

    /// Puts a reloaded configuration and its models in use.
    pub fn replace(&self, config: Config, models: BTreeMap<String, Arc<Model>>) {
        let mut slot = self.loaded.write().unwrap_or_else(|p| p.into_inner());
        let generation = slot.generation + 1;
        *slot = Arc::new(Loaded {
            config: Arc::new(config),
            models: Arc::new(models),
            generation,
        });
        drop(slot);
        let mut r = lock(&self.reload);
        r.loaded = SystemTime::now();
        r.count += 1;
        r.error = None;
    }

    pub fn newest(&self) -> Option<Arc<SweepEntry>> {
        self.latest.borrow().clone()
    }

    /// A model by name, or an error naming the known ones.
    pub fn model(&self, name: &str) -> Result<Arc<Model>, String> {
        let models = self.models();
        models.get(name).cloned().ok_or_else(|| {
            let known: Vec<&str> = models.keys().map(String::as_str).collect();
            format!("unknown object {name:?}; known objects: {}", known.join(", "))
        })
    }

    /// One line on what is wrong with the devices, for error replies ("" when all is well).
    pub fn device_trouble(&self) -> String {
        self.devices.trouble()
    }

    pub fn is_stopping(&self) -> bool {
        self.shutdown.begun()
    }

    /// The daemon's shutdown switch.
    pub fn shutdown(&self) -> &Shutdown {
        &self.shutdown
    }

    /// Publishes a completed sweep as the newest.
    pub fn publish_sweep(&self, entry: Arc<SweepEntry>) {
        self.latest.send_replace(Some(entry));
    }

    /// Follows the newest sweep.
    pub fn sweeps(&self) -> watch::Receiver<Option<Arc<SweepEntry>>> {
        self.latest.subscribe()
    }

    /// Asks an on-demand acquisition loop for a sweep (kept until the loop next waits).
    pub fn want_sweep(&self) {
        self.sweep_wanted.notify_one();
    }

    /// Resolves when a sweep is asked for.
    pub async fn sweep_asked(&self) {
        self.sweep_wanted.notified().await
    }

    /// Records why a task the daemon cannot run without ended.
    pub fn fail(&self, why: String) {
        self.failure.send_replace(Some(why));
    }

    /// Why the daemon failed, if it did.
    pub fn failure(&self) -> Option<String> {
        self.failure.borrow().clone()
    }

    /// Follows the daemon's failure.
    pub fn failures(&self) -> watch::Receiver<Option<String>> {
        self.failure.subscribe()
    }

    /// Moves one client's watch from the objects `old` to `new`.
    pub fn move_watch(&self, old: &[String], new: &[String]) {
        let mut w = lock(&self.watched);
        for o in old {
            if let Some(n) = w.get_mut(o) {
                *n -= 1;
                if *n == 0 {
                    w.remove(o);
                }
            }
        }
        for o in new {
            *w.entry(o.clone()).or_insert(0) += 1;
        }
    }

    /// The objects some client watches.
    pub fn watched(&self) -> Vec<String> {
        lock(&self.watched).keys().cloned().collect()
    }

    /// Tells whoever shows detections (the live view, ROS 2) of one made.
    pub fn announce(&self, event: DetectedEvent) {
        let _ = self.detected.send(event);
    }

    /// Follows the detections as they are made.
    #[cfg(any(feature = "mcap", feature = "foxglove", feature = "ros2"))]
    pub fn detections(&self) -> tokio::sync::broadcast::Receiver<DetectedEvent> {
        self.detected.subscribe()
    }

    /// One of the `detect.workers` slots a detection runs in; `None` once they are closed.
    pub async fn detection_slot(&self) -> Option<tokio::sync::SemaphorePermit<'_>> {
        self.detect_slots.acquire().await.ok()
    }

    /// One of the [`CLOUD_SLOTS`]; `None` once they are closed.
    pub async fn cloud_slot(&self) -> Option<tokio::sync::OwnedSemaphorePermit> {
        self.cloud_slots.clone().acquire_owned().await.ok()
    }

    /// `cloud` requests waiting for one of the slots: while there are any, a transfer that
    /// makes no progress loses its slot sooner.
    pub fn cloud_waiting(&self) -> &std::sync::atomic::AtomicUsize {
        &self.cloud_waiting
    }

    /// Records why the last reload failed (the configuration in use stays).
    pub fn reload_failed(&self, why: String) {
        lock(&self.reload).error = Some(why);
    }

    /// When the configuration was last loaded, how often, and why the last reload failed.
    pub fn reload_status(&self) -> Reload {
        lock(&self.reload).clone()
    }

    /// The rig's fixed transforms, where the backend knows them.
    pub fn mount(&self) -> Option<&super::backend::Mount> {
        self.mount.as_ref()
    }

    /// The devices' states, as the backend reports them.
    pub fn devices(&self) -> &Devices {
        &self.devices
    }

    /// The daemon's counters.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// The PTU's joint angles as the sweeps go.
    pub fn joints(&self) -> &super::backend::JointFeed {
        &self.joints
    }

    pub fn status(&self) -> Status {
        let s = &self.stats;
        let det = lock(&s.detections);
        let periods = lock(&s.sweep_periods);
        let sweep_rate = median_of(&periods).filter(|p| *p > 0.0).map(|p| round3(60.0 / p));
        let config = self.config();
        let reload = self.reload_status();
        let unix = |t: SystemTime| {
            t.duration_since(SystemTime::UNIX_EPOCH)
                .map(|d| d.as_secs_f64())
                .unwrap_or(0.0)
        };
        Status {
            id: None,
            release: env!("CARGO_PKG_VERSION").to_string(),
            failure: self.failure.borrow().clone(),
            uptime_s: round3(self.started.elapsed().as_secs_f64()),
            backend: self.backend.to_string(),
            mode: if config.continuous {
                Mode::Continuous
            } else {
                Mode::OnDemand
            },
            devices: self.devices.snapshot().iter().map(DeviceStatus::json).collect(),
            last_sweep: self.newest().map(|e| e.summary()),
            sweeps: SweepCounts {
                completed: s.sweeps_completed.load(Ordering::Relaxed),
                dropped: s.sweeps_dropped.load(Ordering::Relaxed),
                not_recorded: s.recordings_lost.load(Ordering::Relaxed),
                per_minute: sweep_rate,
            },
            detections: DetectionCounts {
                count: det.count,
                median_run_ms: median_of(&det.run).map(|x| round3(x * 1e3)),
                median_latency_ms: median_of(&det.latency).map(|x| round3(x * 1e3)),
            },
            clients: ClientCounts {
                connected: s.clients.load(Ordering::Relaxed),
                total: s.clients_total.load(Ordering::Relaxed),
                requests: s.requests.load(Ordering::Relaxed),
                errors: s.errors_sent.load(Ordering::Relaxed),
                watch_updates_skipped: s.watch_skipped.load(Ordering::Relaxed),
            },
            watched: lock(&self.watched)
                .keys()
                .cloned()
                .chain(config.watch.iter().cloned())
                .collect::<std::collections::BTreeSet<_>>()
                .into_iter()
                .collect(),
            faults: lock(&s.faults)
                .iter()
                .map(|(t, m)| Fault {
                    time: unix(*t),
                    message: m.clone(),
                })
                .collect(),
            config: ConfigInfo {
                file: config.source.as_ref().map(|p| p.display().to_string()),
                models_dir: config.models_dir.display().to_string(),
                loaded: unix(reload.loaded),
                reloads: reload.count,
                reload_error: reload.error,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2 x 3 sweep of a flat patch.
    fn entry(id: u64) -> Arc<SweepEntry> {
        let sweep = Sweep::flat_patch(None);
        let now = Instant::now();
        Arc::new(SweepEntry::new(
            id,
            Swept {
                sweep,
                started: now,
                last_profile: now,
                recorded: None,
            },
        ))
    }

    /// A sweep's detection is made once per load: asked again it is the same answer, asked after
    /// a reload (which may have changed the model, the seed or the range) it is made anew.
    #[tokio::test]
    async fn a_detection_made_before_a_reload_is_not_served_after_it() {
        let models =
            crate::daemon::load_models(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models")).unwrap();
        let config = Config::embedded_default();
        let shared = Shared::new(config.clone(), models.clone(), "test");
        let e = entry(1);
        let cup = shared.model("cup").unwrap();
        let first = e.detection(&shared, cup.clone(), false).await;
        let again = e.detection(&shared, cup.clone(), false).await;
        assert!(Arc::ptr_eq(&first, &again));
        shared.replace(config, models);
        let after = e.detection(&shared, cup, false).await;
        assert!(!Arc::ptr_eq(&first, &after));
        assert_eq!(shared.loaded().generation, 1);
        assert_eq!(shared.reload_status().count, 1);
    }

    /// The objects asked for on one sweep share its filtered, plane-free scene: the first
    /// detection makes it (and reports its time), the others take it; a reload makes it anew.
    #[tokio::test]
    async fn the_objects_of_one_sweep_share_its_scene() {
        let models =
            crate::daemon::load_models(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models")).unwrap();
        let config = Config::embedded_default();
        let shared = Shared::new(config.clone(), models.clone(), "test");
        let e = entry(1);
        let cup = e.detection(&shared, shared.model("cup").unwrap(), false).await;
        let bowl = e.detection(&shared, shared.model("bowl").unwrap(), false).await;
        assert_eq!(lock(&e.scenes).len(), 1);
        assert_eq!(bowl.report.timing.plane_ms, 0.0);
        assert!(cup.report.timing.plane_ms > 0.0);
        shared.replace(config, models);
        e.detection(&shared, shared.model("bowl").unwrap(), false).await;
        assert_eq!(lock(&e.scenes).len(), 2);
    }
}
