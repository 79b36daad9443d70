//! Diagnostics of both binaries: `tracing` to stderr (stdout stays the command's output), at the
//! level `SQSCAN_LOG` names (`error`, `warn`, `info`, `debug`, `trace`) or the binary's default.
//!
//! Three forms, by where stderr goes:
//! - a terminal: time, level and message, coloured;
//! - the systemd journal (stderr is the stream `JOURNAL_STREAM` names): each line starts with its
//!   syslog priority, `<3>` for an error to `<7>` for debug (sd-daemon(3); journald's
//!   `SyslogLevelPrefix=`, on by default), and carries no time, which journald adds, so that
//!   `journalctl -p err` shows the errors;
//! - anything else (a file, a pipe): as on a terminal without colour codes.
//!
//! The DDS stack's lines (targets `rustdds` and `ros2_client`, the `ros2` feature) are
//! rate-limited: a peer on the network can make RustDDS log an error for each datagram it sends,
//! and a flood of them must not fill the journal.

use std::fmt;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use tracing::{Event, Level, Subscriber};
use tracing_subscriber::fmt::format::{FormatEvent, FormatFields, Writer};
use tracing_subscriber::fmt::{FmtContext, FormattedFields};
use tracing_subscriber::layer::{Context, Layer, SubscriberExt};
use tracing_subscriber::registry::LookupSpan;
use tracing_subscriber::util::SubscriberInitExt;

/// The syslog priority of a level (sd-daemon(3): `<3>` error, `<4>` warning, `<6>` info,
/// `<7>` debug).
pub fn syslog_priority(level: &Level) -> u8 {
    match *level {
        Level::ERROR => 3,
        Level::WARN => 4,
        Level::INFO => 6,
        _ => 7,
    }
}

/// Lines for the journal: `<N>` and the message, with the fields of the spans around it.
struct JournalLines;

impl<S, N> FormatEvent<S, N> for JournalLines
where
    S: Subscriber + for<'a> LookupSpan<'a>,
    N: for<'a> FormatFields<'a> + 'static,
{
    fn format_event(&self, ctx: &FmtContext<'_, S, N>, mut writer: Writer<'_>, event: &Event<'_>) -> fmt::Result {
        let mut line = String::new();
        if let Some(scope) = ctx.event_scope() {
            for span in scope.from_root() {
                line.push_str(span.name());
                if let Some(fields) = span.extensions().get::<FormattedFields<N>>()
                    && !fields.is_empty()
                {
                    line.push_str(&format!("{{{fields}}}"));
                }
                line.push_str(": ");
            }
        }
        ctx.field_format().format_fields(Writer::new(&mut line), event)?;
        // One record a line: line breaks in a message or a span's fields would start records
        // without a priority, so they are written as spaces.
        writeln!(
            writer,
            "<{}>{}",
            syslog_priority(event.metadata().level()),
            line.replace(['\n', '\r'], " ")
        )
    }
}

/// The fields of events and spans as `tracing`'s default writes them, with control characters
/// escaped: messages carry a client's request or a file's token, and a line break or a terminal
/// escape sequence in them must not forge a log line or recolour the terminal.
#[derive(Default)]
struct EscapedFields(tracing_subscriber::fmt::format::DefaultFields);

impl<'w> FormatFields<'w> for EscapedFields {
    fn format_fields<R: tracing_subscriber::field::RecordFields>(
        &self,
        mut writer: Writer<'w>,
        fields: R,
    ) -> fmt::Result {
        let mut text = String::new();
        self.0.format_fields(Writer::new(&mut text), fields)?;
        writer.write_str(&crate::spec::escape_controls(&text))
    }
}

/// Whether stderr is the journal stream systemd connected (`JOURNAL_STREAM` is its
/// `DEVICE:INODE`): only then do the priority prefixes mean anything to the reader.
pub fn stderr_is_journal() -> bool {
    use std::os::fd::AsFd;
    use std::os::unix::fs::MetadataExt;
    let Some(stream) = std::env::var_os("JOURNAL_STREAM") else {
        return false;
    };
    let Some((dev, ino)) = stream.to_str().and_then(|s| s.split_once(':')) else {
        return false;
    };
    let (Ok(dev), Ok(ino)) = (dev.parse::<u64>(), ino.parse::<u64>()) else {
        return false;
    };
    let Ok(fd) = std::io::stderr().as_fd().try_clone_to_owned() else {
        return false;
    };
    std::fs::File::from(fd)
        .metadata()
        .is_ok_and(|m| m.dev() == dev && m.ino() == ino)
}

/// Installs the stderr subscriber; call once at start-up.
pub fn init(default: tracing::Level) {
    use std::io::IsTerminal;
    let level = std::env::var("SQSCAN_LOG")
        .ok()
        .and_then(|l| l.parse().ok())
        .unwrap_or(default);
    let builder = tracing_subscriber::fmt()
        .fmt_fields(EscapedFields::default())
        .with_writer(std::io::stderr)
        .with_max_level(level)
        .with_target(false);
    let quiet = libraries(level);
    if stderr_is_journal() {
        builder
            .with_ansi(false)
            .event_format(JournalLines)
            .finish()
            .with(quiet)
            .with(RateLimit::default())
            .init();
    } else {
        builder
            .with_ansi(std::io::stderr().is_terminal())
            .finish()
            .with(quiet)
            .with(RateLimit::default())
            .init();
    }
}

/// The DDS stack (the `ros2` feature) logs each large datagram and each change of a remote
/// reader as warnings and information: at our `info` and `warn` only its errors are shown, and
/// all of it from `debug` on.
fn libraries(level: Level) -> tracing_subscriber::filter::Targets {
    use tracing_subscriber::filter::LevelFilter;
    let dds = if level >= Level::DEBUG {
        LevelFilter::from_level(level)
    } else {
        LevelFilter::ERROR
    };
    tracing_subscriber::filter::Targets::new()
        .with_default(LevelFilter::from_level(level))
        .with_target("rustdds", dds)
        .with_target("ros2_client", dds)
}

