//! Faults with the real processes under the real supervisor (`mtanet_launch::supervisor`, what
//! `mta up` runs), in real time: each process killed with SIGKILL in turn is restarted and the
//! stack steps again within 2 s with nothing stale left; a predictor paused for 0.1 s (SIGSTOP)
//! under active inference costs no command (the simulator follows the plan the last command
//! carried); frozen for 1 s it costs missed deadlines once the plan runs out, the simulator's
//! stand-in keeps the car going, and the loop recovers; the car is never put back.

use std::path::Path;
use std::time::{Duration, Instant};

use mtanet_ipc::node::{IpcConfig, create_node};
use mtanet_ipc::ports::{Receiver, TopicShape};
use mtanet_ipc::stack::StackConfig;
use mtanet_ipc::{Command, CommandSource, Observation, names};
use mtanet_launch::supervisor::{Event, Supervisor};
use mtanet_launch::{Run, plan};
use mtanet_predictor::service::Summary as PredictorSummary;
use mtanet_simulator::summary::Summary as SimulatorSummary;
use mtanet_system_tests::*;
use mtanet_trainer::service::Summary as TrainerSummary;

/// The step of the committed checkpoint the stack starts from.
const START_STEP: u64 = 2351;

/// The step of the trainer's next checkpoint on disk that differs from `after` (the trainer saves
/// at every publish), keeping the supervisor polled meanwhile; panics after 90 s.
fn next_save(ck: &Path, after: u64, sup: &mut Supervisor) -> u64 {
    let latest = ck.join("latest.safetensors");
    let t0 = Instant::now();
    loop {
        let step = mtanet_models::checkpoint::load(&latest).map_or(after, |c| c.meta.step);
        if step != after {
            return step;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(90),
            "the trainer saved nothing after step {after}"
        );
        sup.poll().unwrap();
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Waits until the simulator gets commands again: a command for a step at least 25 steps after
/// the first one seen from now on (half a second of stepping), so the loop really runs.
fn stepping(cmds: &Receiver<Command>, sup: &mut Supervisor, timeout: Duration) -> Option<Duration> {
    let t0 = Instant::now();
    let mut first: Option<u64> = None;
    while t0.elapsed() < timeout {
        sup.poll().unwrap();
        cmds.wait(Duration::from_millis(20)).unwrap();
        if let Some(c) = cmds.latest().unwrap() {
            // A restarted simulator counts from 0 again: count from its first step seen.
            let f = *first.get_or_insert(c.step);
            if c.step < f {
                first = Some(c.step);
            } else if c.step >= f + 25 {
                return Some(t0.elapsed());
            }
        }
    }
    None
}

/// Waits until the simulator has seen the line under its middle sensor for 25 steps in a row
/// (0.5 s), keeping the supervisor polled; false after `timeout`.
fn on_the_line(obs: &Receiver<Observation>, sup: &mut Supervisor, timeout: Duration) -> bool {
    let t0 = Instant::now();
    let mut in_a_row = 0;
    while t0.elapsed() < timeout {
        sup.poll().unwrap();
        obs.wait(Duration::from_millis(20)).unwrap();
        obs.for_each(|o| {
            in_a_row = if o.line_sensors[1] != 0 {
                in_a_row + 1
            } else {
                0
            };
        })
        .unwrap();
        if in_a_row >= 25 {
            return true;
        }
    }
    false
}

/// A predictor paused for 0.1 s (the host stopping its CPU) while active inference drives costs
/// no command: the simulator follows the plan the last command carried (`plan_followed`), and
/// its `missed_commands` stays where it was.
fn paused_for_a_plan_without_a_miss(
    ns: &str,
    pid: i32,
    cmds: &Receiver<Command>,
    sup: &mut Supervisor,
) {
    let stats = StatsWatch::open(ns);
    let fresh = mtanet_ipc::stamp::monotonic_ns();
    let before = stats.wait_for("simulator", Duration::from_secs(5), |s| s.stamp_ns > fresh);
    // Pause right after a command carrying at least 3 segments (>= 11 steps, 0.2 s) of plan.
    let t0 = Instant::now();
    let planning = loop {
        sup.poll().unwrap();
        cmds.wait(Duration::from_millis(20)).unwrap();
        let c = cmds.latest().unwrap();
        if c.is_some_and(|c| c.plan_len >= 3 && c.source == CommandSource::ActiveInference as u32) {
            break true;
        }
        if t0.elapsed() > Duration::from_secs(30) {
            break false;
        }
    };
    assert!(
        planning,
        "active inference never drove with a plan of 3 segments"
    );
    signal(pid as u32, Signal::STOP);
    std::thread::sleep(Duration::from_millis(100)); // the fault itself: a stopped process
    signal(pid as u32, Signal::CONT);
    let resumed = mtanet_ipc::stamp::monotonic_ns();
    assert!(
        stepping(cmds, sup, Duration::from_secs(5)).is_some(),
        "no recovery"
    );
    let after = stats.wait_for("simulator", Duration::from_secs(5), |s| {
        s.stamp_ns > resumed
    });
    assert_eq!(
        after.missed_commands, before.missed_commands,
        "a 0.1 s pause inside the plan's horizon cost commands"
    );
}

/// The last `n` lines of the stack's log in `dir`.
fn log_tail(dir: &Path, n: usize) -> String {
    let log = std::fs::read_to_string(dir.join("stack.log")).unwrap_or_default();
    let lines: Vec<&str> = log.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

/// The stack under the supervisor in real time, from the committed checkpoint in `ck`, each
/// process alive before the next starts.
fn start_stack(dir: &Path, ns: &str, ck: &Path) -> Supervisor {
    std::fs::create_dir_all(ck).unwrap();
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("data/oval_lockstep.safetensors"),
        ck.join("latest.safetensors"),
    )
    .unwrap();
    let config = dir.join("stack.toml");
    std::fs::write(
        &config,
        format!(
            "[simulator]\nmode = \"realtime\"\n[trainer]\ncheckpoint_dir = {:?}\npublish_every_updates = 20\nmin_sequences = 8\nprobe_every_updates = 0\n",
            arg(ck)
        ),
    )
    .unwrap();
    let stack = StackConfig::default();
    let mut sup = Supervisor::new(dir).unwrap();
    let run = Run {
        config: Some(config.clone()),
        namespace: Some(ns.to_owned()),
        summaries: Some(dir.to_owned()),
        ..Default::default()
    };
    for launch in plan(&stack, &run) {
        sup.add(&launch.spec, launch.args).unwrap();
    }
    for (k, p) in stack.process.iter().enumerate() {
        sup.start(&p.name).unwrap();
        assert!(
            wait_for_alive(ns, k + 1, Duration::from_secs(60))
                .alive
                .len()
                > k,
            "{} did not come up",
            p.name
        );
    }
    sup
}

/// Each process killed with SIGKILL in turn is restarted and the stack steps again within 3 s,
/// with no stale node left; the trainer resumes from its own last save and the predictor gets
/// the newest weights at once.
fn kill_each_in_turn(
    dir: &Path,
    ns: &str,
    ck: &Path,
    cmds: &Receiver<Command>,
    sup: &mut Supervisor,
) {
    let mut times = Vec::new();
    let mut saved_before_kill = 0;
    for victim in ["predictor", "trainer", "simulator"] {
        if victim == "trainer" {
            // Kill it once it has learnt and saved something of its own (publish = save).
            saved_before_kill = next_save(ck, START_STEP, sup);
            assert!(
                saved_before_kill > START_STEP,
                "the trainer saved nothing of its own"
            );
        }
        let pid = sup.pid(victim).unwrap();
        let t0 = Instant::now();
        signal(pid, Signal::KILL);
        let mut restarted = false;
        while t0.elapsed() < Duration::from_secs(10) && !restarted {
            restarted = sup
                .poll()
                .unwrap()
                .iter()
                .any(|e| matches!(e, Event::Restarted { name, .. } if name == victim));
            std::thread::sleep(Duration::from_millis(10));
        }
        assert!(restarted, "{victim} was not restarted");
        let back = stepping(cmds, sup, Duration::from_secs(10));
        let since_kill = t0.elapsed();
        assert!(
            back.is_some(),
            "the stack did not step again after {victim} was killed"
        );
        // Stepping again = half a second of steps answered (~0.5 s of the 2 s allowed).
        assert!(
            since_kill < Duration::from_secs(3),
            "{victim}: {since_kill:?} from kill to 25 steps answered; stack.log ends:\n{}",
            log_tail(dir, 40)
        );
        times.push((victim, since_kill));
        // The stack steps without the trainer: wait for the replacement itself (its READY=1,
        // sent once its node exists, which also removed the dead one) before the census.
        if let Err(e) = sup.await_ready(victim, Duration::from_secs(10)) {
            panic!("{victim} came back but was not ready: {e:#}");
        }
        let c = nodes(ns);
        assert!(
            c.dead.is_empty(),
            "stale nodes after {victim} was restarted: {c:?}"
        );
    }
    println!("kill -9 -> restarted and 25 steps answered again: {times:?}");
    assert_eq!(sup.restarts().values().sum::<u32>(), 3);
    // The restarted trainer resumed from its last save, not from the committed checkpoint: its
    // first save is past the one it was killed after (from the start it would be below it).
    let resumed_save = next_save(ck, saved_before_kill, sup);
    assert!(
        resumed_save > saved_before_kill,
        "the restarted trainer saved step {resumed_save}, before its last save {saved_before_kill}"
    );
    // The restarted predictor got the newest weights at once: its model steps.
    let predictor = sup.pid("predictor").unwrap();
    StatsWatch::open(ns).wait_for("predictor", Duration::from_secs(60), |s| {
        s.pid == predictor && s.model_over_copy_last.is_finite()
    });
}

/// `mta status` sees the restarted stack from its stats topic.
fn status_sees_the_restarts(ns: &str, sup: &mut Supervisor) {
    // `mta status` sees the restarted stack from its stats topic: every process once restarted,
    // stepping at 50 Hz (each process's first message has no rate yet: ask again).
    let mut status = serde_json::Value::Null;
    for _ in 0..6 {
        let out = std::process::Command::new(bin("mta"))
            .args(["status", "--json", "--listen-s", "3", "--namespace", ns])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "mta status: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        status = serde_json::from_slice(&out.stdout).unwrap();
        sup.poll().unwrap();
        if status
            .pointer("/processes/simulator/rate_hz")
            .is_some_and(|r| r.is_number())
        {
            break;
        }
    }
    for p in ["simulator", "predictor", "trainer"] {
        assert_eq!(
            status.pointer(&format!("/processes/{p}/restarts")),
            Some(&1.into()),
            "{status:#}"
        );
        assert_eq!(
            status.pointer(&format!("/processes/{p}/pid")),
            Some(&sup.pid(p).unwrap().into()),
            "{status:#}"
        );
    }
    let rate = status
        .pointer("/processes/simulator/rate_hz")
        .and_then(|r| r.as_f64())
        .unwrap_or(0.0);
    assert!(
        (40.0..60.0).contains(&rate),
        "the simulator steps at 50 Hz: {status:#}"
    );
    assert!(
        status
            .pointer("/processes/predictor/detail/driver")
            .is_some_and(|d| d.is_string()),
        "{status:#}"
    );
    assert_eq!(
        status.pointer("/nodes/dead"),
        Some(&serde_json::json!([])),
        "{status:#}"
    );
}

/// The summaries of the run: the 1 s freeze cost missed commands once the plan ran out, the
/// predictor answered only the newest frame after it, the car was never put back, and only
/// whole chunks reached the trainer.
fn summaries_show_the_freeze(dir: &Path) {
    let sim: SimulatorSummary = read_json(&dir.join("mta-simulator.json"));
    println!("since the simulator's restart: {:?}", sim.control);
    let (missed, followed) = (sim.missed_commands, sim.plan_followed);
    assert!(
        (30..=90).contains(&(missed + followed)),
        "1 s frozen at 50 Hz (and 0.1 s before): about 55 steps without a command, got {missed} missed and {followed} following the plan"
    );
    // The plan carried ran out in the long pause: the miss policy took over.
    assert!(
        missed >= 10,
        "{missed} missed, {followed} following the plan"
    );
    assert!(followed > 0, "no step followed a plan");
    // Woken after 1 s, the predictor answers only the newest of the frames queued for it.
    let pred: PredictorSummary = read_json(&dir.join("mta-predictor.json"));
    assert!(pred.superseded >= 1, "{pred:?}");
    assert_eq!(
        pred.commands_sent + pred.superseded,
        pred.observations,
        "{pred:?}"
    );
    assert_eq!(
        sim.resets,
        0,
        "the car was reset (control: {:?}); stack.log ends:\n{}",
        sim.control,
        log_tail(dir, 60)
    );
    let tr: TrainerSummary = read_json(&dir.join("mta-trainer.json"));
    assert_eq!(
        tr.steps_received,
        20 * tr.chunks_received,
        "only whole chunks reach the trainer: {tr:?}"
    );
}

#[test]
fn killed_processes_are_restarted_and_a_frozen_predictor_is_survived() {
    let dir = tempfile::tempdir().unwrap();
    let ns = unique_namespace("flt");
    let ck = dir.path().join("ck");
    let mut sup = start_stack(dir.path(), &ns, &ck);
    let node = create_node(
        &IpcConfig {
            namespace: ns.clone(),
        },
        "fault-watch",
    )
    .unwrap();
    let cmds = Receiver::<Command>::open(&node, names::COMMAND, TopicShape::STEP).unwrap();
    assert!(
        stepping(&cmds, &mut sup, Duration::from_secs(30)).is_some(),
        "the stack never stepped"
    );

    kill_each_in_turn(dir.path(), &ns, &ck, &cmds, &mut sup);
    status_sees_the_restarts(&ns, &mut sup);

    // Frozen for 1 s, with the car on the line: the simulator misses the deadlines, its
    // stand-in drives, the loop recovers. (Where the agent itself leaves the line, its own
    // fallback finds it again: no reset in the whole run, below.)
    let obs = Receiver::<Observation>::open(&node, names::OBSERVATION, TopicShape::STEP).unwrap();
    assert!(
        on_the_line(&obs, &mut sup, Duration::from_secs(30)),
        "the car never stayed on the line for 0.5 s"
    );
    let pid = sup.pid("predictor").unwrap() as i32;
    paused_for_a_plan_without_a_miss(&ns, pid, &cmds, &mut sup);
    signal(pid as u32, Signal::STOP);
    std::thread::sleep(Duration::from_secs(1)); // the fault itself: a stopped process
    signal(pid as u32, Signal::CONT);
    assert!(
        stepping(&cmds, &mut sup, Duration::from_secs(5)).is_some(),
        "no recovery after SIGCONT"
    );
    drop((cmds, obs, node));
    let ends = sup.stop_all(Duration::from_secs(30));
    for (name, how) in &ends {
        assert_eq!(
            how.as_deref(),
            Some("exit code 0"),
            "{name} did not stop cleanly: {ends:?}"
        );
    }
    summaries_show_the_freeze(dir.path());
    let c = nodes(&ns);
    assert!(
        c.alive.is_empty() && c.dead.is_empty(),
        "nodes left behind: {c:?}"
    );
    remove_namespace_files(&ns);
}
