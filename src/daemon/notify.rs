//! A minimal systemd `sd_notify` client, written from the protocol in `sd_notify(3)`.
//!
//! Under a `Type=notify` unit systemd puts the address of its notification socket in
//! `NOTIFY_SOCKET`: either a filesystem path (`/run/systemd/notify`) or, when it starts with
//! `@`, a Linux abstract socket name (the `@` stands for the leading NUL byte). A message is one
//! datagram of newline-separated `VARIABLE=value` assignments, e.g. `READY=1` or
//! `STATUS=sweeping table 2`.
//!
//! [`Notifier::from_env`] is `None` when the process does not run under systemd, so the daemon
//! can notify unconditionally:
//!
//! ```no_run
//! use sqscan::daemon::notify::{Notifier, watchdog_interval};
//!
//! let notifier = Notifier::from_env();
//! if let Some(n) = &notifier {
//!     n.ready().ok();
//! }
//! // Ping at half the interval systemd configured (WatchdogSec=).
//! let ping_every = watchdog_interval().map(|d| d / 2);
//! # let _ = ping_every;
//! ```
//!
//! Nothing here changes the process environment: `NOTIFY_SOCKET`, `WATCHDOG_USEC` and
//! `WATCHDOG_PID` stay set and are inherited by children. (Unsetting them would need
//! `std::env::remove_var`, which is `unsafe` in a multi-threaded process; a caller that spawns
//! children which must not notify should clear those variables on the `Command` instead.)
//!
//! Sending is a blocking `sendto(2)` on a Unix datagram socket. systemd reads its socket
//! promptly and the messages are tiny, so the call is short enough to make from async code.

use std::io;
use std::os::unix::net::{SocketAddr, UnixDatagram};
use std::path::Path;
use std::time::Duration;

/// The environment variable that holds the notification socket address.
pub const NOTIFY_SOCKET: &str = "NOTIFY_SOCKET";
/// The environment variable that holds the watchdog interval in microseconds.
pub const WATCHDOG_USEC: &str = "WATCHDOG_USEC";
/// The environment variable that names the process the watchdog settings are meant for.
pub const WATCHDOG_PID: &str = "WATCHDOG_PID";

/// A client for systemd's notification socket.
#[derive(Debug)]
pub struct Notifier {
    /// Where messages go.
    addr: SocketAddr,
    /// The address as given (`/run/systemd/notify` or `@name`), for error messages.
    display: String,
    /// An unbound datagram socket (close-on-exec), reused for every message.
    socket: UnixDatagram,
}

impl Notifier {
    /// The notifier for `NOTIFY_SOCKET`, or `None` when the variable is unset or empty (not
    /// running under systemd, or under a unit that is not `Type=notify`). An address this client
    /// cannot use (a relative path, `vsock:`, a path too long for a socket address) is logged as
    /// a warning and also gives `None`. Nothing is removed from the environment.
    pub fn from_env() -> Option<Notifier> {
        let value = std::env::var_os(NOTIFY_SOCKET)?;
        if value.is_empty() {
            return None;
        }
        let Some(value) = value.to_str() else {
            tracing::warn!("{NOTIFY_SOCKET} is not valid UTF-8 ({value:?}); not notifying systemd");
            return None;
        };
        match Notifier::from_value(value) {
            Ok(n) => Some(n),
            Err(e) => {
                tracing::warn!("{e}; not notifying systemd");
                None
            }
        }
    }

