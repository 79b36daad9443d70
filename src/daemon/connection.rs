//! One client's connection: its reader, the requests it has in flight and its watch.
//!
//! The reader takes a line at a time, and only while the client has room in its queue and fewer
//! than [`MAX_IN_FLIGHT`] requests unanswered: a client that does not read its replies stalls
//! itself alone. A [`Handler`] answers each request: `watch` and `unwatch` change the connection,
//! `status` and `models` are answered at once, the rest (which may wait for a sweep) run in tasks
//! of their own so that a `find` waiting on the next sweep does not hold up a `status`.

use std::os::fd::RawFd;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use serde_json::Value;
use tokio::io::{AsyncRead, AsyncWrite, BufReader};
use tokio::sync::{Notify, Semaphore, mpsc};
use tokio::task::{AbortHandle, JoinSet};

use super::answer::{answer, detection_reply, handle};
use super::config::MAX_REQUEST_BYTES;
use super::idle::Idle;
use super::lines::LineReader;
use super::outbox::{Outbox, Outgoing, spawn_writer};
use super::protocol::{self, Command, Request};
use super::reply::{ErrorCode, Reply, Version, Watch};
use super::shutdown::Listener;
use super::state::{Shared, lock};

/// Requests of one client in progress at most (beyond them its next line is not read yet).
pub const MAX_IN_FLIGHT: usize = 64;

/// The reply that closes an idle client whose slot a new client took.
const EVICTED: &str = "closing: idle, and a new client needs the slot";

/// Serves one client until it leaves, idles out or the daemon stops.
pub(super) async fn client<R, W>(shared: Arc<Shared>, idle: Idle, mut rd: BufReader<R>, wr: W, fd: RawFd)
where
    R: AsyncRead + Unpin + Send + 'static,
    W: AsyncWrite + Unpin + Send + 'static,
{
    let (tx, rx) = mpsc::channel::<Outgoing>(shared.config().client_queue);
    let out = Outbox::new(tx, shared.clone(), Some(fd));
    // The writer holds no sender: the queue closes when the last sender (the connection's and
    // its tasks') is gone, and the writer ends with it. Each message gives its room back when
    // written (or dropped).
    let writer = spawn_writer(shared.clone(), rx, wr, out.room.clone());
    out.reply(Reply::Version(Version::now())).await;
    let mut handler = Handler::new(shared, out);
    let mut presence = Presence::new(idle);
    let mut lines = LineReader::default();
    while let Some(req) = handler.next_request(&mut rd, &mut lines, &mut presence).await {
        if handler.request(req).await == Flow::Close {
            break;
        }
    }
    presence.leave();
    handler.close(writer).await;
}

/// Whether the connection goes on after a request.
#[derive(Debug, PartialEq, Eq)]
enum Flow {
    Go,
    Close,
}

/// What woke the reader.
enum Woke {
    /// A line, its end or a read error (as [`LineReader::next`] gives them).
    Line(std::io::Result<Option<Result<(), usize>>>),
    /// A request finished: the client may be idle now.
    Finished,
    /// The connection is over (the daemon stops, the client left or idled out).
    Close,
}

/// The connection's place in the daemon's registry of idle clients: registered while it has
/// nothing in flight and no watch, so that a new client that finds every slot taken may close
/// it.
struct Presence {
    idle: Idle,
    me: u64,
    evict: Arc<Notify>,
    /// When the client last did something.
    active: Instant,
}

impl Presence {
    fn new(idle: Idle) -> Presence {
        let me = {
            let mut i = lock(&idle);
            i.next_id += 1;
            i.next_id
        };
        Presence {
            idle,
            me,
            evict: Arc::new(Notify::new()),
            active: Instant::now(),
        }
    }

    /// Registers the client as idle (since it was last active), or as busy.
    fn mark(&self, is_idle: bool) {
        let mut i = lock(&self.idle);
        if is_idle {
            i.idle
                .entry(self.me)
                .or_insert_with(|| (self.active, self.evict.clone()));
        } else {
            i.idle.remove(&self.me);
        }
    }

    /// Marks the client busy after it was idle; false when a new client took its slot meanwhile
    /// (the registry no longer holds it): that client waits for the slot.
    fn wake(&self) -> bool {
        lock(&self.idle).idle.remove(&self.me).is_some()
    }

    fn leave(&self) {
        lock(&self.idle).idle.remove(&self.me);
    }
}

