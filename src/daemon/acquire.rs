//! The acquisition loop: sweeps continuously or on demand, publishes each completed sweep, keeps
//! the watched objects' detections warm, records, and survives device faults (a failed sweep is
//! dropped and counted, the device reopened with backoff).

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Instant;

use tokio::task::JoinSet;

use super::backend::Backend;
use super::record;
use super::state::{Shared, SweepEntry};

/// Runs until shutdown.
pub async fn run<B: Backend>(shared: Arc<Shared>, mut backend: B) {
    shared.devices().set(backend.devices());
    let mut shutdown = shared.shutdown().listen();
    let mut next_id = 1u64;
    let mut forward = true;
    let mut last_completed: Option<Instant> = None;
    // Held, not detached: a sweep completed just before a stop is still written out.
    let mut recordings: JoinSet<()> = JoinSet::new();
    loop {
        while recordings.try_join_next().is_some() {}
        if shared.is_stopping() {
            break;
        }
        if !shared.config().continuous {
            tokio::select! {
                () = shared.sweep_asked() => {}
                () = shutdown.thrown() => break,
            }
        }
        let result = tokio::select! {
            r = backend.sweep(forward, shared.devices(), shared.joints()) => r,
            () = shutdown.thrown() => break,
        };
        match result {
            Ok(data) => {
                let entry = Arc::new(SweepEntry::new(next_id, data));
                next_id += 1;
                shared.stats().sweeps_completed.fetch_add(1, Ordering::Relaxed);
                if let Some(prev) = last_completed {
                    shared.stats().record_sweep_period(prev.elapsed().as_secs_f64());
                }
                last_completed = Some(entry.completed);
                tracing::info!(
                    "sweep {}: {} points, {} profiles",
                    entry.id,
                    entry.points,
                    entry.sweep.profiles
                );
                shared.publish_sweep(entry.clone());
                warm_detections(&shared, &entry);
                if let Some(dir) = shared.config().record_dir.clone() {
                    recordings.spawn(record_sweep(shared.clone(), entry.clone(), dir));
                }
                if shared.config().sweep.back_and_forth {
                    forward = !forward;
                }
                if !shared.config().sweep.pause.is_zero() {
                    tokio::select! {
                        () = tokio::time::sleep(shared.config().sweep.pause) => {}
                        () = shutdown.thrown() => break,
                    }
                }
            }
            Err(f) => {
                shared.stats().sweeps_dropped.fetch_add(1, Ordering::Relaxed);
                tracing::warn!("sweep dropped: {}", f.message);
                shared.stats().record_fault(format!("sweep dropped: {}", f.message));
                // A failed sweep leaves the unit somewhere in the range: start the next one
                // from the configured start.
                forward = true;
                if !shared.config().continuous {
                    // Whoever asked is still waiting: try again.
                    shared.want_sweep();
                }
            }
        }
    }
    backend.stop().await;
    // The daemon's stop bounds this wait; a write already on the blocking pool finishes even
    // past it, as the runtime waits for its blocking threads.
    while recordings.join_next().await.is_some() {}
}

/// Starts the detections that someone is bound to want on a new sweep: the configured watch
/// list and the objects clients watch. They run once per sweep whoever asks first.
/// The objects detected on every sweep: the configuration's and the clients' watches.
fn watched_objects(shared: &Shared) -> Vec<String> {
    let mut objects: Vec<String> = shared.config().watch.clone();
    objects.extend(shared.watched());
    objects.sort();
    objects.dedup();
    objects
}

/// Records a sweep; with `[record] mcap`, after the watched objects' detections on it are done
/// (they are the ones [`warm_detections`] started: awaiting them starts nothing new).
async fn record_sweep(shared: Arc<Shared>, entry: Arc<SweepEntry>, dir: std::path::PathBuf) {
    let config = shared.config();
    let mut extras = record::Extras::default();
    if config.record_mcap {
        let mut found = Vec::new();
        for name in watched_objects(&shared) {
            if let Ok(model) = shared.model(&name) {
                let d = entry.detection(&shared, model.clone(), false).await;
                found.push((model, d));
            }
        }
        extras.mcap = Some(found);
        extras.mount = shared.mount().copied();
    }
    let (keep, frame, mcap) = (config.record_keep, config.frame_id.clone(), config.record_mcap);
    let e = entry.clone();
    let id = entry.id;
    // (whether the sweep's recording is lost, what failed)
    let written = tokio::task::spawn_blocking(move || {
        record::write_sweep(&dir, &e, &frame, extras)
            .map_err(|err| (true, format!("sweep {id} not recorded: {err:#}")))?;
        record::prune(&dir, keep).map_err(|err| (false, format!("pruning the recordings: {err:#}")))?;
        record::index(&dir, mcap).map_err(|err| (false, format!("indexing the recordings: {err:#}")))
    })
    .await
    .unwrap_or_else(|join| {
        Err((
            true,
            format!("sweep {id} not recorded: the recording task failed: {join}"),
        ))
    });
    if let Err((lost, err)) = written {
        if lost {
            shared.stats().recordings_lost.fetch_add(1, Ordering::Relaxed);
        }
        tracing::error!("{err}");
        shared.stats().record_fault(err);
    }
}

fn warm_detections(shared: &Arc<Shared>, entry: &Arc<SweepEntry>) {
    for name in watched_objects(shared) {
        if let Ok(model) = shared.model(&name) {
            let (s, e) = (shared.clone(), entry.clone());
            tokio::spawn(async move {
                e.detection(&s, model, false).await;
            });
        }
    }
}
