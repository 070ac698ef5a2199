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
mod report;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::bail;
use indicatif::{ProgressBar, ProgressStyle};
use mtanet_ipc::stack::StackConfig;
use mtanet_launch::runcfg;
use mtanet_launch::stack::{leftover_shm, nodes, remove_namespace_files, unique_namespace};
use mtanet_launch::supervisor::{Event, Supervisor};
use mtanet_report::print_table;
use mtanet_summaries::files::{read_json, write_json};
use mtanet_summaries::run_folder;

use crate::load::CpuHog;
use crate::pauses::PauseWatch;
use crate::pingpong::{Floor, Priorities};
use crate::process::{rss_and_fds, scheduling};
use crate::report::{Samples, Summaries, Watched};

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
    let online = mtanet_ipc::sched::online_cpus();
    let hog = CpuHog::start(if args.cpu_hog { online } else { 0 })?;
    if let Some(cpus) = &args.cpus {
        load::confine(cpus)?;
    }
    let machine = mtanet_summaries::soak::Machine::here(hog.len());
    eprintln!("[soak] {machine}");
    let watch = PauseWatch::start(&mtanet_ipc::sched::allowed_cpus())?;
    let out = args.out.clone();
    let mode = if args.lockstep {
        "lockstep"
    } else {
        "realtime"
    };
    let soak = Prepared::new(&args, mode)?;

    // 1. The transport floor, alone on the machine, then beside the stack all through.
    let alone = Duration::from_secs_f64(args.pingpong_seconds);
    let floor = Floor::start(&soak.ns, &out, alone, soak.priorities())?;
    // 2. The stack.
    let mut sup = Supervisor::new(&out)?;
    let ran = soak.run_stack(&mut sup, &args);
    let floor = floor.finish()?;
    let ends = sup.stop_all(Duration::from_secs(60));
    drop(hog);
    let (pauses, machine_pauses) = watch.finish();
    let ran = ran.map_err(|e| anyhow::anyhow!("{e:#}; logs in {}", out.display()))?;
    for (name, how) in &ends {
        if how.as_deref() != Some("exit code 0") && name != "simulator" {
            bail!(
                "{name} did not stop cleanly ({how:?}); logs in {}",
                out.display()
            );
        }
    }
    let summaries = read_summaries(&out)?;
    let leftovers = (nodes(&soak.ns), leftover_shm(&soak.ns));
    remove_namespace_files(&soak.ns);
    let names: Vec<String> = soak.stack.process.iter().map(|p| p.name.clone()).collect();
    let watched = Watched {
        mode: mode.into(),
        minutes: args.minutes,
        machine,
        floor,
        pauses,
        machine_pauses,
        classes: ran.classes,
        first: ran.first,
        last: ran.last,
        restarts: sup.restarts(),
        clean_exit: leftovers.0.alive.is_empty()
            && leftovers.0.dead.is_empty()
            && leftovers.1.is_empty(),
    };
    let (beside, pred, sim) = (watched.floor.1.histogram(), &summaries.pred, &summaries.sim);
    let report = report::soak_report(&summaries, watched, &names);
    write_json(&out.join(run_folder::SOAK), &report)?;
    mtanet_report::latency_picture(
        &out.join("soak.png"),
        &[
            ("raw ping-pong round trip (beside the stack)", &beside),
            ("observation -> predictor", &pred.obs_to_predictor_hist),
            ("predictor compute", &pred.compute_hist),
            ("command -> simulator", &sim.cmd_to_sim_hist),
            ("simulator step", &sim.step_time_hist),
        ],
    )?;
    print_table(&report);
    if !report.clean_exit {
        bail!("the stack left iceoryx2 resources behind: {leftovers:?}");
    }
    Ok(())
}

/// The three services' exit summaries in the run folder `out`.
fn read_summaries(out: &Path) -> anyhow::Result<Summaries> {
    let of = |name: &str| out.join(run_folder::summary_of(name));
    Ok(Summaries {
        sim: read_json(&of("mta-simulator"))?,
        pred: read_json(&of("mta-predictor"))?,
        trainer: read_json(&of("mta-trainer"))?,
    })
}

/// The soak's run folder and stack, ready to start: the checked config, the track, the
/// starting checkpoint handed to the trainer, a private namespace.
struct Prepared {
    config: PathBuf,
    track: PathBuf,
    start_ck: Option<PathBuf>,
    ns: String,
    stack: StackConfig,
}

/// What watching the stack gave: each process's scheduling class and its samples.
struct Ran {
    classes: BTreeMap<String, String>,
    first: Samples,
    last: Samples,
}

