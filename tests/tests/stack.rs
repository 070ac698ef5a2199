//! The three real binaries as separate processes over real iceoryx2 shared memory.

use std::time::Duration;

use mtanet_predictor::service::Summary as PredictorSummary;
use mtanet_simulator::summary::Summary as SimulatorSummary;
use mtanet_system_tests::*;
use mtanet_trainer::service::Summary as TrainerSummary;

const SIGTERM: Signal = Signal::TERM;
const SIGKILL: Signal = Signal::KILL;

/// After a stack is gone: no node alive or dead, no shared memory left but the node counter.
fn assert_namespace_clean(ns: &str) {
    let c = nodes(ns);
    assert!(
        c.alive.is_empty() && c.dead.is_empty(),
        "nodes left behind in {ns}: {c:?}"
    );
    let services = mtanet_ipc::node::services(&mtanet_ipc::node::IpcConfig {
        namespace: ns.into(),
    })
    .unwrap();
    assert!(
        services.is_empty(),
        "services left behind in {ns}: {services:?}"
    );
    let shm = leftover_shm(ns);
    assert!(shm.is_empty(), "shared memory left behind in {ns}: {shm:?}");
    remove_namespace_files(ns);
}

fn exit_ok(p: &mut Proc) {
    let status = p.wait(Duration::from_secs(20));
    assert!(
        status.success(),
        "{} exited with {status}; log:\n{}",
        p.name,
        p.log_tail()
    );
}

#[test]
fn lockstep_500_steps_every_step_answered_and_clean_sigterm_exit() {
    let dir = tempfile::tempdir().unwrap();
    let ns = unique_namespace("lk");
    let run = Run {
        max_steps: Some(500),
        ..run_in(&ns, dir.path())
    };
    let mut trainer = start("mta-trainer", &run, &[], dir.path());
    let mut predictor = start("mta-predictor", &run, &[], dir.path());
    let c = wait_for_alive(&ns, 2, Duration::from_secs(30));
    assert_eq!(
        c.alive,
        vec!["mta-predictor", "mta-trainer"],
        "peers did not come up"
    );

    let mut sim = start(
        "mta-simulator",
        &run,
        &["--mode", "lockstep", "--expect-trainer"],
        dir.path(),
    );
    let status = sim.wait(Duration::from_secs(120));
    assert!(
        status.success(),
        "simulator failed: {status}\n{}",
        sim.log_tail()
    );
    // Stopped at once: the trainer must take in the chunks still queued (after the simulator,
    // their publisher, has gone).
    predictor.signal(SIGTERM);
    trainer.signal(SIGTERM);
    exit_ok(&mut predictor);
    exit_ok(&mut trainer);

    let s: SimulatorSummary = read_json(&summary(&run, "mta-simulator"));
    assert_eq!(s.steps, 500);
    assert_eq!(
        s.commands_received, 500,
        "every step must get its own command: {s:?}"
    );
    assert_eq!(s.missed_commands, 0, "{s:?}");
    assert_eq!(s.teacher_steps, 0, "{s:?}");
    assert_eq!(s.replay_chunks_sent, 25, "{s:?}");
    assert!(s.round_trip.p50_us > 0.0, "{s:?}");
    let p: PredictorSummary = read_json(&summary(&run, "mta-predictor"));
    assert_eq!(p.commands_sent, 500, "{p:?}");
    assert_eq!(p.step_gaps, 0, "{p:?}");
    let t: TrainerSummary = read_json(&summary(&run, "mta-trainer"));
    assert_eq!(t.chunks_received, 25, "trainer must see every chunk: {t:?}");
    assert_eq!(t.chunks_lost, 0, "{t:?}");
    assert_eq!(t.steps_received, 500, "{t:?}");
    assert_namespace_clean(&ns);
}

