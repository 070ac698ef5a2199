//! One run: `mta up --lockstep` as a child process in a namespace of its own, its output in a
//! log beside the run folder. The child gets its own process group, so a Ctrl-C at the
//! terminal reaches only `mta experiment`, which passes one SIGTERM on (a second signal would
//! make `mta up` exit at once and leave its stack behind).

use mtanet_summaries::run_folder;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

use anyhow::{Context, bail};
use std::os::unix::process::CommandExt;

/// A run in progress, for the progress bar and for stopping it.
#[derive(Debug, Clone)]
pub struct Current {
    pub label: String,
    pub dir: PathBuf,
    pub sim_seconds: f64,
    pid: u32,
}

/// The runs in progress, one slot per job.
pub struct Live {
    slots: Mutex<Vec<Option<Current>>>,
}

impl Live {
    pub fn new(jobs: usize) -> Self {
        Self {
            slots: Mutex::new(vec![None; jobs]),
        }
    }

    pub fn current(&self) -> Vec<Current> {
        self.lock().iter().flatten().cloned().collect()
    }

    /// SIGTERM to every run in progress (each `mta up` stops its stack and writes its report).
    pub fn stop_all(&self) {
        for c in self.lock().iter().flatten() {
            // The slot is cleared before the child is reaped (see `up`): the pid is still ours.
            mtanet_ipc::child::signal(c.pid, mtanet_ipc::child::Signal::TERM);
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<Option<Current>>> {
        self.slots.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// What to run.
pub struct Run<'a> {
    /// The cell's label and the run's name, for the progress bar.
    pub label: String,
    pub track: &'a Path,
    pub sim_seconds: f64,
    pub out: PathBuf,
    pub config: &'a Path,
    /// Evaluation: drive from this checkpoint with no learning.
    pub checkpoint: Option<&'a Path>,
    /// The reactive rule alone (`mta up --rule`).
    pub rule: bool,
    /// The run's own iceoryx2 namespace.
    pub namespace: String,
}

impl Run<'_> {
    /// Where the run's `mta up` output goes: beside its folder.
    pub fn log(&self) -> PathBuf {
        self.out.with_extension("log")
    }
}

/// Runs `run` in job slot `slot` of `live`; an error names the log. A run that ends early
/// (stopped, or a stack that gave up) is an error too: its figures would not be comparable.
pub fn up(run: &Run, live: &Live, slot: usize) -> anyhow::Result<()> {
    let log = run.log();
    let file =
        std::fs::File::create(&log).with_context(|| format!("creating {}", log.display()))?;
    let ns = &run.namespace;
    let mut cmd = Command::new(mtanet_launch::stack::bin_dir().join("mta"));
    cmd.arg("up")
        .arg("--lockstep")
        .arg("--sim-seconds")
        .arg(run.sim_seconds.to_string())
        .arg("--track")
        .arg(run.track)
        .arg("--out")
        .arg(&run.out)
        .arg("--config")
        .arg(run.config)
        .arg("--namespace")
        .arg(ns);
    if let Some(ck) = run.checkpoint {
        cmd.arg("--checkpoint").arg(ck).arg("--no-learning");
    }
    if run.rule {
        cmd.arg("--rule");
    }
    cmd.stdout(file.try_clone()?).stderr(file).process_group(0);
    let mut child = cmd.spawn().context("starting mta up")?;
    live.lock()[slot] = Some(Current {
        label: run.label.clone(),
        dir: run.out.clone(),
        sim_seconds: run.sim_seconds,
        pid: child.id(),
    });
    // Wait without reaping, clear the slot, then reap: `stop_all` never signals a pid that
    // could already belong to another process.
    let waited = wait_unreaped(child.id());
    live.lock()[slot] = None;
    let status = child.wait().context("waiting for mta up")?;
    waited?;
    mtanet_launch::stack::remove_namespace_files(ns);
    if !status.success() {
        bail!("mta up failed ({status}); see {}", log.display());
    }
    let report: mtanet_report::Report =
        mtanet_summaries::files::read_json(&run.out.join(run_folder::REPORT))?;
    let want = (run.sim_seconds / mtanet_ipc::CONTROL_PERIOD_S).round() as u64;
    if report.steps < want {
        bail!(
            "the run stopped at step {} of {want}; see {}",
            report.steps,
            log.display()
        );
    }
    Ok(())
}

fn wait_unreaped(pid: u32) -> anyhow::Result<()> {
    use rustix::process::{Pid, WaitId, WaitIdOptions, waitid};
    let pid = Pid::from_raw(pid as i32).context("waiting for mta up: pid 0")?;
    let flags = WaitIdOptions::EXITED | WaitIdOptions::NOWAIT;
    loop {
        match waitid(WaitId::Pid(pid), flags) {
            Ok(_) => return Ok(()),
            Err(rustix::io::Errno::INTR) => continue,
            Err(e) => return Err(std::io::Error::from(e)).context("waiting for mta up"),
        }
    }
}

/// Simulated seconds a run has reached, from its `progress.csv` (a row a second); 0 before the
/// first row.
pub fn sim_seconds_reached(dir: &Path) -> f64 {
    use mtanet_summaries::rows::{ProgressRow, read};
    read::<ProgressRow>(&dir.join(run_folder::PROGRESS))
        .ok()
        .and_then(|rows| rows.last().map(|r| r.sim_s))
        .unwrap_or(0.0)
}
