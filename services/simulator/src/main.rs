//! `mta-simulator`: the MuJoCo line-tracer world as an iceoryx2 service; or alone with the
//! teacher driving (`--teacher-only`) for tests and data collection; or `--write-mjcf` to look
//! at the scene in another MuJoCo.

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Parser;
use mtanet_ipc::cli::CommonArgs;
use mtanet_ipc::node::{IpcConfig, create_node};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::{logging, systemd};
use mtanet_scenes::{SceneConfig, Teacher, World};
use mtanet_simulator::config::{Mode, SimulatorConfig};
use mtanet_simulator::{service, standalone};

#[derive(Parser, Debug)]
#[command(
    name = "mta-simulator",
    version,
    about = "MuJoCo line-tracer world for mtanet"
)]
struct Args {
    /// Config sections read: [ipc], [simulator], [simulator.scene], [simulator.teacher].
    #[command(flatten)]
    common: CommonArgs,
    /// Track CSV, or `generated:N` for a generated track (overrides simulator.scene.track).
    #[arg(long)]
    track: Option<PathBuf>,
    /// lockstep or realtime (overrides simulator.mode).
    #[arg(long, value_parser = parse_mode)]
    mode: Option<Mode>,
    /// Stop after this many steps (overrides simulator.max_steps; 0 = until a signal).
    #[arg(long)]
    max_steps: Option<u64>,
    /// Wait for a trainer to subscribe before the first step (lockstep).
    #[arg(long)]
    expect_trainer: bool,
    /// Seed of the teacher's exploration noise (overrides simulator.teacher.seed).
    #[arg(long)]
    seed: Option<u64>,
    /// Std of the teacher's exploration noise in rad/s (overrides simulator.teacher.noise_std).
    #[arg(long)]
    noise: Option<f32>,
    /// Run alone with the teacher driving, no iceoryx2.
    #[arg(long, requires_all = ["sim_seconds", "report"])]
    teacher_only: bool,
    /// Simulated seconds to run (with --teacher-only).
    #[arg(long)]
    sim_seconds: Option<f64>,
    /// Report JSON (with --teacher-only): laps, lateral_error_m, steps, real_time_factor...
    #[arg(long)]
    report: Option<PathBuf>,
    /// Record a dataset .npz (with --teacher-only).
    #[arg(long, requires = "teacher_only")]
    record: Option<PathBuf>,
    /// Steps per recorded sequence.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..))]
    seq_len: u64,
    /// Lockstep pacing: trainer updates per 1000 steps (overrides
    /// simulator.pace_updates_per_1000_steps; 0: off).
    #[arg(long)]
    pace: Option<f64>,
    /// Write the scene's generated MJCF to this file and exit (open it in MuJoCo's own viewer,
    /// or check it with another MuJoCo version: it also loads in MuJoCo 2.2).
    #[arg(long, conflicts_with_all = ["teacher_only", "trace"])]
    write_mjcf: Option<PathBuf>,
    /// Service mode: write the car's path and who drove it (CSV) to this file.
    #[arg(long, conflicts_with = "teacher_only")]
    trace: Option<PathBuf>,
}

fn parse_mode(s: &str) -> Result<Mode, String> {
    match s {
        "lockstep" => Ok(Mode::Lockstep),
        "realtime" => Ok(Mode::Realtime),
        _ => Err(format!("unknown mode {s:?}: use lockstep or realtime")),
    }
}

fn main() -> anyhow::Result<()> {
    logging::init();
    let args = Args::parse();
    let (mut cfg, ipc, shutdown): (SimulatorConfig, _, _) = args.common.start("simulator")?;
    apply_flags(&args, &mut cfg);
    let mut teacher = Teacher::new(&cfg.teacher);
    if let Some(path) = &args.write_mjcf {
        return write_mjcf(&cfg.scene, path);
    }
    if args.teacher_only {
        return teacher_only(&args, &cfg, &mut teacher, &shutdown);
    }
    (cfg.validate()).map_err(|e| args.common.invalid_config("simulator", e))?;
    serve(&args, &cfg, &ipc, &mut teacher, &shutdown)
}

