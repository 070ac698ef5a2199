//! Beyond one machine, on one: the robot's domain (simulator, predictor) and the trainer's
//! domain (its own iceoryx2 prefix, as if on a GPU host) joined by iceoryx2's Zenoh link tunnel
//! (`iox2-link-tunnel-zenoh` 0.10, installed by ops/setup.sh): one tunnel per domain, TCP on
//! loopback with explicit endpoints, multicast scouting off. Replay chunks must cross to the
//! trainer's domain and weights come back; the round trip of each is measured and printed.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use mtanet_ipc::node::{IpcConfig, create_node};
use mtanet_ipc::ports::{Receiver, Sender, TopicShape};
use mtanet_ipc::weights_topic::{WeightsReceiver, WeightsSender};
use mtanet_ipc::{ReplayChunk, WeightsHeader, names, stamp};
use mtanet_predictor::service::Summary as PredictorSummary;
use mtanet_simulator::summary::Summary as SimulatorSummary;
use mtanet_system_tests::{
    Proc, Run, Signal, read_json, remove_namespace_files, run_in, start, summary, unique_namespace,
};
use mtanet_trainer::service::Summary as TrainerSummary;

/// The topics that cross (ARCHITECTURE.md "Beyond one machine"); each names a publish-subscribe
/// service and the event service that wakes its readers.
const CROSSING: [&str; 3] = [names::REPLAY, names::WEIGHTS, names::TRAINER_STATUS];

fn tunnel_bin() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../.deps/iox2/bin/iox2-link-tunnel-zenoh")
}

/// A tunnel process, stopped with SIGINT (its clean stop) when dropped.
struct Tunnel(Child, PathBuf);

impl Drop for Tunnel {
    fn drop(&mut self) {
        let _ = mtanet_ipc::child::stop_with(&mut self.0, Signal::INT, Duration::from_secs(5));
    }
}

/// Starts the tunnel of namespace `ns` in `dir`: iceoryx2 reads `config/iceoryx2.toml` from the
/// working directory, where the prefix puts it in the namespace's domain.
fn tunnel(dir: &Path, ns: &str, zenoh: &str, wake_on: &str) -> Tunnel {
    std::fs::create_dir_all(dir.join("config")).unwrap();
    std::fs::write(
        dir.join("config/iceoryx2.toml"),
        format!("[global]\nprefix = \"iox2_{ns}_\"\n"),
    )
    .unwrap();
    std::fs::write(dir.join("zenoh.json5"), zenoh).unwrap();
    let bin = tunnel_bin();
    assert!(
        bin.exists(),
        "{} is missing: run ./ops/setup.sh",
        bin.display()
    );
    let log = dir.join("tunnel.log");
    let mut cmd = Command::new(&bin);
    cmd.current_dir(dir)
        .args([
            "--zenoh-config",
            "zenoh.json5",
            "--reactive",
            "--poll",
            "50",
            "--listener",
            wake_on,
        ])
        .stdout(std::fs::File::create(&log).unwrap())
        .stderr(Stdio::from(
            std::fs::File::options().append(true).open(&log).unwrap(),
        ));
    for s in CROSSING {
        cmd.args(["--allow", s]);
    }
    Tunnel(cmd.spawn().unwrap(), log)
}

