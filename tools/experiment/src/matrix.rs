//! The matrix's cells (variant x seed), their folders and what is known of them on disk:
//! `DIR/<variant>/<seed>/cell.json`, written atomically when the cell has finished, makes it
//! done (an interrupted experiment resumes past it); `failed.json` names the error and the log
//! of a cell that failed, and the next invocation runs it again from an empty folder.

use std::path::{Path, PathBuf};

use anyhow::bail;
use serde::{Deserialize, Serialize};

use crate::metrics::Metrics;
use crate::spec::{Heldout, Spec};

/// `learn`: from scratch on the learn track; `eval`: the learnt checkpoint, no learning;
/// `rule`: the reactive rule alone on the evaluation track (no model, no exploration), the
/// baseline each evaluation run is compared with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    Learn,
    Eval,
    Rule,
}

impl Phase {
    pub const ALL: [Phase; 3] = [Phase::Learn, Phase::Eval, Phase::Rule];

    pub fn name(self) -> &'static str {
        match self {
            Phase::Learn => "learn",
            Phase::Eval => "eval",
            Phase::Rule => "rule",
        }
    }
}

/// One row of results.csv: one run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Row {
    pub variant: String,
    pub seed: u64,
    pub phase: Phase,
    pub track: String,
    pub metrics: Metrics,
}

/// What a finished cell was run with: a cell.json that does not match the experiment as it is
/// now is not silently reused.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellKey {
    pub variant: String,
    pub seed: u64,
    pub learn_track: PathBuf,
    pub learn_sim_seconds: f64,
    #[serde(default)]
    pub learn_also_tracks: Vec<PathBuf>,
    pub eval_tracks: Vec<PathBuf>,
    pub eval_sim_seconds: f64,
    pub heldout: Heldout,
    /// The cell's whole stack config, as TOML.
    pub config: String,
}

/// `cell.json`: a finished cell.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CellRecord {
    pub key: CellKey,
    pub rows: Vec<Row>,
    pub wall_seconds: f64,
    /// Empty in cells recorded before it was (read as "not recorded").
    #[serde(default)]
    pub made_with: MadeWith,
}

/// The code and the machine a cell ran on: an experiment resumed across sessions can mix
/// commits, and wall times depend on the CPU.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MadeWith {
    /// `git describe` of the build (`-dirty`: uncommitted changes), "unknown" outside git.
    pub commit: String,
    /// E.g. "AMD EPYC (no AVX-512), 2 CPUs".
    pub cpu: String,
}

impl MadeWith {
    pub fn here() -> Self {
        Self {
            commit: env!("MTANET_COMMIT").to_string(),
            cpu: mtanet_summaries::soak::Machine::here(0).cpu(),
        }
    }
}

/// `failed.json`: a cell that failed, to be run again.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Failure {
    pub error: String,
    /// The log of the run that failed (its `mta up` output; the processes' logs beside it).
    pub log: Option<PathBuf>,
}

pub struct Cell {
    pub key: CellKey,
    pub dir: PathBuf,
    /// Its runs' iceoryx2 namespaces start with this (`<prefix>c<index>`; each run adds `r<k>`).
    pub namespace: String,
    /// The cell's stack config.
    pub config: toml::Table,
}

pub enum State {
    Done(CellRecord),
    Failed(Failure),
    Todo,
}

impl Cell {
    pub fn new(
        spec: &Spec,
        out: &Path,
        variant: &str,
        seed: u64,
        config: toml::Table,
    ) -> anyhow::Result<Self> {
        Ok(Self {
            key: CellKey {
                variant: variant.into(),
                seed,
                learn_track: spec.learn_track.clone(),
                learn_sim_seconds: spec.learn_sim_seconds,
                learn_also_tracks: spec.learn_also_tracks.clone(),
                eval_tracks: spec.eval_tracks.clone(),
                eval_sim_seconds: spec.eval_sim_seconds,
                heldout: spec.heldout.clone(),
                config: toml::to_string(&config)?,
            },
            dir: out.join(variant).join(seed.to_string()),
            namespace: String::new(),
            config,
        })
    }

