//! `mta`: the operator CLI, a thin shell over the crates that do the work: `mtanet-launch`
//! (up, systemd), `mtanet-soak`, `mtanet-observe` (status, top, record,
//! replay), `mtanet-report` (report, plot), `mtanet-offline` (train, figures, synth, probe,
//! drive, track, analyze) and `mtanet-experiment` (experiment).

use clap::{Parser, Subcommand};
use mtanet_launch::{systemd, up};
use mtanet_observe::{record, replay, status, top};
use mtanet_offline::{evaluate, figures, synth, track, train};
use mtanet_report::{plot, report};
use mtanet_soak as soak;
use mtanet_soak::pingpong;

#[derive(Parser)]
#[command(
    name = "mta",
    version,
    about = "mtanet operator CLI: training, reports, soak runs, status"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Train MTA-PredNet offline from a dataset .npz.
    Train(train::TrainArgs),
    /// Regenerate the figure strip and analysis of a checkpoint on a dataset.
    Figures(figures::FiguresArgs),
    /// Write a synthetic action-conditioned dataset .npz.
    Synth(synth::SynthArgs),
    /// Show the nodes and topics of a running stack.
    Status(status::StatusArgs),
    /// Live terminal view of a running stack (processes, topics, driver, trainer, trends).
    Top(top::TopArgs),
    /// Soak: the real workload for M minutes (real time or lockstep) against the raw iceoryx2
    /// ping-pong floor; soak.json, soak.png and a table of percentiles.
    Soak(soak::SoakArgs),
    /// The far side of the soak's raw ping-pong (started by `mta soak`).
    #[command(hide = true)]
    PingpongPeer(pingpong::PeerArgs),
    /// Record the live topics of a running stack into an MCAP file.
    Record(record::RecordArgs),
    /// Play a recording's observations (and weights) to a predictor in place of the simulator,
    /// comparing its commands with the recorded ones.
    Replay(replay::ReplayArgs),
    /// Run the whole stack here (trainer, predictor, simulator) with a live progress line and a
    /// report in the run folder (what ./ops/run_local.sh runs).
    Up(up::UpArgs),
    /// Write a run folder's report.json and pictures from its summaries and trace.
    Report(report::ReportArgs),
    /// Draw a run folder's curves as PNGs: learning curve, live model error, step latency.
    Plot(plot::PlotArgs),
    /// Counterfactual probe of a checkpoint on a track: does it rank commands like the world?
    Probe(evaluate::ProbeArgs),
    /// Drive a track in-process by active inference, through a checkpoint or the MuJoCo oracle.
    Drive(evaluate::DriveArgs),
    /// Write a generated track nobody tuned on (`generated:N`) as a track CSV, and its scene.
    Track(track::TrackArgs),
    /// Render the systemd units of the stack from its [stack] section.
    Systemd(systemd::SystemdArgs),
    /// Run a matrix of variants x seeds (learn on one track, evaluate on others) and summarise
    /// it over seeds: results.csv, summary.md, plots.
    Experiment(mtanet_experiment::ExperimentArgs),
    /// Measure a checkpoint's layers on a drive: each layer's timescale, what it holds about the
    /// road (cross-validated read-outs against frame baselines), the paper's figure strip.
    Analyze(mtanet_offline::analyze::AnalyzeArgs),
}

fn main() -> anyhow::Result<()> {
    mtanet_ipc::logging::init();
    match Cli::parse().cmd {
        Cmd::Train(a) => train::run(a),
        Cmd::Figures(a) => figures::run(a),
        Cmd::Synth(a) => synth::run(a),
        Cmd::Status(a) => status::run(a),
        Cmd::Top(a) => top::run(a),
        Cmd::Soak(a) => soak::run(a),
        Cmd::PingpongPeer(a) => pingpong::peer(a),
        Cmd::Up(a) => up::run(a),
        Cmd::Record(a) => record::run(a),
        Cmd::Replay(a) => replay::run(a),
        Cmd::Report(a) => report::run(a, &mtanet_offline::analyze::strip::strip_on_track),
        Cmd::Plot(a) => plot::run(a),
        Cmd::Probe(a) => evaluate::probe(a),
        Cmd::Drive(a) => evaluate::drive_cmd(a),
        Cmd::Track(a) => track::run(a),
        Cmd::Systemd(a) => systemd::run(a),
        Cmd::Experiment(a) => mtanet_experiment::run(a),
        Cmd::Analyze(a) => mtanet_offline::analyze::run(a),
    }
}
