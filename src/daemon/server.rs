//! The socket server: JSON lines over a Unix socket (and optionally TCP), in the manner of gpsd.
//!
//! Each connection has a reader (requests), a writer (one task that owns the socket's write
//! half) and a bounded queue between them. Every request runs in its own task so a `find`
//! waiting on the next sweep does not hold up a `status` on the same connection. The queue is
//! bounded by its count of lines and by [`MAX_QUEUED_BYTES`]: replies to requests wait for room
//! in it, and no further request of the connection is read while it is full (a client that does
//! not read only stalls itself, and costs the daemon that much); `watch` updates never wait:
//! when the queue is full they are skipped and counted. A writer that cannot write for [`WRITE_TIMEOUT`] drops the client. A
//! client with nothing in flight and no watch is idle: it is closed after the configured idle
//! timeout (a line sent only in part does not count as activity), and when every slot is taken
//! the longest-idle client is closed to make room for a new one. Nothing here can block
//! acquisition, which only publishes into a `watch` channel.
//!
//! Over 600 lines, of which a fifth are its tests: a connection's reader, queue and writer, and
//! the requests answered on them, are one piece; `cloud`'s points are in `cloud.rs`.

use std::os::fd::{AsRawFd, RawFd};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use serde_json::Value;
use tokio::io::{AsyncRead, AsyncWrite, AsyncWriteExt, BufReader};
use tokio::net::{TcpListener, UnixListener};
use tokio::sync::{Notify, Semaphore, mpsc};
use tokio::task::JoinSet;

use crate::detect::output::report_json;

use super::cloud::{Payload, cloud};
use super::config::{Config, MAX_REQUEST_BYTES};
use super::idle::Idle;
use super::lines::LineReader;
use super::protocol::{self, Command, Request};
use super::reply::{DetectionReply, ErrorCode, ModelJson, ModelPart, Models, Reply, SweepReply, Version, Watch};
use super::socket::bind_unix;
use super::state::{Shared, SweepEntry, lock, round3, stopped};

/// Requests of one client in progress at most (beyond them its next line is not read yet).
pub const MAX_IN_FLIGHT: usize = 64;

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
struct Outgoing {
    bytes: Vec<u8>,
    _room: tokio::sync::OwnedSemaphorePermit,
    slots: Vec<tokio::sync::OwnedSemaphorePermit>,
}

/// Bytes written at a time, each within [`WRITE_TIMEOUT`].
const WRITE_CHUNK: usize = 64 * 1024;

/// How long a new client waits for the slot of an idle client closed to make room for it.
const EVICT_WAIT: Duration = Duration::from_secs(2);

/// What the daemon listens on. The caller binds them (tests bind `127.0.0.1:0` or a socket in
/// a temporary directory); [`Listeners::bind`] binds the configured ones.
#[derive(Debug, Default)]
pub struct Listeners {
    /// A Unix socket, and its path: the file is removed when the daemon stops.
    pub unix: Option<(UnixListener, PathBuf)>,
    pub tcp: Option<TcpListener>,
}

impl Listeners {
    /// The configured Unix socket (with its permission bits) and TCP address, if any.
    pub async fn bind(config: &Config) -> Result<Listeners> {
        let unix = bind_unix(&config.socket, config.socket_mode)?;
        if let Some(addr) = config.tcp.filter(|a| !a.ip().is_loopback()) {
            tracing::warn!("listening on tcp {addr}, which other machines reach: anyone who does can ask for sweeps");
        }
        let tcp = match config.tcp {
            Some(addr) => Some(
                TcpListener::bind(addr)
                    .await
                    .with_context(|| format!("cannot listen on tcp {addr}"))?,
            ),
            None => None,
        };
        Ok(Listeners {
            unix: Some((unix, config.socket.clone())),
            tcp,
        })
    }

    /// The Unix socket's path, if there is one.
    pub fn socket_path(&self) -> Option<&Path> {
        self.unix.as_ref().map(|(_, p)| p.as_path())
    }
}

