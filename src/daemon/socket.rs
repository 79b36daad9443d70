//! The daemon's Unix socket file: bound so that it never replaces what is not a socket, never
//! takes over a live daemon's, and appears at its path with its permission bits already set.

use std::os::unix::fs::PermissionsExt;
use std::path::Path;

use anyhow::{Context, Result, bail};
use tokio::net::UnixListener;

/// Binds the Unix socket: refuses to take over a socket a live daemon answers on, removes a
/// stale one (and nothing that is not a socket), and gives it its permission bits before it
/// appears at `path`: it is bound in a private directory (mode 0700) beside `path`, set to
/// `mode` there and renamed into place, so no client can reach it under the umask's bits.
pub fn bind_unix(path: &Path, mode: u32) -> Result<UnixListener> {
    use std::os::unix::fs::{DirBuilderExt, FileTypeExt};
    if let Ok(meta) = std::fs::symlink_metadata(path) {
        if !meta.file_type().is_socket() {
            bail!("{} exists and is not a socket: not removing it", path.display());
        }
        if std::os::unix::net::UnixStream::connect(path).is_ok() {
            bail!("{} is in use by a running daemon", path.display());
        }
        std::fs::remove_file(path).with_context(|| format!("cannot remove the stale socket {}", path.display()))?;
    }
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let name = path
        .file_name()
        .with_context(|| format!("{} names no file", path.display()))?;
    let private = dir.join(format!(".{}.{}.bind", name.to_string_lossy(), std::process::id()));
    // A directory left by a daemon of the same pid that died while binding.
    let _ = std::fs::remove_file(private.join("s"));
    let _ = std::fs::remove_dir(&private);
    std::fs::DirBuilder::new()
        .mode(0o700)
        .create(&private)
        .with_context(|| format!("cannot create {}", private.display()))?;
    let bound = (|| -> Result<UnixListener> {
        let tmp = private.join("s");
        let listener = UnixListener::bind(&tmp).with_context(|| format!("cannot listen on {}", path.display()))?;
        std::fs::set_permissions(&tmp, std::fs::Permissions::from_mode(mode))
            .with_context(|| format!("cannot set the mode of {}", path.display()))?;
        std::fs::rename(&tmp, path).with_context(|| format!("cannot move the socket to {}", path.display()))?;
        Ok(listener)
    })();
    let _ = std::fs::remove_file(private.join("s"));
    let _ = std::fs::remove_dir(&private);
    bound
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("sqscan-bind-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// `sqscand --socket FILE` once deleted a regular file as a "stale socket".
    #[tokio::test]
    async fn a_regular_file_is_not_taken_for_a_stale_socket() {
        let d = scratch("file");
        let file = d.join("notes.txt");
        std::fs::write(&file, "keep me").unwrap();
        let e = bind_unix(&file, 0o660).unwrap_err().to_string();
        assert!(e.contains("not a socket"), "{e}");
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep me");
        let _ = std::fs::remove_dir_all(&d);
    }

    /// The socket was once bound under the umask's bits and only then given its mode. Now
    /// it appears at its path with its mode, answers there, and leaves no private directory.
    #[tokio::test]
    async fn the_socket_appears_with_its_mode_and_a_stale_one_is_replaced() {
        let d = scratch("mode");
        let path = d.join("s.sock");
        // A stale socket: bound, then its listener dropped.
        drop(std::os::unix::net::UnixListener::bind(&path).unwrap());
        let listener = bind_unix(&path, 0o600).unwrap();
        let meta = std::fs::metadata(&path).unwrap();
        assert_eq!(meta.permissions().mode() & 0o777, 0o600);
        let client = tokio::net::UnixStream::connect(&path).await.unwrap();
        let (_server, _) = listener.accept().await.unwrap();
        drop(client);
        let left: Vec<_> = std::fs::read_dir(&d).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(left, vec![std::ffi::OsString::from("s.sock")]);
        // A second daemon on the same path is refused while the first listens.
        let e = bind_unix(&path, 0o600).unwrap_err().to_string();
        assert!(e.contains("in use"), "{e}");
        let _ = std::fs::remove_dir_all(&d);
    }
}