    pub fn label(&self) -> String {
        format!("{}/{}", self.key.variant, self.key.seed)
    }

    pub fn record_path(&self) -> PathBuf {
        self.dir.join("cell.json")
    }

    pub fn failure_path(&self) -> PathBuf {
        self.dir.join("failed.json")
    }

    /// What the folder holds. A finished cell run with another matrix or config is an error:
    /// its results would be mixed with this experiment's.
    pub fn state(&self) -> anyhow::Result<State> {
        match mtanet_summaries::files::read_json::<CellRecord>(&self.record_path()) {
            Ok(rec) if rec.key == self.key => return Ok(State::Done(rec)),
            Ok(rec) => bail!(
                "{} was run with another experiment ({}): use another --out, or remove the folder to run it again",
                self.dir.display(),
                differences(&rec.key, &self.key)
            ),
            Err(e) if e.is_not_found() => {}
            Err(e) => return Err(e.into()),
        }
        match mtanet_summaries::files::read_json::<Failure>(&self.failure_path()) {
            Ok(f) => Ok(State::Failed(f)),
            Err(e) if e.is_not_found() => Ok(State::Todo),
            Err(e) => Err(e.into()),
        }
    }

    /// Empties the folder for a fresh run: a trainer would resume from a failed attempt's
    /// checkpoint, and its files would mix with the new ones.
    pub fn reset(&self) -> anyhow::Result<()> {
        if self.dir.exists() {
            std::fs::remove_dir_all(&self.dir)?;
        }
        std::fs::create_dir_all(&self.dir)?;
        // Evaluation drives its one track; the learning also drives `learn_also_tracks`.
        let mut eval = self.config.clone();
        if let Some(toml::Value::Table(sim)) = eval.get_mut("simulator") {
            sim.remove("also_tracks");
        }
        mtanet_summaries::files::write_bytes(
            &self.eval_config(),
            toml::to_string(&eval)?.as_bytes(),
        )?;
        let mut learn = self.config.clone();
        let mut tracks: Vec<toml::Value> = learn
            .get("simulator")
            .and_then(|s| s.get("also_tracks"))
            .and_then(|t| t.as_array().cloned())
            .unwrap_or_default();
        let more = self.key.learn_also_tracks.iter();
        tracks.extend(more.map(|t| toml::Value::String(t.display().to_string())));
        let sim = learn
            .entry("simulator")
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if let (toml::Value::Table(sim), false) = (sim, tracks.is_empty()) {
            sim.insert("also_tracks".into(), toml::Value::Array(tracks));
        }
        mtanet_summaries::files::write_bytes(
            &self.learn_config(),
            toml::to_string(&learn)?.as_bytes(),
        )?;
        Ok(())
    }

    /// The stack config the evaluation runs use (no `also_tracks`).
    pub fn eval_config(&self) -> PathBuf {
        self.dir.join("cell.toml")
    }

    /// The stack config the learn run uses (`also_tracks` with the spec's `learn_also_tracks`).
    pub fn learn_config(&self) -> PathBuf {
        self.dir.join("learn.toml")
    }
}

fn differences(a: &CellKey, b: &CellKey) -> String {
    let mut d = Vec::new();
    if a.learn_track != b.learn_track
        || a.learn_sim_seconds != b.learn_sim_seconds
        || a.learn_also_tracks != b.learn_also_tracks
    {
        d.push("learn track or seconds");
    }
    if a.eval_tracks != b.eval_tracks || a.eval_sim_seconds != b.eval_sim_seconds {
        d.push("eval tracks or seconds");
    }
    if a.heldout != b.heldout {
        d.push("held-out drive");
    }
    if a.config != b.config {
        d.push("stack config");
    }
    if d.is_empty() {
        d.push("variant or seed");
    }
    d.join(", ") + " differ"
}

