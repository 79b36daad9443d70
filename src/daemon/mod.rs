//! `sqscand`: scans continuously (or on demand), detects the objects clients ask for on every
//! completed sweep, and answers over a local socket (`docs/PROTOCOL.md`).
//!
//! Tasks, all on one tokio runtime:
//! - acquisition ([`acquire::run`]): drives the [`Backend`] (the simulator, a PTU and a sensor,
//!   or whatever implements the trait), publishes each sweep;
//! - the server ([`server::serve`]): one task a client, one a request;
//! - detections: on the blocking pool, once per (sweep, object), at most `detect.workers` at a
//!   time ([`state::SweepEntry::detection`]);
//! - systemd: READY once listening, STATUS after each sweep, WATCHDOG at half the interval.
//!
//! [`Daemon::serve`] takes its backend and its listeners from the caller, so a test can hand it
//! a socket bound to `127.0.0.1:0` and a backend of its own; [`Daemon::start`] builds both from
//! the configuration, as `sqscand` does.
//!
//! Module arrows point one way: `backend` (the trait and the types it hands over) at the
//! bottom; `simulator` and `hardware` implement it; `state` holds what the tasks share, with
//! the [`shutdown`] switch every task listens to; `acquire` and `server` run on it. Within the server: `server` accepts clients, `connection`
//! serves one (its reader and its `Handler`, a method a request kind), over
//! `outbox` (its queue and writer); `answer` replies to requests, `cloud` sends points, and
//! both wait for sweeps through `waiting`.

mod acquire;
mod answer;
mod backend;
#[cfg(feature = "mcap")]
mod bag;
pub mod cli;
mod cloud;
pub mod config;
mod connection;
mod hardware;
mod idle;
mod lines;
pub mod memory;
pub mod notify;
mod outbox;
pub mod protocol;
mod record;
#[cfg(feature = "mcap")]
mod record_mcap;
mod replay;
pub mod reply;
#[cfg(feature = "ros2")]
mod ros2;
mod server;
pub mod shutdown;
mod simulator;
mod socket;
mod state;
#[cfg(any(feature = "mcap", feature = "foxglove", feature = "ros2"))]
mod topics;
#[cfg(feature = "foxglove")]
mod view;
mod waiting;

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Result, bail};

use crate::model::{self, Model};

pub use backend::{Backend, DeviceStatus, Devices, JointFeed, JointSample, Recorded, SweepFailure, Swept};
use config::{BackendConfig, Config};
use hardware::HardwareBackend;
use replay::ReplayBackend;
pub use server::Listeners;
use simulator::SimBackend;
use state::Shared;

/// Loads every model of the directory; a broken file is reported and skipped, not fatal (one
/// bad model must not take the scanner down), but an empty set is.
pub fn load_models(dir: &std::path::Path) -> Result<BTreeMap<String, Arc<Model>>> {
    if !dir.is_dir() {
        bail!("{}", model::missing_models_dir(dir));
    }
    let mut out = BTreeMap::new();
    for m in model::load_dir(dir).map_err(|e| anyhow::anyhow!(e.with_causes()))? {
        match m {
            Ok(m) => {
                out.insert(m.name.clone(), Arc::new(m));
            }
            Err(e) => tracing::error!("skipping a model: {}", e.with_causes()),
        }
    }
    if out.is_empty() {
        bail!("no usable model in {}", dir.display());
    }
    Ok(out)
}

/// Refuses a watch list naming an object there is no model of.
fn check_watch(config: &Config, models: &BTreeMap<String, Arc<Model>>) -> Result<()> {
    if let Some(w) = config.watch.iter().find(|w| !models.contains_key(*w)) {
        bail!(
            "{}: watch.objects: unknown object {w:?}",
            config
                .source
                .as_deref()
                .map(|p| p.display().to_string())
                .unwrap_or_default()
        );
    }
    Ok(())
}

