//! The local supervisor: starts the stack's processes (`[stack]`, `mtanet_ipc::stack`) in their
//! order, restarts one that fails (exits non-zero or is killed) with a doubling back-off and a
//! limit per time window, like the systemd units, and stops them all in reverse order with one
//! SIGTERM each. Every process's stderr goes to `<binary>.log` and, prefixed with its name, to the
//! combined `stack.log` in the run folder.

use std::collections::{BTreeMap, VecDeque};
use std::fs::File;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{ExitStatus, Stdio};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::Context;
use mtanet_ipc::stack::ProcessSpec;
use serde::Serialize;

use crate::notify::NotifySocket;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum State {
    NotStarted,
    Running,
    /// Failed; a restart is due at the back-off's end.
    Restarting,
    /// Exited successfully (not restarted).
    Done,
    /// Failed more often than the policy allows.
    GaveUp,
    Stopped,
}

/// What [`Supervisor::poll`] saw.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    Failed {
        name: String,
        status: String,
        restart_in: Duration,
    },
    Restarted {
        name: String,
        pid: u32,
        restarts: u32,
    },
    Done {
        name: String,
    },
    GaveUp {
        name: String,
        status: String,
    },
}

struct Child {
    spec: ProcessSpec,
    args: Vec<String>,
    process: Option<std::process::Child>,
    logger: Option<JoinHandle<()>>,
    state: State,
    restarts: u32,
    recent: VecDeque<Instant>,
    backoff: Duration,
    restart_at: Option<Instant>,
    started: Instant,
    notify: Option<NotifySocket>,
}

impl Child {
    /// Takes in the exit of a running process: done, given up (a success, no restart policy,
    /// or too many failures in the policy's window), or to restart after its back-off.
    fn exited(&mut self, status: ExitStatus, now: Instant) -> Event {
        self.process = None;
        if let Some(l) = self.logger.take() {
            let _ = l.join();
        }
        let name = self.spec.name.clone();
        if status.success() {
            self.state = State::Done;
            return Event::Done { name };
        }
        let policy = &self.spec.restart;
        let window = Duration::from_secs_f64(policy.window_s);
        while self
            .recent
            .front()
            .is_some_and(|t| now.duration_since(*t) > window)
        {
            self.recent.pop_front();
        }
        if !policy.on_failure || self.recent.len() as u32 >= policy.limit {
            self.state = State::GaveUp;
            let status = describe(status);
            return Event::GaveUp { name, status };
        }
        // A process that had run well past the longest back-off starts over short.
        if self.started.elapsed() > Duration::from_secs_f64(2.0 * policy.max_backoff_s) {
            self.backoff = Duration::from_secs_f64(policy.backoff_s);
        }
        self.recent.push_back(now);
        self.state = State::Restarting;
        self.restart_at = Some(now + self.backoff);
        let restart_in = self.backoff;
        self.backoff = (self.backoff * 2).min(Duration::from_secs_f64(policy.max_backoff_s));
        Event::Failed {
            name,
            status: describe(status),
            restart_in,
        }
    }
}

pub struct Supervisor {
    dir: PathBuf,
    combined: Arc<Mutex<File>>,
    children: Vec<Child>,
}

fn describe(s: ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (s.code(), s.signal()) {
        (Some(c), _) => format!("exit code {c}"),
        (_, Some(sig)) => format!("signal {sig}"),
        _ => s.to_string(),
    }
}

impl Supervisor {
    /// Logs go to `dir` (`stack.log` combined, `<binary>.log` each).
    pub fn new(dir: &Path) -> anyhow::Result<Self> {
        let combined = File::create(dir.join("stack.log")).context("creating stack.log")?;
        Ok(Self {
            dir: dir.to_owned(),
            combined: Arc::new(Mutex::new(combined)),
            children: Vec::new(),
        })
    }

    /// Adds a process (not started) with its whole argument list.
    pub fn add(&mut self, spec: &ProcessSpec, args: Vec<String>) -> anyhow::Result<()> {
        let log = self.log_path(&spec.binary);
        File::create(&log).with_context(|| format!("creating {}", log.display()))?;
        self.children.push(Child {
            spec: spec.clone(),
            args,
            process: None,
            logger: None,
            state: State::NotStarted,
            restarts: 0,
            recent: VecDeque::new(),
            backoff: Duration::from_secs_f64(spec.restart.backoff_s),
            restart_at: None,
            started: Instant::now(),
            notify: None,
        });
        Ok(())
    }

    pub fn log_path(&self, binary: &str) -> PathBuf {
        self.dir.join(format!("{binary}.log"))
    }

    fn note(&self, line: &str) {
        if let Ok(mut f) = self.combined.lock() {
            let _ = writeln!(f, "[supervisor] {line}");
        }
    }

    fn index(&self, name: &str) -> anyhow::Result<usize> {
        self.children
            .iter()
            .position(|c| c.spec.name == name)
            .with_context(|| format!("no process named {name:?} in the stack"))
    }

    /// Adds the plan's processes and starts them in its order, each ready (READY=1) before the
    /// next starts: the simulator creates the services the others open. If one does not get
    /// ready, those started are stopped and its error returned. Each name with its pid.
    pub fn start_plan(
        &mut self,
        launches: Vec<crate::plan::Launch>,
        ready: Duration,
    ) -> anyhow::Result<Vec<(String, u32)>> {
        let names: Vec<String> = launches.iter().map(|l| l.spec.name.clone()).collect();
        for l in launches {
            self.add(&l.spec, l.args)?;
        }
        let mut started = Vec::new();
        for name in names {
            let pid = self.start(&name)?;
            if let Err(e) = self.await_ready(&name, ready) {
                self.stop_all(Duration::from_secs(20));
                return Err(e);
            }
            started.push((name, pid));
        }
        Ok(started)
    }

