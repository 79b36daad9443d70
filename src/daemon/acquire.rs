//! The acquisition loop: sweeps continuously or on demand, publishes each completed sweep, keeps
//! the watched objects' detections warm, records, and survives device faults (a failed sweep is
//! dropped and counted, the device reopened with backoff).

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Instant;

use super::backend::Backend;
use super::record;
use super::state::{Shared, SweepEntry, lock, stopped};

/// Runs until shutdown.
pub async fn run<B: Backend>(shared: Arc<Shared>, mut backend: B) {
    shared.devices.set(backend.devices());
    let mut shutdown = shared.shutdown.subscribe();
    let mut next_id = 1u64;
    let mut forward = true;
    let mut last_completed: Option<Instant> = None;
    loop {
        if shared.is_stopping() {
            break;
        }
        if !shared.config().continuous {
            tokio::select! {
                () = shared.sweep_wanted.notified() => {}
                () = stopped(&mut shutdown) => break,
            }
        }
        let result = tokio::select! {
            r = backend.sweep(forward, &shared.devices) => r,
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
                    entry.sweep.profiles
                );
                shared.latest.send_replace(Some(entry.clone()));
                warm_detections(&shared, &entry);
                if let Some(dir) = shared.config().record_dir.clone() {
                    let keep = shared.config().record_keep;
                    let frame = shared.config().frame_id.clone();
                    let e = entry.clone();
                    let s = shared.clone();
                    tokio::task::spawn_blocking(move || {
                        if let Err(err) = record::write_sweep(&dir, &e, keep, &frame) {
                            tracing::error!("recording sweep {}: {err:#}", e.id);
                            s.stats.record_fault(format!("recording sweep {}: {err:#}", e.id));
                        }
                    });
                }
                if shared.config().sweep.back_and_forth {
                    forward = !forward;
                }
                if !shared.config().sweep.pause.is_zero() {
                    tokio::select! {
                        () = tokio::time::sleep(shared.config().sweep.pause) => {}
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
                if !shared.config().continuous {
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
    let mut objects: Vec<String> = shared.config().watch.clone();
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