    /// The notifier for a `NOTIFY_SOCKET` value: an absolute path, or `@name` for the abstract
    /// socket `\0name`. Anything else (empty, relative, `vsock:...`) is an `InvalidInput` error
    /// that quotes the value.
    pub fn from_value(value: &str) -> io::Result<Notifier> {
        if let Some(name) = value.strip_prefix('@')
            && !name.is_empty()
        {
            return Notifier::abstract_name(name.as_bytes());
        }
        if value.starts_with('/') {
            return Notifier::new(value);
        }
        Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{NOTIFY_SOCKET}={value:?}: expected an absolute socket path or @abstract-name"),
        ))
    }

    /// The notifier for the datagram socket bound at `path`.
    pub fn new(path: impl AsRef<Path>) -> io::Result<Notifier> {
        let path = path.as_ref();
        let display = path.display().to_string();
        let addr = SocketAddr::from_pathname(path).map_err(|e| with_addr(&display, "bad socket address", e))?;
        Notifier::with_addr(addr, display)
    }

    /// The notifier for the Linux abstract socket `name` (given without the leading NUL byte or `@`).
    #[cfg(any(target_os = "linux", target_os = "android"))]
    pub fn abstract_name(name: &[u8]) -> io::Result<Notifier> {
        #[cfg(target_os = "android")]
        use std::os::android::net::SocketAddrExt;
        #[cfg(target_os = "linux")]
        use std::os::linux::net::SocketAddrExt;

        let display = format!("@{}", String::from_utf8_lossy(name));
        let addr = SocketAddr::from_abstract_name(name).map_err(|e| with_addr(&display, "bad socket address", e))?;
        Notifier::with_addr(addr, display)
    }

    /// Abstract sockets exist only on Linux.
    #[cfg(not(any(target_os = "linux", target_os = "android")))]
    pub fn abstract_name(name: &[u8]) -> io::Result<Notifier> {
        let display = format!("@{}", String::from_utf8_lossy(name));
        Err(io::Error::new(
            io::ErrorKind::Unsupported,
            format!("sd_notify socket {display}: abstract sockets need Linux"),
        ))
    }

    fn with_addr(addr: SocketAddr, display: String) -> io::Result<Notifier> {
        let socket = UnixDatagram::unbound().map_err(|e| with_addr(&display, "cannot create socket", e))?;
        Ok(Notifier { addr, display, socket })
    }

    /// The socket address as given: a path, or `@name` for an abstract socket.
    pub fn socket_name(&self) -> &str {
        &self.display
    }

    /// Sends `state` (one or more newline-separated `VARIABLE=value` lines) as one datagram.
    /// A NUL byte in `state` is an `InvalidInput` error (systemd drops such messages); errors
    /// name the socket.
    pub fn notify(&self, state: &str) -> io::Result<()> {
        if state.as_bytes().contains(&0) {
            return Err(with_addr(
                &self.display,
                "cannot send",
                io::Error::new(io::ErrorKind::InvalidInput, "message contains a NUL byte"),
            ));
        }
        let sent = self
            .socket
            .send_to_addr(state.as_bytes(), &self.addr)
            .map_err(|e| with_addr(&self.display, "cannot send", e))?;
        if sent != state.len() {
            return Err(with_addr(
                &self.display,
                "cannot send",
                io::Error::new(
                    io::ErrorKind::WriteZero,
                    format!("short datagram write ({sent} of {} bytes)", state.len()),
                ),
            ));
        }
        Ok(())
    }

    /// `READY=1`: start-up is finished (and, after [`reloading`](Self::reloading), the reload is).
    pub fn ready(&self) -> io::Result<()> {
        self.notify("READY=1")
    }

    /// `STATUS=text`, shown by `systemctl status`. Line breaks (and NUL bytes) in `text` become
    /// spaces so the status stays one assignment on one line.
    pub fn status(&self, text: &str) -> io::Result<()> {
        self.notify(&status_message(text))
    }

    /// `WATCHDOG=1`: keep-alive ping; send it at half of [`watchdog_interval`].
    pub fn watchdog(&self) -> io::Result<()> {
        self.notify("WATCHDOG=1")
    }

    /// `STOPPING=1`: the service has begun shutting down.
    pub fn stopping(&self) -> io::Result<()> {
        self.notify("STOPPING=1")
    }

    /// `RELOADING=1` with `MONOTONIC_USEC=` (the current `CLOCK_MONOTONIC` time, which systemd
    /// wants with a reload notification). Send [`ready`](Self::ready) when the reload is done.
    pub fn reloading(&self) -> io::Result<()> {
        self.notify(&format!("RELOADING=1\nMONOTONIC_USEC={}", monotonic_usec()?))
    }
}

/// The `STATUS=` message for `text`, with `\r`, `\n` and NUL replaced by spaces.
pub fn status_message(text: &str) -> String {
    let one_line: String = text
        .chars()
        .map(|c| if matches!(c, '\n' | '\r' | '\0') { ' ' } else { c })
        .collect();
    format!("STATUS={one_line}")
}

/// The watchdog interval systemd expects pings within (`WatchdogSec=`), from `WATCHDOG_USEC`
/// and `WATCHDOG_PID` in the environment; `None` when the watchdog is off, is meant for another
/// process, or the variables are malformed (logged as a warning).
///
/// This is the full interval: callers should send [`Notifier::watchdog`] every half of it, as
/// `sd_watchdog_enabled(3)` recommends, so one late tick does not get the service killed.
pub fn watchdog_interval() -> Option<Duration> {
    let usec = std::env::var(WATCHDOG_USEC).ok();
    let pid = std::env::var(WATCHDOG_PID).ok();
    match parse_watchdog(usec.as_deref(), pid.as_deref(), std::process::id()) {
        Ok(interval) => interval,
        Err(e) => {
            tracing::warn!("{e}; watchdog pings disabled");
            None
        }
    }
}