/// Loads what the configuration names (models, scene or calibration) without starting
/// anything: `sqscand --check`. Returns the models.
pub fn check(config: &Config) -> Result<BTreeMap<String, Arc<Model>>> {
    let models = load_models(&config.models_dir)?;
    check_watch(config, &models)?;
    match &config.backend {
        BackendConfig::Sim { scene, seed, realtime } => {
            SimBackend::new(scene, &config.models_dir, *seed, *realtime, &config.sweep)?;
        }
        BackendConfig::Hardware(h) => {
            HardwareBackend::new(h, &config.sweep)?;
            for w in HardwareBackend::check_devices(h)? {
                tracing::warn!("{w}");
            }
        }
        BackendConfig::Replay { dir, speed, looping } => {
            ReplayBackend::new(dir, *speed, *looping)?.check_all()?;
        }
    }
    Ok(models)
}

/// `sqscand --check --probe`: [`check`], then opens the configured devices (a rig's PTU and
/// sensor) and returns a line on each; an error names the device that failed. Other backends
/// have no devices: their line says so.
pub async fn probe(config: &Config) -> Result<Vec<String>> {
    match &config.backend {
        BackendConfig::Hardware(h) => HardwareBackend::new(h, &config.sweep)?.probe().await,
        BackendConfig::Sim { .. } => Ok(vec!["the simulator has no devices to probe".into()]),
        BackendConfig::Replay { .. } => Ok(vec!["a replay has no devices to probe".into()]),
    }
}

/// A running daemon's handle, for `main` and for tests that run it in-process.
pub struct Daemon {
    shared: Arc<Shared>,
    tasks: Vec<tokio::task::JoinHandle<()>>,
    socket: Option<std::path::PathBuf>,
    notifier: Option<Arc<notify::Notifier>>,
}

impl Daemon {
    /// `sqscand`'s way in: loads the models and the configured backend, binds the configured
    /// sockets, and [`serve`](Self::serve)s. Must run inside a tokio runtime.
    pub async fn start(config: Config, notifier: Option<notify::Notifier>) -> Result<Daemon> {
        let models = load_models(&config.models_dir)?;
        check_watch(&config, &models)?;
        // The backend before the sockets: a configuration that cannot scan leaves no socket.
        match &config.backend {
            BackendConfig::Sim { scene, seed, realtime } => {
                let backend = SimBackend::new(scene, &config.models_dir, *seed, *realtime, &config.sweep)?;
                let listeners = Listeners::bind(&config).await?;
                Daemon::serve(config, models, backend, listeners, notifier)
            }
            BackendConfig::Hardware(h) => {
                let mut backend = HardwareBackend::new(h, &config.sweep)?;
                for w in HardwareBackend::check_devices(h)? {
                    tracing::warn!("{w}");
                }
                backend.check_camera().await?;
                let listeners = Listeners::bind(&config).await?;
                Daemon::serve(config, models, backend, listeners, notifier)
            }
            BackendConfig::Replay { dir, speed, looping } => {
                let backend = ReplayBackend::new(dir, *speed, *looping)?;
                tracing::info!("replaying {} sweeps from {}", backend.sweeps(), dir.display());
                let listeners = Listeners::bind(&config).await?;
                Daemon::serve(config, models, backend, listeners, notifier)
            }
        }
    }

