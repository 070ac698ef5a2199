//! The one launch plan and the one spawner. Each process's argument list is built here from
//! `[stack]` and what the run asks for; `mta up`, `mta soak`, `mta systemd` and the system tests
//! all start the stack from [`plan`], and every process of the stack is started by [`command`].

use std::ffi::OsStr;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use mtanet_ipc::stack::{ProcessSpec, RestartPolicy, StackConfig};

use crate::stack::bin_dir;

/// What a run asks of the stack beyond its `[stack]` section. Every field is optional: the
/// default is the stack as `[stack]` and the config's own sections describe it (a systemd unit).
#[derive(Debug, Clone, Default)]
pub struct Run {
    /// The config file every process reads.
    pub config: Option<PathBuf>,
    /// A private iceoryx2 namespace; `None`: the config's `[ipc] namespace`.
    pub namespace: Option<String>,
    /// Folder where each process writes its summary, `<binary>.json`, when it stops.
    pub summaries: Option<PathBuf>,
    /// The track the simulator drives and the trainer probes the model on.
    pub track: Option<PathBuf>,
    /// Weights the predictor drives from at once, not after the trainer's first publish.
    pub checkpoint: Option<PathBuf>,
    /// The simulator's per-step trace (CSV).
    pub trace: Option<PathBuf>,
    /// Steps after which the simulator ends the run.
    pub max_steps: Option<u64>,
    /// Leave the trainer out (drive a fixed checkpoint).
    pub no_trainer: bool,
    /// Record the run's topics (`mta record`).
    pub record: Option<Recording>,
}

/// What a recorder of the run writes.
#[derive(Debug, Clone)]
pub struct Recording {
    pub out: PathBuf,
    /// Its summary (`RecordSummary` as JSON).
    pub summary: PathBuf,
    /// The weights' checkpoint bytes too (~1 MB each), not only their headers.
    pub weight_blobs: bool,
}

/// The recorder's name in a plan.
pub const RECORDER: &str = "recorder";

/// One process of the plan: its entry of `[stack]` and its whole argument list.
#[derive(Debug, Clone)]
pub struct Launch {
    pub spec: ProcessSpec,
    pub args: Vec<String>,
}

/// The processes of `stack` in start order, each with its arguments for `run`; a recorder
/// first, so it hears the first observation (and, stopped last, the last).
pub fn plan(stack: &StackConfig, run: &Run) -> Vec<Launch> {
    let recorder = run.record.as_ref().map(|_| {
        let spec = ProcessSpec {
            name: RECORDER.into(),
            binary: "mta".into(),
            description: "mtanet recorder".into(),
            args: vec![],
            // A recorder that failed costs the recording, not the run.
            restart: RestartPolicy {
                on_failure: false,
                ..Default::default()
            },
            watchdog_s: 10,
            realtime_priority: None,
        };
        Launch {
            args: args(&spec, run),
            spec,
        }
    });
    let stack = stack
        .process
        .iter()
        .filter(|spec| !(run.no_trainer && spec.binary == "mta-trainer"))
        .map(|spec| Launch {
            spec: spec.clone(),
            args: args(spec, run),
        });
    recorder.into_iter().chain(stack).collect()
}

/// The arguments of process `binary` in the default stack for `run` (the system tests start
/// processes one at a time, adding what a test needs).
pub fn args_of(binary: &str, run: &Run) -> Vec<String> {
    let stack = StackConfig::default();
    let spec = stack
        .process
        .iter()
        .find(|s| s.binary == binary)
        .unwrap_or_else(|| panic!("{binary} is not a process of the default stack"));
    args(spec, run)
}

fn args(spec: &ProcessSpec, run: &Run) -> Vec<String> {
    let path = |p: &Path| p.to_string_lossy().into_owned();
    let mut a: Vec<String> = Vec::new();
    if spec.name == RECORDER {
        a.push("record".into());
    }
    let mut flag = |name: &str, value: String| a.extend([format!("--{name}"), value]);
    if let Some(c) = &run.config {
        flag("config", path(c));
    }
    if let Some(ns) = &run.namespace {
        flag("namespace", ns.clone());
    }
    if let Some(dir) = &run.summaries
        && spec.name != RECORDER
    {
        flag("summary", path(&dir.join(format!("{}.json", spec.binary))));
    }
    match spec.binary.as_str() {
        "mta" => {
            if let Some(r) = &run.record {
                flag("summary", path(&r.summary));
                flag("out", path(&r.out));
                if r.weight_blobs {
                    a.push("--weight-blobs".into());
                }
            }
        }
        "mta-trainer" => {
            if let Some(t) = &run.track {
                flag("track", path(t));
            }
        }
        "mta-predictor" => {
            if let Some(ck) = &run.checkpoint {
                flag("checkpoint", path(ck));
            }
        }
        "mta-simulator" => {
            if let Some(t) = &run.track {
                flag("track", path(t));
            }
            if let Some(t) = &run.trace {
                flag("trace", path(t));
            }
            if let Some(n) = run.max_steps {
                flag("max-steps", n.to_string());
            }
        }
        _ => {}
    }
    a.extend(spec.args.iter().cloned());
    a
}