/// The watchdog interval for given values of `WATCHDOG_USEC` and `WATCHDOG_PID` (`None` when
/// unset), seen from process `my_pid`; what [`watchdog_interval`] does, without the environment.
///
/// - `usec` unset: `Ok(None)` (no watchdog).
/// - `pid` set and a valid pid other than `my_pid`: `Ok(None)` (the settings are for another
///   process, e.g. our parent).
/// - otherwise `Ok(Some(interval))` with the full interval; ping at half of it.
///
/// A `usec` that is not a decimal integer in `1..u64::MAX` (systemd's "infinity"), or a `pid`
/// that is not a positive decimal integer, is an `InvalidData` error that quotes the value.
pub fn parse_watchdog(usec: Option<&str>, pid: Option<&str>, my_pid: u32) -> io::Result<Option<Duration>> {
    let Some(usec) = usec else {
        return Ok(None);
    };
    if let Some(pid) = pid {
        let parsed: u32 = parse_decimal(pid)
            .and_then(|p| u32::try_from(p).ok())
            .filter(|&p| p > 0)
            .ok_or_else(|| invalid_env(WATCHDOG_PID, pid, "a positive process id"))?;
        if parsed != my_pid {
            return Ok(None);
        }
    }
    let micros = parse_decimal(usec)
        .filter(|&us| us > 0 && us < u64::MAX)
        .ok_or_else(|| invalid_env(WATCHDOG_USEC, usec, "a positive number of microseconds"))?;
    Ok(Some(Duration::from_micros(micros)))
}

/// Plain decimal digits only: no sign, no spaces, no empty string (stricter than `str::parse`,
/// which takes a leading `+`).
fn parse_decimal(s: &str) -> Option<u64> {
    if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    s.parse().ok()
}

fn invalid_env(var: &str, value: &str, expected: &str) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!("{var}={value:?} is malformed: expected {expected}"),
    )
}

fn with_addr(display: &str, what: &str, e: io::Error) -> io::Error {
    io::Error::new(e.kind(), format!("sd_notify socket {display}: {what}: {e}"))
}

