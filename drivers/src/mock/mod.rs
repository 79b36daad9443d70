//! Mock devices, written from the device's side, and the pseudo-terminal they run on.
//!
//! A [`MockDevice`] is a pure protocol simulation: bytes from the host in, reply messages out,
//! at a time the caller gives. [`MockPort`] puts one on a pty so that a driver opens the slave
//! path exactly as it opens hardware, and injects faults ([`Faults`]) between the device and the
//! line: garbage, dropped and corrupted replies, delays, and an unplug after N replies.
//!
//! The mock knows nothing of scenes: the main crate's rig mock shares a device (behind a mutex)
//! with a simulated profile sensor that asks it for [`MockDevice::joint_angles`].

pub mod flir;
#[cfg(feature = "gige")]
pub mod gige;
pub mod netns;
pub mod powercube;
pub mod sensor;

use std::io;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_serial::{SerialPort, SerialStream};

pub use flir::{MockFlirAxisConfig, MockFlirConfig, MockFlirPtu};
pub use powercube::{MockModule, MockModuleConfig, MockPowerCube, MockPowerCubeConfig};
pub use sensor::SensorView;

/// The device side of a protocol.
pub trait MockDevice: Send {
    /// Takes bytes from the host at `now`; returns the device's replies, one message each (the
    /// unit that fault injection drops, corrupts or delays).
    fn receive(&mut self, bytes: &[u8], now: Instant) -> Vec<Vec<u8>>;

    /// A copy of `reply` that fails the protocol's integrity check (a bad checksum).
    fn corrupt(&self, reply: &[u8]) -> Vec<u8>;

    /// Device angles (pan, tilt) in rad at `now`.
    fn joint_angles(&mut self, now: Instant) -> (f64, f64);

    /// The line noise to send for random `junk` bytes. A framed protocol with a checksum sends
    /// them as they are; a line protocol without one cannot tell random bytes that spell a
    /// reply from a reply, so its mock shapes the noise into what such a line can survive.
    fn noise(&self, junk: Vec<u8>) -> Vec<u8> {
        junk
    }

    /// Whether the device has answers that wait on time rather than on input (a PTU-D46's
    /// `a `, "await completion"): [`MockPort::serve`] then calls [`poll`](Self::poll) every
    /// [`POLL_PERIOD`] as well as on input.
    fn wants_poll(&self) -> bool {
        false
    }

    /// Answers that have become due by `now`.
    fn poll(&mut self, _now: Instant) -> Vec<Vec<u8>> {
        Vec::new()
    }
}

/// How often [`MockPort::serve`] polls a device that [`MockDevice::wants_poll`].
pub const POLL_PERIOD: Duration = Duration::from_millis(2);

/// Faults injected between a mock device and its line. Every counter is over replies sent
/// (1-based); 0 disables a fault.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Faults {
    /// Before every Nth reply, send 1..=16 random bytes.
    pub garbage_every: u64,
    /// Swallow every Nth reply (a lost reply: the driver must time out and retry).
    pub drop_every: u64,
    /// Send every Nth reply with a bad checksum.
    pub corrupt_every: u64,
    /// Wait this long before each reply.
    pub delay: Duration,
    /// After this many replies, close the line (the device is unplugged).
    pub disconnect_after: Option<u64>,
    /// Seed of the garbage bytes.
    pub seed: u64,
}

impl Faults {
    fn hits(every: u64, n: u64) -> bool {
        every != 0 && n.is_multiple_of(every)
    }
}

/// Why [`MockPort::serve`] returned.
#[derive(Debug)]
pub enum ServeEnd {
    /// `Faults::disconnect_after` replies were sent and the line was closed.
    Unplugged { replies: u64 },
}

/// A pseudo-terminal a mock device answers on. The driver opens [`MockPort::path`] (or the
/// symlink at the link path) as it would a serial port.
///
/// The mock keeps its own handle on the slave side open for its whole life: without it the
/// master reads EIO whenever no driver has the port open, and bytes written while nobody
/// listens would be lost to a hangup.
pub struct MockPort {
    master: SerialStream,
    _slave: SerialStream,
    path: PathBuf,
    link: Option<PathBuf>,
}

