//! Command-line options every service shares, and the start-up they imply.

use std::path::PathBuf;

use anyhow::Context;
use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::config::{ConfigError, ConfigFile};
use crate::node::IpcConfig;
use crate::shutdown::Shutdown;

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

impl CommonArgs {
    /// The start of every service's `main`: signal handlers first (a signal during start-up must
    /// already stop cleanly), then the config file with the service's own `section`.
    pub fn start<C: DeserializeOwned + Default>(
        &self,
        section: &str,
    ) -> anyhow::Result<(C, IpcConfig, Shutdown)> {
        let shutdown = Shutdown::install().context("installing signal handlers")?;
        let (file, ipc) = self.load()?;
        let cfg = file.section(section)?;
        Ok((cfg, ipc, shutdown))
    }

    /// An error for a config value that parsed but makes no sense, naming the file and section.
    pub fn invalid_config(&self, section: &str, e: impl std::fmt::Display) -> anyhow::Error {
        let file =
            (self.config.as_deref()).map_or("<defaults>".into(), |p| p.display().to_string());
        anyhow::anyhow!("config file {file}: [{section}] {e}")
    }

    /// Writes the run summary if `--summary` was given.
    pub fn write_summary(&self, summary: &impl Serialize) -> anyhow::Result<()> {
        if let Some(path) = &self.summary {
            mtanet_summaries::files::write_json(path, summary)
                .with_context(|| format!("writing {}", path.display()))?;
        }
        Ok(())
    }
}
