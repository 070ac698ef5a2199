//! Drives the simulator service (on its own thread, real iceoryx2) with a scripted predictor.

use std::time::Duration;

use mtanet_ipc::node::{IpcConfig, create_node};
use mtanet_ipc::ports::{Receiver, Sender, TopicShape};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::{Command, CommandSource, Observation, ReplayChunk, names, stamp};
use mtanet_scenes::{GroundTruth, SceneConfig, Teacher, TeacherConfig, World};
use mtanet_simulator::config::SimulatorConfig;
use mtanet_simulator::service::{Ports, Summary, run};

/// What the scripted predictor saw and the simulator reported.
pub struct Drive {
    pub summary: Summary,
    pub truth: GroundTruth,
    /// Episode of every observation, in order.
    pub episodes: Vec<u8>,
    /// Every observation, and every replay chunk received, in order.
    pub observations: Vec<Observation>,
    pub chunks: Vec<Box<ReplayChunk>>,
}

/// Runs `cfg.max_steps` lockstep steps answering each observation with `command(obs)`.
#[allow(dead_code)]
pub fn drive(
    tag: &str,
    cfg: SimulatorConfig,
    mut command: impl FnMut(&Observation) -> [f32; 2],
) -> Drive {
    drive_with(tag, cfg, move |o| (command(o), CommandSource::Reactive))
}

/// [`drive`] with the source of each command scripted too.
#[allow(dead_code)]
pub fn drive_with(
    tag: &str,
    cfg: SimulatorConfig,
    mut command: impl FnMut(&Observation) -> ([f32; 2], CommandSource),
) -> Drive {
    drive_script(tag, cfg, move |o, c| {
        let (wheels, source) = command(o);
        c.wheel_velocity = wheels;
        c.source = source as u32;
        true
    })
}

/// Runs `cfg.max_steps` steps; `answer` fills the command for each observation (step, stamps
/// and source filled in already), or returns false to leave it unanswered.
pub fn drive_script(
    tag: &str,
    cfg: SimulatorConfig,
    mut answer: impl FnMut(&Observation, &mut Command) -> bool,
) -> Drive {
    let ns = IpcConfig {
        namespace: format!("{tag}{}", std::process::id()),
    };
    let sim_ns = ns.clone();
    let steps = cfg.max_steps;
    // The simulator runs on its own thread with its own node (iceoryx2 ports are not Send).
    let sim = std::thread::spawn(move || {
        let node = create_node(&sim_ns, "sim-under-test").unwrap();
        let ports = Ports::open(&node).unwrap();
        let mut world = World::new(&SceneConfig::default()).unwrap();
        let mut teacher = Teacher::new(&TeacherConfig::default());
        let summary = run(
            &node,
            &ports,
            std::slice::from_mut(&mut world),
            &mut teacher,
            &cfg,
            &Shutdown::manual(),
            None,
        )
        .unwrap();
        (summary, world.truth())
    });
    let mut episodes = Vec::new();
    let mut observations = Vec::new();
    let mut chunks = Vec::new();
    {
        let node = create_node(&ns, "scripted-predictor").unwrap();
        let obs =
            Receiver::<Observation>::open(&node, names::OBSERVATION, TopicShape::STEP).unwrap();
        let cmd = Sender::<Command>::open(&node, names::COMMAND, TopicShape::STEP).unwrap();
        let replay =
            Receiver::<ReplayChunk>::open(&node, names::REPLAY, TopicShape::REPLAY).unwrap();
        let take = |chunks: &mut Vec<Box<ReplayChunk>>| {
            replay
                .for_each(|c| {
                    let mut b: Box<ReplayChunk> = bytemuck::zeroed_box();
                    *b = *c;
                    chunks.push(b);
                })
                .unwrap();
        };
        while (episodes.len() as u64) < steps && !sim.is_finished() {
            obs.wait(Duration::from_millis(50)).unwrap();
            obs.drain_events().unwrap();
            let mut pending = Vec::new();
            obs.for_each(|o| pending.push(*o)).unwrap();
            for o in pending {
                episodes.push(o.episode);
                observations.push(o);
                let mut c: Command = bytemuck::Zeroable::zeroed();
                c.step = o.step;
                c.obs_stamp_ns = o.stamp_ns;
                c.source = CommandSource::Reactive as u32;
                if answer(&o, &mut c) {
                    cmd.send_with(|s| {
                        *s = c;
                        s.stamp_ns = stamp::monotonic_ns();
                    })
                    .unwrap();
                }
            }
            take(&mut chunks);
        }
        // The simulator lingers with its replay publisher while a subscriber is connected.
        while !sim.is_finished() {
            take(&mut chunks);
            std::thread::sleep(Duration::from_millis(5));
        }
        take(&mut chunks);
    }
    let (summary, truth) = sim.join().unwrap();
    // iceoryx2 keeps a node counter per namespace by design; this namespace is used once.
    mtanet_ipc::node::remove_namespace_files(&ns.namespace);
    Drive {
        summary,
        truth,
        episodes,
        observations,
        chunks,
    }
}
