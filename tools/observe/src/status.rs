//! `mta status [--json] [--watch]`: the running stack of a namespace, from iceoryx2's own node and
//! service listing (alive and dead nodes, topics) plus the stats topic every process publishes
//! once a second (rate, latency percentiles, CPU, memory, restarts, who drives, the model's live
//! error, the trainer's progress). `--cleanup` removes what dead nodes left behind.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use mtanet_ipc::cli::CommonArgs;
use mtanet_ipc::latency::LatencySummary;
use mtanet_ipc::node::{
    IpcConfig, NodeCensus, ServiceEntry, census, create_node, create_observer_node, services,
};
use mtanet_ipc::ports::Receiver;
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::{CommandSource, ProcessStats, names, stamp, stats};
use serde::Serialize;

#[derive(Debug, clap::Args)]
pub struct StatusArgs {
    #[command(flatten)]
    common: CommonArgs,
    /// Remove the resources of dead nodes (processes that crashed or were killed).
    #[arg(long)]
    cleanup: bool,
    /// One JSON object (with --watch: one per line, JSON Lines).
    #[arg(long)]
    json: bool,
    /// Refresh once a second until Ctrl-C.
    #[arg(long)]
    watch: bool,
    /// How long to listen for the processes' stats (they publish once a second).
    #[arg(long, default_value_t = 1.5)]
    listen_s: f64,
}

/// One process as its last stats message describes it.
#[derive(Debug, Clone, Serialize)]
pub struct ProcessView {
    pub pid: u32,
    pub restarts: u32,
    /// Seconds since its last message (a process silent for > 3 s is shown as such).
    pub age_s: f64,
    pub count: u64,
    pub rate_hz: Option<f64>,
    pub cpu_percent: f64,
    pub rss_kb: u64,
    /// Of its unit of work (a step, a tick's compute, an update); the stats message carries no
    /// p90 (0 here).
    pub latency: LatencySummary,
    /// The role's own figures (laps, driver, fallbacks, loss, ...).
    pub detail: BTreeMap<&'static str, serde_json::Value>,
}

