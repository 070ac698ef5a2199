//! What `mta up` and `mta soak` share before they start a stack: the effective config in the run
//! folder, and a starting checkpoint checked and probed on the run's track.

use mtanet_summaries::run_folder;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use mtanet_ipc::config::ConfigFile;
use mtanet_ipc::stack::StackConfig;

/// The config the processes get: the user's, with the run folder's checkpoint directory and
/// learning log (unless it names its own) and the mode; checked section by section before anything starts.
/// `rule_alone`: exploration and active inference off, the baseline a learnt driver is judged by.
pub fn effective_config(
    config: Option<&Path>,
    mode: Option<&str>,
    rule_alone: bool,
    out: &Path,
) -> anyhow::Result<(PathBuf, PathBuf)> {
    let source = config
        .map(Path::to_path_buf)
        .or_else(|| Some(PathBuf::from("ops/mtanet.toml")).filter(|p| p.exists()));
    // The user's file is checked as written, so that its errors name it (not the run folder's
    // copy), and before the run folder is made: a config that fails leaves nothing behind.
    if let Some(p) = &source {
        check(&ConfigFile::load(Some(p))?)?;
    }
    let mut table: toml::Table = match &source {
        Some(p) => mtanet_summaries::files::read_table(p)?,
        None => toml::Table::new(),
    };
    let section = |t: &mut toml::Table, name: &str| -> anyhow::Result<toml::Table> {
        match t.remove(name) {
            None => Ok(toml::Table::new()),
            Some(toml::Value::Table(s)) => Ok(s),
            Some(_) => bail!("[{name}] in the config must be a table"),
        }
    };
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut trainer = section(&mut table, "trainer")?;
    let ck_dir = match trainer.get("checkpoint_dir").and_then(|v| v.as_str()) {
        Some(d) => PathBuf::from(d),
        None => {
            let d = std::path::absolute(out.join(run_folder::CHECKPOINTS))?;
            trainer.insert(
                "checkpoint_dir".into(),
                d.to_string_lossy().into_owned().into(),
            );
            d
        }
    };
    if !trainer.contains_key("learning_log") {
        let log = std::path::absolute(out.join("learning.jsonl"))?;
        trainer.insert(
            "learning_log".into(),
            log.to_string_lossy().into_owned().into(),
        );
    }
    table.insert("trainer".into(), trainer.into());
    let mut sim = section(&mut table, "simulator")?;
    if let Some(m) = mode {
        sim.insert("mode".into(), m.into());
    }
    table.insert("simulator".into(), sim.into());
    if rule_alone {
        rule_only(&mut table)?;
    }
    let path = out.join(run_folder::STACK);
    mtanet_summaries::files::write_bytes(&path, toml::to_string(&table)?.as_bytes())?;
    check(&ConfigFile::load(Some(&path))?)?;
    Ok((path, ck_dir))
}

/// Turns off whatever would drive instead of the rule or disturb it: exploration, active
/// inference, the teacher's noise.
fn rule_only(table: &mut toml::Table) -> anyhow::Result<()> {
    for (path, key) in [
        (&["predictor", "exploration"][..], "enabled"),
        (&["predictor", "active_inference"], "enabled"),
    ] {
        sub_table(table, path)?.insert(key.into(), false.into());
    }
    sub_table(table, &["simulator", "teacher"])?.insert("noise_std".into(), 0.0.into());
    Ok(())
}

/// The table at `path`, made where missing; an error where a key on the way is not a table.
fn sub_table<'t>(table: &'t mut toml::Table, path: &[&str]) -> anyhow::Result<&'t mut toml::Table> {
    let mut t = table;
    for (i, name) in path.iter().enumerate() {
        let v = t
            .entry(name.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        t = v
            .as_table_mut()
            .with_context(|| format!("[{}] in the config must be a table", path[..=i].join(".")))?;
    }
    Ok(t)
}

/// Every section, as the services will read it: a typo fails here, naming file and key.
/// `mta experiment` checks each variant's merged config with it before anything runs.
pub fn check(file: &ConfigFile) -> anyhow::Result<()> {
    let sim: mtanet_simulator::config::SimulatorConfig = file.section("simulator")?;
    sim.validate().map_err(|e| file.invalid("[simulator]", e))?;
    let predictor: mtanet_predictor::config::PredictorConfig = file.section("predictor")?;
    predictor
        .active_inference
        .validate()
        .map_err(|e| file.invalid("[predictor.active_inference]", e.to_string()))?;
    let trainer: mtanet_trainer::config::TrainerConfig = file.section("trainer")?;
    // The network's own rules (one tau per layer, ...) and the wire contract, which the trainer
    // would otherwise only check once it starts.
    let wire = (mtanet_ipc::IMAGE_HEIGHT, mtanet_ipc::IMAGE_WIDTH);
    (trainer.model.validate())
        .and_then(|()| trainer.model.check_wire(wire, mtanet_ipc::ACTION_DIM))
        .map_err(|e| file.invalid("[trainer.model]", e.to_string()))?;
    let stack: StackConfig = file.section("stack")?;
    stack.validate().map_err(|e| file.invalid("[stack]", e))?;
    Ok(())
}

