//! Logs go through `tracing` to stderr (journald picks them up under systemd). `RUST_LOG` picks the
//! level; iceoryx2's own log is routed into tracing by its `tracing` feature.

use std::io::IsTerminal;

use tracing_subscriber::EnvFilter;

/// Sets up the global subscriber. Default level: info, iceoryx2 at warn.
pub fn init() {
    let filter =
        EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info,iceoryx2=warn"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_target(false)
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr)
        .try_init();
}