/// Accepts clients until shutdown.
pub async fn serve(shared: Arc<Shared>, listeners: Listeners) {
    // Fixed for the daemon's life: a reload does not resize the server.
    let slots = Arc::new(Semaphore::new(slots_total(&shared)));
    let idle: Idle = Arc::default();
    let mut shutdown = shared.shutdown.subscribe();
    let (unix, socket_path) = match listeners.unix {
        Some((l, p)) => (Some(l), p),
        None => (None, PathBuf::new()),
    };
    let tcp = listeners.tcp;
    // Held, not detached: on shutdown each client is told why before the process exits, and
    // the runtime's end would otherwise drop a goodbye still in its queue.
    let mut clients: JoinSet<()> = JoinSet::new();
    let mut refused = Refused::default();
    // When the first client left since the heap was last trimmed.
    let mut untrimmed: Option<Instant> = None;
    loop {
        tokio::select! {
            r = accept_unix(unix.as_ref()) => match r {
                Ok(stream) => {
                    let fd = stream.as_raw_fd();
                    let (rd, wr) = stream.into_split();
                    spawn_client(&mut clients, &shared, &slots, &idle, (rd, wr, fd));
                }
                Err(e) => accept_failed(&idle, &mut refused, &format!("accept on {}", socket_path.display()), e).await,
            },
            r = accept_tcp(tcp.as_ref()) => match r {
                Ok(stream) => {
                    let _ = stream.set_nodelay(true);
                    let fd = stream.as_raw_fd();
                    let (rd, wr) = stream.into_split();
                    spawn_client(&mut clients, &shared, &slots, &idle, (rd, wr, fd));
                }
                Err(e) => accept_failed(&idle, &mut refused, "accept on tcp", e).await,
            },
            Some(_) = clients.join_next(), if !clients.is_empty() => {
                untrimmed.get_or_insert_with(Instant::now);
            }
            () = tokio::time::sleep_until(untrimmed.map_or_else(tokio::time::Instant::now, |t| (t + TRIM_AFTER).into())), if untrimmed.is_some() => {
                super::memory::give_back_memory();
                untrimmed = None;
            }
            () = stopped(&mut shutdown) => break,
        }
    }
    // Each client sees the shutdown itself, says so and flushes (bounded by its writer's
    // timeout; the daemon's stop bounds the whole wait).
    while clients.join_next().await.is_some() {}
}

/// Failed accepts since the last warning about them, and when that was.
#[derive(Default)]
struct Refused {
    count: u64,
    warned: Option<Instant>,
}

/// A failed accept: out of descriptors (the connection waits in the listen queue), the
/// longest-idle client is closed to free one, as a new client would have it closed for its slot;
/// a warning at most every 10 s says how many failed.
async fn accept_failed(idle: &Idle, refused: &mut Refused, what: &str, e: std::io::Error) {
    let out_of_descriptors = matches!(e.raw_os_error(), Some(libc::EMFILE | libc::ENFILE));
    let evicted = out_of_descriptors && lock(idle).evict_oldest();
    refused.count += 1;
    if refused.warned.is_none_or(|t| t.elapsed() >= Duration::from_secs(10)) {
        let more = if refused.count > 1 {
            format!(" ({} failed since the last warning)", refused.count)
        } else {
            String::new()
        };
        let action = if evicted {
            "; closing the longest-idle client"
        } else {
            ""
        };
        tracing::warn!("{what}: {e}{more}{action}");
        refused.count = 0;
        refused.warned = Some(Instant::now());
    }
    tokio::time::sleep(Duration::from_millis(50)).await;
}

/// The next client on the Unix socket; never, without one.
async fn accept_unix(l: Option<&UnixListener>) -> std::io::Result<tokio::net::UnixStream> {
    match l {
        Some(l) => l.accept().await.map(|(s, _)| s),
        None => std::future::pending().await,
    }
}

/// The next client on TCP; never, without a TCP listener.
async fn accept_tcp(l: Option<&TcpListener>) -> std::io::Result<tokio::net::TcpStream> {
    match l {
        Some(l) => l.accept().await.map(|(s, _)| s),
        None => std::future::pending().await,
    }
}