    /// Starts (or restarts) process `name` now.
    pub fn start(&mut self, name: &str) -> anyhow::Result<u32> {
        let i = self.index(name)?;
        let log_path = self.log_path(&self.children[i].spec.binary);
        let combined = Arc::clone(&self.combined);
        let c = &mut self.children[i];
        let notify = NotifySocket::bind(&c.spec.name)?;
        let mut cmd = crate::plan::command(&c.spec.binary, &c.args, c.spec.realtime_priority, true);
        // The process reports it on the stats topic (`mta status`).
        cmd.env(mtanet_ipc::stats::RESTARTS_ENV, c.restarts.to_string())
            // Its READY=1 (see `await_ready`); the units get the same from systemd.
            .env("NOTIFY_SOCKET", notify.path())
            .stderr(Stdio::piped());
        let mut child = cmd
            .spawn()
            .with_context(|| crate::plan::missing_hint(&c.spec.binary))?;
        let pid = child.id();
        if let Some(prio) = c.spec.realtime_priority {
            if !mtanet_ipc::sched::is_fifo(pid) {
                tracing::warn!(process = %name, prio, "could not give it SCHED_FIFO (needs root or CAP_SYS_NICE); it runs with the normal scheduler");
            }
        }
        let stderr = child.stderr.take().expect("stderr is piped");
        let tag = c.spec.name.clone();
        let mut own = std::fs::OpenOptions::new().append(true).open(&log_path)?;
        c.logger = Some(std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines() {
                let Ok(line) = line else { break };
                let _ = writeln!(own, "{line}");
                if let Ok(mut f) = combined.lock() {
                    let _ = writeln!(f, "[{tag}] {line}");
                }
            }
        }));
        c.process = Some(child);
        c.notify = Some(notify);
        c.state = State::Running;
        c.started = Instant::now();
        c.restart_at = None;
        self.note(&format!("started {name} (pid {pid})"));
        Ok(pid)
    }

    /// Waits until process `name` (started) says READY=1 on its notification socket: its ports
    /// are open and its loop is about to run. An error if it exits first or takes `timeout`.
    pub fn await_ready(&mut self, name: &str, timeout: Duration) -> anyhow::Result<()> {
        let i = self.index(name)?;
        let log = self.log_path(&self.children[i].spec.binary);
        let c = &mut self.children[i];
        let deadline = Instant::now() + timeout;
        loop {
            let sock = c.notify.as_ref().context("not started")?;
            if sock.ready_within(Duration::from_millis(50))? {
                return Ok(());
            }
            if let Some(s) = c.process.as_mut().and_then(|p| p.try_wait().ok().flatten()) {
                anyhow::bail!(
                    "{name} exited ({}) before it was ready; see {}",
                    describe(s),
                    log.display()
                );
            }
            anyhow::ensure!(
                Instant::now() < deadline,
                "{name} was not ready within {timeout:?}; see {}",
                log.display()
            );
        }
    }

    /// Reaps exited processes and restarts failed ones whose back-off is over. Never blocks.
    pub fn poll(&mut self) -> anyhow::Result<Vec<Event>> {
        let mut events = Vec::new();
        let now = Instant::now();
        let mut to_start = Vec::new();
        for c in &mut self.children {
            match c.state {
                State::Running => {
                    let Some(status) = c.process.as_mut().and_then(|p| p.try_wait().ok().flatten())
                    else {
                        continue;
                    };
                    events.push(c.exited(status, now));
                }
                State::Restarting if c.restart_at.is_some_and(|t| now >= t) => {
                    to_start.push(c.spec.name.clone());
                }
                _ => {}
            }
        }
        for e in &events {
            self.note(&format!("{e:?}"));
        }
        for name in to_start {
            let i = self.index(&name)?;
            self.children[i].restarts += 1;
            let pid = self.start(&name)?;
            let restarts = self.children[i].restarts;
            self.note(&format!("restarted {name} (pid {pid}, restart {restarts})"));
            events.push(Event::Restarted {
                name,
                pid,
                restarts,
            });
        }
        Ok(events)
    }

    pub fn state(&self, name: &str) -> Option<State> {
        self.children
            .iter()
            .find(|c| c.spec.name == name)
            .map(|c| c.state)
    }

    pub fn pid(&self, name: &str) -> Option<u32> {
        self.children
            .iter()
            .find(|c| c.spec.name == name)
            .and_then(|c| c.process.as_ref().map(|p| p.id()))
    }

    /// Restarts per process so far.
    pub fn restarts(&self) -> BTreeMap<String, u32> {
        self.children
            .iter()
            .map(|c| (c.spec.name.clone(), c.restarts))
            .collect()
    }

    /// Stops every running process, last started first: one SIGTERM, then SIGKILL after
    /// `timeout`. Returns how each one ended (`None`: had to be killed).
    pub fn stop_all(&mut self, timeout: Duration) -> Vec<(String, Option<String>)> {
        let mut out = Vec::new();
        for c in self.children.iter_mut().rev() {
            c.restart_at = None;
            let Some(p) = c.process.as_mut() else {
                if c.state == State::Restarting {
                    c.state = State::Stopped;
                }
                continue;
            };
            let status = mtanet_ipc::child::stop(p, timeout);
            c.process = None;
            if let Some(l) = c.logger.take() {
                let _ = l.join();
            }
            c.state = State::Stopped;
            out.push((c.spec.name.clone(), status.map(describe)));
        }
        out.reverse();
        out
    }
}

impl Drop for Supervisor {
    fn drop(&mut self) {
        for c in &mut self.children {
            if let Some(p) = c.process.as_mut() {
                let _ = p.kill();
                let _ = p.wait();
            }
        }
    }
}
