//! `mta soak`: the real workload for M minutes, in real time (default) or lockstep: the trainer
//! learning, the predictor stepping its model and planning, under the supervisor (`[stack]`), in
//! a private namespace. A raw iceoryx2 ping-pong with the same payloads and wake-up mechanism
//! measures the transport floor in the same run: alone before the stack starts, and beside it
//! all through (the floor under the same load, which the target compares with). Writes `soak.json`
//! ([`SoakReport`]) and `soak.png`, and prints a table with the targets.

pub mod load;
pub mod pauses;
pub mod pingpong;
mod process;

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};
use mtanet_ipc::config::ConfigFile;
use mtanet_ipc::stack::StackConfig;
use mtanet_launch::runcfg;
use mtanet_launch::stack::{
    bin_dir, leftover_shm, nodes, remove_namespace_files, unique_namespace,
};
use mtanet_launch::supervisor::{Event, Supervisor};
use mtanet_report::print_table;
use mtanet_summaries::incident::{Incident, IncidentKind};
use mtanet_summaries::predictor::Summary as PredictorSummary;
use mtanet_summaries::simulator::Summary as SimulatorSummary;
use mtanet_summaries::soak::{
    Control, IncidentCounts, ProcessUse, ReplayCounts, SoakReport, StartEnd,
};
use mtanet_summaries::trainer::Summary as TrainerSummary;

use crate::load::CpuHog;
use crate::pauses::PauseWatch;
use crate::process::{rss_and_fds, scheduling};

#[derive(Debug, clap::Args)]
pub struct SoakArgs {
    /// Minutes of simulated time (50 steps a second).
    #[arg(long, default_value_t = 1.0)]
    minutes: f64,
    /// Lockstep instead of real time.
    #[arg(long, conflicts_with = "realtime")]
    lockstep: bool,
    /// Real time, 50 Hz (the default).
    #[arg(long)]
    realtime: bool,
    /// Start the trainer (and so the predictor) from this checkpoint, so active inference plans
    /// from the start.
    #[arg(long)]
    checkpoint: Option<PathBuf>,
    /// Output folder (logs, summaries, soak.json, soak.png).
    #[arg(long)]
    out: PathBuf,
    /// Stack config (default ops/mtanet.toml when it exists).
    #[arg(long)]
    config: Option<PathBuf>,
    #[arg(long)]
    track: Option<PathBuf>,
    /// Seconds of raw ping-pong before the stack starts.
    #[arg(long, default_value_t = 15.0)]
    pingpong_seconds: f64,
    /// A CPU hog at normal priority on every core all through (`yes > /dev/null` each): what
    /// a busy or slower machine leaves the stack.
    #[arg(long)]
    cpu_hog: bool,
    /// Confine the whole run (stack and ping-pong) to these CPUs, e.g. `0` or `0-1`.
    #[arg(long)]
    cpus: Option<String>,
}

