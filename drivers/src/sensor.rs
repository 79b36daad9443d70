//! The laser profile sensor: SQPF frames from any byte stream, and its start/stop command.
//!
//! The sensor (or the bridge in front of it) streams one SQPF frame per profile while acquisition
//! is on. The host switches acquisition with one ASCII line on the same link:
//!
//! ```text
//!  host -> sensor   "START\n"   begin acquisition (frames follow at the sensor's rate)
//!                   "STOP\n"    end acquisition (frames already on the line still arrive)
//! ```
//!
//! Neither is acknowledged: the stream itself is the answer. A sensor ignores lines it does not
//! know. Sequence numbers continue across STOP/START, so a restart of the sensor itself shows
//! as a [`SeqEvent::Restart`].
//!
//! The device decodes frames incrementally ([`ProfileDecoder`]), skipping garbage and frames
//! with bad headers or CRCs (counted, never fatal: the next good frame follows), classifies
//! every sequence number ([`SequenceTracker`]) and stamps each profile with the host's monotonic
//! receive time.

use std::future::Future;
use std::path::Path;
use std::time::{Duration, Instant};

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::sync::mpsc;
use tokio::time::timeout;

use crate::Error;
use crate::link::{Link, SerialLink, classify_io, deadline_after, open_serial};
use crate::profile::{Profile, ProfileDecoder, ProfileDecoderStats, SeqCounts, SeqEvent, SequenceTracker};

/// The command that starts acquisition.
pub const START: &[u8] = b"START\n";
/// The command that stops acquisition.
pub const STOP: &[u8] = b"STOP\n";

/// Configuration of a profile sensor link.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorConfig {
    /// Line speed when opened as a serial port (ignored by ptys and sockets).
    pub baud: u32,
    /// After this long without a byte, a frame candidate still waiting for its bytes is dropped
    /// (it was garbage that happened to contain the magic): the decoder then finds the frames
    /// after it without waiting for up to a maximal frame length of further input.
    pub idle_resync: Duration,
    /// Backward sequence steps up to this many are late frames; beyond, a sensor restart.
    pub reorder_window: u32,
}

impl Default for SensorConfig {
    fn default() -> Self {
        Self {
            baud: 921_600,
            idle_resync: Duration::from_millis(100),
            reorder_window: SequenceTracker::DEFAULT_REORDER_WINDOW,
        }
    }
}

/// A decoded profile as received.
#[derive(Clone, Debug, PartialEq)]
pub struct ReceivedProfile {
    pub profile: Profile,
    /// Host monotonic time when the read that completed the frame returned. Frames completed by
    /// the same read share it; the sensor's own `timestamp_ns` is the exposure time.
    pub received: Instant,
    /// What the sequence number says about the stream.
    pub seq: SeqEvent,
}

/// A source of laser profiles, whatever the sensor: the one interface a sweep is acquired
/// through (as [`PanTilt`](crate::PanTilt) is for the unit that moves it). [`ProfileSensor`]
/// implements it for SQPF streams; another sensor (a GigE Vision camera, a replay of recorded
/// profiles) implements it and nothing else changes.
pub trait ProfileSource: Send {
    /// Starts acquisition; profiles follow at the sensor's rate.
    fn start(&mut self) -> impl Future<Output = Result<(), Error>> + Send;

    /// Stops acquisition. Profiles already on their way may still arrive.
    fn stop(&mut self) -> impl Future<Output = Result<(), Error>> + Send;

    /// The next good profile, waiting at most `wait`: [`Error::Timeout`] when none came,
    /// another error when the sensor failed. Cancel-safe: dropping the future loses no profile
    /// that was not returned.
    fn next_profile(&mut self, wait: Duration) -> impl Future<Output = Result<ReceivedProfile, Error>> + Send;
}

/// A profile sensor over any byte stream.
pub struct ProfileSensor<S> {
    link: S,
    cfg: SensorConfig,
    decoder: ProfileDecoder,
    tracker: SequenceTracker,
    frame_errors: u64,
    resyncs: u64,
}

impl ProfileSensor<SerialLink> {
    /// Opens the serial port (or pty) at `path`. Sends nothing: call [`start`](Self::start).
    pub fn open(path: &Path, cfg: SensorConfig) -> Result<Self, Error> {
        let link = open_serial(path, cfg.baud)?;
        Ok(Self::new(link, cfg))
    }
}

