//! The experiment file: one matrix of variants x seeds, learnt on one track and evaluated on
//! others. Read with `deny_unknown_fields` (a misspelt key is an error naming the file and key)
//! and checked before anything runs (`Spec::load`); each variant's stack config is built and
//! checked in `config.rs`.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// Why an experiment file cannot be run.
#[derive(Debug, thiserror::Error)]
pub enum SpecError {
    /// The file cannot be read, is not TOML, or has an unknown or badly typed key.
    #[error(transparent)]
    File(#[from] mtanet_summaries::files::FileError),
    /// A value parsed but cannot be run.
    #[error("experiment {path}: {key} {message}")]
    Invalid {
        path: PathBuf,
        key: String,
        message: String,
    },
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    pub name: String,
    /// What the experiment asks (goes into summary.md).
    #[serde(default)]
    pub description: String,
    /// Each seed sets every seed in the stack (see `config::SEED_KEYS`).
    pub seeds: Vec<u64>,
    /// Learnt from scratch, in lockstep, for `learn_sim_seconds`.
    pub learn_track: PathBuf,
    pub learn_sim_seconds: f64,
    /// More tracks the learning drives in turn after `learn_track` (its `[simulator]
    /// also_tracks`, each for `switch_track_after_s`); the trainer probes on `learn_track`.
    #[serde(default)]
    pub learn_also_tracks: Vec<PathBuf>,
    /// Driven by the learnt checkpoint with no learning, each for `eval_sim_seconds`.
    #[serde(default)]
    pub eval_tracks: Vec<PathBuf>,
    #[serde(default)]
    pub eval_sim_seconds: f64,
    /// Merged over the stack config for every variant, before the variant's own overrides
    /// (a short smoke run needs the trainer to start sooner in all of them, say).
    #[serde(default)]
    pub overrides: toml::Table,
    #[serde(default)]
    pub heldout: Heldout,
    #[serde(default)]
    pub bootstrap: Bootstrap,
    #[serde(default)]
    pub analysis: AnalysisDrive,
    #[serde(rename = "variant")]
    pub variants: Vec<Variant>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Variant {
    pub name: String,
    #[serde(default)]
    pub description: String,
    /// Merged over the stack config (tables key by key, any other value replaced).
    #[serde(default)]
    pub overrides: toml::Table,
}

/// The fixed held-out drive every cell's checkpoint is scored on (next-frame error over
/// copy-last): a seeded recording of the reactive rule with exploration, made once per
/// experiment into `heldout.npz`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Heldout {
    pub track: PathBuf,
    pub sim_seconds: f64,
    pub seed: u64,
}

impl Default for Heldout {
    fn default() -> Self {
        Self {
            track: PathBuf::from("generated:9001"),
            sim_seconds: 60.0,
            seed: 9001,
        }
    }
}

/// The drive on which every cell's learnt checkpoint is analysed (`mta analyze`: timescales
/// and read-outs per layer): the same for every cell.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AnalysisDrive {
    /// Default: the first evaluation track (none: no analysis).
    pub track: Option<PathBuf>,
    /// At least 5 laps of the track are needed (the read-outs' folds).
    pub sim_seconds: f64,
    pub seed: u64,
}

impl Default for AnalysisDrive {
    fn default() -> Self {
        Self {
            track: None,
            sim_seconds: 300.0,
            seed: 0,
        }
    }
}

impl Spec {
    /// The analysis drive's track, if there is one.
    pub fn analysis_track(&self) -> Option<&Path> {
        (self.analysis.track.as_deref()).or(self.eval_tracks.first().map(PathBuf::as_path))
    }
}

/// The percentile bootstrap of the difference of two variants' medians in summary.md.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Bootstrap {
    pub resamples: usize,
    pub confidence: f64,
    pub seed: u64,
}

impl Default for Bootstrap {
    fn default() -> Self {
        Self {
            resamples: 2000,
            confidence: 0.95,
            seed: 0,
        }
    }
}

/// Folder names the experiment keeps for itself beside the variants' folders.
const RESERVED: [&str; 1] = ["plots"];