/// How a process of the stack is started: `bin_dir()/<binary>` with `args`, the caller's
/// `RUST_LOG` (default `info`), stdout discarded, and exactly the scheduling class asked for
/// (`SCHED_FIFO` at `realtime_priority`, else the normal scheduler), never the class of the
/// thread that starts it: a real-time caller would otherwise make the trainer real-time too.
/// In `own_group`, a Ctrl-C at the terminal reaches only the parent, which stops each child
/// with one signal (a second one makes a process exit without its clean-up).
pub fn command<S: AsRef<OsStr>>(
    binary: &str,
    args: &[S],
    realtime_priority: Option<i32>,
    own_group: bool,
) -> Command {
    let mut cmd = Command::new(bin_dir().join(binary));
    if own_group {
        cmd.process_group(0);
    }
    cmd.args(args)
        .env(
            "RUST_LOG",
            std::env::var("RUST_LOG").unwrap_or_else(|_| "info".into()),
        )
        .stdout(Stdio::null());
    // SAFETY: the hook only calls sched_setscheduler(2), async-signal-safe, on the child.
    unsafe {
        cmd.pre_exec(move || {
            mtanet_ipc::sched::set_class_in_child(realtime_priority);
            Ok(())
        });
    }
    cmd
}

/// A hint for a binary that could not be started.
pub fn missing_hint(binary: &str) -> String {
    format!(
        "starting {} (build with cargo build --release --workspace --bins)",
        bin_dir().join(binary).display()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_process_gets_the_runs_config_namespace_and_its_own_flags() {
        let run = Run {
            config: Some("/c.toml".into()),
            namespace: Some("ns1".into()),
            summaries: Some("/out".into()),
            track: Some("/t.csv".into()),
            checkpoint: Some("/w.safetensors".into()),
            max_steps: Some(500),
            ..Default::default()
        };
        let p = plan(&StackConfig::default(), &run);
        let names: Vec<&str> = p.iter().map(|l| l.spec.binary.as_str()).collect();
        assert_eq!(names, ["mta-trainer", "mta-predictor", "mta-simulator"]);
        for l in &p {
            let joined = l.args.join(" ");
            assert!(
                joined.starts_with("--config /c.toml --namespace ns1"),
                "{joined}"
            );
            let summary = format!("--summary /out/{}.json", l.spec.binary);
            assert!(joined.contains(&summary), "{joined}");
        }
        let of = |b: &str| {
            p.iter()
                .find(|l| l.spec.binary == b)
                .unwrap()
                .args
                .join(" ")
        };
        assert!(of("mta-predictor").contains("--checkpoint /w.safetensors"));
        assert!(of("mta-simulator").contains("--track /t.csv --max-steps 500"));
        assert!(of("mta-trainer").contains("--track /t.csv"));
        assert!(!of("mta-trainer").contains("--checkpoint"));
        assert_eq!(args_of("mta-simulator", &run), p[2].args);
    }

    #[test]
    fn without_a_trainer_and_for_a_unit_only_what_is_asked_for() {
        let run = Run {
            no_trainer: true,
            ..Default::default()
        };
        let p = plan(&StackConfig::default(), &run);
        assert_eq!(p.len(), 2);
        assert!(p.iter().all(|l| l.args == l.spec.args), "{p:?}");
    }

    #[test]
    fn a_recorder_starts_first_with_its_own_files() {
        let run = Run {
            config: Some("/c.toml".into()),
            namespace: Some("ns1".into()),
            summaries: Some("/out".into()),
            record: Some(Recording {
                out: "/out/r.mcap".into(),
                summary: "/out/r.json".into(),
                weight_blobs: true,
            }),
            ..Default::default()
        };
        let p = plan(&StackConfig::default(), &run);
        assert_eq!(p.len(), 4);
        assert_eq!(
            (p[0].spec.name.as_str(), p[0].spec.binary.as_str()),
            (RECORDER, "mta")
        );
        assert!(!p[0].spec.restart.on_failure);
        assert_eq!(
            p[0].args.join(" "),
            "record --config /c.toml --namespace ns1 --summary /out/r.json --out /out/r.mcap --weight-blobs"
        );
        assert_eq!(p[1].spec.binary, "mta-trainer");
    }
}