fn spawn_client<R, W>(
    clients: &mut JoinSet<()>,
    shared: &Arc<Shared>,
    slots: &Arc<Semaphore>,
    idle: &Idle,
    (rd, mut wr, fd): (R, W, RawFd),
) where
    R: AsyncRead + Unpin + Send + 'static,
    W: AsyncWrite + Unpin + Send + 'static,
{
    let shared = shared.clone();
    let (slots, idle) = (slots.clone(), idle.clone());
    clients.spawn(async move {
        let permit = match slots.clone().try_acquire_owned() {
            Ok(p) => Ok(p),
            // Every slot taken: close the longest-idle client and take its slot.
            Err(_) if lock(&idle).evict_oldest() => tokio::time::timeout(EVICT_WAIT, slots.acquire_owned())
                .await
                .map_err(|_| ())
                .and_then(|r| r.map_err(|_| ())),
            Err(_) => Err(()),
        };
        let Ok(_permit) = permit else {
            let msg = Reply::error(
                None,
                ErrorCode::Busy,
                format!("too many clients (max {}), none of them idle", slots_total(&shared)),
            );
            let _ = tokio::time::timeout(Duration::from_secs(1), wr.write_all(msg.line().as_bytes())).await;
            return;
        };
        shared.stats.clients.fetch_add(1, Ordering::Relaxed);
        shared.stats.clients_total.fetch_add(1, Ordering::Relaxed);
        client(shared.clone(), idle, BufReader::new(rd), wr, fd).await;
        shared.stats.clients.fetch_sub(1, Ordering::Relaxed);
    });
}

/// How soon after a client leaves the heap is trimmed: at most once this often while clients
/// come and go, once after a burst of them has left.
const TRIM_AFTER: Duration = Duration::from_secs(1);

/// The number of client slots the server was started with: `server.max_clients`, unless the
/// descriptors the process may open (its soft limit, raised to the hard one at the first call)
/// cannot hold that many clients besides the daemon's own files; then as many as they can.
fn slots_total(shared: &Shared) -> usize {
    static LIMIT: std::sync::OnceLock<Option<u64>> = std::sync::OnceLock::new();
    let limit = *LIMIT.get_or_init(|| {
        let l = raise_descriptor_limit();
        if let Some(l) = l {
            tracing::info!("open file limit {l}");
        }
        l
    });
    let wanted = shared.config().max_clients;
    let slots = client_slots(wanted, limit);
    if slots < wanted {
        static WARNED: std::sync::Once = std::sync::Once::new();
        WARNED.call_once(|| {
            tracing::warn!(
                "server.max_clients = {wanted}, but the open file limit ({}) holds {slots} clients besides the daemon's own {OWN_DESCRIPTORS} descriptors: serving {slots} (raise LimitNOFILE)",
                limit.unwrap_or(0)
            )
        });
    }
    slots
}

/// Descriptors kept for the daemon's own files and sockets (serial lines, the sensor's sockets,
/// recordings, models, DDS and the live view), beside one per client.
const OWN_DESCRIPTORS: u64 = 128;

/// Client slots for `max_clients` under a descriptor limit (`None`: unknown, no bound).
fn client_slots(max_clients: usize, limit: Option<u64>) -> usize {
    match limit {
        Some(l) => max_clients.min(l.saturating_sub(OWN_DESCRIPTORS).max(1) as usize),
        None => max_clients,
    }
}

/// Raise the soft limit of open files to the hard one (systemd's default soft limit, 1024, is
/// the default `max_clients` with nothing to spare), and return the soft limit in force.
fn raise_descriptor_limit() -> Option<u64> {
    let mut r = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes only into the struct given.
    if unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut r) } != 0 {
        return None;
    }
    // An unlimited hard limit is no number the kernel takes for open files (fs.nr_open bounds
    // it): ask for a million.
    let target = if r.rlim_max == libc::RLIM_INFINITY {
        1 << 20
    } else {
        r.rlim_max
    };
    if r.rlim_cur < target {
        let raised = libc::rlimit {
            rlim_cur: target,
            rlim_max: r.rlim_max,
        };
        // SAFETY: setrlimit reads only the struct given.
        if unsafe { libc::setrlimit(libc::RLIMIT_NOFILE, &raised) } == 0 {
            r.rlim_cur = target;
        }
    }
    Some(r.rlim_cur)
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
                let wanted = holds_slots && shared.cloud_waiting.load(Ordering::Relaxed) > 0;
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
struct Outbox {
    tx: mpsc::Sender<Outgoing>,
    room: Arc<Semaphore>,
    shared: Arc<Shared>,
    fd: Option<RawFd>,
}

