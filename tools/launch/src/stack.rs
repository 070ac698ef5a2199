//! Where the stack's binaries are, a private iceoryx2 namespace for a run, and what a namespace
//! holds (its nodes, files left behind). Used by `mta soak`, `mta systemd` and the system tests.

use std::path::PathBuf;

use mtanet_ipc::node::{IpcConfig, NodeCensus, census};
pub use mtanet_ipc::node::{leftover_shm, remove_namespace_files};

/// `target/<profile>/`, where cargo puts the binaries (tests run from `target/<profile>/deps/`).
pub fn bin_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("own executable path");
    let dir = exe.parent().expect("executable has a directory");
    let dir = if dir.ends_with("deps") {
        dir.parent().unwrap_or(dir)
    } else {
        dir
    };
    dir.to_path_buf()
}

/// A namespace no other test or stack uses.
pub fn unique_namespace(tag: &str) -> String {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .subsec_nanos();
    format!("{tag}{}x{nanos}", std::process::id())
}

/// Nodes of a namespace.
pub fn nodes(ns: &str) -> NodeCensus {
    census(&IpcConfig {
        namespace: ns.into(),
    })
    .expect("valid namespace")
}
