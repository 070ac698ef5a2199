//! systemd `Type=notify` support: READY once the ports exist, WATCHDOG from the loop, STOPPING on
//! the way out. Outside systemd (no NOTIFY_SOCKET) every call is a cheap no-op.

use std::time::{Duration, Instant};

use sd_notify::NotifyState;

/// Tells systemd the service is ready (ports created, loop about to start).
pub fn ready(status: &str) {
    let _ = sd_notify::notify(false, &[NotifyState::Ready, NotifyState::Status(status)]);
}

/// Tells systemd the service is stopping.
pub fn stopping() {
    let _ = sd_notify::notify(false, &[NotifyState::Stopping]);
}

/// Pets the systemd watchdog at half its period, from the service loop, so a hung loop (not just
/// a dead process) gets restarted.
pub struct Watchdog {
    period: Option<Duration>,
    last: Instant,
}

impl Watchdog {
    pub fn from_env() -> Self {
        let mut usec = 0;
        let period =
            sd_notify::watchdog_enabled(false, &mut usec).then(|| Duration::from_micros(usec / 2));
        Self {
            period,
            last: Instant::now(),
        }
    }

    /// Call every loop iteration; notifies only when half the watchdog period has passed.
    pub fn pet(&mut self) {
        if let Some(p) = self.period
            && self.last.elapsed() >= p
        {
            let _ = sd_notify::notify(false, &[NotifyState::Watchdog]);
            self.last = Instant::now();
        }
    }
}