impl ProcessView {
    /// `p50/p99/p99.9/max` in whole microseconds.
    pub fn latency_text(&self) -> String {
        let l = &self.latency;
        format!(
            "{:.0}/{:.0}/{:.0}/{:.0}",
            l.p50_us, l.p99_us, l.p999_us, l.max_us
        )
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct Status {
    pub namespace: String,
    pub nodes: NodeCensus,
    pub services: Vec<ServiceEntry>,
    pub processes: BTreeMap<String, ProcessView>,
}

/// A float as the message has it (f32), without the digits f32 does not carry.
fn finite(x: f32) -> Option<f64> {
    x.is_finite()
        .then(|| format!("{x:.6e}").parse().unwrap_or(f64::from(x)))
}

pub fn view(s: &ProcessStats) -> ProcessView {
    use serde_json::json;
    let mut detail = BTreeMap::new();
    match s.role() {
        "simulator" => {
            detail.insert("laps", json!(s.laps));
            detail.insert("missed_commands", json!(s.missed_commands));
        }
        "predictor" => {
            let driver = CommandSource::from_u32(s.driver).map_or("?", CommandSource::name);
            detail.insert("driver", json!(driver));
            detail.insert("fallbacks", json!(s.fallbacks));
            detail.insert(
                "model_over_copy_last",
                json!(finite(s.model_over_copy_last)),
            );
            detail.insert("model_version", json!(s.model_version));
            detail.insert("weights_installed", json!(s.weights_installed));
            detail.insert("weights_rejected", json!(s.weights_rejected));
            detail.insert("weights_held_back", json!(s.weights_held_back));
        }
        "trainer" => {
            detail.insert("replay_sequences", json!(s.replay_sequences));
            detail.insert("chunks_lost", json!(s.chunks_lost));
            detail.insert("loss", json!(finite(s.loss)));
            detail.insert("weights_published", json!(s.weights_published));
            detail.insert("resumed_from_update", json!(s.resumed_from_update));
        }
        _ => {}
    }
    let latency = LatencySummary {
        count: s.count,
        p50_us: f64::from(s.p50_us),
        p90_us: 0.0,
        p99_us: f64::from(s.p99_us),
        p999_us: f64::from(s.p999_us),
        max_us: f64::from(s.max_us),
    };
    ProcessView {
        pid: s.pid,
        restarts: s.restarts,
        age_s: stamp::elapsed_ns(s.stamp_ns) as f64 * 1e-9,
        count: s.count,
        rate_hz: finite(s.rate_hz),
        cpu_percent: f64::from(s.cpu_percent),
        rss_kb: s.rss_kb,
        latency,
        detail,
    }
}

/// Listens on the stats topic for up to `listen`, or until every alive mtanet process spoke.
fn listen(
    rx: &Receiver<ProcessStats>,
    latest: &mut BTreeMap<String, ProcessStats>,
    listen: Duration,
    expect: usize,
) -> anyhow::Result<()> {
    let until = Instant::now() + listen;
    let mut heard = std::collections::BTreeSet::new();
    loop {
        rx.for_each(|s| {
            heard.insert(s.role().to_string());
            latest.insert(s.role().to_string(), *s);
        })?;
        let left = until.saturating_duration_since(Instant::now());
        if left.is_zero() || (expect > 0 && heard.len() >= expect) {
            return Ok(());
        }
        rx.wait(left)?;
    }
}

pub fn snapshot(
    ipc: &IpcConfig,
    rx: &Receiver<ProcessStats>,
    latest: &mut BTreeMap<String, ProcessStats>,
    wait: Duration,
) -> anyhow::Result<Status> {
    let nodes = census(ipc)?;
    let roles = ["mta-simulator", "mta-predictor", "mta-trainer"];
    let expect = nodes
        .alive
        .iter()
        .filter(|n| roles.contains(&n.as_str()))
        .count();
    listen(rx, latest, wait, expect)?;
    Ok(Status {
        namespace: ipc.namespace.clone(),
        nodes,
        services: services(ipc)?,
        processes: latest.iter().map(|(k, v)| (k.clone(), view(v))).collect(),
    })
}

fn print_text(s: &Status) {
    println!("namespace {}", s.namespace);
    let list = |v: &[String]| {
        if v.is_empty() {
            "-".to_string()
        } else {
            v.join(", ")
        }
    };
    println!("  nodes alive: {}", list(&s.nodes.alive));
    if !s.nodes.dead.is_empty() {
        println!(
            "  nodes DEAD:  {} (run `mta status --cleanup`)",
            list(&s.nodes.dead)
        );
    }
    for e in &s.services {
        println!(
            "  service {:<22} {:<17} nodes {}",
            e.name, e.pattern, e.nodes
        );
    }
    if s.processes.is_empty() {
        println!(
            "  processes:   no stats heard (nothing running, or a build without the stats topic)"
        );
        return;
    }
    println!(
        "  {:<10} {:>7} {:>4} {:>9} {:>9} {:>5} {:>7}  {:<27}  detail",
        "process",
        "pid",
        "rst",
        "count",
        "rate/s",
        "cpu%",
        "rss MB",
        "latency us p50/p99/p99.9/max"
    );
    for (name, p) in &s.processes {
        let lat = p.latency_text();
        let detail: Vec<String> = p.detail.iter().map(|(k, v)| format!("{k} {v}")).collect();
        let silent = if p.age_s > 3.0 {
            format!(" SILENT {:.0} s", p.age_s)
        } else {
            String::new()
        };
        println!(
            "  {:<10} {:>7} {:>4} {:>9} {:>9} {:>5.0} {:>7.1}  {:<27}  {}{silent}",
            name,
            p.pid,
            p.restarts,
            p.count,
            p.rate_hz.map_or("-".into(), |r| format!("{r:.1}")),
            p.cpu_percent,
            p.rss_kb as f64 / 1024.0,
            lat,
            detail.join(", ")
        );
    }
}

pub fn run(args: StatusArgs) -> anyhow::Result<()> {
    let (_, ipc) = args.common.load()?;
    if args.cleanup {
        // Creating a node cleans dead nodes of the namespace (see mtanet_ipc::node).
        drop(create_node(&ipc, "mta-status-cleanup")?);
    }
    let shutdown = Shutdown::install()?;
    // An observer: it must not clean the dead nodes it is there to report.
    let node = create_observer_node(&ipc, &format!("status-{}", std::process::id()))?;
    let rx = Receiver::<ProcessStats>::open(&node, names::STATS, stats::SHAPE)?;
    let mut latest = BTreeMap::new();
    let mut wait = Duration::from_secs_f64(args.listen_s.max(0.0));
    loop {
        let s = snapshot(&ipc, &rx, &mut latest, wait)?;
        if args.json {
            println!("{}", serde_json::to_string(&s)?);
        } else {
            if args.watch {
                print!("\x1b[H\x1b[2J");
            }
            print_text(&s);
        }
        if !args.watch || shutdown.requested() {
            return Ok(());
        }
        // Later rounds: one refresh a second, whatever came in meanwhile.
        wait = Duration::from_secs(1);
        let t = Instant::now();
        while t.elapsed() < wait && !shutdown.requested() {
            rx.wait(wait.saturating_sub(t.elapsed()))?;
            rx.for_each(|m| {
                latest.insert(m.role().to_string(), *m);
            })?;
        }
        if shutdown.requested() {
            return Ok(());
        }
        wait = Duration::ZERO;
    }
}