    /// Runs `backend` and answers clients on `listeners` until [`stop`](Self::stop), and tells
    /// systemd it is ready. `config` gives the rest (sweep mode, detection, recording, watch
    /// list); its `backend`, `socket` and `tcp` are not looked at. Must run inside a tokio
    /// runtime.
    pub fn serve<B: Backend>(
        config: Config,
        models: BTreeMap<String, Arc<Model>>,
        backend: B,
        listeners: Listeners,
        notifier: Option<notify::Notifier>,
    ) -> Result<Daemon> {
        let notifier = notifier.map(Arc::new);
        check_watch(&config, &models)?;
        let socket = listeners.socket_path().map(Path::to_owned);
        // The ROS 2 node before anything runs: one that cannot start refuses the configuration
        // here, before systemd hears READY and clients are told where to ask.
        #[cfg(feature = "ros2")]
        let ros2_node = match config.ros2.clone() {
            Some(cfg) => match ros2::Started::new(&cfg) {
                Ok(node) => Some((cfg, node)),
                Err(e) => {
                    if let Some(s) = &socket {
                        let _ = std::fs::remove_file(s);
                    }
                    return Err(e.context("the ROS 2 node"));
                }
            },
            None => None,
        };
        let shared = Arc::new(Shared::new(config, models, backend.name()).with_mount(backend.mount()));
        let essential = [
            ("acquisition", tokio::spawn(acquire::run(shared.clone(), backend))),
            ("server", tokio::spawn(server::serve(shared.clone(), listeners))),
        ];
        let mut tasks = vec![tokio::spawn(supervise(shared.clone(), essential))];
        #[cfg(feature = "foxglove")]
        if let Some(listen) = shared.config().foxglove_listen {
            tasks.push(tokio::spawn(view::run(shared.clone(), listen)));
        }
        #[cfg(feature = "ros2")]
        if let Some((cfg, node)) = ros2_node {
            tasks.push(tokio::spawn(ros2::run(shared.clone(), cfg, node)));
        }
        if let Some(n) = &notifier {
            if let Err(e) = n.ready() {
                tracing::warn!("sd_notify READY to {}: {e}", n.socket_name());
            }
            tasks.push(tokio::spawn(systemd_task(shared.clone(), n.clone())));
        }
        Ok(Daemon {
            shared,
            tasks,
            socket,
            notifier,
        })
    }

    /// Why the daemon cannot go on, once a task it cannot run without has ended before
    /// [`stop`](Self::stop) (a panic or a fatal error); pending until then.
    pub async fn failed(&self) -> String {
        let mut rx = self.shared.failures();
        match rx.wait_for(Option::is_some).await {
            Ok(f) => f.clone().unwrap_or_default(),
            Err(_) => std::future::pending().await,
        }
    }

    /// Reloads (SIGHUP, `systemctl reload`): reads the configuration with `load`, loads the
    /// models it names, and puts both in use; requests under way finish with what they began
    /// with, and no client is dropped. Settings fixed for the daemon's life (the sockets, the
    /// client limits, the scanner, the sweep, the detection workers) keep their old values,
    /// each change logged as needing a restart. A configuration or model set that does not load
    /// is refused: the old one stays in use, and `status` says why (`config.reload_error`).
    /// Tells systemd `RELOADING=1` before and `READY=1` after, either way.
    pub fn reload(&self, load: impl FnOnce() -> Result<Config>) -> Result<()> {
        if let Some(n) = &self.notifier
            && let Err(e) = n.reloading()
        {
            tracing::warn!("sd_notify RELOADING to {}: {e}", n.socket_name());
        }
        let result = load().and_then(|new| {
            let models = load_models(&new.models_dir)?;
            check_watch(&new, &models)?;
            // A client's watch would go silent: refuse, as for the configuration's own list.
            let watched: Vec<String> = self.shared.watched();
            if let Some(w) = watched.iter().find(|w| !models.contains_key(*w)) {
                bail!("{}: no model {w:?}, which a client watches", new.models_dir.display());
            }
            Ok((new, models))
        });
        let outcome = match result {
            Ok((new, models)) => {
                let (config, kept) = keep_fixed(&self.shared.config(), new);
                for k in kept {
                    tracing::warn!("reload: {k} changed, which takes a restart; the old value stays in use");
                }
                tracing::info!("reloaded: {} models from {}", models.len(), config.models_dir.display());
                self.shared.replace(config, models);
                Ok(())
            }
            Err(e) => {
                let why = format!("{e:#}");
                tracing::error!("reload refused, the running configuration stays in use: {why}");
                lock_reload_error(&self.shared, why);
                Err(e)
            }
        };
        if let Some(n) = &self.notifier {
            let _ = n.ready();
        }
        outcome
    }

    /// The Unix socket's path, if the daemon listens on one.
    pub fn socket(&self) -> Option<&Path> {
        self.socket.as_deref()
    }

