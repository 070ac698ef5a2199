//! Load beside a run: a CPU hog on every core, or the run confined to some cores, so that a
//! real-time figure measured on a fast machine also holds for a slower or busier one; and the
//! CPU a figure was measured on.

use std::process::{Child, Command, Stdio};

use anyhow::{Context, bail};
use mtanet_ipc::sched;

/// One busy process per core at normal priority (`yes > /dev/null`), until dropped.
pub struct CpuHog(Vec<Child>);

impl CpuHog {
    pub fn start(processes: usize) -> anyhow::Result<Self> {
        let mut hog = Self(Vec::new());
        for _ in 0..processes {
            let child = Command::new("yes")
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .context("starting `yes` as a CPU hog")?;
            hog.0.push(child);
        }
        Ok(hog)
    }

    pub fn len(&self) -> usize {
        self.0.len()
    }
}

impl Drop for CpuHog {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Confines this process, and every process it starts from now on, to `cpus` ("0", "0-1",
/// "0,2").
pub fn confine(cpus: &str) -> anyhow::Result<()> {
    let mut set = Vec::new();
    for part in cpus.split(',') {
        let (a, b) = match part.split_once('-') {
            Some((a, b)) => (a, b),
            None => (part, part),
        };
        let parse = |v: &str| -> anyhow::Result<usize> {
            v.trim()
                .parse()
                .with_context(|| format!("--cpus {cpus:?}: {v:?} is not a CPU number"))
        };
        let (a, b) = (parse(a)?, parse(b)?);
        if a > b || b >= sched::MAX_CPUS {
            bail!("--cpus {cpus:?}: {part:?} is not a range of CPUs");
        }
        set.extend(a..=b);
    }
    sched::set_affinity(&set).with_context(|| format!("--cpus {cpus:?}: sched_setaffinity failed"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_cpu_lists_are_refused_with_the_list_named() {
        for bad in ["x", "1-0", "0-99999"] {
            let e = confine(bad).unwrap_err().to_string();
            assert!(e.contains(bad), "{e}");
        }
    }
}
