//! `mta up`: the whole stack on this machine (what `./ops/run_local.sh` runs). Starts the
//! trainer, the predictor and the simulator as separate processes on one stack config, shows
//! one live progress line, stops them cleanly on Ctrl-C / SIGTERM or when the simulated time is
//! up, and leaves in the run folder: each process's log and summary, the effective config
//! (`stack.toml`), the car's trace, the learned checkpoint (`model.safetensors`) and the
//! report (`report.json`, `lap_trace.png`, `latency.png`, `figure.png`; see `mta report`).

use mtanet_summaries::run_folder;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use mtanet_ipc::config::ConfigFile;
use mtanet_ipc::node::{IpcConfig, create_node};
use mtanet_ipc::ports::{Receiver, TopicShape};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::stack::StackConfig;
use mtanet_ipc::{Command, Observation, names};
use mtanet_report::RunInfo;

use crate::progress::{ProgressCsv, progress};
use crate::runcfg;
use crate::supervisor::{Event, Supervisor};

#[derive(Debug, clap::Args)]
pub struct UpArgs {
    /// Stack config (TOML; default ops/mtanet.toml when it exists, else built-in defaults).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Track CSV, or `generated:N` for a generated track (default: the shipped oval).
    #[arg(long)]
    track: Option<PathBuf>,
    /// Stop after this much simulated time (0: until Ctrl-C).
    #[arg(long, default_value_t = 0.0)]
    sim_seconds: f64,
    /// Lockstep: every step waits for its command (default: real time, 50 Hz).
    #[arg(long)]
    lockstep: bool,
    /// Run folder (default runs/<timestamp>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Start from this learned checkpoint: the trainer resumes from it and the predictor gets it
    /// at once (with --no-learning the predictor alone loads it).
    #[arg(long)]
    checkpoint: Option<PathBuf>,
    /// No trainer: the predictor drives with --checkpoint as it is.
    #[arg(long, requires = "checkpoint")]
    no_learning: bool,
    /// The reactive rule alone: no trainer, no model, no exploration, no active inference (the
    /// baseline a learnt driver is compared with).
    #[arg(long, conflicts_with_all = ["checkpoint", "no_learning", "record"])]
    rule: bool,
    /// Record the run's topics into `recording.mcap` in the run folder (`mta record`; replay it
    /// with `mta replay`).
    #[arg(long)]
    record: bool,
    /// With --record: the weights' checkpoint bytes too (~1 MB each), so a replay can hand a
    /// predictor the same weights at the same steps.
    #[arg(long, requires = "record")]
    record_weight_blobs: bool,
    /// iceoryx2 namespace (default: the config's [ipc] namespace).
    #[arg(long)]
    namespace: Option<String>,
}

use crate::plan::RECORDER;

/// A run folder of its own under `runs/`, named by the local time; a second run started in the
/// same second gets `-2`, `-3`, ... (made here, atomically, so two runs never share one).
fn reserve_out() -> anyhow::Result<PathBuf> {
    let now = std::process::Command::new("date")
        .arg("+%Y%m%d-%H%M%S")
        .output();
    let stamp = now
        .ok()
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .unwrap_or_else(|| "run".into());
    let runs = PathBuf::from("runs");
    std::fs::create_dir_all(&runs).context("creating runs/")?;
    for n in 1.. {
        let out = match n {
            1 => runs.join(&stamp),
            n => runs.join(format!("{stamp}-{n}")),
        };
        match std::fs::create_dir(&out) {
            Ok(()) => return Ok(out),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e).with_context(|| format!("creating {}", out.display())),
        }
    }
    unreachable!("an unbounded range ends only by returning")
}

pub fn run(args: UpArgs) -> anyhow::Result<()> {
    let shutdown = Shutdown::install().context("installing signal handlers")?;
    let (out, reserved) = match &args.out {
        Some(o) => (o.clone(), false),
        None => (reserve_out()?, true),
    };
    let mode = args.lockstep.then_some("lockstep");
    let checked = runcfg::effective_config(args.config.as_deref(), mode, args.rule, &out);
    if checked.is_err() && reserved {
        // Still empty: a config that fails its check leaves no run folder behind.
        let _ = std::fs::remove_dir(&out);
    }
    let (config, ck_dir) = checked?;
    let mut ipc: IpcConfig = ConfigFile::load(Some(&config))?.section("ipc")?;
    if let Some(ns) = &args.namespace {
        ipc.namespace = ns.clone();
    }
    refuse_live_namespace(&ipc, &out, reserved)?;
    let learning = !(args.no_learning || args.rule);
    let runcfg::Prepared {
        file,
        track,
        start_ck,
        realtime,
        stack,
    } = runcfg::prepare(
        &config,
        &ck_dir,
        &out,
        args.track.as_deref(),
        args.checkpoint.as_deref(),
        learning,
    )?;
    let info = RunInfo {
        track: track.clone(),
        // The mode the simulator runs in (the flag, else the config's, else real time).
        lockstep: !realtime,
        learning,
        checkpoint: args.checkpoint.clone(),
        config: args.config.clone(),
    };
    mtanet_summaries::files::write_json(&out.join(run_folder::RUN), &info)?;
    eprintln!(
        "[up] run folder {}; config {}",
        out.display(),
        config.display()
    );

    let mut sup = Supervisor::new(&out)?;
    let run = plan_run(&args, &config, &ipc, &out, &track, start_ck);
    start_in_order(&mut sup, &stack, &run)?;

    let target = (args.sim_seconds > 0.0).then_some(args.sim_seconds);
    let outcome = watch(
        &ipc,
        &mut sup,
        &shutdown,
        &out.join(run_folder::PROGRESS),
        target,
    );
    if let Some(line) = &outcome.as_ref().err() {
        eprintln!("\n[up] {line:#}");
    }
    eprintln!("\n[up] stopping");
    let failed = stop_all(&mut sup);
    conclude(
        &sup,
        &file,
        &track,
        &out,
        &ck_dir,
        args.checkpoint.as_deref(),
    )?;
    outcome?;
    if !failed.is_empty() {
        bail!("{}", failed.join("; "));
    }
    Ok(())
}

