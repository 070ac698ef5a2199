#!/usr/bin/env bash
# Runs the whole mtanet stack on this machine: sets up what is missing, builds, then starts the
# trainer, the predictor and the simulator as separate processes on the default scene and config
# (ops/mtanet.toml). Ctrl-C (or SIGTERM) stops all three cleanly.
#
#   ./ops/run_local.sh [--seconds N] [--config FILE] [--track FILE] [--lockstep]
#
# Logs and run summaries go to runs/<timestamp>/.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
seconds=0; config="$root/ops/mtanet.toml"; sim_extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --seconds) seconds=$2; shift 2 ;;
    --config) config=$2; shift 2 ;;
    --track) sim_extra+=(--track "$2"); shift 2 ;;
    --lockstep) sim_extra+=(--mode lockstep); shift ;;
    -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
    *) echo "run_local: unknown option $1 (see --help)" >&2; exit 2 ;;
  esac
done

./ops/setup.sh
echo "[run] building the services (release; first build ~10 min on 2 cores)"
cargo build --release --workspace --bins
bin="$root/target/release"
run="$root/runs/$(date +%Y%m%d-%H%M%S)"
mkdir -p "$run"
echo "[run] config $config; logs and summaries in $run"

pids=(); timer=()
start() { # name, args...
  local name=$1; shift
  # Own session: a terminal Ctrl-C reaches only this script, which then sends one SIGTERM each
  # (a second signal would make a service exit at once, skipping its clean-up).
  setsid "$bin/$name" --config "$config" --summary "$run/$name.json" "$@" 2>"$run/$name.log" &
  pids+=($!)
  echo "[run] started $name (pid $!)"
}
stop() {
  trap - INT TERM
  kill "${timer[@]}" 2>/dev/null || true
  echo "[run] stopping: SIGTERM to ${pids[*]}"
  kill -TERM "${pids[@]}" 2>/dev/null || true
  local rc=0
  for p in "${pids[@]}"; do wait "$p" || rc=$?; done
  echo "[run] all stopped (last non-zero exit: $rc)"
  for f in "$run"/*.json; do [ -f "$f" ] && echo "[run] summary $(basename "$f"): $(tr -d ' \n' <"$f" | cut -c1-400)"; done
  "$bin/mta" status --config "$config" || true
  exit "$rc"
}
trap stop INT TERM

start mta-trainer
start mta-predictor
start mta-simulator "${sim_extra[@]}"
sleep 1
"$bin/mta" status --config "$config" || true
echo "[run] running; Ctrl-C to stop. Follow progress: tail -f $run/*.log"
# Wait (interruptibly, so Ctrl-C/SIGTERM run the trap at once) for the timer or for a service
# that exits on its own, which is an error worth reporting.
if [ "$seconds" -gt 0 ]; then
  sleep "$seconds" &
  timer=($!)
fi
wait -n -p finished "${pids[@]}" "${timer[@]}" || true
if [ "${#timer[@]}" -gt 0 ] && [ "$finished" = "${timer[0]}" ]; then
  echo "[run] $seconds s are up"
else
  echo "[run] a service (pid $finished) exited on its own; stopping the rest" >&2
  kill "${timer[@]}" 2>/dev/null || true
fi
stop