    /// Stops every task (halting the PTU), removes the socket. Bounded in time: a detection
    /// still running on the blocking pool is abandoned, not waited for.
    pub async fn stop(self) {
        if let Some(n) = &self.notifier {
            let _ = n.stopping();
        }
        self.shared.shutdown().begin();
        let all = futures_join(self.tasks);
        if tokio::time::timeout(Duration::from_millis(1500), all).await.is_err() {
            tracing::warn!("some tasks did not stop in time");
        }
        if let Some(s) = &self.socket {
            let _ = std::fs::remove_file(s);
        }
    }
}

/// `new` with the settings that a running daemon cannot change taken from `old`, and the names
/// of those that differed.
fn keep_fixed(old: &Config, mut new: Config) -> (Config, Vec<&'static str>) {
    let mut kept = Vec::new();
    macro_rules! fixed {
        ($($name:literal => $field:ident),* $(,)?) => {
            $(
                if new.$field != old.$field {
                    kept.push($name);
                    new.$field = old.$field.clone();
                }
            )*
        };
    }
    fixed!(
        "server.socket" => socket,
        "server.socket_mode" => socket_mode,
        "server.tcp" => tcp,
        "server.frame_id (it names the calibration's base frame)" => frame_id,
        "server.max_clients" => max_clients,
        "server.client_queue" => client_queue,
        "the scanner ([acquisition] backend, [sim], [hardware] or [replay])" => backend,
        "acquisition.mode" => continuous,
        "[sweep]" => sweep,
        "detect.workers" => detect_workers,
    );
    (new, kept)
}

fn lock_reload_error(shared: &Shared, why: String) {
    shared.reload_failed(why);
}

async fn futures_join(tasks: Vec<tokio::task::JoinHandle<()>>) {
    for t in tasks {
        let _ = t.await;
    }
}

/// Waits on the tasks the daemon cannot run without. The first to end before shutdown is the
/// daemon's failure: recorded in `shared.failure` (for `status`, the watchdog and
/// [`Daemon::failed`]) and logged. Ends when every task has ended.
async fn supervise(shared: Arc<Shared>, tasks: [(&'static str, tokio::task::JoinHandle<()>); 2]) {
    let [(name_a, mut a), (name_b, mut b)] = tasks;
    let (name, result, rest) = tokio::select! {
        r = &mut a => (name_a, r, b),
        r = &mut b => (name_b, r, a),
    };
    if !shared.shutdown().begun() {
        let why = match result {
            Ok(()) => format!("the {name} task ended"),
            Err(e) if e.is_panic() => {
                let p = e.into_panic();
                let msg = p
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| p.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "no message".into());
                format!("the {name} task panicked: {msg}")
            }
            Err(_) => format!("the {name} task was cancelled"),
        };
        tracing::error!("{why}; the daemon cannot go on");
        shared.fail(why);
    }
    let _ = rest.await;
}

/// STATUS after each sweep and WATCHDOG pings while the acquisition loop and the runtime live,
/// and no essential task has failed.
async fn systemd_task(shared: Arc<Shared>, n: Arc<notify::Notifier>) {
    let period = notify::watchdog_interval().map(|w| w / 2);
    let mut sweeps = shared.sweeps();
    let mut tick = tokio::time::interval(period.unwrap_or(Duration::from_secs(3600)));
    let mut shutdown = shared.shutdown().listen();
    loop {
        tokio::select! {
            _ = tick.tick() => {
                if let Some(f) = shared.failure().as_ref() {
                    // No more pings: systemd's watchdog restarts the service.
                    let _ = n.status(&format!("failed: {f}"));
                    return;
                }
                if period.is_some() {
                    let _ = n.watchdog();
                }
            }
            r = sweeps.changed() => {
                if r.is_err() { return; }
                let text = match sweeps.borrow_and_update().as_ref() {
                    Some(e) => format!("sweep {}: {} points; {}", e.id, e.points, shared.devices().summary()),
                    None => shared.devices().summary(),
                };
                let _ = n.status(&text);
            }
            () = shutdown.thrown() => return,
        }
    }
}