/// The permits a line of `n` bytes takes: all of them for a line larger than the bound.
fn room_for(n: usize) -> u32 {
    n.clamp(1, MAX_QUEUED_BYTES) as u32
}

impl Outbox {
    fn new(tx: mpsc::Sender<Outgoing>, shared: Arc<Shared>, fd: Option<RawFd>) -> Outbox {
        Outbox {
            tx,
            room: Arc::new(Semaphore::new(MAX_QUEUED_BYTES)),
            shared,
            fd,
        }
    }

    /// Whether the client has read everything sent to it: nothing queued here, and nothing
    /// left unread in the socket's send buffer (TIOCOUTQ, for Unix and TCP sockets alike).
    fn all_read(&self) -> bool {
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
    async fn drained(&self) {
        let _ = self.room.acquire().await;
    }

    /// A reply: waits for room (only this client is held up by its own slowness).
    async fn reply(&self, v: Reply) {
        self.reply_with(v, None).await;
    }

    /// A reply and the payload that follows its line (with the `cloud` slot it holds), queued
    /// as one message so that nothing (a watch update) comes between them.
    async fn reply_with(&self, v: Reply, payload: Option<Payload>) {
        if v.is_error() {
            self.shared.stats.errors_sent.fetch_add(1, Ordering::Relaxed);
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
    fn update(&self, v: Reply) {
        if !self.try_queue(v) {
            self.shared.stats.watch_skipped.fetch_add(1, Ordering::Relaxed);
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
    fn try_goodbye(&self) {
        self.try_queue(Reply::error(None, ErrorCode::Stopping, "the daemon is stopping"));
    }
}

async fn client<R, W>(shared: Arc<Shared>, idle: Idle, mut rd: BufReader<R>, mut wr: W, fd: RawFd)
where
    R: AsyncRead + Unpin + Send + 'static,
    W: AsyncWrite + Unpin + Send + 'static,
{
    let (tx, mut rx) = mpsc::channel::<Outgoing>(shared.config().client_queue);
    let out = Outbox::new(tx, shared.clone(), Some(fd));
    // The writer holds no sender: the queue closes when the last sender (the connection's and
    // its tasks') is gone, and the writer ends with it. Each message gives its room back when
    // written (or dropped).
    let room = out.room.clone();
    let s = shared.clone();
    let writer = tokio::spawn(async move {
        while let Some(l) = rx.recv().await {
            if !write_message(&s, &mut wr, &l).await {
                break;
            }
        }
        // Whatever waits for room (the reader, a reply) is let go: the connection is over.
        room.close();
    });
    out.reply(Reply::Version(Version::now())).await;
    let evict = Arc::new(Notify::new());
    let me = {
        let mut i = lock(&idle);
        i.next_id += 1;
        i.next_id
    };
    let idle_timeout = shared.config().idle_timeout;
    let mut active = Instant::now();
    let mut tasks: JoinSet<()> = JoinSet::new();
    let mut watch_task: Option<tokio::task::AbortHandle> = None;
    let mut watching: Vec<String> = Vec::new();
    // One cloud of this connection in memory at a time: a client cannot take every slot.
    let cloud_gate = Arc::new(Semaphore::new(1));
    let mut shutdown = shared.shutdown.subscribe();
    let mut lines = LineReader::default();
    loop {
        // Idle: nothing in flight and no watch. Registered as such, so a new client that finds
        // every slot taken may close it; and closed after the idle timeout.
        let is_idle = tasks.is_empty() && watch_task.is_none();
        {
            let mut i = lock(&idle);
            if is_idle {
                i.idle.entry(me).or_insert_with(|| (active, evict.clone()));
            } else {
                i.idle.remove(&me);
            }
        }
        let got = tokio::select! {
            r = lines.next(&mut rd) => r,
            () = stopped(&mut shutdown) => {
                // Whatever is in flight will not be answered: say why before closing.
                out.reply(Reply::error(None, ErrorCode::Stopping, "the daemon is stopping")).await;
                break;
            }
            // A dead writer means the client is gone.
            () = out.tx.closed() => break,
            // A finished request may leave the client idle.
            Some(_) = tasks.join_next(), if !tasks.is_empty() => {
                active = Instant::now();
                continue;
            }
            () = tokio::time::sleep_until((active + idle_timeout).into()), if is_idle => {
                let msg = format!("closing: idle for {} s", idle_timeout.as_secs_f64());
                out.reply(Reply::error(None, ErrorCode::Idle, msg)).await;
                break;
            }
            () = evict.notified(), if is_idle => {
                out.reply(Reply::error(None, ErrorCode::Idle, "closing: idle, and a new client needs the slot")).await;
                break;
            }
        };
        active = Instant::now();
        // Idle until this line came in: unless a new client took this one's slot meanwhile (the
        // registry no longer holds it), it is busy now. If it did, that client is waiting for
        // the slot: close, as the eviction said, and do not leave its signal for a later idle
        // spell.
        if is_idle && lock(&idle).idle.remove(&me).is_none() {
            out.reply(Reply::error(
                None,
                ErrorCode::Idle,
                "closing: idle, and a new client needs the slot",
            ))
            .await;
            break;
        }
        // Stop reading from a client with MAX_IN_FLIGHT requests unanswered, or whose queue is
        // full (it is not reading its replies): backpressure on that client alone. Its writer's
        // timeout ends it if it never reads again.
        while tasks.len() > MAX_IN_FLIGHT {
            if tasks.join_next().await.is_none() {
                break;
            }
        }
        tokio::select! {
            biased;
            () = out.drained() => {}
            () = stopped(&mut shutdown) => {
                out.try_goodbye();
                break;
            }
        }
        let buf = std::mem::take(&mut lines.buf);
        let req = match got {
            Ok(None) | Err(_) => break,
            Ok(Some(Err(len))) => {
                out.reply(Reply::error(
                    None,
                    ErrorCode::TooLarge,
                    format!("request of {len} bytes is over the limit of {MAX_REQUEST_BYTES} bytes; skipped"),
                ))
                .await;
                continue;
            }
            Ok(Some(Ok(()))) => {
                if buf.iter().all(|b| b.is_ascii_whitespace()) {
                    continue;
                }
                shared.stats.requests.fetch_add(1, Ordering::Relaxed);
                match protocol::parse_request(&buf) {
                    Ok(r) => r,
                    Err(e) => {
                        out.reply(e.reply()).await;
                        continue;
                    }
                }
            }
        };
        match req.command {
            Command::Watch { ref objects } => {
                if let Some(missing) = objects.iter().find_map(|o| shared.model(o).err()) {
                    out.reply(Reply::error(req.id.clone(), ErrorCode::UnknownObject, missing))
                        .await;
                    continue;
                }
                if let Some(t) = watch_task.take() {
                    t.abort();
                }
                set_watched(&shared, &watching, objects);
                watching = objects.clone();
                out.reply(Reply::Watch(Watch {
                    id: req.id.clone(),
                    objects: objects.clone(),
                    enable: true,
                }))
                .await;
                watch_task = Some(tasks.spawn(watch(shared.clone(), out.clone(), objects.clone(), req.id.clone())));
            }
            Command::Unwatch => {
                if let Some(t) = watch_task.take() {
                    t.abort();
                }
                set_watched(&shared, &watching, &[]);
                watching.clear();
                out.reply(Reply::Watch(Watch {
                    id: req.id.clone(),
                    objects: Vec::new(),
                    enable: false,
                }))
                .await;
            }
            // Answered at once: here, so that a client sending these and not reading waits
            // for its own queue instead of piling up replies in tasks.
            Command::Status | Command::Models => {
                let reply = answer(&shared, &req).await.with_id(req.id.clone());
                tokio::select! {
                    biased;
                    () = out.reply(reply) => {}
                    () = stopped(&mut shutdown) => {
                        out.try_goodbye();
                        break;
                    }
                }
            }
            _ => {
                let (s, o, gate) = (shared.clone(), out.clone(), cloud_gate.clone());
                tasks.spawn(async move {
                    let (reply, payload) = handle(&s, &req, gate, &|| o.all_read()).await;
                    o.reply_with(reply.with_id(req.id.clone()), payload).await;
                });
            }
        }
    }
    lock(&idle).idle.remove(&me);
    set_watched(&shared, &watching, &[]);
    tasks.abort_all();
    drop(out);
    // Let queued replies go out (bounded by the writer's own timeout).
    let _ = tokio::time::timeout(Duration::from_secs(1), writer).await;
}

/// Moves this client's watch from `old` to `new` in the shared refcounts.
fn set_watched(shared: &Shared, old: &[String], new: &[String]) {
    let mut w = lock(&shared.watched);
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

/// Every sweep's detections of `objects`, until aborted.
async fn watch(shared: Arc<Shared>, out: Outbox, objects: Vec<String>, id: Option<Value>) {
    let mut rx = shared.latest.subscribe();
    // The newest sweep so far is answered at once; then each new one.
    rx.mark_changed();
    if !shared.config().continuous {
        shared.sweep_wanted.notify_one();
    }
    loop {
        if rx.changed().await.is_err() {
            return;
        }
        let Some(entry) = rx.borrow_and_update().clone() else {
            continue;
        };
        for name in &objects {
            let Ok(model) = shared.model(name) else { continue };
            let det = entry.detection(&shared, model, false).await;
            out.update(detection_reply(&entry, &det, false, &shared.config().frame_id).with_id(id.clone()));
        }
        if !shared.config().continuous {
            shared.sweep_wanted.notify_one();
        }
    }
}

/// The `detection` reply: the detector's JSON, the sweep it was made on and how old that is.
pub fn detection_reply(entry: &SweepEntry, det: &super::state::Detected, all: bool, frame: &str) -> Reply {
    Reply::Detection(Box::new(DetectionReply {
        id: None,
        report: report_json(&det.report, all),
        frame: frame.to_string(),
        sweep: entry.reference(),
        latency_ms: round3(det.latency.as_secs_f64() * 1e3),
    }))
}

/// Answers one request (not watch/unwatch, which change the connection): the reply, and the
/// payload that follows its line (`cloud`'s points).
async fn handle(
    shared: &Arc<Shared>,
    req: &Request,
    gate: Arc<Semaphore>,
    all_read: &(dyn Fn() -> bool + Send + Sync),
) -> (Reply, Option<Payload>) {
    match &req.command {
        Command::Cloud { max_age_s, timeout_s } => cloud(shared, *max_age_s, *timeout_s, gate, all_read).await,
        _ => (answer(shared, req).await, None),
    }
}

/// The reply to a request without a payload.
async fn answer(shared: &Arc<Shared>, req: &Request) -> Reply {
    match &req.command {
        Command::Status => Reply::Status(Box::new(shared.status())),
        Command::Models => models_reply(shared),
        Command::Find {
            object,
            max_age_s,
            timeout_s,
            all,
        } => {
            let model = match shared.model(object) {
                Ok(m) => m,
                Err(e) => return Reply::error(None, ErrorCode::UnknownObject, e),
            };
            let asked = Instant::now();
            let deadline = asked + Duration::from_secs_f64(*timeout_s);
            let max_age = Duration::from_secs_f64(*max_age_s);
            let fresh = |e: &SweepEntry| e.age() <= max_age || e.completed >= asked;
            let entry = match wait_for_sweep(shared, deadline, fresh).await {
                Ok(e) => e,
                Err((code, msg)) => return Reply::error(None, code, format!("find {object}: {msg}")),
            };
            let det = entry.detection(shared, model, *all).await;
            detection_reply(&entry, &det, *all, &shared.config().frame_id)
        }
        Command::Scan { timeout_s } => {
            let asked = Instant::now();
            let deadline = asked + Duration::from_secs_f64(*timeout_s);
            // A sweep begun after the request: it shows the scene as it is now.
            match wait_for_sweep(shared, deadline, |e| e.started >= asked).await {
                Ok(e) => Reply::Sweep(Box::new(SweepReply {
                    id: None,
                    sweep: e.summary(),
                })),
                Err((code, msg)) => Reply::error(None, code, format!("scan: {msg}")),
            }
        }
        Command::Watch { .. } | Command::Unwatch | Command::Cloud { .. } => {
            Reply::error(None, ErrorCode::Internal, "handled elsewhere")
        }
    }
}

/// How often a request waiting for a sweep looks whether the source has finished.
const FINISHED_POLL: Duration = Duration::from_millis(100);

/// The newest sweep that satisfies `ok`, waiting (and asking an on-demand loop for one) until
/// `deadline`, or until the source has finished (a replay that served every sweep).
pub(super) async fn wait_for_sweep(
    shared: &Arc<Shared>,
    deadline: Instant,
    ok: impl Fn(&SweepEntry) -> bool,
) -> Result<Arc<SweepEntry>, (ErrorCode, String)> {
    let mut rx = shared.latest.subscribe();
    loop {
        if let Some(e) = rx.borrow_and_update().clone()
            && ok(&e)
        {
            return Ok(e);
        }
        if let Some(finished) = shared.devices.finished() {
            let last = match shared.newest() {
                Some(e) => format!("the last sweep ({}) is {:.1} s old", e.id, e.age().as_secs_f64()),
                None => "no sweep was served".into(),
            };
            return Err((ErrorCode::ReplayFinished, format!("{finished}; {last}")));
        }
        if !shared.config().continuous {
            shared.sweep_wanted.notify_one();
        }
        // A replay that runs out says so on its devices, not with a sweep: look at them now and
        // then while waiting.
        let changed = loop {
            let slice = deadline.min(Instant::now() + FINISHED_POLL);
            match tokio::time::timeout_at(slice.into(), rx.changed()).await {
                Ok(r) => break Some(r),
                Err(_) if Instant::now() >= deadline => break None,
                Err(_) if shared.devices.finished().is_some() => break Some(Ok(())),
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

fn models_reply(shared: &Shared) -> Reply {
    let models = shared
        .models()
        .values()
        .map(|m| ModelJson {
            name: m.name.clone(),
            parts: m
                .parts
                .iter()
                .map(|p| ModelPart {
                    name: p.name.clone(),
                    size_m: p.shape.a,
                    shape: [p.shape.e1, p.shape.e2],
                    taper: [p.shape.kx, p.shape.ky],
                    open: p.open,
                })
                .collect(),
        })
        .collect();
    Reply::Models(Models { id: None, models })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Under systemd's default soft limit of 1024 open files, 1,024 idle clients took every
    /// descriptor: accept failed ("Too many open files") and nobody else got in. The slots
    /// leave the daemon its own descriptors.
    #[test]
    fn client_slots_leave_the_daemon_its_own_descriptors() {
        assert_eq!(client_slots(1024, Some(1024)), 1024 - OWN_DESCRIPTORS as usize);
        assert_eq!(client_slots(1024, Some(524_288)), 1024);
        assert_eq!(client_slots(1024, None), 1024);
        assert_eq!(client_slots(10, Some(3)), 1);
        assert_eq!(client_slots(1024, Some(0)), 1);
    }

    #[test]
    fn the_descriptor_limit_is_raised_to_the_hard_one() {
        let l = raise_descriptor_limit().expect("getrlimit");
        let mut r = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        // SAFETY: getrlimit writes only into the struct given.
        assert_eq!(unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut r) }, 0);
        assert_eq!(r.rlim_cur, l);
        assert!(
            r.rlim_max == libc::RLIM_INFINITY || r.rlim_cur == r.rlim_max,
            "{l} of {}",
            r.rlim_max
        );
    }

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
        assert_eq!(shared.stats.watch_skipped.load(Ordering::Relaxed), 3);
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
        let skipped = shared.stats.watch_skipped.load(Ordering::Relaxed) as usize;
        assert_eq!(skipped, 1000 - MAX_QUEUED_BYTES / n);
    }
}