/// Starts the plan's processes in order, each one ready (READY=1: ports open, loop running)
/// before the next, as the Type=notify units do: the simulator comes last and its first step
/// finds its peers answering. A process that does not come up stops the others.
/// Two stacks in one namespace would answer each other's observations: refused (removing the
/// run folder made for this run, still empty).
fn refuse_live_namespace(ipc: &IpcConfig, out: &Path, reserved: bool) -> anyhow::Result<()> {
    let live = mtanet_ipc::node::census(ipc)?.alive;
    if live.is_empty() {
        return Ok(());
    }
    if reserved {
        let _ = std::fs::remove_dir_all(out);
    }
    bail!(
        "namespace {:?} is in use by a live stack ({}): stop it, or give this one another \
         with --namespace NAME (or [ipc] namespace in the config)",
        ipc.namespace,
        live.join(", ")
    )
}

/// The launch plan's inputs for this run: its config, namespace, folder, track and checkpoint.
fn plan_run(
    args: &UpArgs,
    config: &Path,
    ipc: &IpcConfig,
    out: &Path,
    track: &Path,
    start_ck: Option<PathBuf>,
) -> crate::plan::Run {
    crate::plan::Run {
        config: Some(config.to_path_buf()),
        namespace: Some(ipc.namespace.clone()),
        summaries: Some(out.to_path_buf()),
        track: Some(track.to_path_buf()),
        checkpoint: start_ck,
        trace: Some(out.join(run_folder::TRACE)),
        max_steps: (args.sim_seconds > 0.0)
            .then(|| (args.sim_seconds / mtanet_ipc::CONTROL_PERIOD_S).round() as u64),
        no_trainer: args.no_learning || args.rule,
        record: args.record.then(|| crate::plan::Recording {
            out: out.join("recording.mcap"),
            summary: out.join("recording.json"),
            weight_blobs: args.record_weight_blobs,
        }),
    }
}

/// Stops every process; what did not end cleanly.
fn stop_all(sup: &mut Supervisor) -> Vec<String> {
    let mut failed = Vec::new();
    for (name, how) in sup.stop_all(Duration::from_secs(60)) {
        match how.as_deref() {
            Some("exit code 0") => {}
            Some(other) => failed.push(format!("{name} ended with {other}")),
            None => failed.push(format!("{name} did not stop within 60 s")),
        }
    }
    failed
}

fn start_in_order(
    sup: &mut Supervisor,
    stack: &StackConfig,
    run: &crate::plan::Run,
) -> anyhow::Result<()> {
    let started = sup.start_plan(crate::plan::plan(stack, run), Duration::from_secs(60))?;
    for (name, pid) in started {
        eprintln!("[up] started {name} (pid {pid})");
    }
    Ok(())
}

/// After the stack stopped: the supervisor's restarts, the learnt (or given) model in the run
/// folder, the rule alone on the same track for the same time, `report.json` and its summary.
fn conclude(
    sup: &Supervisor,
    file: &ConfigFile,
    track: &Path,
    out: &Path,
    ck_dir: &Path,
    checkpoint: Option<&Path>,
) -> anyhow::Result<()> {
    let restarts = sup.restarts();
    let summary = mtanet_summaries::supervisor::SupervisorSummary { restarts };
    mtanet_summaries::files::write_json(&out.join(run_folder::SUPERVISOR), &summary)?;
    let latest = ck_dir.join(run_folder::LATEST);
    if latest.exists() {
        std::fs::copy(&latest, out.join(run_folder::MODEL))?;
    } else if let Some(ck) = checkpoint {
        std::fs::copy(ck, out.join(run_folder::MODEL))?;
    }
    eprintln!("[up] the reactive rule alone on the same track for the same time (the baseline)");
    if let Err(e) = crate::baseline::write_rule_alone(file, track, out) {
        eprintln!("[up] no rule-alone baseline: {e:#}");
    }
    let r = mtanet_report::write(out, &mtanet_offline::analyze::strip::strip_on_track)?;
    eprintln!(
        "[up] {} steps ({:.0} s simulated) in {:.0} s; laps {} (active inference {}); control {}; report {}",
        r.steps,
        r.sim_seconds,
        r.wall_seconds,
        r.laps.completed,
        r.laps.completed_under_active_inference,
        r.control,
        out.join(run_folder::REPORT).display()
    );
    print_versus_rule(&r);
    Ok(())
}

