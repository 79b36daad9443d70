//! `sqscand`: scans continuously (or on demand), detects the objects clients ask for on every
//! completed sweep, and answers over a local socket (`docs/PROTOCOL.md`).
//!
//! Tasks, all on one tokio runtime:
//! - acquisition ([`acquire::run`]): drives the backend (simulator or PTU + sensor), publishes
//!   each sweep, reopens failed devices with backoff;
//! - the server ([`server::serve`]): one task a client, one a request;
//! - detections: on the blocking pool, once per (sweep, object), at most `detect.workers` at a
//!   time ([`state::SweepEntry::detection`]);
//! - systemd: READY once listening, STATUS after each sweep, WATCHDOG at half the interval.

pub mod acquire;
pub mod config;
pub mod hardware;
pub mod notify;
pub mod protocol;
pub mod record;
pub mod server;
pub mod state;

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result, bail};

use crate::model::{self, Model};

use config::Config;
use state::{Shared, lock};

/// Loads every model of the directory; a broken file is reported and skipped, not fatal (one
/// bad model must not take the scanner down), but an empty set is.
pub fn load_models(dir: &std::path::Path) -> Result<BTreeMap<String, Arc<Model>>> {
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

/// A running daemon's handle, for `main` and for tests that run it in-process.
pub struct Daemon {
    pub shared: Arc<Shared>,
    tasks: Vec<tokio::task::JoinHandle<()>>,
    socket: std::path::PathBuf,
    notifier: Option<Arc<notify::Notifier>>,
}

impl Daemon {
    /// Loads models and the backend, binds the sockets, starts the tasks, and tells systemd
    /// it is ready. Must run inside a tokio runtime.
    pub async fn start(config: Config, notifier: Option<notify::Notifier>) -> Result<Daemon> {
        let notifier = notifier.map(Arc::new);
        let models = load_models(&config.models_dir)?;
        for w in &config.watch {
            if !models.contains_key(w) {
                bail!(
                    "{}: watch.objects: unknown object {w:?}",
                    config
                        .source
                        .as_deref()
                        .map(|p| p.display().to_string())
                        .unwrap_or_default()
                );
            }
        }
        let backend = acquire::AnyBackend::from_config(&config)?;
        let unix = server::bind_unix(&config.socket, config.socket_mode)?;
        let tcp = match config.tcp {
            Some(addr) => Some(
                tokio::net::TcpListener::bind(addr)
                    .await
                    .with_context(|| format!("cannot listen on tcp {addr}"))?,
            ),
            None => None,
        };
        let socket = config.socket.clone();
        let shared = Arc::new(Shared::new(config, models));
        let mut tasks = vec![
            tokio::spawn(acquire::run(shared.clone(), backend)),
            tokio::spawn(server::serve(shared.clone(), unix, tcp, socket.clone())),
        ];
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

    pub fn socket(&self) -> &std::path::Path {
        &self.socket
    }

    /// Stops every task (halting the PTU), removes the socket. Bounded in time: a detection
    /// still running on the blocking pool is abandoned, not waited for.
    pub async fn stop(self) {
        if let Some(n) = &self.notifier {
            let _ = n.stopping();
        }
        self.shared.shutdown.send_replace(true);
        let all = futures_join(self.tasks);
        if tokio::time::timeout(Duration::from_millis(1500), all).await.is_err() {
            tracing::warn!("some tasks did not stop in time");
        }
        let _ = std::fs::remove_file(&self.socket);
    }
}

async fn futures_join(tasks: Vec<tokio::task::JoinHandle<()>>) {
    for t in tasks {
        let _ = t.await;
    }
}

/// STATUS after each sweep and WATCHDOG pings while the acquisition loop and the runtime live.
async fn systemd_task(shared: Arc<Shared>, n: Arc<notify::Notifier>) {
    let period = notify::watchdog_interval().map(|w| w / 2);
    let mut sweeps = shared.latest.subscribe();
    let mut tick = tokio::time::interval(period.unwrap_or(Duration::from_secs(3600)));
    let mut shutdown = shared.shutdown.subscribe();
    loop {
        tokio::select! {
            _ = tick.tick() => {
                if period.is_some() {
                    let _ = n.watchdog();
                }
            }
            r = sweeps.changed() => {
                if r.is_err() { return; }
                let text = match sweeps.borrow_and_update().as_ref() {
                    Some(e) => format!("sweep {}: {} points; {}", e.id, e.points, device_line(&shared)),
                    None => device_line(&shared),
                };
                let _ = n.status(&text);
            }
            () = state::stopped(&mut shutdown) => return,
        }
    }
}

fn device_line(shared: &Shared) -> String {
    lock(&shared.devices)
        .iter()
        .map(|d| format!("{} {}", d.name, if d.connected { "ok" } else { "down" }))
        .collect::<Vec<_>>()
        .join(", ")
}
