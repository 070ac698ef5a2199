//! A predictor that sends NaN/inf wheel commands over real iceoryx2: the simulator rejects and
//! counts them and keeps driving with the last good command.

use std::time::Duration;

use mtanet_ipc::node::{IpcConfig, create_node};
use mtanet_ipc::ports::{Receiver, Sender, TopicShape};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::{Command, Observation, names, stamp};
use mtanet_scenes::{SceneConfig, Teacher, TeacherConfig, World};
use mtanet_simulator::config::SimulatorConfig;
use mtanet_simulator::service::{Ports, run};

#[test]
fn non_finite_commands_are_rejected_counted_and_survived() {
    let ns = IpcConfig {
        namespace: format!("nan{}", std::process::id()),
    };
    let sim_ns = ns.clone();
    // The simulator runs on its own thread with its own node (iceoryx2 ports are not Send).
    let sim = std::thread::spawn(move || {
        let node = create_node(&sim_ns, "sim-under-test").unwrap();
        let ports = Ports::open(&node).unwrap();
        let mut world = World::new(&SceneConfig::default()).unwrap();
        let mut teacher = Teacher::new(&TeacherConfig::default());
        let cfg = SimulatorConfig {
            max_steps: 200,
            wait_for_peers_s: 20.0,
            ..Default::default()
        };
        let summary = run(
            &node,
            &ports,
            &mut world,
            &mut teacher,
            &cfg,
            &Shutdown::manual(),
        )
        .unwrap();
        (summary, world.truth())
    });

    let node = create_node(&ns, "nan-predictor").unwrap();
    let obs = Receiver::<Observation>::open(&node, names::OBSERVATION, TopicShape::STEP).unwrap();
    let cmd = Sender::<Command>::open(&node, names::COMMAND, TopicShape::STEP).unwrap();
    let mut answered = 0u64;
    while answered < 200 && !sim.is_finished() {
        obs.wait(Duration::from_millis(50)).unwrap();
        obs.drain_events().unwrap();
        let mut pending = Vec::new();
        obs.for_each(|o| pending.push((o.step, o.stamp_ns)))
            .unwrap();
        for (step, obs_stamp) in pending {
            // Every 4th command is poisoned, alternating NaN and +inf.
            let wheels = match step % 8 {
                3 => [f32::NAN, 5.0],
                7 => [5.0, f32::INFINITY],
                _ => [6.0, 6.0],
            };
            cmd.send_with(|c| {
                c.step = step;
                c.obs_stamp_ns = obs_stamp;
                c.wheel_velocity = wheels;
                c.stamp_ns = stamp::monotonic_ns();
            })
            .unwrap();
            answered += 1;
        }
    }
    let (summary, truth) = sim.join().unwrap();
    drop((obs, cmd, node));
    // iceoryx2 keeps a node counter per namespace by design; this namespace is used once.
    for e in std::fs::read_dir("/dev/shm").unwrap().flatten() {
        if e.file_name()
            .to_string_lossy()
            .starts_with(&format!("iox2_{}_", ns.namespace))
        {
            let _ = std::fs::remove_file(e.path());
        }
    }
    assert_eq!(summary.steps, 200);
    assert_eq!(summary.commands_received, 200, "{summary:?}");
    assert_eq!(summary.rejected_commands, 50, "{summary:?}");
    // Driving straight at 6 rad/s for 4 s: it moved forward despite the poison.
    assert!(truth.track_s > 0.5, "car did not keep driving: {truth:?}");
}