impl Prepared {
    fn new(args: &SoakArgs, mode: &str) -> anyhow::Result<Self> {
        let out = &args.out;
        let (config, ck_dir) =
            runcfg::effective_config(args.config.as_deref(), Some(mode), false, out)?;
        let runcfg::Prepared {
            track,
            start_ck,
            stack,
            ..
        } = runcfg::prepare(
            &config,
            &ck_dir,
            out,
            args.track.as_deref(),
            args.checkpoint.as_deref(),
            true,
        )?;
        Ok(Self {
            config,
            track,
            start_ck,
            ns: unique_namespace("soak"),
            stack,
        })
    }

    /// The ping-pong runs at the simulator's and the predictor's real-time priorities.
    fn priorities(&self) -> Priorities {
        let prio = |binary: &str| {
            let p = self.stack.process.iter().find(|p| p.binary == binary);
            p.and_then(|p| p.realtime_priority)
        };
        Priorities {
            simulator: prio("mta-simulator"),
            predictor: prio("mta-predictor"),
        }
    }

    /// Starts the stack, each process ready before the next as `mta up` starts them, and
    /// watches it until the simulator is done.
    fn run_stack(&self, sup: &mut Supervisor, args: &SoakArgs) -> anyhow::Result<Ran> {
        let steps = (args.minutes * 60.0 / mtanet_ipc::CONTROL_PERIOD_S).round() as u64;
        let run = mtanet_launch::Run {
            config: Some(self.config.clone()),
            namespace: Some(self.ns.clone()),
            summaries: Some(args.out.clone()),
            track: Some(self.track.clone()),
            checkpoint: self.start_ck.clone(),
            max_steps: Some(steps),
            ..Default::default()
        };
        let started = sup.start_plan(
            mtanet_launch::plan(&self.stack, &run),
            Duration::from_secs(60),
        )?;
        let classes = started
            .into_iter()
            .map(|(name, pid)| (name, scheduling(pid)))
            .collect();
        let (first, last) = self.watch(sup, args, steps)?;
        Ok(Ran {
            classes,
            first,
            last,
        })
    }

    /// Samples each process's memory and files (once warmed up, and the latest) until the
    /// simulator is done; an error if a process fails or the run overstays.
    fn watch(
        &self,
        sup: &mut Supervisor,
        args: &SoakArgs,
        steps: u64,
    ) -> anyhow::Result<(Samples, Samples)> {
        let seconds = args.minutes * 60.0;
        let bar = ProgressBar::new(steps).with_style(
            ProgressStyle::with_template("[soak] {msg} {bar:40} {elapsed}/{duration}")
                .expect("valid template"),
        );
        bar.set_message(format!(
            "{}, {:.1} min",
            if args.lockstep {
                "lockstep"
            } else {
                "realtime"
            },
            args.minutes
        ));
        let sample = |sup: &Supervisor, into: &mut Samples| {
            for spec in &self.stack.process {
                if let Some(pid) = sup.pid(&spec.name) {
                    into.insert(spec.name.clone(), rss_and_fds(pid));
                }
            }
        };
        let slack = if args.lockstep { 4.0 } else { 1.5 };
        let limit = Duration::from_secs_f64(120.0 + seconds * slack);
        // Resource use once warmed up (a quarter in: the trainer has trained, probed and
        // published by then).
        let warm = Duration::from_secs_f64((seconds / 4.0).max(30.0));
        let (mut first, mut last) = (Samples::new(), Samples::new());
        let t0 = Instant::now();
        let outcome = loop {
            let failed = sup.poll()?.into_iter().find_map(|e| match e {
                Event::Done { name } if name == "simulator" => Some(Ok(())),
                Event::GaveUp { name, status } | Event::Failed { name, status, .. } => {
                    Some(Err(anyhow::anyhow!("{name} failed ({status})")))
                }
                _ => None,
            });
            if let Some(done) = failed {
                break done;
            }
            if first.is_empty() && t0.elapsed() > warm {
                sample(sup, &mut first);
            }
            sample(sup, &mut last);
            let elapsed = t0.elapsed();
            bar.set_position(
                (elapsed.as_secs_f64() / seconds * steps as f64).min(steps as f64) as u64,
            );
            if elapsed > limit {
                break Err(anyhow::anyhow!(
                    "the simulator was still running after {limit:?}"
                ));
            }
            std::thread::sleep(Duration::from_millis(250));
        };
        bar.finish_and_clear();
        outcome.map(|()| (first, last))
    }
}
