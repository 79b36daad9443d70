//! The daemon's shutdown: one switch that every task watches. It is thrown once (a signal,
//! [`Daemon::stop`](super::Daemon::stop), or a task the daemon cannot run without ending), and
//! each task then finishes what it must (a client is told why and flushed, a recording is
//! closed) and ends.

use tokio::sync::watch;

/// The switch, held by the daemon's shared state.
pub struct Shutdown(watch::Sender<bool>);

impl Default for Shutdown {
    fn default() -> Self {
        Shutdown(watch::channel(false).0)
    }
}

impl Shutdown {
    /// Throws the switch; throwing it again changes nothing.
    pub fn begin(&self) {
        self.0.send_replace(true);
    }

    /// Whether the switch has been thrown.
    pub fn begun(&self) -> bool {
        *self.0.borrow()
    }

    /// A listener for a task: it hears the switch however long after it was thrown.
    pub fn listen(&self) -> Listener {
        Listener(self.0.subscribe())
    }
}

/// What a task holds to hear the switch.
pub struct Listener(watch::Receiver<bool>);

impl Listener {
    /// Resolves once the switch has been thrown (at once if it has been), or the daemon's state
    /// is gone. Cancel-safe: a `select!` branch may drop it and wait again.
    pub async fn thrown(&mut self) {
        let _ = self.0.wait_for(|s| *s).await;
    }
}
