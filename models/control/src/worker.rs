//! Where plans are computed: inline (deterministic, for tests and offline driving) or on a thread
//! of its own (the predictor in real time: a plan may take longer than a control period, and the
//! control loop must answer every step at once).

use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::cost::Cost;
use crate::drive::{Drive, Wheels};
use crate::planner::{Imagination, Outcome, Planner};

/// One planning request: plan the segments after `segment`, from `start` rolled forward through
/// `committed` (the command sent for `segment`).
pub struct PlanJob<S> {
    pub segment: u64,
    pub start: S,
    pub committed: Wheels,
    pub cost: Cost,
    /// Forget the warm start and begin from holding this (a new episode, a switch to planning).
    pub restart: Option<Drive>,
    /// When the plan was asked for: its compute time counts from here, not from when a worker
    /// picked it up.
    pub asked: Instant,
    /// Real time: the plan must be done by then (see [`Planner::plan`]); `None`: the configured
    /// work runs to the end (lockstep).
    pub deadline: Option<Instant>,
}

pub struct PlanDone {
    /// The `segment` of the job; the plan's first segment is `segment + 1`.
    pub segment: u64,
    pub outcome: anyhow::Result<Outcome>,
    /// From the moment the plan was asked for to its result.
    pub compute: Duration,
}

/// At most one job outstanding at a time.
pub trait PlanService<S> {
    fn submit(&mut self, job: PlanJob<S>) -> anyhow::Result<()>;
    /// The outstanding job's result, waiting at most `timeout`; `None` if it is not done by then
    /// (or nothing is outstanding).
    fn wait(&mut self, timeout: Duration) -> Option<PlanDone>;
    /// True when no job is outstanding.
    fn idle(&self) -> bool;
}

fn run_job<I: Imagination>(
    planner: &mut Planner,
    imagination: &mut I,
    job: PlanJob<I::Start>,
) -> PlanDone {
    if let Some(d) = job.restart {
        planner.reset(d);
    }
    let before = Drive::from_wheels(job.committed);
    let outcome = imagination
        .start(job.start, job.committed)
        .and_then(|()| planner.plan(imagination, &job.cost, before, job.deadline));
    PlanDone {
        segment: job.segment,
        outcome,
        compute: job.asked.elapsed(),
    }
}

/// Plans at once, in the caller's thread.
pub struct Inline<I: Imagination> {
    pub planner: Planner,
    pub imagination: I,
    done: Option<PlanDone>,
}

impl<I: Imagination> Inline<I> {
    pub fn new(planner: Planner, imagination: I) -> Self {
        Self {
            planner,
            imagination,
            done: None,
        }
    }
}

impl<I: Imagination> PlanService<I::Start> for Inline<I> {
    fn submit(&mut self, job: PlanJob<I::Start>) -> anyhow::Result<()> {
        anyhow::ensure!(self.done.is_none(), "a plan is already outstanding");
        self.done = Some(run_job(&mut self.planner, &mut self.imagination, job));
        Ok(())
    }

    fn wait(&mut self, _timeout: Duration) -> Option<PlanDone> {
        self.done.take()
    }

    fn idle(&self) -> bool {
        self.done.is_none()
    }
}

enum ToWorker<I: Imagination> {
    Job(PlanJob<I::Start>),
    /// Runs on the worker's imagination (e.g. new weights for its copy of the model).
    Update(Box<dyn FnOnce(&mut I) + Send>),
}

/// Plans on a thread of its own. Dropping it stops the thread after the job in progress.
pub struct Threaded<I: Imagination> {
    to: Option<mpsc::Sender<ToWorker<I>>>,
    from: mpsc::Receiver<PlanDone>,
    outstanding: bool,
    thread: Option<JoinHandle<()>>,
}

impl<I> Threaded<I>
where
    I: Imagination + Send + 'static,
    I::Start: Send + 'static,
{
    /// `init` runs first on the new thread (e.g. to set libtorch's thread count there).
    pub fn spawn(
        mut planner: Planner,
        mut imagination: I,
        init: impl FnOnce() + Send + 'static,
    ) -> anyhow::Result<Self> {
        let (to, jobs) = mpsc::channel::<ToWorker<I>>();
        let (done_tx, from) = mpsc::channel();
        let thread = std::thread::Builder::new()
            .name("planner".into())
            .spawn(move || {
                init();
                let t0 = Instant::now();
                let sizes = planner.batch_sizes();
                match imagination.warm_up(&sizes, planner.config().horizon) {
                    Ok(()) => tracing::info!(?sizes, took = ?t0.elapsed(), "planner warmed up"),
                    Err(e) => tracing::warn!("planner warm-up failed: {e:#}"),
                }
                for msg in jobs {
                    match msg {
                        ToWorker::Job(job) => {
                            let done = run_job(&mut planner, &mut imagination, job);
                            if done_tx.send(done).is_err() {
                                return;
                            }
                        }
                        ToWorker::Update(f) => f(&mut imagination),
                    }
                }
            })?;
        Ok(Self {
            to: Some(to),
            from,
            outstanding: false,
            thread: Some(thread),
        })
    }

    /// Applies `f` to the worker's imagination before its next job.
    pub fn update(&self, f: impl FnOnce(&mut I) + Send + 'static) -> anyhow::Result<()> {
        self.to
            .as_ref()
            .expect("sender lives until drop")
            .send(ToWorker::Update(Box::new(f)))
            .map_err(|_| anyhow::anyhow!("the planner thread has stopped"))
    }
}

impl<I> PlanService<I::Start> for Threaded<I>
where
    I: Imagination + Send + 'static,
    I::Start: Send + 'static,
{
    fn submit(&mut self, job: PlanJob<I::Start>) -> anyhow::Result<()> {
        anyhow::ensure!(!self.outstanding, "a plan is already outstanding");
        self.to
            .as_ref()
            .expect("sender lives until drop")
            .send(ToWorker::Job(job))
            .map_err(|_| anyhow::anyhow!("the planner thread has stopped"))?;
        self.outstanding = true;
        Ok(())
    }

    fn wait(&mut self, timeout: Duration) -> Option<PlanDone> {
        if !self.outstanding {
            return None;
        }
        match self.from.recv_timeout(timeout) {
            Ok(done) => {
                self.outstanding = false;
                Some(done)
            }
            Err(mpsc::RecvTimeoutError::Timeout) => None,
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                self.outstanding = false;
                Some(PlanDone {
                    segment: u64::MAX,
                    outcome: Err(anyhow::anyhow!("the planner thread has stopped")),
                    compute: Duration::ZERO,
                })
            }
        }
    }

    fn idle(&self) -> bool {
        !self.outstanding
    }
}

impl<I: Imagination> Drop for Threaded<I> {
    fn drop(&mut self) {
        self.to = None; // ends the worker's loop
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
