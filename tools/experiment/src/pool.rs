//! Runs the cells still to do, `jobs` side by side (each run in its own iceoryx2 namespace),
//! under one progress bar: cells done of all, and each running cell's simulated time. On
//! SIGINT/SIGTERM the runs in progress are stopped and no further cell starts.

use std::collections::VecDeque;
use std::path::Path;
use std::sync::Mutex;
use std::sync::mpsc;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};
use mtanet_ipc::shutdown::Shutdown;

use crate::cell::CellError;
use crate::matrix::{Cell, CellRecord};
use crate::run::{Live, sim_seconds_reached};

pub type Outcome = Result<CellRecord, CellError>;

/// Runs `todo` (indices into `cells`); returns each one's outcome as it finished. Cells not
/// started because of a stop are left out.
pub fn run(
    cells: &[Cell],
    todo: Vec<usize>,
    done_before: usize,
    jobs: usize,
    heldout: &Path,
    shutdown: &Shutdown,
) -> Vec<(usize, Outcome)> {
    let jobs = jobs.clamp(1, todo.len().max(1));
    let bar = ProgressBar::new(cells.len() as u64).with_style(
        ProgressStyle::with_template(
            "[experiment] {pos}/{len} cells {bar:30} {elapsed_precise} {msg}",
        )
        .expect("a valid template"),
    );
    bar.set_position(done_before as u64);
    let queue = Mutex::new(todo.into_iter().collect::<VecDeque<_>>());
    let live = Live::new(jobs);
    let (tx, rx) = mpsc::channel();
    let mut outcomes = Vec::new();
    std::thread::scope(|s| {
        for slot in 0..jobs {
            let (tx, queue, live) = (tx.clone(), &queue, &live);
            s.spawn(move || {
                while let Some(i) = next(queue) {
                    let out = crate::cell::run(&cells[i], heldout, live, slot);
                    if tx.send((i, out)).is_err() {
                        return;
                    }
                }
            });
        }
        drop(tx);
        let mut stopping = false;
        loop {
            match rx.recv_timeout(Duration::from_millis(500)) {
                Ok((i, out)) => {
                    report(&bar, &cells[i], &out, shutdown.requested());
                    bar.inc(1);
                    outcomes.push((i, out));
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
                Err(mpsc::RecvTimeoutError::Timeout) => {}
            }
            if shutdown.requested() && !stopping {
                stopping = true;
                bar.println("[experiment] stopping: the runs in progress end, no new cell starts");
                queue.lock().unwrap_or_else(|p| p.into_inner()).clear();
                live.stop_all();
            }
            bar.set_message(running(&live));
        }
    });
    bar.finish_and_clear();
    outcomes
}

fn next(queue: &Mutex<VecDeque<usize>>) -> Option<usize> {
    queue.lock().unwrap_or_else(|p| p.into_inner()).pop_front()
}

/// One line per finished cell, above the bar.
fn report(bar: &ProgressBar, cell: &Cell, out: &Outcome, stopping: bool) {
    bar.suspend(|| match out {
        Ok(rec) => {
            tracing::info!(cell = %cell.label(), wall_s = rec.wall_seconds.round(), "cell done")
        }
        // Stopped by us: not a failure, it runs again next time.
        Err(e) if stopping => {
            tracing::warn!(cell = %cell.label(), "cell stopped: {:#}", e.error)
        }
        Err(e) => {
            let log = e.log.as_ref().map(|l| l.display().to_string());
            let log = log.unwrap_or_default();
            tracing::error!(cell = %cell.label(), log, "cell failed: {:#}", e.error)
        }
    });
}

/// `paper/0 learn 312/1200 s | flat/0 learn 140/1200 s`
fn running(live: &Live) -> String {
    live.current()
        .iter()
        .map(|c| {
            format!(
                "{} {:.0}/{:.0} s",
                c.label,
                sim_seconds_reached(&c.dir),
                c.sim_seconds
            )
        })
        .collect::<Vec<_>>()
        .join(" | ")
}