/// Lockstep without a trainer (an evaluation run) waits for a late command as long as the
/// predictor lives: a predictor stopped for 1 s (five times the per-step timeout) costs time,
/// not steps driven by a stand-in, so a loaded machine drives the same run.
#[test]
fn lockstep_without_a_trainer_waits_out_a_stopped_predictor() {
    // Long enough (several seconds) that the stop falls inside the run.
    const STEPS: u64 = 20_000;
    let dir = tempfile::tempdir().unwrap();
    let ns = unique_namespace("ls");
    let run = Run {
        max_steps: Some(STEPS),
        ..run_in(&ns, dir.path())
    };
    let mut predictor = start("mta-predictor", &run, &[], dir.path());
    wait_for_alive(&ns, 1, Duration::from_secs(30));
    let mut sim = start("mta-simulator", &run, &["--mode", "lockstep"], dir.path());
    let stats = StatsWatch::open(&ns);
    stats.wait_for("predictor", Duration::from_secs(30), |s| s.count > 0);
    predictor.signal(Signal::STOP);
    std::thread::sleep(Duration::from_secs(1)); // the fault itself: a stopped process
    predictor.signal(Signal::CONT);
    assert!(
        sim.is_running(),
        "the run ended before the stop was over: make it longer"
    );
    drop(stats);
    let status = sim.wait(Duration::from_secs(120));
    assert!(
        status.success(),
        "simulator failed: {status}\n{}",
        sim.log_tail()
    );
    predictor.signal(SIGTERM);
    exit_ok(&mut predictor);
    let s: SimulatorSummary = read_json(&summary(&run, "mta-simulator"));
    assert_eq!(s.steps, STEPS);
    assert_eq!(s.commands_received, STEPS, "{s:?}");
    assert_eq!((s.missed_commands, s.teacher_steps), (0, 0), "{s:?}");
    assert_namespace_clean(&ns);
}

#[test]
fn a_killed_predictor_is_survived_cleaned_up_and_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let ns = unique_namespace("kp");
    let run = run_in(&ns, dir.path());
    let mut trainer = start("mta-trainer", &run, &[], dir.path());
    let mut predictor = start("mta-predictor", &run, &[], dir.path());
    wait_for_alive(&ns, 2, Duration::from_secs(30));
    let mut sim = start("mta-simulator", &run, &["--mode", "lockstep"], dir.path());
    let stats = StatsWatch::open(&ns);
    stats.wait_for("predictor", Duration::from_secs(30), |s| s.count > 0);

    predictor.signal(SIGKILL);
    predictor.wait(Duration::from_secs(5));
    // The simulator notices the silence, cleans the dead node and lets the teacher drive.
    stats.wait_for("simulator", Duration::from_secs(30), |s| {
        s.missed_commands > 0
    });
    wait_until(
        "the dead predictor's node cleaned",
        Duration::from_secs(30),
        || nodes(&ns).dead.is_empty(),
    );
    assert!(
        sim.is_running(),
        "simulator died with its peer:\n{}",
        sim.log_tail()
    );

    // The killed one wrote no summary: this one's is the only one.
    let mut predictor2 = start("mta-predictor", &run, &[], dir.path());
    // libtorch takes a while to load under load: up to a minute for its first commands.
    let p2 = predictor2.pid() as u32;
    stats.wait_for("predictor", Duration::from_secs(60), |s| {
        s.pid == p2 && s.count > 0
    });
    drop(stats);
    for p in [&sim, &predictor2, &trainer] {
        p.signal(SIGTERM);
    }
    exit_ok(&mut sim);
    exit_ok(&mut predictor2);
    exit_ok(&mut trainer);

    let s: SimulatorSummary = read_json(&summary(&run, "mta-simulator"));
    assert!(
        s.missed_commands >= 1,
        "the kill must show as missed commands: {s:?}"
    );
    assert!(s.dead_nodes_cleaned >= 1, "{s:?}");
    assert!(
        s.teacher_steps > 0,
        "the teacher drives while no predictor lives: {s:?}"
    );
    let p2: PredictorSummary = read_json(&summary(&run, "mta-predictor"));
    assert!(
        p2.commands_sent > 0,
        "the replacement predictor must take over: {p2:?}"
    );
    assert_namespace_clean(&ns);
}