/// Answers one connection's requests: its queue, the requests in flight, its watch.
struct Handler {
    shared: Arc<Shared>,
    out: Outbox,
    tasks: JoinSet<()>,
    watch_task: Option<AbortHandle>,
    /// The objects this connection watches (counted in the shared refcounts).
    watching: Vec<String>,
    /// One cloud of this connection in memory at a time: a client cannot take every slot.
    cloud_gate: Arc<Semaphore>,
    shutdown: Listener,
}

impl Handler {
    fn new(shared: Arc<Shared>, out: Outbox) -> Handler {
        let shutdown = shared.shutdown().listen();
        Handler {
            shared,
            out,
            tasks: JoinSet::new(),
            watch_task: None,
            watching: Vec::new(),
            cloud_gate: Arc::new(Semaphore::new(1)),
            shutdown,
        }
    }

    /// Idle: nothing in flight and no watch.
    fn is_idle(&self) -> bool {
        self.tasks.is_empty() && self.watch_task.is_none()
    }

    /// The next request to answer; `None` when the connection is over. Malformed and oversized
    /// lines are answered with an error here and skipped.
    async fn next_request<R: AsyncRead + Unpin>(
        &mut self,
        rd: &mut BufReader<R>,
        lines: &mut LineReader,
        presence: &mut Presence,
    ) -> Option<Request> {
        loop {
            let is_idle = self.is_idle();
            presence.mark(is_idle);
            let got = match self.wake(rd, lines, presence, is_idle).await {
                Woke::Line(got) => got,
                Woke::Finished => {
                    presence.active = Instant::now();
                    continue;
                }
                Woke::Close => return None,
            };
            presence.active = Instant::now();
            // Idle until this line came in: unless a new client took this one's slot
            // meanwhile, it is busy now. If it did, close, as the eviction said, and do not
            // leave its signal for a later idle spell.
            if is_idle && !presence.wake() {
                self.out.reply(Reply::error(None, ErrorCode::Idle, EVICTED)).await;
                return None;
            }
            if !self.room_to_read().await {
                return None;
            }
            let buf = std::mem::take(&mut lines.buf);
            match got {
                Ok(None) | Err(_) => return None,
                Ok(Some(Err(len))) => {
                    let msg = format!("request of {len} bytes is over the limit of {MAX_REQUEST_BYTES} bytes; skipped");
                    self.out.reply(Reply::error(None, ErrorCode::TooLarge, msg)).await;
                }
                Ok(Some(Ok(()))) if buf.iter().all(|b| b.is_ascii_whitespace()) => {}
                Ok(Some(Ok(()))) => {
                    self.shared.stats().requests.fetch_add(1, Ordering::Relaxed);
                    match protocol::parse_request(&buf) {
                        Ok(r) => return Some(r),
                        Err(e) => self.out.reply(e.reply()).await,
                    }
                }
            }
        }
    }

    /// Waits for a line, a finished request, or the end of the connection: the daemon
    /// stopping, the client gone, or (while idle) the idle timeout or an eviction.
    async fn wake<R: AsyncRead + Unpin>(
        &mut self,
        rd: &mut BufReader<R>,
        lines: &mut LineReader,
        presence: &Presence,
        is_idle: bool,
    ) -> Woke {
        let idle_timeout = self.shared.config().idle_timeout;
        tokio::select! {
            r = lines.next(rd) => Woke::Line(r),
            () = self.shutdown.thrown() => {
                // Whatever is in flight will not be answered: say why before closing.
                self.out.reply(Reply::error(None, ErrorCode::Stopping, "the daemon is stopping")).await;
                Woke::Close
            }
            // A dead writer means the client is gone.
            () = self.out.tx.closed() => Woke::Close,
            Some(_) = self.tasks.join_next(), if !self.tasks.is_empty() => Woke::Finished,
            () = tokio::time::sleep_until((presence.active + idle_timeout).into()), if is_idle => {
                let msg = format!("closing: idle for {} s", idle_timeout.as_secs_f64());
                self.out.reply(Reply::error(None, ErrorCode::Idle, msg)).await;
                Woke::Close
            }
            () = presence.evict.notified(), if is_idle => {
                self.out.reply(Reply::error(None, ErrorCode::Idle, EVICTED)).await;
                Woke::Close
            }
        }
    }

