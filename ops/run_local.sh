#!/usr/bin/env bash
# Runs the whole mtanet stack on this machine: sets up what is missing, builds, then starts the
# trainer, the predictor and the simulator as separate processes (`mta up`) with one live
# progress line. Ctrl-C (or SIGTERM) stops all three cleanly and writes the run's report.
#
#   ./ops/run_local.sh [--track FILE] [--sim-seconds S] [--lockstep] [--out DIR]
#                      [--config FILE] [--checkpoint FILE [--no-learning]] [--record]
#
# Defaults: the oval, until Ctrl-C, real time, runs/<timestamp>/, ops/mtanet.toml. The run
# folder gets report.json, lap_trace.png, latency.png, figure.png, learning.png,
# model_error.png, model.safetensors, learning.jsonl, each process's log and summary, the car's
# trace and, with --record, recording.mcap. `mta up --help` says more.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
case "${1:-}" in -h|--help) sed -n '2,12p' "$0"; exit 0 ;; esac

./ops/setup.sh
echo "[run] building the services (release; first build ~10 min on 2 cores)"
cargo build --release --workspace --bins
config=(--config "$root/ops/mtanet.toml")
for a in "$@"; do [ "$a" = "--config" ] && config=(); done
# exec: Ctrl-C and SIGTERM go straight to mta up, which stops the services one signal each.
exec "$root/target/release/mta" up "${config[@]}" "$@"
