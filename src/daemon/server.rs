//! The socket server: JSON lines over a Unix socket (and optionally TCP), in the manner of gpsd.
//!
//! It accepts clients up to the slots the descriptors allow, each served by
//! [`connection`](super::connection) (a reader, a writer and a bounded queue between them, see
//! [`outbox`](super::outbox)); when every slot is taken the longest-idle client is closed to
//! make room for a new one, and a client refused says why. Nothing here can block acquisition,
//! which only publishes into a `watch` channel.

use std::os::fd::{AsRawFd, RawFd};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use tokio::io::{AsyncRead, AsyncWrite, AsyncWriteExt, BufReader};
use tokio::net::{TcpListener, UnixListener};
use tokio::sync::Semaphore;
use tokio::task::JoinSet;

use super::config::Config;
use super::connection::client;
use super::idle::Idle;
use super::reply::{ErrorCode, Reply};
use super::socket::bind_unix;
use super::state::{Shared, lock};

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
    let mut shutdown = shared.shutdown().listen();
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
            () = shutdown.thrown() => break,
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
        shared.stats().clients.fetch_add(1, Ordering::Relaxed);
        shared.stats().clients_total.fetch_add(1, Ordering::Relaxed);
        client(shared.clone(), idle, BufReader::new(rd), wr, fd).await;
        shared.stats().clients.fetch_sub(1, Ordering::Relaxed);
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
}