    /// Waits until another request may be read: fewer than [`MAX_IN_FLIGHT`] unanswered and
    /// room in the queue (the client reads its replies); backpressure on this client alone, its
    /// writer's timeout ends it if it never reads again. False when the daemon stops meanwhile.
    async fn room_to_read(&mut self) -> bool {
        while self.tasks.len() > MAX_IN_FLIGHT {
            if self.tasks.join_next().await.is_none() {
                break;
            }
        }
        tokio::select! {
            biased;
            () = self.out.drained() => true,
            () = self.shutdown.thrown() => {
                self.out.try_goodbye();
                false
            }
        }
    }

    /// Answers one request, or starts the task that will.
    async fn request(&mut self, req: Request) -> Flow {
        match &req.command {
            Command::Watch { objects, grasps } => {
                let objects = objects.clone();
                self.watch(req.id, objects, *grasps).await;
                Flow::Go
            }
            Command::Unwatch => {
                self.unwatch(req.id).await;
                Flow::Go
            }
            Command::Status | Command::Models => self.answer_now(&req).await,
            Command::Find { .. } | Command::Scan { .. } | Command::Cloud { .. } => {
                self.spawn(req);
                Flow::Go
            }
        }
    }

    /// `watch`: every sweep's detections of `objects` from now on, replacing an earlier watch.
    async fn watch(&mut self, id: Option<Value>, objects: Vec<String>, grasps: usize) {
        if let Some(missing) = objects.iter().find_map(|o| self.shared.model(o).err()) {
            self.out
                .reply(Reply::error(id, ErrorCode::UnknownObject, missing))
                .await;
            return;
        }
        self.stop_watch();
        self.shared.move_watch(&self.watching, &objects);
        self.watching = objects.clone();
        self.out
            .reply(Reply::Watch(Watch {
                id: id.clone(),
                objects: objects.clone(),
                enable: true,
            }))
            .await;
        let task = watch_sweeps(self.shared.clone(), self.out.clone(), objects, grasps, id);
        self.watch_task = Some(self.tasks.spawn(task));
    }

    /// `unwatch`: no more updates.
    async fn unwatch(&mut self, id: Option<Value>) {
        self.stop_watch();
        self.shared.move_watch(&self.watching, &[]);
        self.watching.clear();
        self.out
            .reply(Reply::Watch(Watch {
                id,
                objects: Vec::new(),
                enable: false,
            }))
            .await;
    }

    fn stop_watch(&mut self) {
        if let Some(t) = self.watch_task.take() {
            t.abort();
        }
    }

    /// `status` and `models`, answered at once: here, so that a client sending these and not
    /// reading waits for its own queue instead of piling up replies in tasks.
    async fn answer_now(&mut self, req: &Request) -> Flow {
        let reply = answer(&self.shared, req).await.with_id(req.id.clone());
        tokio::select! {
            biased;
            () = self.out.reply(reply) => Flow::Go,
            () = self.shutdown.thrown() => {
                self.out.try_goodbye();
                Flow::Close
            }
        }
    }

    /// `find`, `scan` and `cloud`, which may wait for a sweep: in a task of their own.
    fn spawn(&mut self, req: Request) {
        let (s, o, gate) = (self.shared.clone(), self.out.clone(), self.cloud_gate.clone());
        self.tasks.spawn(async move {
            let (reply, payload) = handle(&s, &req, gate, &|| o.all_read()).await;
            o.reply_with(reply.with_id(req.id.clone()), payload).await;
        });
    }

    /// Ends the connection: its watch and requests in flight, then lets the queued replies go
    /// out (bounded by the writer's own timeout).
    async fn close(mut self, writer: tokio::task::JoinHandle<()>) {
        self.shared.move_watch(&self.watching, &[]);
        self.tasks.abort_all();
        drop(self.out);
        let _ = tokio::time::timeout(Duration::from_secs(1), writer).await;
    }
}

/// Every sweep's detections of `objects`, until aborted.
async fn watch_sweeps(shared: Arc<Shared>, out: Outbox, objects: Vec<String>, grasps: usize, id: Option<Value>) {
    let mut rx = shared.sweeps();
    // The newest sweep so far is answered at once; then each new one.
    rx.mark_changed();
    if !shared.config().continuous {
        shared.want_sweep();
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
            let det = entry.detection(&shared, model.clone(), false).await;
            let config = shared.config();
            let grasps = Some((&*model, &config.gripper, grasps));
            out.update(detection_reply(&entry, &det, false, &config.frame_id, grasps).with_id(id.clone()));
        }
        if !shared.config().continuous {
            shared.want_sweep();
        }
    }
}