impl MockPort {
    /// Creates a pty pair; if `link` is given, points a symlink there at the slave (replacing
    /// an existing symlink, never a regular file).
    pub fn create(link: Option<&Path>) -> io::Result<Self> {
        let (master, slave) = SerialStream::pair().map_err(io::Error::from)?;
        let path = slave
            .name()
            .map(PathBuf::from)
            .ok_or_else(|| io::Error::other("pty slave has no name"))?;
        if let Some(link) = link {
            replace_symlink(&path, link)?;
        }
        Ok(Self {
            master,
            _slave: slave,
            path,
            link: link.map(Path::to_owned),
        })
    }

    /// The slave device path (e.g. `/dev/pts/7`).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The symlink kept at the link path, if any.
    pub fn link(&self) -> Option<&Path> {
        self.link.as_deref()
    }

    /// Answers the host with `device` until the line is unplugged by `faults`, an IO error, or
    /// the future is dropped (which closes the pty: dropping it is an unplug too).
    pub async fn serve<D: MockDevice + ?Sized>(
        mut self,
        device: Arc<Mutex<D>>,
        faults: Faults,
    ) -> io::Result<ServeEnd> {
        let mut rng = faults.seed | 1;
        let mut replies = 0u64;
        let mut buf = [0u8; 1024];
        loop {
            let polling = device.lock().unwrap_or_else(|p| p.into_inner()).wants_poll();
            // `read` is cancel-safe: losing the race to the poll timer loses no bytes.
            let input = if polling {
                tokio::select! {
                    r = self.master.read(&mut buf) => Some(r?),
                    () = tokio::time::sleep(POLL_PERIOD) => None,
                }
            } else {
                Some(self.master.read(&mut buf).await?)
            };
            if input == Some(0) {
                return Err(io::ErrorKind::UnexpectedEof.into());
            }
            let (out, corrupted) = {
                let mut dev = device.lock().unwrap_or_else(|p| p.into_inner());
                let now = Instant::now();
                let out = match input {
                    Some(n) => dev.receive(buf.get(..n).unwrap_or_default(), now),
                    None => dev.poll(now),
                };
                let corrupted: Vec<Vec<u8>> = out.iter().map(|r| dev.corrupt(r)).collect();
                (out, corrupted)
            };
            for (reply, bad) in out.into_iter().zip(corrupted) {
                replies += 1;
                if !faults.delay.is_zero() {
                    tokio::time::sleep(faults.delay).await;
                }
                if Faults::hits(faults.garbage_every, replies) {
                    let len = 1 + (xorshift(&mut rng) % 16) as usize;
                    let junk: Vec<u8> = (0..len).map(|_| xorshift(&mut rng) as u8).collect();
                    let junk = device.lock().unwrap_or_else(|p| p.into_inner()).noise(junk);
                    self.master.write_all(&junk).await?;
                }
                // A dropped reply still counts towards the unplug.
                if !Faults::hits(faults.drop_every, replies) {
                    let wire = if Faults::hits(faults.corrupt_every, replies) {
                        bad
                    } else {
                        reply
                    };
                    self.master.write_all(&wire).await?;
                }
                if faults.disconnect_after.is_some_and(|n| replies >= n) {
                    return Ok(ServeEnd::Unplugged { replies });
                }
            }
        }
    }
}

/// Points `link` at `target`, atomically: a new symlink beside it, renamed over the old one.
fn replace_symlink(target: &Path, link: &Path) -> io::Result<()> {
    if let Ok(meta) = std::fs::symlink_metadata(link)
        && !meta.file_type().is_symlink()
    {
        return Err(io::Error::new(
            io::ErrorKind::AlreadyExists,
            format!("{} exists and is not a symlink", link.display()),
        ));
    }
    let name = link.file_name().unwrap_or_default().to_string_lossy();
    let tmp = link.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
    let _ = std::fs::remove_file(&tmp);
    std::os::unix::fs::symlink(target, &tmp)?;
    std::fs::rename(&tmp, link)
}

fn xorshift(s: &mut u64) -> u64 {
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    *s
}
