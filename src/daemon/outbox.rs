//! A client's outbound queue and the task that writes it: replies wait for room in it, watch
//! updates are skipped when it is full, and a client that stops reading is dropped.

use std::os::fd::RawFd;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use tokio::io::{AsyncWrite, AsyncWriteExt};
use tokio::sync::{Semaphore, mpsc};

use super::cloud::Payload;
use super::reply::{ErrorCode, Reply};
use super::state::Shared;

/// A client that cannot take a line for this long is dropped.
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(10);

/// A client that takes nothing of its cloud for this long while another `cloud` request waits
/// for a slot is dropped, so clients that stop reading cannot keep the slots from others.
pub const STALL_WHILE_WANTED: Duration = Duration::from_secs(2);

/// How often a stalled write looks at the clock.
const STALL_POLL: Duration = Duration::from_millis(250);

/// Bytes of replies and updates queued for one client at most (one larger reply goes alone): a
/// client that does not read costs the daemon this much, whatever its ids, however many
/// requests it sends and objects it watches. Sixteen `models` replies of the shipped models.
pub const MAX_QUEUED_BYTES: usize = 64 * 1024;

/// A queued message: its bytes, its share of the connection's [`MAX_QUEUED_BYTES`] (a cloud's
/// payload is bounded by its slots instead), and the `cloud` slots it holds; both are given
/// back when it has been written, or dropped with the connection.
pub(super) struct Outgoing {
    bytes: Vec<u8>,
    _room: tokio::sync::OwnedSemaphorePermit,
    slots: Vec<tokio::sync::OwnedSemaphorePermit>,
}

/// Bytes written at a time, each within [`WRITE_TIMEOUT`].
const WRITE_CHUNK: usize = 64 * 1024;

/// The writer of one connection: writes what the queue brings until it closes (its last sender
/// gone) or the client stops reading; then lets go whatever waits for room.
pub(super) fn spawn_writer<W>(
    shared: Arc<Shared>,
    mut rx: mpsc::Receiver<Outgoing>,
    mut wr: W,
    room: Arc<Semaphore>,
) -> tokio::task::JoinHandle<()>
where
    W: AsyncWrite + Unpin + Send + 'static,
{
    tokio::spawn(async move {
        while let Some(l) = rx.recv().await {
            if !write_message(&shared, &mut wr, &l).await {
                break;
            }
        }
        // Whatever waits for room (the reader, a reply) is let go: the connection is over.
        room.close();
    })
}

/// Writes one queued message, false when the client is gone or does not read. A client that
/// reads slowly but steadily is not cut off: only one that makes no progress for
/// [`WRITE_TIMEOUT`], or for [`STALL_WHILE_WANTED`] while it holds a `cloud` slot that another
/// request waits for.
async fn write_message<W: AsyncWrite + Unpin>(shared: &Shared, wr: &mut W, l: &Outgoing) -> bool {
    let holds_slots = !l.slots.is_empty();
    let mut written = 0;
    let mut progress = Instant::now();
    while written < l.bytes.len() {
        let chunk = &l.bytes[written..l.bytes.len().min(written + WRITE_CHUNK)];
        // write() gives up nothing when it times out (nothing was written), so it is tried
        // again after each look at the clock.
        match tokio::time::timeout(STALL_POLL, wr.write(chunk)).await {
            Ok(Ok(0) | Err(_)) => return false,
            Ok(Ok(n)) => {
                written += n;
                progress = Instant::now();
            }
            Err(_) => {
                let wanted = holds_slots && shared.cloud_waiting().load(Ordering::Relaxed) > 0;
                let limit = if wanted { STALL_WHILE_WANTED } else { WRITE_TIMEOUT };
                if progress.elapsed() >= limit {
                    return false;
                }
            }
        }
    }
    true
}

/// A client's outbound queue: lines, and the room left of its [`MAX_QUEUED_BYTES`] (a permit a
/// byte); and its socket, to ask the kernel what the client has not read yet.
#[derive(Clone)]
pub(super) struct Outbox {
    pub(super) tx: mpsc::Sender<Outgoing>,
    pub(super) room: Arc<Semaphore>,
    shared: Arc<Shared>,
    fd: Option<RawFd>,
}

/// The permits a line of `n` bytes takes: all of them for a line larger than the bound.
fn room_for(n: usize) -> u32 {
    n.clamp(1, MAX_QUEUED_BYTES) as u32
}

impl Outbox {
    pub(super) fn new(tx: mpsc::Sender<Outgoing>, shared: Arc<Shared>, fd: Option<RawFd>) -> Outbox {
        Outbox {
            tx,
            room: Arc::new(Semaphore::new(MAX_QUEUED_BYTES)),
            shared,
            fd,
        }
    }