fn zenoh_config(listen: Option<u16>, connect: Option<u16>) -> String {
    let ep = |p: Option<u16>| p.map_or(String::new(), |p| format!("\"tcp/127.0.0.1:{p}\""));
    format!(
        "{{ mode: \"peer\", listen: {{ endpoints: [{}] }}, connect: {{ endpoints: [{}] }},\n  \
         scouting: {{ multicast: {{ enabled: false }}, gossip: {{ enabled: false }} }} }}\n",
        ep(listen),
        ep(connect)
    )
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn pct(mut v: Vec<f64>) -> String {
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    format!(
        "p50 {:.1} ms, max {:.1} ms (n = {})",
        at(0.5),
        at(1.0),
        v.len()
    )
}

/// Replay chunks, robot -> trainer: sent until the tunnels have found each other and one
/// arrives, then 20 more, each checked intact; their latencies (ms).
fn replay_latencies(
    replay_out: &Sender<ReplayChunk>,
    replay_in: &Receiver<ReplayChunk>,
    logs: &dyn Fn() -> String,
) -> Vec<f64> {
    let send_chunk = |seq: u64| {
        replay_out
            .send_with(|c| {
                c.seq = seq;
                c.images[19][95] = seq as f32;
                c.stamp_ns = stamp::monotonic_ns();
            })
            .unwrap()
    };
    let t0 = Instant::now();
    let mut seq = 0;
    let mut first = None;
    while first.is_none() {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "no replay chunk crossed in 60 s:\n{}",
            logs()
        );
        seq += 1;
        send_chunk(seq);
        replay_in.wait(Duration::from_millis(200)).unwrap();
        replay_in.for_each(|c| first = Some(c.seq)).unwrap();
    }
    println!(
        "first replay chunk crossed {:.1} s after the tunnels started",
        t0.elapsed().as_secs_f64()
    );
    let mut replay_ms = Vec::new();
    for _ in 0..20 {
        seq += 1;
        send_chunk(seq);
        let t = Instant::now();
        let mut got = None;
        while got.is_none() && t.elapsed() < Duration::from_secs(5) {
            replay_in.wait(Duration::from_millis(100)).unwrap();
            replay_in
                .for_each(|c| {
                    if c.seq == seq {
                        got = Some((stamp::elapsed_ns(c.stamp_ns), c.images[19][95]));
                    }
                })
                .unwrap();
        }
        let (ns, marker) = got.unwrap_or_else(|| panic!("chunk {seq} did not cross:\n{}", logs()));
        assert_eq!(marker, seq as f32, "the chunk's payload crossed intact");
        replay_ms.push(ns as f64 * 1e-6);
    }

    replay_ms
}

/// Weights, trainer -> robot: the committed checkpoint (~1 MB) as the trainer sends it, five
/// versions, each checked byte for byte; the blob's size and the latencies (ms).
fn weights_latencies(
    weights_out: &WeightsSender,
    weights_in: &WeightsReceiver,
    logs: &dyn Fn() -> String,
) -> (usize, Vec<f64>) {
    let blob =
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("data/oval_lockstep.safetensors"))
            .unwrap();
    let mut weights_ms = Vec::new();
    for version in 1..=5u64 {
        let header = WeightsHeader {
            version,
            train_step: version,
            ..Default::default()
        };
        let t = Instant::now();
        let mut sent: Option<Instant> = None;
        let got = loop {
            assert!(
                t.elapsed() < Duration::from_secs(30),
                "weights version {version} did not cross:\n{}",
                logs()
            );
            // The first one again each second until the weights bridge is up; later ones once.
            if sent.is_none_or(|s| version == 1 && s.elapsed() > Duration::from_secs(1)) {
                weights_out.send(header, &blob).unwrap();
                sent = Some(Instant::now());
            }
            let _ = weights_in
                .listener()
                .timed_wait(|_| {}, Duration::from_millis(50));
            let g = weights_in
                .latest(|h, bytes| {
                    (
                        h.version,
                        stamp::elapsed_ns(h.stamp_ns),
                        bytes == blob.as_slice(),
                    )
                })
                .unwrap();
            if let Some(g) = g.filter(|g| g.0 == version) {
                break g;
            }
        };
        assert!(got.2, "weights version {version} crossed byte for byte");
        weights_ms.push(got.1 as f64 * 1e-6);
    }
    (blob.len(), weights_ms)
}

