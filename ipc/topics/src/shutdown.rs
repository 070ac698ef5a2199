//! Clean termination on SIGINT/SIGTERM/SIGHUP through signal-hook. iceoryx2's own handling is
//! disabled (see `node`), so this flag is the only thing that ends a service loop; loops wait
//! with a timeout and check it. A second SIGINT/SIGTERM exits at once (status 1), for a stuck process.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};

/// Set once a termination signal arrived.
#[derive(Clone, Debug)]
pub struct Shutdown(Arc<AtomicBool>);

impl Shutdown {
    /// Registers the handlers. Call once, early in `main`.
    pub fn install() -> std::io::Result<Self> {
        let flag = Arc::new(AtomicBool::new(false));
        for sig in [SIGINT, SIGTERM, SIGHUP] {
            // Order matters: the conditional exit sees the flag as it was before this signal.
            signal_hook::flag::register_conditional_shutdown(sig, 1, Arc::clone(&flag))?;
            signal_hook::flag::register(sig, Arc::clone(&flag))?;
        }
        Ok(Self(flag))
    }

    /// A flag no signal sets, for tests and embedded runs; trip it with [`Shutdown::request`].
    pub fn manual() -> Self {
        Self(Arc::new(AtomicBool::new(false)))
    }

    pub fn requested(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }

    pub fn request(&self) {
        self.0.store(true, Ordering::Relaxed);
    }
}
