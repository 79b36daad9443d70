//! A mock profile sensor on a pty: it reads `START`/`STOP` lines and, while started, sends one
//! SQPF frame every period, with the sensor's own clock and sequence numbers.
//!
//! What a profile contains is the caller's business (a [`SensorView`]): the main crate's rig
//! mock renders the scene at the mock PTU's current angles; tests use synthetic profiles.

use std::io;
use std::time::{Duration, Instant};

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::time::MissedTickBehavior;

use super::{Faults, MockPort, ServeEnd, xorshift};
use crate::profile::{Profile, encode_profile};

/// What the sensor sees: a profile's range rows (and intensity) at host time `now`. The mock
/// fills in the sequence number and the timestamp.
pub trait SensorView: Send {
    fn render(&mut self, now: Instant) -> Profile;
}

impl<F: FnMut(Instant) -> Profile + Send> SensorView for F {
    fn render(&mut self, now: Instant) -> Profile {
        self(now)
    }
}

impl MockPort {
    /// Runs a profile sensor on this pty: `START`/`STOP` lines (case-insensitive, CR or LF)
    /// switch acquisition; while on, a profile from `source` every `period`, its `seq` counting
    /// from 0 and its `timestamp_ns` on the sensor's clock (monotonic ns since this call).
    /// Faults count frames: garbage before a frame, a dropped frame (its sequence number is
    /// used up, so the host sees a gap), a corrupted frame (one payload byte flipped: a CRC
    /// failure), an unplug after N frames. Runs until unplugged, an IO error, or dropped.
    pub async fn stream<P: SensorView>(
        mut self,
        mut source: P,
        period: Duration,
        faults: Faults,
    ) -> io::Result<ServeEnd> {
        let clock = Instant::now();
        let mut rng = faults.seed | 1;
        let mut rendered = 0u64;
        let mut seq = 0u32;
        let mut started = false;
        let mut line = Vec::new();
        let mut buf = [0u8; 256];
        let mut tick = tokio::time::interval(period.max(Duration::from_micros(100)));
        tick.set_missed_tick_behavior(MissedTickBehavior::Delay);
        loop {
            tokio::select! {
                r = self.master.read(&mut buf) => {
                    let n = r?;
                    if n == 0 {
                        return Err(io::ErrorKind::UnexpectedEof.into());
                    }
                    for &b in buf.get(..n).unwrap_or_default() {
                        if b != b'\n' && b != b'\r' {
                            // Commands are short; a runaway line is noise and is cut.
                            if line.len() < 64 {
                                line.push(b);
                            }
                            continue;
                        }
                        let command = String::from_utf8_lossy(&line).trim().to_ascii_uppercase();
                        line.clear();
                        match command.as_str() {
                            "START" if !started => {
                                started = true;
                                tick.reset_immediately();
                            }
                            "STOP" if started => {
                                started = false;
                            }
                            // A sensor ignores what it does not know (and repeats).
                            _ => {}
                        }
                    }
                }
                now = tick.tick(), if started => {
                    let now = now.into_std();
                    let mut profile = source.render(now);
                    profile.seq = seq;
                    profile.timestamp_ns = u64::try_from(now.saturating_duration_since(clock).as_nanos()).unwrap_or(u64::MAX);
                    seq = seq.wrapping_add(1);
                    rendered += 1;
                    let n = rendered;
                    let Ok(mut frame) = encode_profile(&profile) else {
                        // The source made a profile the format cannot carry: nothing to send.
                        continue;
                    };
                    if Faults::hits(faults.garbage_every, n) {
                        let len = 1 + (xorshift(&mut rng) % 16) as usize;
                        let junk: Vec<u8> = (0..len).map(|_| xorshift(&mut rng) as u8).collect();
                        self.send(&junk, period).await?;
                    }
                    if Faults::hits(faults.corrupt_every, n)
                        && let Some(b) = frame.get_mut(24)
                    {
                        *b ^= 0x01;
                    }
                    if !Faults::hits(faults.drop_every, n) {
                        self.send(&frame, period).await?;
                    }
                    if faults.disconnect_after.is_some_and(|limit| n >= limit) {
                        return Ok(ServeEnd::Unplugged { replies: n });
                    }
                }
            }
        }
    }
}

impl MockPort {
    /// Writes `bytes` unless the line stays full for several periods (nobody reads the pty):
    /// then the rest is lost, as on an overrun serial line, instead of stalling the sensor
    /// (which must keep reading its commands). The host's decoder drops the broken frame.
    async fn send(&mut self, bytes: &[u8], period: Duration) -> io::Result<()> {
        let patience = period.saturating_mul(4).max(Duration::from_millis(50));
        match tokio::time::timeout(patience, self.master.write_all(bytes)).await {
            Ok(r) => r,
            Err(_full) => Ok(()),
        }
    }
}