/// The targets whose lines are rate-limited: the DDS stack's (with their modules).
const RATE_LIMITED: [&str; 2] = ["rustdds", "ros2_client"];

/// Lines shown from each rate-limited target in a window; the rest are counted.
const LINES_PER_WINDOW: u32 = 5;
const WINDOW: Duration = Duration::from_secs(1);

/// Which of [`RATE_LIMITED`] a target is (itself or one of its modules).
fn rate_limited(target: &str) -> Option<usize> {
    RATE_LIMITED.iter().position(|t| {
        target
            .strip_prefix(t)
            .is_some_and(|rest| rest.is_empty() || rest.starts_with("::"))
    })
}

/// One target's window: when it started, the lines shown in it and those held back.
#[derive(Default, Clone, Copy)]
struct Window {
    start: Option<Instant>,
    shown: u32,
    suppressed: u64,
}

/// At most [`LINES_PER_WINDOW`] lines a [`WINDOW`] from each rate-limited target. The lines held
/// back in a window are told in one line when the next line of any target is logged after the
/// window.
#[derive(Default)]
struct Limiter {
    windows: [Window; RATE_LIMITED.len()],
}

impl Limiter {
    /// Whether a line of target `which` (an index in [`RATE_LIMITED`], or None for any other
    /// target) is shown at `now`, and the windows that ended with lines held back: (target,
    /// lines, the window's length).
    fn admit(&mut self, which: Option<usize>, now: Instant) -> (bool, Vec<(&'static str, u64, Duration)>) {
        let mut ended = Vec::new();
        for (i, w) in self.windows.iter_mut().enumerate() {
            if let Some(start) = w.start
                && now.duration_since(start) >= WINDOW
            {
                if w.suppressed > 0 {
                    ended.push((RATE_LIMITED[i], w.suppressed, now.duration_since(start)));
                }
                *w = Window::default();
            }
        }
        let shown = match which {
            None => true,
            Some(i) => {
                let w = &mut self.windows[i];
                w.start.get_or_insert(now);
                if w.shown < LINES_PER_WINDOW {
                    w.shown += 1;
                    true
                } else {
                    w.suppressed += 1;
                    false
                }
            }
        };
        (shown, ended)
    }
}

/// The rate limit as a layer: a line held back is disabled for every layer.
#[derive(Default)]
struct RateLimit(Mutex<Limiter>);

/// Which of [`RATE_LIMITED`] a line comes from. RustDDS and ros2-client log through the `log`
/// crate: their lines come as events of target `log`, with the real target in a field.
fn event_rate_limited(event: &Event<'_>) -> Option<usize> {
    struct LogTarget(Option<usize>);
    impl tracing::field::Visit for LogTarget {
        fn record_str(&mut self, field: &tracing::field::Field, value: &str) {
            if field.name() == "log.target" {
                self.0 = rate_limited(value);
            }
        }
        fn record_debug(&mut self, _: &tracing::field::Field, _: &dyn fmt::Debug) {}
    }
    let target = event.metadata().target();
    if target != "log" {
        return rate_limited(target);
    }
    let mut v = LogTarget(None);
    event.record(&mut v);
    v.0
}

impl<S: Subscriber> Layer<S> for RateLimit {
    fn event_enabled(&self, event: &Event<'_>, _ctx: Context<'_, S>) -> bool {
        let which = event_rate_limited(event);
        let Ok(mut limiter) = self.0.lock() else {
            return true;
        };
        let (shown, ended) = limiter.admit(which, Instant::now());
        drop(limiter);
        // Logged here, before the line that ended the window: of a target not rate-limited, so
        // it comes back to this layer only to be shown.
        for (target, n, over) in ended {
            tracing::warn!(
                "{n} more lines from {target} in {:.1} s not shown (at most {LINES_PER_WINDOW} a second)",
                over.as_secs_f64()
            );
        }
        shown
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_dds_targets_are_rate_limited_and_others_are_not() {
        assert_eq!(rate_limited("rustdds"), Some(0));
        assert_eq!(rate_limited("rustdds::rtps::fragment_assembler"), Some(0));
        assert_eq!(rate_limited("ros2_client::node"), Some(1));
        assert_eq!(rate_limited("rustdds_like"), None);
        assert_eq!(rate_limited("sqscan::daemon"), None);
    }

    /// A flood shows a few lines a second, then how many were held back; other targets are
    /// never held back.
    #[test]
    fn a_flood_shows_a_few_lines_a_second_and_then_how_many_were_not_shown() {
        let mut l = Limiter::default();
        let t0 = Instant::now();
        let shown = (0..1000)
            .filter(|i| l.admit(Some(0), t0 + Duration::from_micros(*i)).0)
            .count();
        assert_eq!(shown, LINES_PER_WINDOW as usize);
        assert!(l.admit(None, t0 + Duration::from_millis(10)).0);
        // ros2_client has a window of its own.
        assert!(l.admit(Some(1), t0 + Duration::from_millis(20)).0);
        let (shown, ended) = l.admit(None, t0 + Duration::from_millis(1500));
        assert!(shown);
        assert_eq!(ended.len(), 1);
        assert_eq!((ended[0].0, ended[0].1), ("rustdds", 1000 - LINES_PER_WINDOW as u64));
        // A new window: lines shown again, nothing more to tell.
        let (shown, ended) = l.admit(Some(0), t0 + Duration::from_millis(1600));
        assert!(shown && ended.is_empty());
    }
}