/// The run's active inference beside the rule alone on the same track for the same time.
fn print_versus_rule(r: &mtanet_report::Report) {
    let Some(b) = &r.rule_alone else { return };
    let mm = |v: Option<f64>| v.map_or("-".into(), |m| format!("{:.2} mm", m * 1e3));
    let s = |v: Option<f64>| v.map_or("-".into(), |t| format!("{t:.2} s"));
    eprintln!(
        "[up] lateral error: active inference {}, the rule alone {}; lap time: active \
         inference {}, the rule alone {}",
        mm(r.lateral_error_m.active_inference_mean),
        mm(b.lateral_mean_m),
        s(r.laps.lap_time_active_inference_s),
        s(b.lap_time_s)
    );
}

/// The live progress line, restarting failed processes, until a signal, the simulator's end,
/// or a process that failed more often than its restart policy allows.
/// Every second a line also goes to `progress_csv` (the live model-vs-copy-last curve that
/// `mta plot` draws).
fn watch(
    ipc: &IpcConfig,
    sup: &mut Supervisor,
    shutdown: &Shutdown,
    progress_csv: &Path,
    target_sim_s: Option<f64>,
) -> anyhow::Result<()> {
    let mut csv = ProgressCsv::create(progress_csv)?;
    let mut last_row = Instant::now();
    let node = create_node(ipc, "mta-up")?;
    let obs = Receiver::<Observation>::open(&node, names::OBSERVATION, TopicShape::STEP)?;
    let cmds = Receiver::<Command>::open(&node, names::COMMAND, TopicShape::STEP)?;
    let tty = std::io::stderr().is_terminal();
    let start = Instant::now();
    let mut last_print = Instant::now();
    let mut latest = Latest::default();
    while !shutdown.requested() {
        if simulator_done(sup.poll()?)? {
            return Ok(());
        }
        obs.wait(Duration::from_millis(100))?;
        latest.take_in(&obs, &cmds)?;
        if last_row.elapsed() >= Duration::from_secs(1) {
            last_row = Instant::now();
            let (o, c) = (latest.obs.as_ref(), latest.cmd.as_ref());
            csv.row(o, c, latest.laps(), start.elapsed());
        }
        if last_print.elapsed() >= Duration::from_secs(if tty { 1 } else { 10 }) {
            last_print = Instant::now();
            let (o, c) = (latest.obs.as_ref(), latest.cmd.as_ref());
            let mut line = progress(o, c, latest.laps(), start.elapsed(), target_sim_s);
            let restarts: u32 = sup.restarts().values().sum();
            if restarts > 0 {
                line.push_str(&format!(" | restarts {restarts}"));
            }
            if tty {
                eprint!("\r{line:<120}");
                let _ = std::io::stderr().flush();
            } else {
                eprintln!("[up] {line}");
            }
        }
    }
    Ok(())
}

/// The newest observation and command seen, and the laps over all episodes so far.
#[derive(Default)]
struct Latest {
    obs: Option<Observation>,
    cmd: Option<Command>,
    episode: u8,
    laps_before: u32,
    laps_in: u32,
}

impl Latest {
    fn take_in(
        &mut self,
        obs: &Receiver<Observation>,
        cmds: &Receiver<Command>,
    ) -> anyhow::Result<()> {
        if let Some(o) = obs.latest()? {
            if o.episode != self.episode {
                (self.episode, self.laps_before, self.laps_in) = (o.episode, self.laps(), 0);
            }
            self.laps_in = o.truth.laps;
            self.obs = Some(o);
        }
        if let Some(c) = cmds.latest()? {
            self.cmd = Some(c);
        }
        Ok(())
    }

    fn laps(&self) -> u32 {
        self.laps_before + self.laps_in
    }
}

/// Says what the supervisor did; true once the simulator has ended its run, an error once a
/// process other than the recorder ended or failed past its restart policy.
fn simulator_done(events: Vec<Event>) -> anyhow::Result<bool> {
    for e in events {
        match e {
            Event::Done { name } if name == "simulator" => return Ok(true),
            // A recorder that failed costs the recording, not the run.
            Event::Done { name } | Event::GaveUp { name, .. } if name == RECORDER => {
                eprintln!("\n[up] the recorder stopped; see mta.log (the run goes on)");
            }
            Event::Done { name } => bail!("{name} exited on its own"),
            Event::GaveUp { name, status } => {
                bail!("{name} failed ({status}) more often than its restart policy allows")
            }
            Event::Failed {
                name,
                status,
                restart_in,
            } => eprintln!(
                "\n[up] {name} failed ({status}): restarting in {:.1} s",
                restart_in.as_secs_f64()
            ),
            Event::Restarted {
                name,
                pid,
                restarts,
            } => eprintln!("[up] restarted {name} (pid {pid}, restart {restarts})"),
        }
    }
    Ok(false)
}
