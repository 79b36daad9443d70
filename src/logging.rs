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

use std::fmt;

use tracing::{Event, Level, Subscriber};
use tracing_subscriber::fmt::format::{FormatEvent, FormatFields, Writer};
use tracing_subscriber::fmt::{FmtContext, FormattedFields};
use tracing_subscriber::layer::SubscriberExt;
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
            .init();
    } else {
        builder
            .with_ansi(std::io::stderr().is_terminal())
            .finish()
            .with(quiet)
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