/// The cells in the order they run: seed by seed, every variant of a seed before the next
/// seed, so an experiment stopped early still compares the variants.
pub fn cells(
    spec: &Spec,
    out: &Path,
    configs: &[(String, toml::Table)],
    namespace: &str,
) -> anyhow::Result<Vec<Cell>> {
    let mut cells = Vec::new();
    for &seed in &spec.seeds {
        for (name, table) in configs {
            let config = crate::config::cell(table, seed)?;
            let mut cell = Cell::new(spec, out, name, seed, config)?;
            cell.namespace = format!("{namespace}c{}", cells.len());
            cells.push(cell);
        }
    }
    Ok(cells)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> Spec {
        toml::from_str(
            "name = \"t\"\nseeds = [0, 1]\nlearn_track = \"generated:5\"\nlearn_sim_seconds = 20\n\
             [[variant]]\nname = \"a\"\n[[variant]]\nname = \"b\"\n",
        )
        .unwrap()
    }

    #[test]
    fn a_cell_is_todo_then_failed_then_done_and_another_config_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let s = spec();
        let configs = vec![
            ("a".into(), toml::Table::new()),
            ("b".into(), toml::Table::new()),
        ];
        let cells = cells(&s, dir.path(), &configs, "t").unwrap();
        let labels: Vec<String> = cells.iter().map(Cell::label).collect();
        assert_eq!(labels, ["a/0", "b/0", "a/1", "b/1"]);
        assert_eq!(cells[3].namespace, "tc3");
        let c = &cells[0];
        assert!(matches!(c.state().unwrap(), State::Todo));
        c.reset().unwrap();
        let failure = Failure {
            error: "boom".into(),
            log: None,
        };
        mtanet_summaries::files::write_json(&c.failure_path(), &failure).unwrap();
        assert!(matches!(c.state().unwrap(), State::Failed(f) if f.error == "boom"));
        c.reset().unwrap();
        assert!(
            matches!(c.state().unwrap(), State::Todo),
            "reset clears the failure"
        );
        let rec = CellRecord {
            key: c.key.clone(),
            rows: vec![],
            wall_seconds: 1.0,
            made_with: MadeWith::here(),
        };
        mtanet_summaries::files::write_json(&c.record_path(), &rec).unwrap();
        assert!(matches!(c.state().unwrap(), State::Done(_)));
        let other: toml::Table = toml::from_str("[trainer]\nnice = 5\n").unwrap();
        let changed = Cell::new(
            &s,
            dir.path(),
            "a",
            0,
            crate::config::cell(&other, 0).unwrap(),
        )
        .unwrap();
        let e = changed.state().err().expect("another config").to_string();
        assert!(e.contains("stack config"), "{e}");
    }

    /// The learn run drives the variant's and the spec's extra tracks; the evaluation runs drive
    /// their one track only.
    #[test]
    fn only_the_learn_run_drives_the_extra_tracks() {
        let dir = tempfile::tempdir().unwrap();
        let mut s = spec();
        s.learn_also_tracks = vec!["hairpins:1".into()];
        let variant: toml::Table =
            toml::from_str("[simulator]\nalso_tracks = [\"generated:7\"]\nlog_every_s = 2.0\n")
                .unwrap();
        let cells = cells(&s, dir.path(), &[("a".into(), variant)], "t").unwrap();
        cells[0].reset().unwrap();
        let read = |p: PathBuf| -> toml::Table {
            toml::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
        };
        let (learn, eval) = (read(cells[0].learn_config()), read(cells[0].eval_config()));
        let tracks = learn["simulator"]["also_tracks"].as_array().unwrap();
        let tracks: Vec<&str> = tracks.iter().map(|t| t.as_str().unwrap()).collect();
        assert_eq!(tracks, ["generated:7", "hairpins:1"]);
        assert!(eval["simulator"].get("also_tracks").is_none(), "{eval:?}");
        assert_eq!(eval["simulator"]["log_every_s"].as_float(), Some(2.0));
        assert_eq!(learn["simulator"]["log_every_s"].as_float(), Some(2.0));

        // Without extra tracks the learn config names none (not an empty list).
        let plain = super::cells(
            &spec(),
            dir.path(),
            &[("b".into(), toml::Table::new())],
            "t",
        )
        .unwrap();
        plain[0].reset().unwrap();
        let learn = read(plain[0].learn_config());
        assert!(learn["simulator"].get("also_tracks").is_none(), "{learn:?}");
    }
}
