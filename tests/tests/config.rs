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
            "publsh_every_updates",
        ),
        (
            "[trainer]\npublish_every_updates = \"ten\"\n",
            "publish_every_updates",
        ),
        ("trainer = 5\n", "must be a table"),
    ];
    for (text, key) in cases {
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
                err.contains("bad.toml") && err.contains("[trainer]") && err.contains(key),
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