#[test]
fn realtime_stack_stops_cleanly_on_sigterm() {
    let dir = tempfile::tempdir().unwrap();
    let ns = unique_namespace("rt");
    let run = run_in(&ns, dir.path());
    let mut trainer = start("mta-trainer", &run, &[], dir.path());
    let mut predictor = start("mta-predictor", &run, &[], dir.path());
    wait_for_alive(&ns, 2, Duration::from_secs(30));
    let mut sim = start("mta-simulator", &run, &["--mode", "realtime"], dir.path());
    let started = std::time::Instant::now();
    let stats = StatsWatch::open(&ns);
    stats.wait_for("simulator", Duration::from_secs(30), |s| s.count >= 50);
    drop(stats);
    for p in [&sim, &predictor, &trainer] {
        p.signal(SIGTERM);
    }
    exit_ok(&mut sim);
    let ran_s = started.elapsed().as_secs_f64();
    exit_ok(&mut predictor);
    exit_ok(&mut trainer);
    let s: SimulatorSummary = read_json(&summary(&run, "mta-simulator"));
    let steps = s.steps;
    // Real time paces at 50 Hz: never more steps than 50 a second of the simulator's life.
    assert!(
        steps >= 50 && steps as f64 <= 50.0 * ran_s + 5.0,
        "real-time mode ran unpaced: {steps} steps in {ran_s:.2} s"
    );
    assert!(s.commands_received > 0, "{s:?}");
    assert_namespace_clean(&ns);
}

/// iceoryx2 drops the samples of a publisher that left before the subscriber connected to it
/// (eclipse-iceoryx/iceoryx2#39). A trainer frozen for the whole run (as if starved of CPU) and
/// released while the simulator lingers at exit still gets every chunk.
#[test]
fn a_trainer_that_missed_the_whole_run_still_gets_the_chunks() {
    let dir = tempfile::tempdir().unwrap();
    let ns = unique_namespace("lg");
    let run = Run {
        max_steps: Some(200),
        ..run_in(&ns, dir.path())
    };
    let mut trainer = start("mta-trainer", &run, &[], dir.path());
    let mut predictor = start("mta-predictor", &run, &[], dir.path());
    wait_for_alive(&ns, 2, Duration::from_secs(30));
    let stats = StatsWatch::open(&ns);
    // Frozen inside its loop (it reports from there), subscribed but not yet connected to any
    // simulator.
    stats.wait_for("trainer", Duration::from_secs(60), |_| true);
    trainer.signal(Signal::STOP);
    // Unpaced: a paced lockstep simulator waits for its trainer (it learns on a schedule), a
    // free-running one (real time, or lockstep without pacing) does not.
    let free = ["--mode", "lockstep", "--expect-trainer", "--pace", "0"];
    let mut sim = start("mta-simulator", &run, &free, dir.path());
    // The run's last figures come right before the simulator lingers for its subscriber.
    stats.wait_for("simulator", Duration::from_secs(60), |s| s.count == 200);
    assert!(
        sim.is_running(),
        "the simulator did not linger for its subscriber"
    );
    trainer.signal(Signal::CONT);
    drop(stats); // its node must be gone before the namespace is checked
    exit_ok(&mut sim);
    for p in [&predictor, &trainer] {
        p.signal(SIGTERM);
    }
    exit_ok(&mut trainer);
    exit_ok(&mut predictor);
    let t: TrainerSummary = read_json(&summary(&run, "mta-trainer"));
    assert_eq!(t.chunks_received, 10, "{t:?}");
    assert_namespace_clean(&ns);
}