/// A run's inputs once its config is in the run folder (`effective_config`): the config read
/// back, the track (checked), the starting checkpoint probed on it, the mode the simulator runs
/// in and the stack for that mode. `mta up` and `mta soak` prepare a run through here.
pub struct Prepared {
    pub file: ConfigFile,
    pub track: PathBuf,
    /// `start.safetensors` in the run folder, for the predictor (and the trainer's latest
    /// checkpoint when it learns).
    pub start_ck: Option<PathBuf>,
    pub realtime: bool,
    pub stack: StackConfig,
}

pub fn prepare(
    config: &Path,
    ck_dir: &Path,
    out: &Path,
    track: Option<&Path>,
    checkpoint: Option<&Path>,
    learning: bool,
) -> anyhow::Result<Prepared> {
    let file = ConfigFile::load(Some(config))?;
    let scene: mtanet_scenes::SceneConfig = file.section("simulator.scene")?;
    let track = track.map_or(scene.track, Path::to_path_buf);
    mtanet_scenes::Track::load(&track).with_context(|| format!("the track {}", track.display()))?;
    let start_ck = match checkpoint {
        Some(ck) => {
            let probed = probed_copy(ck, &file, &track, out)?;
            if learning {
                start_trainer_from(ck, &probed, ck_dir)?;
            }
            Some(probed)
        }
        None => None,
    };
    let sim: mtanet_simulator::config::SimulatorConfig = file.section("simulator")?;
    let realtime = sim.mode == mtanet_simulator::config::Mode::Realtime;
    let stack = file.section::<StackConfig>("stack")?.for_mode(realtime);
    Ok(Prepared {
        file,
        track,
        start_ck,
        realtime,
        stack,
    })
}

/// Lets the trainer resume from `original` (its checked copy `probed`): the copy becomes the
/// latest checkpoint in `ck_dir`, and Adam's moments saved beside the original, if any, come
/// with it (a resumed learner that restarts its moments from zero takes oversized first steps).
pub fn start_trainer_from(original: &Path, probed: &Path, ck_dir: &Path) -> anyhow::Result<()> {
    use mtanet_models::train::optimizer_path;
    std::fs::create_dir_all(ck_dir).with_context(|| format!("creating {}", ck_dir.display()))?;
    let latest = ck_dir.join(run_folder::LATEST);
    std::fs::copy(probed, &latest).with_context(|| format!("writing {}", latest.display()))?;
    let moments = optimizer_path(original);
    if moments.exists() {
        let to = optimizer_path(&latest);
        std::fs::copy(&moments, &to).with_context(|| format!("writing {}", to.display()))?;
    }
    Ok(())
}

/// Checks the starting checkpoint and writes `start.safetensors` in the run folder with a
/// probe recorded (the predictor trusts weights for control only with a passing probe). A
/// checkpoint that carries the probe of its own training keeps it: the probe measures the model,
/// and re-measured on a track with few bends it would say more about the track (on a straight,
/// every command ranks alike). A checkpoint without one is probed on this run's track.
pub fn probed_copy(
    ck: &Path,
    file: &ConfigFile,
    track: &Path,
    out: &Path,
) -> anyhow::Result<PathBuf> {
    use mtanet_models::checkpoint;
    let bytes =
        std::fs::read(ck).with_context(|| format!("reading the checkpoint {}", ck.display()))?;
    let mut loaded = checkpoint::from_bytes(&bytes)
        .with_context(|| format!("the checkpoint {}", ck.display()))?;
    if let (Some(p), Some(at)) = (loaded.meta.probe, loaded.meta.probe_step) {
        eprintln!(
            "[up] checkpoint {} (step {}): its training's counterfactual probe = {p:.3} (at step {at})",
            ck.display(),
            loaded.meta.step,
        );
        let path = out.join(run_folder::START);
        std::fs::write(&path, &bytes).with_context(|| format!("writing {}", path.display()))?;
        return Ok(path);
    }
    let agent: mtanet_control::AgentConfig = file.section("predictor.active_inference")?;
    let trainer: mtanet_trainer::config::TrainerConfig = file.section("trainer")?;
    let scene = mtanet_scenes::SceneConfig::default().with_track(track.to_path_buf());
    tch::set_num_threads(1);
    let probe = mtanet_eval::probe(&scene, &bytes, &agent, &trainer.probe)
        .with_context(|| format!("probing {} on {}", ck.display(), track.display()))?;
    eprintln!(
        "[up] checkpoint {} (step {}): counterfactual probe on {} = {:.3}",
        ck.display(),
        loaded.meta.step,
        track.display(),
        probe.rank_correlation
    );
    loaded.meta = loaded
        .meta
        .clone()
        .with_probe(Some((loaded.meta.step, probe.rank_correlation)));
    let (vs, _) = loaded.build()?;
    let path = out.join(run_folder::START);
    checkpoint::save(&path, &vs, &loaded.config, &loaded.meta)?;
    Ok(path)
}
