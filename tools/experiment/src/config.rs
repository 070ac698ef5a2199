//! Each cell's stack config: the base config (`--config`, else `ops/mtanet.toml`, else the
//! defaults), the experiment's `overrides`, the variant's, then the cell's seed in every seed
//! key. Checked the way `mta up` checks a config (`mtanet_launch::runcfg::check`), so a typo in
//! an override is an error naming the variant and the key before any run starts.

use std::path::{Path, PathBuf};

use anyhow::bail;
use mtanet_ipc::config::ConfigFile;

use crate::spec::{Spec, Variant};

/// Every seed in the stack, each set to the cell's seed: the teacher's noise (the simulator's
/// miss policy), the reactive rule's exploration, the planner's CEM samples, the trainer's
/// initialisation and batches, and the counterfactual probe's states.
pub const SEED_KEYS: [&str; 5] = [
    "simulator.teacher.seed",
    "predictor.exploration.seed",
    "predictor.active_inference.planner.seed",
    "trainer.train.seed",
    "trainer.probe.seed",
];

/// Keys each run sets for itself (namespace, mode and length by `mta up`'s flags, which win
/// over the config): an override of one would be silently ignored.
const RUN_KEYS: [&str; 3] = ["ipc.namespace", "simulator.mode", "simulator.max_steps"];

/// Keys that would make runs share files: `mta up` puts them in each run folder unless the
/// config sets them, so neither the base config nor an override may.
const SHARED_KEYS: [&str; 2] = ["trainer.checkpoint_dir", "trainer.learning_log"];

/// The base stack config as a table, and where it came from (for messages).
pub fn base(config: Option<&Path>) -> anyhow::Result<(toml::Table, String)> {
    let source = config
        .map(Path::to_path_buf)
        .or_else(|| Some(PathBuf::from("ops/mtanet.toml")).filter(|p| p.exists()));
    Ok(match source {
        Some(p) => (
            mtanet_summaries::files::read_table(&p)?,
            p.display().to_string(),
        ),
        None => (toml::Table::new(), "<defaults>".into()),
    })
}

pub use mtanet_summaries::files::merge_tables as merge;

fn get<'a>(t: &'a toml::Table, dotted: &str) -> Option<&'a toml::Value> {
    let (path, last) = dotted.rsplit_once('.').unwrap_or(("", dotted));
    let mut t = t;
    for part in path.split('.').filter(|p| !p.is_empty()) {
        t = t.get(part)?.as_table()?;
    }
    t.get(last)
}

fn set(t: &mut toml::Table, dotted: &str, value: toml::Value) {
    let (path, last) = dotted.rsplit_once('.').unwrap_or(("", dotted));
    let mut t = t;
    for part in path.split('.').filter(|p| !p.is_empty()) {
        let entry = t
            .entry(part.to_string())
            .or_insert_with(|| toml::Table::new().into());
        if !entry.is_table() {
            *entry = toml::Table::new().into();
        }
        t = entry.as_table_mut().expect("made a table above");
    }
    t.insert(last.to_string(), value);
}

/// A variant's stack config before seeding: base, experiment overrides, its own; checked.
/// `file` names the experiment in errors.
pub fn variant(
    base: &toml::Table,
    spec: &Spec,
    v: &Variant,
    file: &Path,
) -> anyhow::Result<toml::Table> {
    let origin = format!("{}, variant {:?}", file.display(), v.name);
    for (over, whose) in [
        (&spec.overrides, "[overrides]"),
        (&v.overrides, "its overrides"),
    ] {
        for key in SEED_KEYS {
            if get(over, key).is_some() {
                bail!("{origin}: {whose} set {key}, which each cell sets from its seed (`seeds`)");
            }
        }
        for key in RUN_KEYS {
            if get(over, key).is_some() {
                bail!("{origin}: {whose} set {key}, which mta experiment sets for each run");
            }
        }
    }
    let mut table = base.clone();
    merge(&mut table, &spec.overrides);
    merge(&mut table, &v.overrides);
    for key in SHARED_KEYS {
        if get(&table, key).is_some() {
            bail!("{origin}: the config sets {key}: every run needs its own, in its folder");
        }
    }
    // The origin stands in for the file's path, so every error names the variant.
    let text = toml::to_string(&table)?;
    mtanet_launch::runcfg::check(&ConfigFile::parse(&text, Path::new(&origin))?)?;
    Ok(table)
}

