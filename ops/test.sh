#!/usr/bin/env bash
# The project's one test command (README; .ci/run calls exactly this): sets up what is missing,
# builds binaries and tests in one profile (release: nothing compiles twice), then runs every test,
# the multi-process system tests included. First run on 2 cores: ~10-15 min, mostly torch-sys and
# zstd-sys; later runs only rebuild what changed.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
./ops/setup.sh
echo "[test] every declared dependency is used (ops/check_deps.py)"
python3 ops/check_deps.py
log="$root/target/test.log"
mkdir -p target
echo "[test] building (release profile; first build ~10 min on 2 cores)"
cargo build --release --workspace --bins
echo "[test] running all tests; full output also in $log"
# libtorch errors can print whole tensors: the full log goes to a file, the console gets results.
set +e
cargo test --release --workspace --lib --bins --tests --no-fail-fast 2>&1 | tee "$log" \
  | grep --line-buffered -E '^(test |running|     Running|test result|failures:|---- |thread .* panicked|error)'
status=${PIPESTATUS[0]}
set -e
if [ "$status" -ne 0 ]; then
  echo "[test] FAILED (exit $status); the failing tests' output:"
  sed -n '/^failures:$/,/^test result/p' "$log" | head -400
  exit "$status"
fi
echo "[test] all tests passed"
