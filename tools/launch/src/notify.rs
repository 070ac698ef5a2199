//! The service manager's side of `sd_notify(3)`, for the local supervisor: each child gets its
//! own datagram socket in `NOTIFY_SOCKET`, and the supervisor starts the next process only once
//! this one has said `READY=1` (its ports open, its loop about to run), as systemd does for the
//! `Type=notify` units. Without it the simulator could publish its first observation while the
//! predictor was still setting up, and that step's command came late.

use std::os::unix::net::UnixDatagram;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;

use anyhow::Context;

static SEQ: AtomicU32 = AtomicU32::new(0);

/// A bound notification socket; the file goes when this does.
pub struct NotifySocket {
    sock: UnixDatagram,
    path: PathBuf,
}

impl NotifySocket {
    /// Binds a fresh socket in the temporary folder (a socket path must stay under 108 bytes,
    /// so not in a run folder of any depth).
    pub fn bind(tag: &str) -> anyhow::Result<Self> {
        let n = SEQ.fetch_add(1, Ordering::Relaxed);
        let path =
            std::env::temp_dir().join(format!("mtanet-{}-{n}-{tag}.notify", std::process::id()));
        let _ = std::fs::remove_file(&path);
        let sock = UnixDatagram::bind(&path)
            .with_context(|| format!("binding the notification socket {}", path.display()))?;
        Ok(Self { sock, path })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Reads notifications for up to `slice`; true once one of them carries `READY=1`.
    pub fn ready_within(&self, slice: Duration) -> anyhow::Result<bool> {
        self.sock
            .set_read_timeout(Some(slice.max(Duration::from_millis(1))))?;
        let mut buf = [0u8; 4096];
        match self.sock.recv(&mut buf) {
            Ok(n) => Ok(String::from_utf8_lossy(&buf[..n])
                .lines()
                .any(|l| l.trim() == "READY=1")),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                Ok(false)
            }
            Err(e) => Err(e).context("reading the notification socket"),
        }
    }
}

impl Drop for NotifySocket {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ready_is_seen_only_when_sent() {
        let s = NotifySocket::bind("test").unwrap();
        assert!(!s.ready_within(Duration::from_millis(5)).unwrap());
        let tx = UnixDatagram::unbound().unwrap();
        tx.send_to(b"STATUS=starting", s.path()).unwrap();
        assert!(!s.ready_within(Duration::from_millis(5)).unwrap());
        tx.send_to(b"READY=1\nSTATUS=running", s.path()).unwrap();
        assert!(s.ready_within(Duration::from_millis(5)).unwrap());
        let path = s.path().to_owned();
        drop(s);
        assert!(!path.exists());
    }
}