impl ProfileSensor<tokio::net::TcpStream> {
    /// Connects to a sensor (or a serial-to-network bridge) that serves the same byte stream
    /// over TCP. Errors name the address.
    pub async fn connect_tcp(addr: &str, cfg: SensorConfig) -> Result<Self, Error> {
        let stream = tokio::net::TcpStream::connect(addr)
            .await
            .map_err(|source| Error::Open {
                path: addr.into(),
                source,
            })?;
        // Commands are tiny and rare: send them at once.
        stream.set_nodelay(true).map_err(Error::Io)?;
        Ok(Self::new(stream, cfg))
    }
}

impl<S: Link> ProfileSensor<S> {
    /// A sensor on `link` (a serial port, a pty, a TCP stream). Sends nothing.
    pub fn new(link: S, cfg: SensorConfig) -> Self {
        Self {
            tracker: SequenceTracker::new(cfg.reorder_window),
            link,
            cfg,
            decoder: ProfileDecoder::new(),
            frame_errors: 0,
            resyncs: 0,
        }
    }

    /// Starts acquisition (`START\n`).
    pub async fn start(&mut self) -> Result<(), Error> {
        self.send(START).await
    }

    /// Stops acquisition (`STOP\n`). Frames already sent still arrive.
    pub async fn stop(&mut self) -> Result<(), Error> {
        self.send(STOP).await
    }

    async fn send(&mut self, line: &[u8]) -> Result<(), Error> {
        self.link.write_all(line).await.map_err(classify_io)?;
        self.link.flush().await.map_err(classify_io)
    }

    /// Sequence totals: received, dropped, duplicates, late, restarts.
    pub fn counts(&self) -> SeqCounts {
        self.tracker.counts()
    }

    /// Decoder totals: profiles, frame errors, bytes skipped while looking for a frame.
    pub fn decoder_stats(&self) -> ProfileDecoderStats {
        self.decoder.stats()
    }

    /// Frames rejected (bad header or CRC).
    pub fn frame_errors(&self) -> u64 {
        self.frame_errors
    }

    /// Frame candidates dropped after the line went idle.
    pub fn idle_resyncs(&self) -> u64 {
        self.resyncs
    }

    /// The link, e.g. to close it.
    pub fn into_inner(self) -> S {
        self.link
    }

    /// The next good profile, waiting at most `wait`. Garbage and bad frames on the way are
    /// skipped and counted. Errors: [`Error::Timeout`] (no profile in time),
    /// [`Error::Disconnected`], [`Error::Io`].
    pub async fn next_profile(&mut self, wait: Duration) -> Result<ReceivedProfile, Error> {
        let deadline = deadline_after(wait);
        let mut received = Instant::now();
        let mut buf = vec![0u8; 8192];
        loop {
            while let Some(item) = self.decoder.next_profile() {
                match item {
                    Ok(profile) => {
                        let seq = self.tracker.observe(profile.seq);
                        return Ok(ReceivedProfile { profile, received, seq });
                    }
                    Err(_) => self.frame_errors += 1,
                }
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(Error::Timeout {
                    waiting_for: "a profile",
                    after: wait,
                });
            }
            match timeout(left.min(self.cfg.idle_resync), self.link.read(&mut buf)).await {
                Err(_idle) => {
                    if self.decoder.pending() > 0 {
                        self.decoder.resync();
                        self.resyncs += 1;
                    }
                }
                Ok(Ok(0)) => return Err(Error::Disconnected),
                Ok(Ok(n)) => {
                    received = Instant::now();
                    self.decoder.push(buf.get(..n).unwrap_or_default());
                }
                Ok(Err(e)) => return Err(classify_io(e)),
            }
        }
    }
}

impl<S: Link> ProfileSource for ProfileSensor<S> {
    async fn start(&mut self) -> Result<(), Error> {
        ProfileSensor::start(self).await
    }

    async fn stop(&mut self) -> Result<(), Error> {
        ProfileSensor::stop(self).await
    }

    async fn next_profile(&mut self, wait: Duration) -> Result<ReceivedProfile, Error> {
        ProfileSensor::next_profile(self, wait).await
    }
}

