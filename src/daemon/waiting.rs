//! Waiting for a sweep fresh enough for a request: the newest that satisfies it, or why there
//! is none before the deadline (a timeout, a device fault, a replay that has finished).

use std::sync::Arc;
use std::time::Instant;

use tokio::time::Duration;

use super::reply::ErrorCode;
use super::state::{Shared, SweepEntry};

/// How often a request waiting for a sweep looks whether the source has finished.
const FINISHED_POLL: Duration = Duration::from_millis(100);

/// The newest sweep that satisfies `ok`, waiting (and asking an on-demand loop for one) until
/// `deadline`, or until the source has finished (a replay that served every sweep).
pub(super) async fn wait_for_sweep(
    shared: &Arc<Shared>,
    deadline: Instant,
    ok: impl Fn(&SweepEntry) -> bool,
) -> Result<Arc<SweepEntry>, (ErrorCode, String)> {
    let mut rx = shared.sweeps();
    loop {
        if let Some(e) = rx.borrow_and_update().clone()
            && ok(&e)
        {
            return Ok(e);
        }
        if let Some(finished) = shared.devices().finished() {
            let last = match shared.newest() {
                Some(e) => format!("the last sweep ({}) is {:.1} s old", e.id, e.age().as_secs_f64()),
                None => "no sweep was served".into(),
            };
            return Err((ErrorCode::ReplayFinished, format!("{finished}; {last}")));
        }
        if !shared.config().continuous {
            shared.want_sweep();
        }
        // A replay that runs out says so on its devices, not with a sweep: look at them now and
        // then while waiting.
        let changed = loop {
            let slice = deadline.min(Instant::now() + FINISHED_POLL);
            match tokio::time::timeout_at(slice.into(), rx.changed()).await {
                Ok(r) => break Some(r),
                Err(_) if Instant::now() >= deadline => break None,
                Err(_) if shared.devices().finished().is_some() => break Some(Ok(())),
                Err(_) => {}
            }
        };
        match changed {
            Some(Ok(())) => {}
            Some(Err(_)) => return Err((ErrorCode::Stopping, "the daemon is stopping".into())),
            None => {
                let trouble = shared.device_trouble();
                let last = match shared.newest() {
                    Some(e) => format!("the last sweep ({}) is {:.1} s old", e.id, e.age().as_secs_f64()),
                    None => "no sweep has completed yet".into(),
                };
                return Err(if trouble.is_empty() {
                    (ErrorCode::Timeout, format!("no fresh sweep before the timeout; {last}"))
                } else {
                    (ErrorCode::Device, format!("device fault: {trouble}; {last}"))
                });
            }
        }
    }
}
