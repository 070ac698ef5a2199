//! The shipped stack config must parse into every section exactly (unknown keys are errors), so a
//! renamed key breaks this test instead of silently falling back to a default in production.

use std::path::Path;

use mtanet_ipc::config::ConfigFile;
use mtanet_ipc::node::IpcConfig;

fn shipped() -> ConfigFile {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../ops/mtanet.toml");
    ConfigFile::load(Some(&path)).expect("ops/mtanet.toml parses")
}

#[test]
fn shipped_config_matches_every_section() {
    let f = shipped();
    let ipc: IpcConfig = f.section("ipc").unwrap();
    assert_eq!(ipc.namespace, "mtanet");
    let sim: mtanet_simulator::config::SimulatorConfig = f.section("simulator").unwrap();
    assert_eq!(sim.mode, mtanet_simulator::config::Mode::Realtime);
    assert_eq!(sim.scene.control_period_s, 0.02);
    assert_eq!(sim.teacher.backoff_steps, 5);
    let _: mtanet_predictor::config::PredictorConfig = f.section("predictor").unwrap();
    let _: mtanet_trainer::config::TrainerConfig = f.section("trainer").unwrap();
    let stack: mtanet_ipc::stack::StackConfig = f.section("stack").unwrap();
    assert_eq!(
        stack,
        mtanet_ipc::stack::StackConfig::default(),
        "the file shows the defaults"
    );
}

#[test]
fn a_typo_in_a_section_is_an_error_naming_it() {
    let f = ConfigFile::parse("[simulator]\ncomand_timeout_ms = 5\n", Path::new("x.toml")).unwrap();
    let e = f
        .section::<mtanet_simulator::config::SimulatorConfig>("simulator")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("comand_timeout_ms") && e.contains("[simulator]") && e.contains("x.toml"),
        "{e}"
    );
}

#[test]
fn a_wrong_type_and_a_bad_stack_entry_are_errors_naming_the_key() {
    let f = ConfigFile::parse(
        "[trainer]\npublish_every_updates = \"ten\"\n",
        Path::new("y.toml"),
    )
    .unwrap();
    let e = f
        .section::<mtanet_trainer::config::TrainerConfig>("trainer")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("publish_every_updates") && e.contains("[trainer]") && e.contains("y.toml"),
        "{e}"
    );
    let f = ConfigFile::parse(
        "[[stack.process]]\nname = \"simulator\"\nbinary = \"mta-simulator\"\nrealtime_priority = 120\n",
        Path::new("z.toml"),
    )
    .unwrap();
    let stack: mtanet_ipc::stack::StackConfig = f.section("stack").unwrap();
    let e = stack.validate().unwrap_err();
    assert!(
        e.contains("realtime_priority") && e.contains("simulator"),
        "{e}"
    );
}

/// `mta up --config bad.toml`: the error names the user's file, section and key (not the run
/// folder's copy), and no run folder is left, with `--out` or the default `runs/<time>`.
#[test]
fn mta_up_names_the_users_file_and_leaves_no_run_folder() {
    let cases = [
        (
            "[trainer]\npublsh_every_updates = 10\n",
            "[trainer]",
            "publsh_every_updates",
        ),
        (
            "[trainer]\npublish_every_updates = \"ten\"\n",
            "[trainer]",
            "publish_every_updates",
        ),
        ("trainer = 5\n", "[trainer]", "must be a table"),
        (
            "[simulator]\nalso_tracks = [\"generated:3\", \"no/such.csv\"]\n",
            "[simulator]",
            "simulator.also_tracks[1]",
        ),
        (
            "[simulator]\nalso_tracks = [\"generated:3\"]\nswitch_track_after_s = 0.0\n",
            "[simulator]",
            "switch_track_after_s",
        ),
    ];
    for (text, section, key) in cases {
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("bad.toml");
        std::fs::write(&bad, text).unwrap();
        let given = dir.path().join("given");
        for out in [Some(&given), None] {
            let mut cmd = std::process::Command::new(mtanet_system_tests::bin("mta"));
            cmd.current_dir(dir.path())
                .args(["up", "--lockstep", "--sim-seconds", "1", "--config"])
                .arg(&bad);
            if let Some(o) = out {
                cmd.arg("--out").arg(o);
            }
            let o = cmd.output().unwrap();
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(!o.status.success(), "{text}: started\n{err}");
            assert!(
                err.contains("bad.toml") && err.contains(section) && err.contains(key),
                "{text}: {err}"
            );
            assert!(!err.contains("stack.toml"), "{text}: names the copy: {err}");
            assert!(!given.exists(), "{text}: left {}", given.display());
            let runs = dir.path().join("runs");
            let left = std::fs::read_dir(&runs).map_or(0, |d| d.count());
            assert_eq!(left, 0, "{text}: left a folder in runs/");
        }
    }
}