impl<S: Link + 'static> ProfileSensor<S> {
    /// Moves the sensor to a task that sends every profile to the returned channel (bounded: a
    /// slow consumer holds the reader back rather than growing memory; the sensor's sequence
    /// numbers then show what the line dropped). The task ends after the first error, which it
    /// sends, or when the receiver is dropped. `wait` is the longest quiet period tolerated.
    pub fn into_channel(mut self, capacity: usize, wait: Duration) -> mpsc::Receiver<Result<ReceivedProfile, Error>> {
        let (tx, rx) = mpsc::channel(capacity.max(1));
        tokio::spawn(async move {
            loop {
                let item = self.next_profile(wait).await;
                let failed = item.is_err();
                if tx.send(item).await.is_err() || failed {
                    return;
                }
            }
        });
        rx
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::encode_profile;

    fn profile(seq: u32) -> Profile {
        Profile {
            seq,
            timestamp_ns: u64::from(seq) * 1_000_000,
            fraction_bits: 4,
            rows: vec![100, 0, 300],
            intensity: None,
        }
    }

    #[tokio::test]
    async fn start_stop_commands_and_a_stream_with_faults() {
        let (host, mut device) = tokio::io::duplex(1 << 16);
        let mut sensor = ProfileSensor::new(host, SensorConfig::default());
        sensor.start().await.unwrap();
        sensor.stop().await.unwrap();
        let mut got = [0u8; 11];
        device.read_exact(&mut got).await.unwrap();
        assert_eq!(&got, b"START\nSTOP\n");

        // Garbage, 0, 1, a corrupted 2, 4 (3 lost), 4 again, and a late 3.
        let mut wire = b"noise SQ".to_vec();
        for seq in [0, 1] {
            wire.extend(encode_profile(&profile(seq)).unwrap());
        }
        let mut bad = encode_profile(&profile(2)).unwrap();
        bad[30] ^= 0x40;
        wire.extend(bad);
        for seq in [4, 4, 3] {
            wire.extend(encode_profile(&profile(seq)).unwrap());
        }
        device.write_all(&wire).await.unwrap();
        let wait = Duration::from_secs(10);
        let mut events = Vec::new();
        for _ in 0..5 {
            let r = sensor.next_profile(wait).await.unwrap();
            events.push((r.profile.seq, r.seq));
        }
        assert_eq!(
            events,
            [
                (0, SeqEvent::First),
                (1, SeqEvent::InOrder),
                (
                    4,
                    SeqEvent::Gap {
                        first_missing: 2,
                        missing: 2
                    }
                ),
                (4, SeqEvent::Duplicate),
                (3, SeqEvent::Late { behind: 1 }),
            ]
        );
        assert_eq!(sensor.frame_errors(), 1);
        let c = sensor.counts();
        assert_eq!((c.received, c.dropped, c.duplicates, c.late), (5, 2, 1, 1));

        // A stalled frame candidate (a magic and a header claiming 1000 columns, then only
        // a complete small frame): the candidate would swallow the frame; once the line has
        // been idle it is dropped and the frame behind it decodes.
        let long = Profile {
            rows: vec![7; 1000],
            ..profile(5)
        };
        let mut wire = encode_profile(&long).unwrap();
        wire.truncate(40);
        wire.extend(encode_profile(&profile(6)).unwrap());
        device.write_all(&wire).await.unwrap();
        let r = sensor.next_profile(wait).await.unwrap();
        assert_eq!(r.profile.seq, 6);
        assert_eq!(sensor.idle_resyncs(), 1);

        drop(device);
        assert!(matches!(sensor.next_profile(wait).await, Err(Error::Disconnected)));
    }

    #[tokio::test]
    async fn over_tcp() {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let server = tokio::spawn(async move {
            let (mut s, _) = listener.accept().await.unwrap();
            let mut cmd = [0u8; 6];
            s.read_exact(&mut cmd).await.unwrap();
            assert_eq!(&cmd, START);
            for seq in 0..3 {
                s.write_all(&encode_profile(&profile(seq)).unwrap()).await.unwrap();
            }
        });
        let mut sensor = ProfileSensor::connect_tcp(&addr, SensorConfig::default())
            .await
            .unwrap();
        sensor.start().await.unwrap();
        for seq in 0..3 {
            let r = sensor.next_profile(Duration::from_secs(10)).await.unwrap();
            assert_eq!(r.profile.seq, seq);
        }
        server.await.unwrap();
        // The server closed the connection: an unplugged sensor.
        assert!(matches!(
            sensor.next_profile(Duration::from_secs(10)).await,
            Err(Error::Disconnected)
        ));
        let e = ProfileSensor::connect_tcp("127.0.0.1:1", SensorConfig::default())
            .await
            .err()
            .expect("nobody listens on port 1");
        assert!(e.to_string().contains("127.0.0.1:1"), "{e}");
    }
}
