//! Lockstep pacing over real iceoryx2: once the trainer trains, the simulator runs at most
//! `pace_updates_per_1000_steps` ahead of the trainer's updates, and runs free again when the
//! trainer leaves.

use std::time::{Duration, Instant};

use mtanet_ipc::node::{IpcConfig, create_node, remove_namespace_files};
use mtanet_ipc::ports::{Receiver, Sender, TopicShape};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::{Command, Observation, TrainerStatus, names, stamp};
use mtanet_scenes::{SceneConfig, Teacher, TeacherConfig, World};
use mtanet_simulator::config::{Mode, SimulatorConfig};
use mtanet_simulator::service::{Ports, run};

#[test]
fn the_simulator_waits_for_the_trainers_updates_and_runs_free_without_it() {
    let ipc = IpcConfig {
        namespace: format!("pace{}", std::process::id()),
    };
    let sim_ipc = ipc.clone();
    let cfg = SimulatorConfig {
        mode: Mode::Lockstep,
        max_steps: 400,
        wait_for_peers_s: 20.0,
        replay: false,
        // 100 updates per 1000 steps: 10 steps per update.
        pace_updates_per_1000_steps: 100.0,
        ..Default::default()
    };
    let node = create_node(&ipc, "scripted-peers").unwrap();
    let status = std::cell::RefCell::new(Some(
        Sender::<TrainerStatus>::open(&node, names::TRAINER_STATUS, TopicShape::STATUS).unwrap(),
    ));
    // The trainer publishes after every update; here the status is repeated while the test waits
    // (iceoryx2 hands its history to a new subscriber only when the publisher sends again).
    let updates = std::cell::Cell::new(0u64);
    let send_status = |updates: u64| {
        if let Some(sender) = status.borrow().as_ref() {
            sender
                .send_with(|s| {
                    s.session_updates = updates;
                    s.updates = updates;
                    s.training = 1;
                    // No weights schedule: this test is about the pace on updates alone.
                    s.next_install_step = u64::MAX;
                    s.stamp_ns = stamp::monotonic_ns();
                })
                .unwrap();
        }
    };
    send_status(0);
    let obs = Receiver::<Observation>::open(&node, names::OBSERVATION, TopicShape::STEP).unwrap();
    let cmd = Sender::<Command>::open(&node, names::COMMAND, TopicShape::STEP).unwrap();
    let sim = std::thread::spawn(move || {
        let node = create_node(&sim_ipc, "sim-under-test").unwrap();
        let ports = Ports::open(&node).unwrap();
        let mut world = World::new(&SceneConfig::default()).unwrap();
        let mut teacher = Teacher::new(&TeacherConfig::default());
        run(
            &node,
            &ports,
            std::slice::from_mut(&mut world),
            &mut teacher,
            &cfg,
            &Shutdown::manual(),
            None,
        )
        .unwrap()
    });
    // Answers every observation; returns the last step seen once none came for `quiet`.
    let mut last = None::<u64>;
    let answer_until_quiet = |quiet: Duration, last: &mut Option<u64>| {
        let mut since = Instant::now();
        while since.elapsed() < quiet {
            send_status(updates.get());
            obs.wait(Duration::from_millis(20)).unwrap();
            obs.drain_events().unwrap();
            let mut seen = Vec::new();
            obs.for_each(|o| seen.push((o.step, o.stamp_ns))).unwrap();
            for (step, stamp_ns) in seen {
                *last = Some(step);
                since = Instant::now();
                cmd.send_with(|c| {
                    c.step = step;
                    c.obs_stamp_ns = stamp_ns;
                    c.wheel_velocity = [6.0, 6.0];
                })
                .unwrap();
            }
        }
    };
    answer_until_quiet(Duration::from_millis(500), &mut last);
    let first_stop = last.expect("the simulator stepped");
    // Pacing starts at the step the status first arrives (a step or few in): from there one
    // update of slack, 10 steps.
    assert!(
        (10..=15).contains(&first_stop),
        "no update yet: about 10 steps ahead at most, got to {first_stop}"
    );
    updates.set(5);
    answer_until_quiet(Duration::from_millis(500), &mut last);
    let second_stop = last.unwrap();
    assert!(
        (second_stop as i64 - first_stop as i64 - 50).abs() <= 1,
        "5 updates buy 50 steps: {first_stop} -> {second_stop}"
    );
    // The trainer leaves: nothing to wait for.
    status.borrow_mut().take();
    answer_until_quiet(Duration::from_millis(1500), &mut last);
    let summary = sim.join().unwrap();
    assert_eq!(summary.steps, 400, "{summary:?}");
    assert_eq!(summary.pace.trainer_updates, 5);
    drop((obs, cmd, node));
    remove_namespace_files(&ipc.namespace);
}
