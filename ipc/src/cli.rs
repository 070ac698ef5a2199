//! Command-line options every service shares, and the start-up they imply.

use std::path::PathBuf;

use crate::config::{ConfigError, ConfigFile};
use crate::node::IpcConfig;

#[derive(Debug, Clone, clap::Args)]
pub struct CommonArgs {
    /// Stack config file (TOML). Every key has a default; see ops/mtanet.toml.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// iceoryx2 namespace (overrides ipc.namespace): stacks in different namespaces never meet.
    #[arg(long)]
    pub namespace: Option<String>,
    /// Write this process's run summary as JSON at exit.
    #[arg(long)]
    pub summary: Option<PathBuf>,
}

impl CommonArgs {
    /// Loads the config file and the `[ipc]` section with the command-line override applied.
    pub fn load(&self) -> Result<(ConfigFile, IpcConfig), ConfigError> {
        let file = ConfigFile::load(self.config.as_deref())?;
        let mut ipc: IpcConfig = file.section("ipc")?;
        if let Some(ns) = &self.namespace {
            ipc.namespace = ns.clone();
        }
        Ok((file, ipc))
    }
}
