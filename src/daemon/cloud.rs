//! `cloud`: a sweep's points handed out after a reply's line, as a binary PCD. Clouds are large
//! (a 600 000-point sweep is about 10 MB), so how many are in memory at once is bounded: one of a
//! connection and [`CLOUD_SLOTS`](super::state::CLOUD_SLOTS) in all, each held from its encoding until the client's writer
//! has written it. The slots are shared fairly: a connection waits for one only once its client
//! has read everything sent to it before (a client that does not read takes none), and a
//! transfer that stalls while others wait loses its slot within seconds (the server's writer).

use std::sync::Arc;
use std::time::{Duration, Instant};

use tokio::sync::Semaphore;

use super::reply::{CloudHeader, ErrorCode, Reply};
use super::state::Shared;
use super::waiting::wait_for_sweep;

/// How often a `cloud` request looks whether its client has read what was sent to it.
const READ_POLL: Duration = Duration::from_millis(20);

/// A request counted in [`Shared::cloud_waiting`] while it lives.
struct Waiting<'a>(&'a Shared);

impl<'a> Waiting<'a> {
    fn new(shared: &'a Shared) -> Self {
        shared
            .cloud_waiting()
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Waiting(shared)
    }
}

impl Drop for Waiting<'_> {
    fn drop(&mut self) {
        self.0
            .cloud_waiting()
            .fetch_sub(1, std::sync::atomic::Ordering::Relaxed);
    }
}

/// A payload after a reply's line, and the `cloud` slots it holds (the daemon's and the
/// connection's).
pub(super) struct Payload {
    pub(super) bytes: Vec<u8>,
    pub(super) slots: Vec<tokio::sync::OwnedSemaphorePermit>,
}

/// `cloud`: the newest sweep no older than `max_age_s` (or the next one, as `find` takes it),
/// as a binary PCD file after the header line. The sweep is found first; then a slot of the
/// connection's and one of the daemon's ([`CLOUD_SLOTS`](super::state::CLOUD_SLOTS)) are taken, held by the encoding and
/// then by the queued message until it is written.
pub(super) async fn cloud(
    shared: &Arc<Shared>,
    max_age_s: f64,
    timeout_s: f64,
    gate: Arc<Semaphore>,
    all_read: &(dyn Fn() -> bool + Send + Sync),
) -> (Reply, Option<Payload>) {
    let asked = Instant::now();
    let deadline = asked + Duration::from_secs_f64(timeout_s);
    let max_age = Duration::from_secs_f64(max_age_s);
    let entry = match wait_for_sweep(shared, deadline, |e| e.age() <= max_age || e.completed >= asked).await {
        Ok(e) => e,
        Err((code, msg)) => return (Reply::error(None, code, format!("cloud: {msg}")), None),
    };
    let slots = async {
        let mine = gate.acquire_owned().await.ok()?;
        while !all_read() {
            tokio::time::sleep(READ_POLL).await;
        }
        let _waiting = Waiting::new(shared);
        let daemon = shared.cloud_slot().await?;
        Some(vec![mine, daemon])
    };
    let Ok(Some(slots)) = tokio::time::timeout_at(deadline.into(), slots).await else {
        let msg = format!(
            "cloud: no room before the timeout: this connection's earlier replies are unread, or its \
             earlier cloud, or the daemon's {}, are still on their way to clients",
            super::state::CLOUD_SLOTS
        );
        return (Reply::error(None, ErrorCode::Busy, msg), None);
    };
    let e = entry.clone();
    // The slots go with the encoding, so a request abandoned meanwhile still holds them until
    // the encoding is done.
    let encoded = tokio::task::spawn_blocking(move || {
        let mut bytes = Vec::new();
        let r = crate::cloud::write_pcd(&mut bytes, &e.sweep.cloud, crate::cloud::PcdData::Binary);
        r.map(|()| (bytes, slots))
    })
    .await;
    let (bytes, slots) = match encoded
        .map_err(|e| e.to_string())
        .and_then(|r| r.map_err(|e| e.to_string()))
    {
        Ok(b) => b,
        Err(err) => return (Reply::error(None, ErrorCode::Internal, format!("cloud: {err}")), None),
    };
    let c = &entry.sweep.cloud;
    // As the PCD header gives them: an unorganized cloud is one row.
    let (width, height) = if c.is_organized() {
        (c.width, c.height)
    } else {
        (c.points.len(), 1)
    };
    let fields = ["x", "y", "z"]
        .into_iter()
        .map(String::from)
        .chain(c.fields.iter().map(|f| f.name.clone()))
        .collect();
    let header = CloudHeader {
        id: None,
        sweep: entry.reference(),
        frame: shared.config().frame_id.clone(),
        width,
        height,
        fields,
        format: "pcd_binary".into(),
        bytes: bytes.len(),
    };
    (Reply::Cloud(Box::new(header)), Some(Payload { bytes, slots }))
}
