//! Node and WaitSet creation with the project's rules: iceoryx2's own signal handling off (it
//! would overwrite signal-hook's handlers, see docs/measurements.md), dead nodes of crashed peers cleaned up
//! at start, and an iceoryx2 prefix per namespace so stacks on one host never see each other.

use iceoryx2::config::Config;
use iceoryx2::node::{NodeState, NodeView};
use iceoryx2::prelude::*;
use serde::{Deserialize, Serialize};

/// The `[ipc]` section of the config file.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IpcConfig {
    /// Isolates one stack from another on the same host (becomes the iceoryx2 file prefix).
    /// Letters, digits, `-` and `_` only.
    pub namespace: String,
}

impl Default for IpcConfig {
    fn default() -> Self {
        Self {
            namespace: "mtanet".into(),
        }
    }
}

/// Why a node could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// The namespace is not usable as a file-name prefix.
    #[error("ipc.namespace {0:?} is invalid: use 1-32 letters, digits, '-' or '_'")]
    BadNamespace(String),
    /// The node name is not a valid iceoryx2 node name.
    #[error("invalid node name {0:?}")]
    BadName(String),
    /// iceoryx2 refused to create the node.
    #[error("iceoryx2 could not create node {name:?}: {source:?}")]
    Create {
        name: String,
        source: iceoryx2::node::NodeCreationFailure,
    },
}

impl IpcConfig {
    /// The iceoryx2 configuration for this namespace, built in code so no config file is needed.
    pub fn iceoryx2(&self) -> Result<Config, NodeError> {
        let ns = &self.namespace;
        let ok = !ns.is_empty()
            && ns.len() <= 32
            && ns
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
        if !ok {
            return Err(NodeError::BadNamespace(ns.clone()));
        }
        let mut config = Config::default();
        config.global.prefix = FileName::new(file_prefix(ns).as_bytes())
            .map_err(|_| NodeError::BadNamespace(ns.clone()))?;
        Ok(config)
    }
}

/// Creates this process's node; cleans up what crashed peers of the namespace left behind.
pub fn create_node(cfg: &IpcConfig, name: &str) -> Result<Node<ipc::Service>, NodeError> {
    let node = create_observer_node(cfg, name)?;
    let cleaned = node.try_cleanup_dead_nodes();
    if cleaned.cleanups > 0 || cleaned.failed_cleanups > 0 {
        tracing::warn!(
            cleaned = cleaned.cleanups,
            failed = cleaned.failed_cleanups,
            "removed resources of dead iceoryx2 nodes (a peer crashed or was killed earlier)"
        );
    }
    Ok(node)
}

/// A node that leaves dead nodes alone, for a viewer that reports them (`mta status`).
pub fn create_observer_node(cfg: &IpcConfig, name: &str) -> Result<Node<ipc::Service>, NodeError> {
    let config = cfg.iceoryx2()?;
    let node_name = NodeName::new(name).map_err(|_| NodeError::BadName(name.into()))?;
    let node = NodeBuilder::new()
        .name(&node_name)
        .config(&config)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|source| NodeError::Create {
            name: name.into(),
            source,
        })?;
    Ok(node)
}

/// A WaitSet that leaves signals to signal-hook.
pub fn create_waitset() -> Result<WaitSet<ipc::Service>, iceoryx2::waitset::WaitSetCreateError> {
    WaitSetBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
}

/// The nodes of a namespace, by state: what `mta status` shows and what tests check after a run.
#[derive(Debug, Default, Clone, PartialEq, Eq, Serialize)]
pub struct NodeCensus {
    pub alive: Vec<String>,
    pub dead: Vec<String>,
    pub other: usize,
}

/// Lists the nodes of the namespace (alive ones by name).
pub fn census(cfg: &IpcConfig) -> Result<NodeCensus, NodeError> {
    let config = cfg.iceoryx2()?;
    let mut census = NodeCensus::default();
    let name_of = |details: Option<&iceoryx2::node::NodeDetails>| {
        details
            .map(|d| d.name().as_str().to_string())
            .unwrap_or_else(|| "?".into())
    };
    // A listing error means the node directory does not exist yet: no nodes.
    let _ = Node::<ipc::Service>::list(&config, |state| {
        match &state {
            NodeState::Alive(view) => census.alive.push(name_of(view.details().as_ref())),
            NodeState::Dead(view) => census.dead.push(name_of(view.details().as_ref())),
            _ => census.other += 1,
        }
        CallbackProgression::Continue
    });
    census.alive.sort();
    census.dead.sort();
    Ok(census)
}

/// One service of a namespace as `mta status` shows it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ServiceEntry {
    pub name: String,
    /// "publish-subscribe", "event", ...
    pub pattern: String,
    /// Nodes attached (any state).
    pub nodes: usize,
}

/// The services that exist in the namespace (they vanish with their last node).
pub fn services(cfg: &IpcConfig) -> Result<Vec<ServiceEntry>, NodeError> {
    use iceoryx2::service::Service as _;
    let config = cfg.iceoryx2()?;
    let mut out = Vec::new();
    let _ = ipc::Service::list(&config, |s| {
        out.push(ServiceEntry {
            name: s.static_details.name().as_str().to_string(),
            pattern: pattern_name(s.static_details.messaging_pattern()).into(),
            nodes: s.dynamic_details.as_ref().map_or(0, |d| d.nodes.len()),
        });
        CallbackProgression::Continue
    });
    out.sort_by(|a, b| (&a.name, &a.pattern).cmp(&(&b.name, &b.pattern)));
    Ok(out)
}

fn pattern_name(
    p: &iceoryx2::service::static_config::messaging_pattern::MessagingPattern,
) -> &'static str {
    use iceoryx2::service::static_config::messaging_pattern::MessagingPattern as P;
    match p {
        P::PublishSubscribe(_) => "publish-subscribe",
        P::Event(_) => "event",
        P::RequestResponse(_) => "request-response",
        P::Blackboard(_) => "blackboard",
        _ => "other",
    }
}

/// What the name of every iceoryx2 file of the namespace starts with.
fn file_prefix(ns: &str) -> String {
    format!("iox2_{ns}_")
}

/// The namespace's files in /dev/shm, by name.
fn shm_files(ns: &str) -> Vec<String> {
    let prefix = file_prefix(ns);
    std::fs::read_dir("/dev/shm")
        .map(|rd| {
            rd.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.starts_with(&prefix))
                .collect()
        })
        .unwrap_or_default()
}

/// Shared-memory files the namespace left in /dev/shm, except the per-namespace node counter
/// that iceoryx2 keeps on purpose (`..._node.<version>.global_mgmt`).
pub fn leftover_shm(ns: &str) -> Vec<String> {
    let mut files = shm_files(ns);
    files.retain(|n| !n.ends_with(".global_mgmt"));
    files
}

/// Removes the namespace's node counter segment, the one file iceoryx2 keeps by design.
pub fn remove_namespace_files(ns: &str) {
    for name in shm_files(ns) {
        let _ = std::fs::remove_file(std::path::Path::new("/dev/shm").join(name));
    }
}
