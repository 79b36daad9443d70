//! The daemon's idle clients, so that a new client finding every slot taken can close the one
//! idle the longest.

use std::sync::Arc;
use std::time::Instant;

use tokio::sync::Notify;

/// The idle clients, by when they became idle: the oldest is closed when a new client finds
/// every slot taken.
#[derive(Default)]
pub(super) struct IdleClients {
    pub(super) next_id: u64,
    pub(super) idle: std::collections::BTreeMap<u64, (Instant, Arc<Notify>)>,
}

pub(super) type Idle = Arc<std::sync::Mutex<IdleClients>>;

impl IdleClients {
    /// Closes the client idle the longest; false when none is idle.
    pub(super) fn evict_oldest(&mut self) -> bool {
        let Some((&id, _)) = self.idle.iter().min_by_key(|(_, (since, _))| *since) else {
            return false;
        };
        if let Some((_, n)) = self.idle.remove(&id) {
            n.notify_one();
        }
        true
    }
}
