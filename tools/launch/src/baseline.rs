//! The reactive rule alone on the run's track for the run's simulated time, in-process (no
//! model, no exploration): the clean baseline `report.json` compares the run's driving with.

use mtanet_summaries::run_folder;
use std::path::Path;

use mtanet_ipc::config::ConfigFile;
use mtanet_report::report::{RULE_ALONE_FILE, RuleAlone};
use mtanet_summaries::simulator::Summary as SimulatorSummary;

/// Writes `rule_alone.json` in `out` for as many steps as the run's simulator made; nothing
/// when the simulator left no summary (the report says why).
pub fn write_rule_alone(file: &ConfigFile, track: &Path, out: &Path) -> anyhow::Result<()> {
    let sim: SimulatorSummary = match mtanet_summaries::files::read_json(
        &out.join(run_folder::summary_of("mta-simulator")),
    ) {
        Ok(s) => s,
        Err(e) if e.is_not_found() => return Ok(()),
        Err(e) => return Err(e.into()),
    };
    if sim.steps == 0 {
        return Ok(());
    }
    let scene: mtanet_scenes::SceneConfig = file.section("simulator.scene")?;
    let simulator: mtanet_simulator::config::SimulatorConfig = file.section("simulator")?;
    let reactive: mtanet_control::ReactiveConfig = file.section("predictor.reactive")?;
    let rule = simulator.reset_rule();
    let cfg = mtanet_eval::DriveConfig {
        max_steps: sim.steps,
        stop_after_ai_laps: 0,
        reset_after_lost_s: rule.after_lost_s,
        lost_lateral_m: rule.lost_lateral_m,
        reverse_reset_m: rule.reverse_m,
        trace_every: 0,
    };
    let mut world = mtanet_scenes::World::new(&scene.with_track(track.to_path_buf()))?;
    let r = mtanet_eval::rule_alone(&mut world, &reactive, &cfg)?;
    let baseline = RuleAlone {
        sim_seconds: r.sim_seconds,
        laps: r.laps,
        lost_line_events: r.lost_events,
        lateral_mean_m: r.lateral_reactive_m,
        lap_time_s: r.control.lap_time_s,
    };
    mtanet_summaries::files::write_json(&out.join(RULE_ALONE_FILE), &baseline)?;
    Ok(())
}