    /// Whether the client has read everything sent to it: nothing queued here, and nothing
    /// left unread in the socket's send buffer (TIOCOUTQ, for Unix and TCP sockets alike).
    pub(super) fn all_read(&self) -> bool {
        if self.room.available_permits() < MAX_QUEUED_BYTES {
            return false;
        }
        let Some(fd) = self.fd else { return true };
        let mut unsent: libc::c_int = 0;
        // SAFETY: TIOCOUTQ writes one int; the descriptor is this connection's socket, open
        // while any of its tasks (the only callers) runs.
        let r = unsafe { libc::ioctl(fd, libc::TIOCOUTQ, &mut unsent) };
        r != 0 || unsent == 0
    }

    /// Waits until the queue has room again (the client has read), or the connection is gone.
    pub(super) async fn drained(&self) {
        let _ = self.room.acquire().await;
    }

    /// A reply: waits for room (only this client is held up by its own slowness).
    pub(super) async fn reply(&self, v: Reply) {
        self.reply_with(v, None).await;
    }

    /// A reply and the payload that follows its line (with the `cloud` slot it holds), queued
    /// as one message so that nothing (a watch update) comes between them.
    pub(super) async fn reply_with(&self, v: Reply, payload: Option<Payload>) {
        if v.is_error() {
            self.shared.stats().errors_sent.fetch_add(1, Ordering::Relaxed);
        }
        let mut l = v.line().into_bytes();
        let Ok(room) = self.room.clone().acquire_many_owned(room_for(l.len())).await else {
            return;
        };
        let mut slots = Vec::new();
        if let Some(p) = payload {
            l.extend_from_slice(&p.bytes);
            slots = p.slots;
        }
        let l = Outgoing {
            bytes: l,
            _room: room,
            slots,
        };
        let _ = self.tx.send(l).await;
    }

    /// An unsolicited update: skipped when the client is behind (its queue full in lines or in
    /// bytes).
    pub(super) fn update(&self, v: Reply) {
        if !self.try_queue(v) {
            self.shared.stats().watch_skipped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Queues a line if there is room now; false if there is none.
    fn try_queue(&self, v: Reply) -> bool {
        let l = v.line().into_bytes();
        let Ok(room) = self.room.clone().try_acquire_many_owned(room_for(l.len())) else {
            return false;
        };
        let message = Outgoing {
            bytes: l,
            _room: room,
            slots: Vec::new(),
        };
        self.tx.try_send(message).is_ok()
    }

    /// The goodbye at a stop while the reader waits on a full queue: queued if it fits now.
    pub(super) fn try_goodbye(&self) {
        self.try_queue(Reply::error(None, ErrorCode::Stopping, "the daemon is stopping"));
    }
}

#[cfg(test)]
mod tests {
    use super::super::reply::ErrorCode;
    use super::*;
    use std::sync::atomic::Ordering;

    #[tokio::test]
    async fn watch_updates_to_a_full_queue_are_skipped_not_waited_for() {
        let config = crate::daemon::config::Config::embedded_default();
        let shared = Arc::new(Shared::new(config, Default::default(), "sim"));
        let (tx, mut rx) = mpsc::channel(2);
        let out = Outbox::new(tx, shared.clone(), None);
        for k in 0..5 {
            // Returns at once even though nobody reads.
            out.update(Reply::error(None, ErrorCode::Internal, format!("k{k}")));
        }
        assert_eq!(shared.stats().watch_skipped.load(Ordering::Relaxed), 3);
        let text = |o: Outgoing| String::from_utf8_lossy(&o.bytes).into_owned();
        assert!(text(rx.recv().await.unwrap()).contains("\"k0\""));
        assert!(text(rx.recv().await.unwrap()).contains("\"k1\""));
    }

    /// A slow watch reader costs the daemon at most MAX_QUEUED_BYTES, however large its updates:
    /// with room for 10,000 lines, updates of 10 kB stop at the byte bound.
    #[tokio::test]
    async fn a_slow_watch_readers_queue_is_bounded_in_bytes() {
        let config = crate::daemon::config::Config::embedded_default();
        let shared = Arc::new(Shared::new(config, Default::default(), "sim"));
        let (tx, _rx) = mpsc::channel(10_000);
        let out = Outbox::new(tx, shared.clone(), None);
        let update = Reply::error(None, ErrorCode::Internal, "x".repeat(10_000));
        let n = update.line().len();
        for _ in 0..1000 {
            out.update(update.clone());
        }
        let queued = MAX_QUEUED_BYTES - out.room.available_permits();
        assert_eq!(queued, MAX_QUEUED_BYTES / n * n);
        let skipped = shared.stats().watch_skipped.load(Ordering::Relaxed) as usize;
        assert_eq!(skipped, 1000 - MAX_QUEUED_BYTES / n);
    }
}
