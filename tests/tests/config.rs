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