/// `CLOCK_MONOTONIC` in microseconds, the clock systemd compares `MONOTONIC_USEC=` with.
fn monotonic_usec() -> io::Result<u64> {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec for the duration of the call.
    if unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) } != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(ts.tv_sec as u64 * 1_000_000 + ts.tv_nsec as u64 / 1_000)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// A receiving socket bound at a fresh temp path, removed on drop.
    struct Receiver {
        path: PathBuf,
        socket: UnixDatagram,
    }

    impl Receiver {
        fn bind() -> Receiver {
            static N: AtomicUsize = AtomicUsize::new(0);
            let n = N.fetch_add(1, Ordering::Relaxed);
            let path = std::env::temp_dir().join(format!("sqscan-notify-{}-{n}.sock", std::process::id()));
            let _ = std::fs::remove_file(&path);
            let socket = UnixDatagram::bind(&path).unwrap();
            socket.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
            Receiver { path, socket }
        }
    }

    impl Drop for Receiver {
        fn drop(&mut self) {
            let _ = std::fs::remove_file(&self.path);
        }
    }

    fn recv(socket: &UnixDatagram) -> String {
        let mut buf = [0u8; 4096];
        let n = socket.recv(&mut buf).unwrap();
        String::from_utf8(buf[..n].to_vec()).unwrap()
    }

    #[test]
    fn path_socket_receives_each_message_exactly() {
        let rx = Receiver::bind();
        let n = Notifier::new(&rx.path).unwrap();
        assert_eq!(n.socket_name(), rx.path.display().to_string());
        n.ready().unwrap();
        n.status("sweeping table 2\nfit 3 of 5\r\ndone").unwrap();
        n.watchdog().unwrap();
        n.stopping().unwrap();
        n.notify("STATUS=raw\nERRNO=0").unwrap();
        assert_eq!(recv(&rx.socket), "READY=1");
        assert_eq!(recv(&rx.socket), "STATUS=sweeping table 2 fit 3 of 5  done");
        assert_eq!(recv(&rx.socket), "WATCHDOG=1");
        assert_eq!(recv(&rx.socket), "STOPPING=1");
        assert_eq!(recv(&rx.socket), "STATUS=raw\nERRNO=0");
    }

    #[test]
    fn from_value_with_absolute_path() {
        let rx = Receiver::bind();
        let n = Notifier::from_value(rx.path.to_str().unwrap()).unwrap();
        n.ready().unwrap();
        assert_eq!(recv(&rx.socket), "READY=1");
    }

    #[test]
    fn reloading_sends_monotonic_time() {
        let rx = Receiver::bind();
        let n = Notifier::new(&rx.path).unwrap();
        n.reloading().unwrap();
        let msg = recv(&rx.socket);
        let (first, second) = msg.split_once('\n').unwrap();
        assert_eq!(first, "RELOADING=1");
        let usec: u64 = second.strip_prefix("MONOTONIC_USEC=").unwrap().parse().unwrap();
        assert!(usec > 0);
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn abstract_socket_from_at_value() {
        use std::os::linux::net::SocketAddrExt;
        let name = format!("sqscan-notify-test-{}", std::process::id());
        let addr = SocketAddr::from_abstract_name(name.as_bytes()).unwrap();
        let rx = UnixDatagram::bind_addr(&addr).unwrap();
        rx.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let n = Notifier::from_value(&format!("@{name}")).unwrap();
        assert_eq!(n.socket_name(), format!("@{name}"));
        n.ready().unwrap();
        n.status("idle").unwrap();
        assert_eq!(recv(&rx), "READY=1");
        assert_eq!(recv(&rx), "STATUS=idle");
    }

    #[test]
    fn unusable_values_are_clear_errors() {
        for value in ["", "@", "run/systemd/notify", "vsock:2:1234"] {
            let e = Notifier::from_value(value).unwrap_err();
            assert_eq!(e.kind(), io::ErrorKind::InvalidInput, "{value:?}");
            assert!(e.to_string().contains(NOTIFY_SOCKET), "{e}");
            assert!(e.to_string().contains(&format!("{value:?}")), "{e}");
        }
        let long = format!("/{}", "x".repeat(200));
        let e = Notifier::from_value(&long).unwrap_err();
        assert!(e.to_string().contains(&long), "{e}");
    }

    #[test]
    fn send_errors_name_the_socket() {
        let path = std::env::temp_dir().join(format!("sqscan-notify-missing-{}.sock", std::process::id()));
        let _ = std::fs::remove_file(&path);
        let n = Notifier::new(&path).unwrap();
        let e = n.ready().unwrap_err();
        assert!(e.to_string().contains(&path.display().to_string()), "{e}");
        assert_eq!(e.kind(), io::ErrorKind::NotFound, "{e}");
    }

    #[test]
    fn nul_byte_is_rejected_before_sending() {
        let rx = Receiver::bind();
        let n = Notifier::new(&rx.path).unwrap();
        let e = n.notify("STATUS=a\0b").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
        assert!(e.to_string().contains(&rx.path.display().to_string()), "{e}");
        // The status helper cleans NULs instead.
        n.status("a\0b").unwrap();
        assert_eq!(recv(&rx.socket), "STATUS=a b");
    }

    #[test]
    fn status_message_is_one_line() {
        assert_eq!(status_message("ok"), "STATUS=ok");
        assert_eq!(status_message("a\nb\r\nc"), "STATUS=a b  c");
        assert_eq!(status_message(""), "STATUS=");
    }

    #[test]
    fn watchdog_unset_is_none() {
        assert_eq!(parse_watchdog(None, None, 42).unwrap(), None);
        assert_eq!(parse_watchdog(None, Some("42"), 42).unwrap(), None);
        // A malformed pid does not matter when there is no watchdog.
        assert_eq!(parse_watchdog(None, Some("x"), 42).unwrap(), None);
    }

    #[test]
    fn watchdog_interval_is_the_full_interval() {
        let ten_s = Some(Duration::from_secs(10));
        assert_eq!(parse_watchdog(Some("10000000"), None, 42).unwrap(), ten_s);
        assert_eq!(parse_watchdog(Some("10000000"), Some("42"), 42).unwrap(), ten_s);
        assert_eq!(
            parse_watchdog(Some("1"), None, 42).unwrap(),
            Some(Duration::from_micros(1))
        );
    }

    #[test]
    fn watchdog_for_another_pid_is_none() {
        assert_eq!(parse_watchdog(Some("10000000"), Some("41"), 42).unwrap(), None);
    }

    #[test]
    fn watchdog_malformed_values_are_errors() {
        for usec in [
            "",
            "0",
            "-5",
            "+5",
            " 5",
            "5s",
            "1.5",
            "18446744073709551615",
            "99999999999999999999",
        ] {
            let e = parse_watchdog(Some(usec), None, 42).unwrap_err();
            assert_eq!(e.kind(), io::ErrorKind::InvalidData, "{usec:?}");
            assert!(e.to_string().contains(WATCHDOG_USEC), "{e}");
            assert!(e.to_string().contains(&format!("{usec:?}")), "{e}");
        }
        for pid in ["", "0", "-1", "abc", "4294967296"] {
            let e = parse_watchdog(Some("10000000"), Some(pid), 42).unwrap_err();
            assert_eq!(e.kind(), io::ErrorKind::InvalidData, "{pid:?}");
            assert!(e.to_string().contains(WATCHDOG_PID), "{e}");
        }
    }
}