/// The command line's overrides of the config file.
fn apply_flags(args: &Args, cfg: &mut SimulatorConfig) {
    if let Some(t) = &args.track {
        cfg.scene.track = t.clone();
    }
    if let Some(s) = args.seed {
        cfg.teacher.seed = s;
    }
    if let Some(n) = args.noise {
        cfg.teacher.noise_std = n;
    }
    if let Some(m) = args.mode {
        cfg.mode = m;
    }
    if let Some(n) = args.max_steps {
        cfg.max_steps = n;
    }
    cfg.expect_trainer |= args.expect_trainer;
    if let Some(p) = args.pace {
        cfg.pace_updates_per_1000_steps = p;
    }
    if args.seed.is_some() && cfg.teacher.noise_std == 0.0 {
        // Without noise the teacher is deterministic: every seed records the same data.
        tracing::warn!(
            "--seed has no effect while the teacher's noise is 0: add --noise STD (rad/s) for varied data"
        );
    }
}

/// `--write-mjcf`: written only after MuJoCo compiled it (World::new), so what is on disk loads.
fn write_mjcf(scene: &SceneConfig, path: &Path) -> anyhow::Result<()> {
    let world = World::new(scene).context("loading the scene (simulator.scene.track)")?;
    mtanet_summaries::files::write_bytes(path, world.mjcf().as_bytes())?;
    println!("{}: the scene of {}", path.display(), scene.track.display());
    Ok(())
}

/// `--teacher-only`: the rule alone drives the first track, no IPC.
fn teacher_only(
    args: &Args,
    cfg: &SimulatorConfig,
    teacher: &mut Teacher,
    shutdown: &Shutdown,
) -> anyhow::Result<()> {
    let world = &mut World::new(&cfg.scene).context("loading the scene (simulator.scene.track)")?;
    let run = standalone::StandaloneRun {
        sim_seconds: args.sim_seconds.unwrap_or_default(),
        record: args.record.clone(),
        seq_len: args.seq_len as usize,
        seed: cfg.teacher.seed,
    };
    let rep = standalone::run(world, teacher, &run, shutdown)?;
    tracing::info!(
        laps = rep.laps,
        lateral_mean_m = rep.lateral_error_m.mean,
        lateral_max_m = rep.lateral_error_m.max,
        rtf = rep.real_time_factor,
        "teacher run done"
    );
    let path = args
        .report
        .as_ref()
        .expect("clap requires --report with --teacher-only");
    mtanet_summaries::files::write_json(path, &rep)?;
    Ok(())
}

/// The service: steps the worlds, answering to the predictor and feeding the trainer.
fn serve(
    args: &Args,
    cfg: &SimulatorConfig,
    ipc: &IpcConfig,
    teacher: &mut Teacher,
    shutdown: &Shutdown,
) -> anyhow::Result<()> {
    let mut worlds = load_worlds(cfg)?;
    let node = create_node(ipc, "mta-simulator")?;
    let ports = service::Ports::open(&node)?;
    systemd::ready("simulator running");
    tracing::info!(namespace = %ipc.namespace, mode = ?cfg.mode, "simulator service started");
    let mut trace = args
        .trace
        .as_deref()
        .map(|p| mtanet_simulator::trace::Trace::create(p, cfg.trace_every_steps))
        .transpose()?;
    let summary = service::run(
        &node,
        &ports,
        &mut worlds,
        teacher,
        cfg,
        shutdown,
        trace.as_mut(),
    );
    systemd::stopping();
    if let Some(t) = trace {
        t.finish()?;
    }
    let summary = summary?;
    tracing::info!(
        steps = summary.steps,
        received = summary.commands_received,
        missed = summary.missed_commands,
        teacher_steps = summary.teacher_steps,
        chunks = summary.replay_chunks_sent,
        round_trip = %summary.round_trip,
        "simulator stopped"
    );
    args.common.write_summary(&summary)
}

/// The worlds of the tracks driven in turn; an error names the track and the config key.
fn load_worlds(cfg: &SimulatorConfig) -> anyhow::Result<Vec<World>> {
    let scenes = cfg.scenes();
    let mut worlds = Vec::with_capacity(scenes.len());
    for (i, scene) in scenes.iter().enumerate() {
        let key = match i {
            0 => "simulator.scene.track".to_string(),
            _ => format!("simulator.also_tracks[{}]", i - 1),
        };
        let world = World::new(scene).with_context(|| {
            format!(
                "loading the scene for track {} ({key})",
                scene.track.display()
            )
        })?;
        tracing::info!(track = %scene.track.display(), length_m = world.track().length_m(), "world ready");
        worlds.push(world);
    }
    Ok(worlds)
}