/// The stack across the tunnels: simulator and predictor in the robot's domain, the trainer
/// (resuming the committed checkpoint, publishing every 10 updates) in its own. Every replay
/// chunk crosses, the trainer learns from them and its weights come back.
fn stack_across(dir: &Path, robot: &str, trainer: &str, logs: &dyn Fn() -> String) {
    let run = dir.join("stack");
    let ck = run.join("ck");
    std::fs::create_dir_all(&ck).unwrap();
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("data/oval_lockstep.safetensors"),
        ck.join("latest.safetensors"),
    )
    .unwrap();
    let config = run.join("stack.toml");
    std::fs::write(
        &config,
        format!(
            "[simulator]\nmode = \"realtime\"\nmax_steps = 1000\n[trainer]\ncheckpoint_dir = {:?}\npublish_every_updates = 10\nmin_sequences = 4\nprobe_every_updates = 0\n",
            ck.to_string_lossy()
        ),
    )
    .unwrap();
    let [robot_run, trainer_run] = [robot, trainer].map(|ns| Run {
        config: Some(config.clone()),
        ..run_in(ns, &run)
    });
    let mut tr = start("mta-trainer", &trainer_run, &[], &run);
    let mut pr = start("mta-predictor", &robot_run, &[], &run);
    // The tunnel's publisher does not hand its history to a subscriber that comes later (the
    // trainer's own does): the predictor gets the weights the trainer learns from here on.
    let mut sim = start("mta-simulator", &robot_run, &[], &run);
    let full = |p: &Proc| std::fs::read_to_string(&p.log).unwrap_or_default();
    let reshaped = |p: &Proc| full(p).contains("other queue sizes");
    assert!(
        sim.wait(Duration::from_secs(120)).success(),
        "{}",
        full(&sim)
    );
    for p in [&pr, &tr] {
        p.signal(Signal::TERM);
    }
    assert!(pr.wait(Duration::from_secs(30)).success(), "{}", full(&pr));
    assert!(tr.wait(Duration::from_secs(30)).success(), "{}", full(&tr));
    for p in [&sim, &pr, &tr] {
        if reshaped(p) {
            println!(
                "{} opened a service the tunnel had created with other queue sizes",
                p.name
            );
        }
    }
    let sim: SimulatorSummary = read_json(&summary(&robot_run, "mta-simulator"));
    let pr: PredictorSummary = read_json(&summary(&robot_run, "mta-predictor"));
    let tr: TrainerSummary = read_json(&summary(&trainer_run, "mta-trainer"));
    let sent = sim.replay_chunks_sent;
    let received = tr.chunks_received;
    println!(
        "stack across the tunnels: {sent} replay chunks sent, {received} received, {} trainer updates, {} weights published, {} received by the predictor",
        tr.session_updates, tr.weights_published, pr.weights_received
    );
    assert!(
        // All of them crossed in every run measured (50 of 50); one may still be in flight
        // when the simulator's linger ends.
        sent >= 45 && received + 1 >= sent,
        "replay chunks crossed: {received} of {sent}\n{tr:?}"
    );
    assert!(
        tr.session_updates >= 10,
        "the trainer learnt from them: {tr:?}"
    );
    assert!(
        pr.weights_received >= 1,
        "weights it learnt came back: {pr:?}\n{}",
        logs()
    );
}

#[test]
fn replay_crosses_to_a_trainer_domain_and_weights_come_back_through_zenoh_tunnels() {
    let dir = tempfile::tempdir().unwrap();
    let (robot, trainer) = (unique_namespace("tnr"), unique_namespace("tnt"));
    let port = free_port();
    // The robot's tunnel listens, the trainer host's connects; each wakes on its own outgoing
    // topic's events and on data from the peer (--reactive), and polls for discovery.
    let a = tunnel(
        &dir.path().join("robot"),
        &robot,
        &zenoh_config(Some(port), None),
        names::REPLAY,
    );
    let b = tunnel(
        &dir.path().join("trainer"),
        &trainer,
        &zenoh_config(None, Some(port)),
        names::WEIGHTS,
    );
    let logs = || {
        [&a.1, &b.1]
            .iter()
            .map(|p| std::fs::read_to_string(p).unwrap_or_default())
            .collect::<Vec<_>>()
            .join("\n---\n")
    };

    let robot_node = create_node(
        &IpcConfig {
            namespace: robot.clone(),
        },
        "robot",
    )
    .unwrap();
    let trainer_node = create_node(
        &IpcConfig {
            namespace: trainer.clone(),
        },
        "trainer-host",
    )
    .unwrap();
    let replay_out =
        Sender::<ReplayChunk>::open(&robot_node, names::REPLAY, TopicShape::REPLAY).unwrap();
    let weights_in = WeightsReceiver::open(&robot_node).unwrap();
    let replay_in =
        Receiver::<ReplayChunk>::open(&trainer_node, names::REPLAY, TopicShape::REPLAY).unwrap();
    let weights_out = WeightsSender::open(&trainer_node).unwrap();

    let replay_ms = replay_latencies(&replay_out, &replay_in, &logs);
    let (blob_len, weights_ms) = weights_latencies(&weights_out, &weights_in, &logs);
    let line = format!(
        "through two Zenoh tunnels on loopback: replay chunk ({} B) {}; weights ({} B) {}\n",
        size_of::<ReplayChunk>(),
        pct(replay_ms),
        blob_len,
        pct(weights_ms)
    );
    print!("{line}");
    let _ = std::io::stdout().flush();
    drop((
        replay_out,
        weights_in,
        replay_in,
        weights_out,
        robot_node,
        trainer_node,
    ));
    stack_across(dir.path(), &robot, &trainer, &logs);
    drop((a, b));
    remove_namespace_files(&robot);
    remove_namespace_files(&trainer);
}