/// The cell's config: the variant's with every seed key set to `seed`.
pub fn cell(variant: &toml::Table, seed: u64) -> anyhow::Result<toml::Table> {
    let mut t = variant.clone();
    let value =
        i64::try_from(seed).map_err(|_| anyhow::anyhow!("seed {seed} exceeds TOML's i64"))?;
    for key in SEED_KEYS {
        set(&mut t, key, value.into());
    }
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(overrides: &str) -> (Spec, tempfile::TempDir) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("e.toml");
        let text = format!(
            "name = \"t\"\nseeds = [3]\nlearn_track = \"generated:5\"\nlearn_sim_seconds = 20\n\
             [[variant]]\nname = \"flat\"\n{overrides}"
        );
        std::fs::write(&path, text).unwrap();
        (Spec::load(&path).unwrap(), dir)
    }

    fn check(overrides: &str) -> anyhow::Result<toml::Table> {
        let (s, _dir) = spec(overrides);
        variant(&toml::Table::new(), &s, &s.variants[0], Path::new("e.toml"))
    }

    #[test]
    fn an_override_merges_and_is_checked_like_the_stack_config() {
        let t = check("[variant.overrides.trainer.model]\ntau = [1.0, 1.0, 1.0]\n").unwrap();
        assert_eq!(
            get(&t, "trainer.model.tau")
                .unwrap()
                .as_array()
                .unwrap()
                .len(),
            3
        );
        let c = cell(&t, 3).unwrap();
        for key in SEED_KEYS {
            assert_eq!(get(&c, key).and_then(|v| v.as_integer()), Some(3), "{key}");
        }
        assert!(
            get(&c, "trainer.model.tau").is_some(),
            "seeding keeps the override"
        );
    }

    #[test]
    fn a_bad_override_key_is_named_with_its_variant() {
        let e = format!(
            "{:#}",
            check("[variant.overrides.trainer.model]\ntaux = [1.0]\n").unwrap_err()
        );
        assert!(
            e.contains("\"flat\"") && e.contains("taux") && e.contains("model"),
            "{e}"
        );
        let e = format!(
            "{:#}",
            check("[variant.overrides.trainr]\nnice = 1\n").unwrap_err()
        );
        assert!(e.contains("\"flat\"") && e.contains("trainr"), "{e}");
        // Parses, but the network cannot be built: one tau per layer.
        let e = format!(
            "{:#}",
            check("[variant.overrides.trainer.model]\ntau = [1.0]\n").unwrap_err()
        );
        assert!(e.contains("\"flat\"") && e.contains("tau"), "{e}");
    }

    #[test]
    fn seeds_and_run_keys_are_not_overridden() {
        let e = check("[variant.overrides.trainer.train]\nseed = 4\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("trainer.train.seed") && e.contains("\"flat\""),
            "{e}"
        );
        let e = check("[variant.overrides.trainer]\ncheckpoint_dir = \"x\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("trainer.checkpoint_dir"), "{e}");
        let e = check("[variant.overrides.simulator]\nmode = \"realtime\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("simulator.mode"), "{e}");
    }

    #[test]
    fn merging_is_recursive_and_replaces_values() {
        let mut a: toml::Table = toml::from_str("[x]\na = 1\nb = [1, 2]\n[x.y]\nc = 1\n").unwrap();
        let b: toml::Table = toml::from_str("[x]\nb = [3]\n[x.y]\nd = 2\n").unwrap();
        merge(&mut a, &b);
        let want: toml::Table =
            toml::from_str("[x]\na = 1\nb = [3]\n[x.y]\nc = 1\nd = 2\n").unwrap();
        assert_eq!(a, want);
    }
}