/// Keys of `want` (the code's defaults) missing from `got` (the file) or different there, by
/// dotted path.
fn differences(path: &str, want: &toml::Value, got: Option<&toml::Value>, out: &mut Vec<String>) {
    match (want, got) {
        (toml::Value::Table(w), Some(toml::Value::Table(g))) => {
            for (k, v) in w {
                differences(&format!("{path}.{k}"), v, g.get(k), out);
            }
        }
        (_, None) => out.push(format!("{path} missing (default {want})")),
        // f32 defaults widen to f64 (0.3 -> 0.30000001192092896): same value to f32 precision.
        (toml::Value::Float(w), Some(toml::Value::Float(g))) if ((w - g) / w).abs() < 1e-6 => {}
        (w, Some(g)) if w != g => out.push(format!("{path} = {g} in the file, {w} in the code")),
        _ => {}
    }
}

fn default_of<T: serde::Serialize + Default>() -> toml::Value {
    toml::Value::try_from(T::default()).unwrap()
}

/// ops/mtanet.toml says "a missing key takes the default shown here": every key of every
/// section's default is in the file, with the same value (unknown keys in the file fail the
/// sections' own parsing, `shipped_config_matches_every_section`).
#[test]
fn the_shipped_file_lists_every_default_with_its_value() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../ops/mtanet.toml");
    let file: toml::Table = toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let sections = [
        ("ipc", default_of::<IpcConfig>()),
        (
            "simulator",
            default_of::<mtanet_simulator::config::SimulatorConfig>(),
        ),
        (
            "predictor",
            default_of::<mtanet_predictor::config::PredictorConfig>(),
        ),
        (
            "trainer",
            default_of::<mtanet_trainer::config::TrainerConfig>(),
        ),
    ];
    let mut out = Vec::new();
    for (name, want) in &sections {
        differences(name, want, file.get(*name), &mut out);
    }
    // The track's default is an absolute path into the checkout: the file names it in a comment.
    out.retain(|d| !d.starts_with("simulator.scene.track missing"));
    assert!(
        out.is_empty(),
        "ops/mtanet.toml and the code's defaults differ:\n{}",
        out.join("\n")
    );
}

/// A second stack in a namespace a live one uses is refused, naming the namespace and the way
/// out, and leaves no run folder.
#[test]
fn mta_up_refuses_a_namespace_in_use() {
    use mtanet_system_tests::*;
    let dir = tempfile::tempdir().unwrap();
    let ns = unique_namespace("busy");
    let mut predictor = start("mta-predictor", &run_in(&ns, dir.path()), &[], dir.path());
    wait_for_alive(&ns, 1, std::time::Duration::from_secs(30));
    let o = std::process::Command::new(bin("mta"))
        .current_dir(dir.path())
        .args([
            "up",
            "--lockstep",
            "--sim-seconds",
            "1",
            "--namespace",
            &ns,
            "--config",
        ])
        .arg(here().join("../ops/mtanet.toml"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "a second stack started\n{err}");
    assert!(
        err.contains(&format!("namespace {ns:?} is in use")) && err.contains("--namespace"),
        "{err}"
    );
    let left = std::fs::read_dir(dir.path().join("runs")).map_or(0, |d| d.count());
    assert_eq!(left, 0, "a run folder was left");
    predictor.signal(Signal::TERM);
    assert!(predictor.wait(std::time::Duration::from_secs(20)).success());
    remove_namespace_files(&ns);
}