impl Spec {
    /// Reads and checks `path`: unique, folder-safe variant names, seeds, durations, tracks
    /// that load (a file, or `generated:N`) and eval tracks with distinct folder names.
    pub fn load(path: &Path) -> Result<Self, SpecError> {
        let spec: Spec = mtanet_summaries::files::read_toml(path)?;
        spec.check(path)?;
        Ok(spec)
    }

    fn check(&self, path: &Path) -> Result<(), SpecError> {
        let bad = |key: &str, message: String| SpecError::Invalid {
            path: path.into(),
            key: key.into(),
            message,
        };
        if !folder_safe(&self.name) {
            return Err(bad("name", format!("{:?} {NAME_RULE}", self.name)));
        }
        if self.seeds.is_empty() {
            return Err(bad("seeds", "is empty: give at least one seed".into()));
        }
        if self.seeds.iter().collect::<BTreeSet<_>>().len() != self.seeds.len() {
            return Err(bad("seeds", format!("{:?} repeats a seed", self.seeds)));
        }
        // NaN fails every comparison: ask for what is wanted, never negate a comparison.
        let at_least = |v: f64, min: f64| v.is_finite() && v >= min;
        if !at_least(self.learn_sim_seconds, 0.02) {
            let v = self.learn_sim_seconds;
            return Err(bad(
                "learn_sim_seconds",
                format!("= {v}: at least one step (0.02 s)"),
            ));
        }
        if !self.eval_tracks.is_empty() && !at_least(self.eval_sim_seconds, 0.02) {
            let v = self.eval_sim_seconds;
            return Err(bad(
                "eval_sim_seconds",
                format!("= {v}: at least one step (0.02 s)"),
            ));
        }
        self.check_variants(&bad)?;
        self.check_tracks(&bad)?;
        let b = &self.bootstrap;
        if b.resamples < 100 || !(0.5..1.0).contains(&b.confidence) {
            let m = format!(
                "resamples {} (>= 100), confidence {} (in [0.5, 1))",
                b.resamples, b.confidence
            );
            return Err(bad("[bootstrap]", m));
        }
        if !at_least(self.analysis.sim_seconds, 60.0) {
            let m = format!("= {}: at least 60 s", self.analysis.sim_seconds);
            return Err(bad("analysis.sim_seconds", m));
        }
        if !at_least(self.heldout.sim_seconds, 10.0) {
            let m = format!("= {}: at least 10 s", self.heldout.sim_seconds);
            return Err(bad("heldout.sim_seconds", m));
        }
        Ok(())
    }

    fn check_variants(&self, bad: &dyn Fn(&str, String) -> SpecError) -> Result<(), SpecError> {
        if self.variants.is_empty() {
            return Err(bad("[[variant]]", "none: give at least one".into()));
        }
        let mut names = BTreeSet::new();
        for v in &self.variants {
            let key = format!("[[variant]] name {:?}", v.name);
            if !folder_safe(&v.name) || RESERVED.contains(&v.name.as_str()) {
                return Err(bad(&key, format!("{NAME_RULE}, and not {RESERVED:?}")));
            }
            if !names.insert(&v.name) {
                return Err(bad(
                    &key,
                    "is used twice: variant names must be unique".into(),
                ));
            }
        }
        Ok(())
    }

    /// Every track loads, and no evaluation track is learnt on or named twice.
    fn check_tracks(&self, bad: &dyn Fn(&str, String) -> SpecError) -> Result<(), SpecError> {
        let tracks = std::iter::once(("learn_track", &self.learn_track))
            .chain(
                self.learn_also_tracks
                    .iter()
                    .map(|t| ("learn_also_tracks", t)),
            )
            .chain(self.eval_tracks.iter().map(|t| ("eval_tracks", t)))
            .chain(std::iter::once(("heldout.track", &self.heldout.track)))
            .chain(self.analysis.track.iter().map(|t| ("analysis.track", t)));
        for (key, track) in tracks {
            mtanet_track::Track::load(track).map_err(|e| {
                bad(
                    key,
                    format!("{}: not a track file nor generated:N: {e}", track.display()),
                )
            })?;
        }
        let mut slugs = BTreeSet::new();
        let learnt: BTreeSet<String> = std::iter::once(&self.learn_track)
            .chain(&self.learn_also_tracks)
            .map(|t| track_slug(t))
            .collect();
        for t in &self.eval_tracks {
            if learnt.contains(&track_slug(t)) {
                let m = format!(
                    "has {} (or a track of its name), a learn track: evaluation is on tracks \
                     the learning never saw",
                    t.display()
                );
                return Err(bad("eval_tracks", m));
            }
            if !slugs.insert(track_slug(t)) {
                let m = format!(
                    "has two tracks named {:?} (the run folder names)",
                    track_slug(t)
                );
                return Err(bad("eval_tracks", m));
            }
        }
        Ok(())
    }
}

