//! `mta soak`: runs the real three-process stack in a private namespace for N lockstep steps and
//! prints per-step latency percentiles (the "lockstep with the predictor" benchmark).

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use indicatif::ProgressBar;
use mtanet_ipc::latency::LatencySummary;
use mtanet_mta::stack::{
    Proc, leftover_shm, nodes, remove_namespace_files, unique_namespace, wait_for_alive,
};
use serde_json::{Value, json};

#[derive(Debug, clap::Args)]
pub struct SoakArgs {
    /// Lockstep steps to run (50 per simulated second).
    #[arg(long, default_value_t = 3000)]
    steps: u64,
    /// Track CSV (default: the oval).
    #[arg(long)]
    track: Option<PathBuf>,
    /// Stack config file passed to every process.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Directory for logs and summaries (default runs/soak-<time>).
    #[arg(long)]
    dir: Option<PathBuf>,
    /// Also write the combined result as JSON here.
    #[arg(long)]
    out: Option<PathBuf>,
}

pub fn run(args: SoakArgs) -> anyhow::Result<()> {
    let dir = args.dir.clone().unwrap_or_else(|| {
        let t = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        PathBuf::from(format!("runs/soak-{}", t.as_secs()))
    });
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let ns = unique_namespace("soak");
    let path = |n: &str| dir.join(n).to_string_lossy().into_owned();
    let mut common = vec!["--namespace".to_string(), ns.clone()];
    if let Some(c) = &args.config {
        common.extend(["--config".into(), c.to_string_lossy().into_owned()]);
    }
    let with = |extra: &[String]| -> Vec<String> { common.iter().chain(extra).cloned().collect() };

    let tr_args = with(&["--summary".into(), path("trainer.json")]);
    let pr_args = with(&["--summary".into(), path("predictor.json")]);
    let mut sim_args = with(&[
        "--summary".into(),
        path("simulator.json"),
        "--mode".into(),
        "lockstep".into(),
        "--expect-trainer".into(),
        // A latency soak runs as fast as the stack answers, not at the trainer's pace.
        "--pace".into(),
        "0".into(),
        "--max-steps".into(),
        args.steps.to_string(),
    ]);
    if let Some(t) = &args.track {
        sim_args.extend(["--track".into(), t.to_string_lossy().into_owned()]);
    }
    let spawn = |name: &str, a: &Vec<String>| Proc::try_spawn(name, a, &dir);
    let mut trainer = spawn("mta-trainer", &tr_args)?;
    let mut predictor = spawn("mta-predictor", &pr_args)?;
    if wait_for_alive(&ns, 2, Duration::from_secs(60)).alive.len() < 2 {
        bail!(
            "predictor/trainer did not come up:\n{}\n{}",
            predictor.log_tail(),
            trainer.log_tail()
        );
    }
    let start = Instant::now();
    let mut sim = spawn("mta-simulator", &sim_args)?;
    let bar =
        ProgressBar::new_spinner().with_message(format!("soak: {} lockstep steps", args.steps));
    let limit = Duration::from_secs_f64(60.0 + args.steps as f64 * 0.25);
    let status = loop {
        if let Some(s) = sim.try_wait_for(Duration::from_millis(100)) {
            break s;
        }
        bar.tick();
        if start.elapsed() > limit {
            bail!(
                "simulator still running after {limit:?}:\n{}",
                sim.log_tail()
            );
        }
    };
    bar.finish_and_clear();
    // No grace period: the trainer takes in what is still queued when it stops.
    for p in [&predictor, &trainer] {
        p.signal(libc::SIGTERM);
    }
    let peer_status = [
        predictor.wait(Duration::from_secs(20)),
        trainer.wait(Duration::from_secs(20)),
    ];
    if !status.success() || peer_status.iter().any(|s| !s.success()) {
        bail!(
            "a process failed (simulator {status}, predictor {}, trainer {}); logs in {}",
            peer_status[0],
            peer_status[1],
            dir.display()
        );
    }
    let read = |n: &str| -> anyhow::Result<Value> {
        let p = dir.join(n);
        Ok(serde_json::from_str(
            &std::fs::read_to_string(&p).with_context(|| format!("reading {}", p.display()))?,
        )?)
    };
    let (sim_s, pr_s, tr_s) = (
        read("simulator.json")?,
        read("predictor.json")?,
        read("trainer.json")?,
    );
    let leftovers = (nodes(&ns), leftover_shm(&ns));
    remove_namespace_files(&ns);

    let lat =
        |v: &Value| -> LatencySummary { serde_json::from_value(v.clone()).unwrap_or_default() };
    let steps = sim_s["steps"].as_u64().unwrap_or(0);
    // The simulator's own clock, from its wait for peers to its last step: without its process
    // start-up and the replay linger at exit.
    let wall = sim_s["wall_seconds"].as_f64().unwrap_or(f64::NAN);
    println!(
        "lockstep soak: {steps} steps in {wall:.2} s wall = {:.0} steps/s, real-time factor {:.1}x",
        steps as f64 / wall,
        sim_s["sim_seconds"].as_f64().unwrap_or(0.0) / wall
    );
    println!(
        "{:<34}{:>10}{:>10}{:>10}{:>10}{:>8}",
        "per step", "p50 us", "p99 us", "p99.9 us", "max us", "n"
    );
    for (name, v) in [
        ("round trip obs->cmd (simulator)", &sim_s["round_trip"]),
        ("whole step (simulator)", &sim_s["step_time"]),
        (
            "observation age at answer (pred.)",
            &pr_s["observation_age"],
        ),
        ("decision compute (predictor)", &pr_s["compute"]),
        ("plan, on its thread (predictor)", &pr_s["plan"]),
    ] {
        let l = lat(v);
        println!(
            "{name:<34}{:>10.1}{:>10.1}{:>10.1}{:>10.1}{:>8}",
            l.p50_us, l.p99_us, l.p999_us, l.max_us, l.count
        );
    }
    println!(
        "answered {}/{steps}, missed {}, stale {}, teacher {}; replay chunks {} sent, {} received, {} lost",
        sim_s["commands_received"],
        sim_s["missed_commands"],
        sim_s["stale_commands"],
        sim_s["teacher_steps"],
        sim_s["replay_chunks_sent"],
        tr_s["chunks_received"],
        tr_s["chunks_lost"]
    );
    let clean =
        leftovers.0.alive.is_empty() && leftovers.0.dead.is_empty() && leftovers.1.is_empty();
    println!(
        "left behind after SIGTERM: {}",
        if clean {
            "nothing".into()
        } else {
            format!("{leftovers:?}")
        }
    );
    let combined = json!({
        "steps": steps, "wall_seconds": wall, "steps_per_second": steps as f64 / wall,
        "simulator": sim_s, "predictor": pr_s, "trainer": tr_s, "clean_exit": clean,
    });
    if let Some(out) = &args.out {
        mtanet_ipc::report::write_json(out, &combined)
            .with_context(|| format!("writing {}", out.display()))?;
    }
    if !clean {
        bail!("the stack left iceoryx2 resources behind: {leftovers:?}");
    }
    Ok(())
}
