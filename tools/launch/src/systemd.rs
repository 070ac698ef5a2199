//! `mta systemd`: renders the systemd units of the stack from `[stack]`, the same description
//! `mta up` supervises: one `mtanet-<name>.service` per process (in start order, each `After=`
//! the one before), and `mtanet.target` wanting them all. `ops/install-systemd.sh` calls it.

use std::fmt::Write as _;
use std::path::PathBuf;

use crate::plan::{Launch, Run, plan};
use anyhow::Context;
use mtanet_ipc::config::ConfigFile;
use mtanet_ipc::stack::{ProcessSpec, StackConfig};

#[derive(Debug, clap::Args)]
pub struct SystemdArgs {
    /// Folder the units are written to (e.g. /etc/systemd/system).
    #[arg(long)]
    dest: PathBuf,
    /// The stack config the services run with (made absolute).
    #[arg(long)]
    config: PathBuf,
    /// Folder of the built binaries (default: this executable's).
    #[arg(long)]
    bin: Option<PathBuf>,
    /// User the services run as.
    #[arg(long)]
    user: String,
}

fn unit(
    launch: &Launch,
    after: Option<&ProcessSpec>,
    nice: Option<i32>,
    bin: &str,
    config: &str,
    user: &str,
) -> String {
    let spec = &launch.spec;
    let r = &spec.restart;
    let mut u = String::new();
    let _ = writeln!(u, "# Rendered by `mta systemd` from [stack] in {config}.");
    let _ = writeln!(
        u,
        "[Unit]\nDescription={}\nPartOf=mtanet.target",
        spec.description
    );
    if let Some(a) = after {
        let _ = writeln!(u, "After=mtanet-{}.service", a.name);
    }
    // The first start counts too: `limit` restarts within the window.
    let _ = writeln!(
        u,
        "StartLimitIntervalSec={}\nStartLimitBurst={}\n",
        r.window_s,
        r.limit + 1
    );
    let _ = writeln!(u, "[Service]");
    let _ = writeln!(
        u,
        "# READY=1 once its iceoryx2 ports exist; WATCHDOG=1 from the service loop."
    );
    let _ = writeln!(u, "Type=notify\nNotifyAccess=main");
    // The program: specifiers are expanded there, variables are not (`$` stays as written).
    let mut exec = quoted(&format!("{bin}/{}", spec.binary), false);
    for a in &launch.args {
        exec.push(' ');
        exec.push_str(&quoted(a, true));
    }
    let _ = writeln!(u, "ExecStart={exec}\nWatchdogSec={}", spec.watchdog_s);
    scheduling(&mut u, spec, nice);
    // systemd 252 has no doubling back-off (RestartSteps= came in 254): the first delay is used.
    let restart = if r.on_failure { "on-failure" } else { "no" };
    let _ = writeln!(u, "Restart={restart}\nRestartSec={}", r.backoff_s);
    let _ = writeln!(
        u,
        "# One SIGTERM ends the loop and releases shared memory; a second would force an immediate exit."
    );
    let _ = writeln!(
        u,
        "KillSignal=SIGTERM\nKillMode=mixed\nTimeoutStopSec=15\nUser={user}"
    );
    let _ = writeln!(
        u,
        "# All mtanet processes must share /dev/shm and /tmp/iceoryx2: never PrivateTmp=, RemoveIPC=,"
    );
    let _ = writeln!(
        u,
        "# DynamicUser= (they would hide or delete the shared memory under the peers).\n"
    );
    let _ = writeln!(u, "[Install]\nWantedBy=mtanet.target");
    u
}

/// The scheduling class `mta up` gives the process (docs/measurements.md, "Sharing the CPU").
fn scheduling(u: &mut String, spec: &ProcessSpec, nice: Option<i32>) {
    match spec.realtime_priority {
        Some(prio) => {
            let _ = writeln!(
                u,
                "# On the 50 Hz path: real-time scheduling. The predictor's planner thread runs\n# SCHED_FIFO below it ([predictor] planner_priority): plans before any normal program."
            );
            let _ = writeln!(u, "CPUSchedulingPolicy=fifo\nCPUSchedulingPriority={prio}");
        }
        None => {
            let _ = writeln!(
                u,
                "# Normal scheduler, at its own niceness ([trainer] nice; the trainer takes nice_beside_fifo\n# itself when its user may run SCHED_FIFO, as the 50 Hz path then does): after the planner."
            );
            let _ = writeln!(u, "CPUSchedulingPolicy=other");
            if let Some(n) = nice {
                let _ = writeln!(u, "Nice={n}");
            }
        }
    }
}

/// A word as systemd's ExecStart= reads it: `%` (a specifier) doubled, `$` (a variable, expanded
/// in the arguments only) doubled there, and quoted where it holds a space or a quote (a
/// checkout under "My Robots/100%" works).
fn quoted(a: &str, argument: bool) -> String {
    let a = a.replace('%', "%%");
    let a = if argument { a.replace('$', "$$") } else { a };
    if a.is_empty() || a.contains([' ', '\t', '"', '\'', '\\']) {
        format!("\"{}\"", a.replace('\\', "\\\\").replace('"', "\\\""))
    } else {
        a
    }
}

pub fn run(args: SystemdArgs) -> anyhow::Result<()> {
    let config = std::path::absolute(&args.config)?;
    let file = ConfigFile::load(Some(&config))?;
    let stack: StackConfig = file.section("stack")?;
    stack.validate().map_err(|e| file.invalid("[stack]", e))?;
    let trainer: mtanet_trainer::config::TrainerConfig = file.section("trainer")?;
    let bin = args.bin.unwrap_or_else(crate::stack::bin_dir);
    let bin = std::path::absolute(&bin)?;
    std::fs::create_dir_all(&args.dest)
        .with_context(|| format!("creating {}", args.dest.display()))?;
    let (bin_s, cfg_s) = (bin.to_string_lossy(), config.to_string_lossy());
    let mut wants = Vec::new();
    // A unit runs the stack the config describes: its namespace, track and no summary files.
    let run = Run {
        config: Some(config.clone()),
        ..Default::default()
    };
    for (i, launch) in plan(&stack, &run).iter().enumerate() {
        let spec = &launch.spec;
        let exe = bin.join(&spec.binary);
        anyhow::ensure!(
            exe.exists(),
            "{} missing: build with cargo build --release --workspace --bins",
            exe.display()
        );
        let after = i.checked_sub(1).map(|j| &stack.process[j]);
        let name = format!("mtanet-{}.service", spec.name);
        let path = args.dest.join(&name);
        // The trainer lowers its own priority too; the unit says the same.
        let nice = (spec.binary == "mta-trainer").then_some(trainer.nice);
        let text = unit(launch, after, nice, &bin_s, &cfg_s, &args.user);
        mtanet_summaries::files::write_bytes(&path, text.as_bytes())?;
        println!("installed {}", path.display());
        wants.push(name);
    }
    let target = format!(
        "[Unit]\nDescription=mtanet stack ({} over iceoryx2)\nWants={}\n\n[Install]\nWantedBy=multi-user.target\n",
        stack
            .process
            .iter()
            .map(|p| p.name.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        wants.join(" ")
    );
    let path = args.dest.join("mtanet.target");
    mtanet_summaries::files::write_bytes(&path, target.as_bytes())?;
    println!("installed {}", path.display());
    Ok(())
}