const NAME_RULE: &str =
    "must be a folder name: letters, digits, '-', '_' or '.', not starting with '.'";

fn folder_safe(name: &str) -> bool {
    !name.is_empty()
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
}

/// The run folder name of a track: `generated:101` -> `generated-101`, `hairpins:2:6` ->
/// `hairpins-2-6`, `a/bends.csv` -> `bends`.
pub fn track_slug(track: &Path) -> String {
    let s = track.to_string_lossy();
    let generated = [
        mtanet_track::GENERATED_PREFIX,
        mtanet_track::HAIRPINS_PREFIX,
    ]
    .iter()
    .any(|p| s.starts_with(p));
    match generated {
        true => s.replace(':', "-"),
        false => track
            .file_stem()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_else(|| "track".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(text: &str) -> Result<Spec, SpecError> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("e.toml");
        std::fs::write(&path, text).unwrap();
        Spec::load(&path)
    }

    const BASE: &str = r#"
name = "tau"
seeds = [0, 1]
learn_track = "generated:5"
learn_sim_seconds = 20
eval_tracks = ["generated:101", "generated:102"]
eval_sim_seconds = 10
"#;

    #[test]
    fn the_issue_format_reads_with_defaults_for_the_additions() {
        let s = load(&format!(
            "{BASE}[[variant]]\nname = \"paper\"\n[[variant]]\nname = \"flat\"\n\
             [variant.overrides.trainer.model]\ntau = [1.0, 1.0, 1.0]\n"
        ))
        .unwrap();
        assert_eq!(s.variants.len(), 2);
        assert_eq!(
            s.variants[1].overrides["trainer"]["model"]["tau"]
                .as_array()
                .unwrap()
                .len(),
            3
        );
        assert_eq!(s.heldout, Heldout::default());
        assert_eq!(s.bootstrap.resamples, 2000);
    }

    #[test]
    fn a_misspelt_key_names_the_key() {
        let e = load(&format!("{BASE}[[variant]]\nnam = \"paper\"\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("e.toml") && e.contains("nam"), "{e}");
    }

    #[test]
    fn bad_matrices_are_refused_naming_the_key() {
        let two = |a: &str, b: &str| {
            format!("[[variant]]\nname = \"{a}\"\n[[variant]]\nname = \"{b}\"\n")
        };
        let cases = [
            (format!("{BASE}{}", two("a", "a")), "unique"),
            (format!("{BASE}{}", two("a", "plots")), "plots"),
            (format!("{BASE}{}", two("a", "b/c")), "folder"),
            (BASE.replace("[0, 1]", "[]") + &two("a", "b"), "seeds"),
            (
                BASE.replace("generated:5", "no/such.csv") + &two("a", "b"),
                "learn_track",
            ),
            (
                BASE.replace("generated:102", "generated:101") + &two("a", "b"),
                "two tracks",
            ),
            (
                BASE.replace(
                    "learn_sim",
                    "learn_also_tracks = [\"generated:102\"]\nlearn_sim",
                ) + &two("a", "b"),
                "a learn track",
            ),
            (
                BASE.replace(
                    "learn_sim",
                    "learn_also_tracks = [\"no/such.csv\"]\nlearn_sim",
                ) + &two("a", "b"),
                "learn_also_tracks",
            ),
            (BASE.to_string(), "variant"),
        ];
        for (text, word) in cases {
            let e = load(&text).unwrap_err().to_string();
            assert!(e.contains(word), "{word}: {e}");
        }
    }

    #[test]
    fn tracks_name_their_run_folders() {
        assert_eq!(track_slug(Path::new("generated:101")), "generated-101");
        assert_eq!(track_slug(Path::new("scenes/tracks/bends.csv")), "bends");
    }
}