pub fn run(args: SoakArgs) -> anyhow::Result<()> {
    // The load first: it is the machine everything below is measured on.
    // SAFETY: sysconf(3) reads a constant of the system.
    let online = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_ONLN) }.max(1) as usize;
    let hog = CpuHog::start(if args.cpu_hog { online } else { 0 })?;
    if let Some(cpus) = &args.cpus {
        load::confine(cpus)?;
    }
    let machine = mtanet_summaries::soak::Machine::here(hog.len());
    eprintln!("[soak] {machine}");
    let watch = PauseWatch::start(&load::allowed_cpus())?;
    let out = args.out.clone();
    let mode = if args.lockstep {
        "lockstep"
    } else {
        "realtime"
    };
    let (config, ck_dir) =
        runcfg::effective_config(args.config.as_deref(), Some(mode), false, &out)?;
    let file = ConfigFile::load(Some(&config))?;
    let scene: mtanet_scenes::SceneConfig = file.section("simulator.scene")?;
    let track = args.track.clone().unwrap_or(scene.track);
    let start_ck = match &args.checkpoint {
        Some(ck) => {
            let probed = runcfg::probed_copy(ck, &file, &track, &out)?;
            std::fs::create_dir_all(&ck_dir)?;
            std::fs::copy(&probed, ck_dir.join("latest.safetensors"))?;
            Some(probed)
        }
        None => None,
    };
    let ns = unique_namespace("soak");
    let sim: mtanet_simulator::config::SimulatorConfig = file.section("simulator")?;
    let realtime = sim.mode == mtanet_simulator::config::Mode::Realtime;
    let stack = file.section::<StackConfig>("stack")?.for_mode(realtime);
    let prio = |binary: &str| {
        stack
            .process
            .iter()
            .find(|p| p.binary == binary)
            .and_then(|p| p.realtime_priority)
    };
    let (sim_prio, pred_prio) = (prio("mta-simulator"), prio("mta-predictor"));

    // 1. The transport floor, alone on the machine.
    let peer = std::process::Command::new(bin_dir().join("mta"))
        .args(["pingpong-peer", "--namespace", &ns])
        .args(pred_prio.map(|p| format!("--priority={p}")))
        .stderr(std::fs::File::create(out.join("pingpong-peer.log"))?)
        .spawn()
        .context("starting the ping-pong peer")?;
    struct Kill(std::process::Child);
    impl Drop for Kill {
        fn drop(&mut self) {
            // SAFETY: kill(2) on our child.
            unsafe { libc::kill(self.0.id() as i32, libc::SIGTERM) };
            let _ = self.0.wait();
        }
    }
    let peer = Kill(peer);
    eprintln!(
        "[soak] raw iceoryx2 ping-pong alone for {:.0} s",
        args.pingpong_seconds
    );
    let period = Duration::from_secs_f64(mtanet_ipc::CONTROL_PERIOD_S);
    // On a thread of its own: it takes the simulator's real-time class, which the processes
    // started from this thread below would otherwise inherit.
    let idle = std::thread::scope(|s| {
        s.spawn(|| {
            let never = std::sync::atomic::AtomicBool::new(false);
            let alone = Duration::from_secs_f64(args.pingpong_seconds);
            crate::pingpong::measure(&ns, period, alone, &never, sim_prio)
        })
        .join()
        .map_err(|_| anyhow::anyhow!("the ping-pong thread panicked"))
    })??
    .0;
    // ...and all through the soak, beside the stack: the floor under the same load.
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let pinger = {
        let (ns, stop) = (ns.clone(), std::sync::Arc::clone(&stop));
        std::thread::spawn(move || {
            crate::pingpong::measure(&ns, period, Duration::from_secs(86_400), &stop, sim_prio)
        })
    };

    // 2. The stack.
    let steps = (args.minutes * 60.0 / mtanet_ipc::CONTROL_PERIOD_S).round() as u64;
    let mut sup = Supervisor::new(&out)?;
    let run = mtanet_launch::Run {
        config: Some(config.clone()),
        namespace: Some(ns.clone()),
        summaries: Some(out.clone()),
        track: Some(track.clone()),
        checkpoint: start_ck.clone(),
        max_steps: Some(steps),
        ..Default::default()
    };
    for launch in mtanet_launch::plan(&stack, &run) {
        sup.add(&launch.spec, launch.args)?;
    }
    // Each one ready (READY=1) before the next, as `mta up` starts them.
    let mut classes = BTreeMap::new();
    for spec in &stack.process {
        let pid = sup.start(&spec.name)?;
        sup.await_ready(&spec.name, Duration::from_secs(60))?;
        classes.insert(spec.name.clone(), scheduling(pid));
    }
    let bar = ProgressBar::new(steps).with_style(
        ProgressStyle::with_template("[soak] {msg} {bar:40} {elapsed}/{duration}")
            .expect("valid template"),
    );
    bar.set_message(format!("{mode}, {:.1} min", args.minutes));
    let t0 = Instant::now();
    let mut first: BTreeMap<String, (u64, u64)> = BTreeMap::new();
    let mut last: BTreeMap<String, (u64, u64)> = BTreeMap::new();
    let sample = |sup: &Supervisor, into: &mut BTreeMap<String, (u64, u64)>| {
        for spec in &stack.process {
            if let Some(pid) = sup.pid(&spec.name) {
                into.insert(spec.name.clone(), rss_and_fds(pid));
            }
        }
    };
    let limit = Duration::from_secs_f64(
        120.0 + args.minutes * 60.0 * if args.lockstep { 4.0 } else { 1.5 },
    );
    let mut failure = None;
    'run: loop {
        for e in sup.poll()? {
            match e {
                Event::Done { name } if name == "simulator" => break 'run,
                Event::GaveUp { name, status } | Event::Failed { name, status, .. } => {
                    failure = Some(format!("{name} failed ({status})"));
                    break 'run;
                }
                _ => {}
            }
        }
        // Resource use once warmed up (a quarter in: the trainer has trained, probed and
        // published by then), and the latest while running.
        let warm = Duration::from_secs_f64((args.minutes * 60.0 / 4.0).max(30.0));
        if first.is_empty() && t0.elapsed() > warm {
            sample(&sup, &mut first);
        }
        sample(&sup, &mut last);
        let elapsed = t0.elapsed();
        bar.set_position(
            ((elapsed.as_secs_f64() / (args.minutes * 60.0)) * steps as f64).min(steps as f64)
                as u64,
        );
        if elapsed > limit {
            failure = Some(format!("the simulator was still running after {limit:?}"));
            break;
        }
        std::thread::sleep(Duration::from_millis(250));
    }
    bar.finish_and_clear();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let (pingpong, pingpong_lost) = pinger
        .join()
        .map_err(|_| anyhow::anyhow!("the ping-pong thread panicked"))??;
    drop(peer);
    let ends = sup.stop_all(Duration::from_secs(60));
    drop(hog);
    let (pauses, machine_pauses) = watch.finish();
    if let Some(f) = failure {
        bail!("{f}; logs in {}", out.display());
    }
    for (name, how) in &ends {
        if how.as_deref() != Some("exit code 0") && name != "simulator" {
            bail!(
                "{name} did not stop cleanly ({how:?}); logs in {}",
                out.display()
            );
        }
    }
    let (sim, pred, tr): (SimulatorSummary, PredictorSummary, TrainerSummary) = (
        mtanet_files::read_json(&out.join("mta-simulator.json"))?,
        mtanet_files::read_json(&out.join("mta-predictor.json"))?,
        mtanet_files::read_json(&out.join("mta-trainer.json"))?,
    );
    let leftovers = (nodes(&ns), leftover_shm(&ns));
    remove_namespace_files(&ns);

    let raw = pingpong.summary();
    let latency = [
        ("raw_pingpong_idle", idle.summary()),
        ("raw_pingpong", raw),
        ("round_trip", sim.round_trip),
        ("obs_to_predictor", pred.obs_to_predictor),
        ("predictor", pred.compute),
        ("cmd_to_sim", sim.cmd_to_sim),
        ("step", sim.step_time),
        ("plan", pred.plan),
        ("tick_jitter", sim.tick_jitter),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    let processes = stack
        .process
        .iter()
        .map(|p| {
            let a = first.get(&p.name).copied().unwrap_or_default();
            let b = last.get(&p.name).copied().unwrap_or_default();
            let use_ = ProcessUse {
                scheduling: classes.get(&p.name).cloned().unwrap_or_default(),
                rss_kb: StartEnd {
                    start: a.0,
                    end: b.0,
                },
                fds: StartEnd {
                    start: a.1,
                    end: b.1,
                },
            };
            (p.name.clone(), use_)
        })
        .collect();
    let incidents: Vec<Incident> = sim
        .incidents
        .iter()
        .chain(&pred.incidents)
        .copied()
        .collect();
    let kind = |k: IncidentKind| incidents.iter().filter(|i| i.kind == k).count();
    let paused = incidents
        .iter()
        .filter(|i| pauses::during_a_pause(&pauses, i.start_ns, i.end_ns, 1_000_000))
        .count();
    let control = Control::new(&sim.control, Some(&pred.control));
    let soak = SoakReport {
        mode: mode.into(),
        minutes: args.minutes,
        steps: sim.steps,
        machine,
        latency,
        overruns: sim.overruns,
        missed_commands: sim.missed_commands,
        dropped_commands: pred.commands_sent.saturating_sub(sim.commands_received),
        replay: ReplayCounts {
            chunks_sent: sim.replay_chunks_sent,
            chunks_received: tr.chunks_received,
            chunks_lost: tr.chunks_lost,
        },
        raw_pingpong_lost: pingpong_lost,
        control: control.clone(),
        active_inference_share: control.active_inference_steps as f64 / sim.steps.max(1) as f64,
        planning: pred.planning,
        machine_pauses,
        incidents: IncidentCounts {
            missed_commands: kind(IncidentKind::MissedCommand),
            overruns: kind(IncidentKind::Overrun),
            late_plans: kind(IncidentKind::LatePlan),
            during_machine_pauses: paused,
            unexplained: incidents.len() - paused,
        },
        trainer_updates: tr.session_updates,
        processes,
        restarts: sup.restarts(),
        clean_exit: leftovers.0.alive.is_empty()
            && leftovers.0.dead.is_empty()
            && leftovers.1.is_empty(),
    };
    mtanet_files::write_json(&out.join("soak.json"), &soak)?;
    mtanet_report::latency_picture(
        &out.join("soak.png"),
        &[
            (
                "raw ping-pong round trip (beside the stack)",
                &pingpong.histogram(),
            ),
            ("observation -> predictor", &pred.obs_to_predictor_hist),
            ("predictor compute", &pred.compute_hist),
            ("command -> simulator", &sim.cmd_to_sim_hist),
            ("simulator step", &sim.step_time_hist),
        ],
    )?;
    print_table(&soak);
    if !soak.clean_exit {
        bail!("the stack left iceoryx2 resources behind: {leftovers:?}");
    }
    Ok(())
}
