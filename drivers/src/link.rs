//! The byte link under a device: opening a serial port, and telling an unplugged device from
//! other IO errors.
//!
//! Devices are generic over any `AsyncRead + AsyncWrite` stream (a serial port, a pty, an
//! in-memory duplex); [`open_serial`] is the one place that knows about real ports.

use std::io;
use std::path::{Path, PathBuf};
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::{Duration, Instant};

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio_serial::{SerialPortBuilderExt, SerialStream};

use crate::Error;

/// Any byte stream a device can run over.
pub trait Link: AsyncRead + AsyncWrite + Unpin + Send {}
impl<T: AsyncRead + AsyncWrite + Unpin + Send> Link for T {}

/// An open serial port (or pty slave): 8N1, raw, no flow control, exclusive while open.
///
/// Exclusivity is TIOCEXCL plus an advisory `flock`, so a second program (or a second `sqscan
/// ptu`) cannot interleave telegrams with ours. TIOCEXCL is a flag on the tty, not on our file
/// descriptor: it outlives our `close()` while anyone else holds the tty open, which is always
/// the case for a pty whose mock keeps its slave open. So dropping a `SerialLink` clears it
/// again; otherwise every non-root user's second open of a mock device would fail with EBUSY.
#[derive(Debug)]
pub struct SerialLink {
    port: SerialStream,
    path: PathBuf,
}

impl SerialLink {
    /// The path the port was opened by (a symlink stays a symlink).
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for SerialLink {
    fn drop(&mut self) {
        // Best effort: the port may already be gone (unplugged), which is fine.
        let _ = self.port.set_exclusive(false);
    }
}

/// Opens `path` at `baud`, 8N1, raw. Errors name the path.
pub fn open_serial(path: &Path, baud: u32) -> Result<SerialLink, Error> {
    let open_error = |source: io::Error| Error::Open {
        path: path.to_owned(),
        source,
    };
    let name = path
        .to_str()
        .ok_or_else(|| open_error(io::Error::new(io::ErrorKind::InvalidInput, "path is not valid UTF-8")))?;
    let port = tokio_serial::new(name, baud)
        .data_bits(tokio_serial::DataBits::Eight)
        .parity(tokio_serial::Parity::None)
        .stop_bits(tokio_serial::StopBits::One)
        .flow_control(tokio_serial::FlowControl::None)
        .open_native_async()
        .map_err(|e| open_error(e.into()))?;
    Ok(SerialLink {
        port,
        path: path.to_owned(),
    })
}

impl AsyncRead for SerialLink {
    fn poll_read(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.port).poll_read(cx, buf)
    }
}

impl AsyncWrite for SerialLink {
    fn poll_write(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.port).poll_write(cx, buf)
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.port).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.port).poll_shutdown(cx)
    }
}

/// `now + wait`, saturating at a century for a `wait` too long to represent (an Instant
/// addition would panic), so that any configured timeout is safe.
pub fn deadline_after(wait: Duration) -> Instant {
    let now = Instant::now();
    now.checked_add(wait)
        .or_else(|| now.checked_add(Duration::from_secs(100 * 365 * 86_400)))
        .unwrap_or(now)
}

/// Maps an IO error on an open link: the ways an unplugged device shows itself become
/// [`Error::Disconnected`], anything else stays [`Error::Io`].
///
/// A USB adapter pulled out gives EIO or ENXIO on Linux; a pty whose master closed gives EIO on
/// read; a socket or pipe whose peer went gives BrokenPipe / ConnectionReset / UnexpectedEof.
pub fn classify_io(e: io::Error) -> Error {
    const EIO: i32 = 5;
    const ENXIO: i32 = 6;
    const ENODEV: i32 = 19;
    let unplugged = matches!(
        e.kind(),
        io::ErrorKind::BrokenPipe
            | io::ErrorKind::ConnectionReset
            | io::ErrorKind::ConnectionAborted
            | io::ErrorKind::UnexpectedEof
            | io::ErrorKind::NotConnected
    ) || matches!(e.raw_os_error(), Some(EIO | ENXIO | ENODEV));
    if unplugged { Error::Disconnected } else { Error::Io(e) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unplug_errors_are_disconnected() {
        assert!(matches!(
            classify_io(io::Error::from_raw_os_error(5)),
            Error::Disconnected
        ));
        assert!(matches!(
            classify_io(io::ErrorKind::BrokenPipe.into()),
            Error::Disconnected
        ));
        assert!(matches!(
            classify_io(io::ErrorKind::PermissionDenied.into()),
            Error::Io(_)
        ));
    }

    #[test]
    fn deadlines_saturate() {
        assert!(deadline_after(Duration::MAX) > Instant::now());
        assert!(deadline_after(Duration::ZERO) <= Instant::now());
    }

    #[test]
    fn open_missing_port_names_the_path() {
        let e = open_serial(Path::new("/nonexistent/tty-sqscan"), 38400).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/tty-sqscan"), "{e}");
    }
}
