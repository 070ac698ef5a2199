//! The system tests' processes: the real binaries started in a private iceoryx2 namespace,
//! stopped with signals, and killed on drop so that a failing test never leaves a stack running.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Child, ExitStatus};
use std::time::{Duration, Instant};

use mtanet_ipc::node::NodeCensus;
use mtanet_launch::stack::{bin_dir, nodes};

pub use mtanet_ipc::child::{Signal, signal};

/// A path as a command-line argument (the tests' temporary paths are UTF-8).
pub fn arg(p: &Path) -> &str {
    p.to_str().expect("a UTF-8 path")
}

/// Path of a workspace binary; panics with the command to build it if it is missing.
pub fn bin(name: &str) -> PathBuf {
    let p = bin_dir().join(name);
    assert!(
        p.exists(),
        "{} is not built: run `cargo build --release --workspace --bins` first (./ops/test.sh does)",
        p.display()
    );
    p
}

/// A child process that is killed (SIGKILL) if still running when dropped.
pub struct Proc {
    pub name: String,
    child: Child,
    pub log: PathBuf,
}

impl Proc {
    /// Starts `bin(name)` with `args`; stderr goes to `<log_dir>/<name>.log`. Panics on failure.
    pub fn spawn<S: AsRef<OsStr>>(name: &str, args: &[S], log_dir: &Path) -> Proc {
        Self::try_spawn(name, args, log_dir).unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`Proc::spawn`] returning an error instead of panicking.
    pub fn try_spawn<S: AsRef<OsStr>>(
        name: &str,
        args: &[S],
        log_dir: &Path,
    ) -> std::io::Result<Proc> {
        Self::try_spawn_with(name, args, log_dir, false)
    }

    /// [`Proc::try_spawn`], optionally in a process group of its own: a Ctrl-C at the terminal
    /// then reaches only the parent, which stops the child with one signal (a second one
    /// would make it exit at once, skipping its clean-up).
    pub fn try_spawn_with<S: AsRef<OsStr>>(
        name: &str,
        args: &[S],
        log_dir: &Path,
        own_group: bool,
    ) -> std::io::Result<Proc> {
        let log = log_dir.join(format!("{name}.log"));
        let child = mtanet_launch::command(name, args, None, own_group)
            .stderr(std::fs::File::create(&log)?)
            .spawn()
            .map_err(|e| {
                let hint = mtanet_launch::missing_hint(name);
                std::io::Error::new(e.kind(), format!("{hint}: {e}"))
            })?;
        Ok(Proc {
            name: name.into(),
            child,
            log,
        })
    }

    pub fn pid(&self) -> i32 {
        self.child.id() as i32
    }

    pub fn signal(&self, sig: Signal) {
        signal(self.child.id(), sig);
    }

    /// Waits for exit up to `timeout`; panics with the log tail if it does not exit.
    pub fn wait(&mut self, timeout: Duration) -> ExitStatus {
        self.try_wait_for(timeout).unwrap_or_else(|| {
            let _ = self.child.kill();
            panic!(
                "{} did not exit within {timeout:?}; log:\n{}",
                self.name,
                self.log_tail()
            )
        })
    }

    /// Waits for exit up to `timeout`; `None` if it is still running.
    pub fn try_wait_for(&mut self, timeout: Duration) -> Option<ExitStatus> {
        mtanet_ipc::child::wait_for(&mut self.child, timeout)
    }

    pub fn is_running(&mut self) -> bool {
        self.child.try_wait().expect("try_wait").is_none()
    }

    pub fn log_tail(&self) -> String {
        let text = std::fs::read_to_string(&self.log).unwrap_or_default();
        let lines: Vec<&str> = text.lines().collect();
        lines[lines.len().saturating_sub(30)..].join("\n")
    }

    /// Waits until the log contains `needle`; false after `timeout`.
    pub fn wait_for_log(&self, needle: &str, timeout: Duration) -> bool {
        let deadline = Instant::now() + timeout;
        while Instant::now() < deadline {
            if std::fs::read_to_string(&self.log)
                .unwrap_or_default()
                .contains(needle)
            {
                return true;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        false
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Waits until `n` nodes of the namespace are alive.
pub fn wait_for_alive(ns: &str, n: usize, timeout: Duration) -> NodeCensus {
    let deadline = Instant::now() + timeout;
    loop {
        let c = nodes(ns);
        if c.alive.len() >= n || Instant::now() > deadline {
            return c;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Waits until `done` holds, checking every 20 ms; panics naming `what` after `timeout`.
pub fn wait_until(what: &str, timeout: Duration, mut done: impl FnMut() -> bool) {
    let deadline = Instant::now() + timeout;
    while !done() {
        assert!(Instant::now() < deadline, "not within {timeout:?}: {what}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Reads a JSON file the stack wrote, typed (a service's `Summary`, or `serde_json::Value` for
/// a file whose type lives in a binary); panics naming the file and the field it cannot read.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> T {
    mtanet_summaries::files::read_json(path).unwrap_or_else(|e| panic!("{e}"))
}
