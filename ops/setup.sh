#!/usr/bin/env bash
# Installs everything mtanet needs that cargo does not fetch itself, into .deps/ (git-ignored).
# Idempotent: every step checks its stamp first, so a second run downloads nothing.
#   libtorch 2.13.0 (for tch 0.26)  <- PyPI wheels torch + nvidia-cuda-runtime + nvidia-cuda-cupti
#   MuJoCo 3.17.0 (for mujoco-rs 7) <- PyPI wheel mujoco
#   mujoco-compile (MuJoCo 2.2.2)   <- Debian package libmujoco-samples, for the 2.2 scene check
#   iox2-link-tunnel-zenoh 0.10.0   <- crates.io (cargo install --locked), for a stack on two hosts
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
deps="$root/.deps"
mkdir -p "$deps"
log() { printf '[setup] %s\n' "$*"; }

# Pinned wheels with the sha256 PyPI publishes for them; pip refuses a file that differs. pip and
# cargo show their own progress (a bar on a terminal, a line per file or crate in a log).
pip_fetch() { # $1 = stage dir; remaining = "name==version --hash=sha256:..." lines
  local dir=$1; shift
  local req="$dir/requirements.txt"
  mkdir -p "$dir"
  printf '%s\n' "$@" >"$req"
  python3 -m pip download --progress-bar on --no-deps --only-binary=:all: --require-hashes \
    --python-version 3.11 --implementation cp --abi cp311 \
    --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 \
    --platform manylinux_2_25_x86_64 --platform manylinux_2_17_x86_64 \
    --platform manylinux2014_x86_64 \
    --dest "$dir" -r "$req"
}

install_libtorch() {
  local dst="$deps/libtorch"
  if [ -f "$dst/.complete" ]; then log "libtorch 2.13.0: present"; return; fi
  log "libtorch 2.13.0: downloading ~560 MB of wheels from PyPI (once)"
  local stage="$deps/stage-libtorch"
  rm -rf "$stage" "$dst"
  pip_fetch "$stage" \
    "torch==2.13.0 --hash=sha256:60fcdcb2f3876e21146cb4524ef06397d727ca9ad5f020818547e25075fe3cb7" \
    "nvidia-cuda-runtime==13.0.96 --hash=sha256:7f82250d7782aa23b6cfe765ecc7db554bd3c2870c43f3d1821f1d18aebf0548" \
    "nvidia-cuda-cupti==13.0.85 --hash=sha256:4eb01c08e859bf924d222250d2e8f8b8ff6d3db4721288cf35d14252a4d933c8"
  log "libtorch: extracting the CPU part"
  mkdir -p "$stage/x" "$dst/lib"
  (cd "$stage/x" && python3 -m zipfile -e "$stage"/torch-2.13.0-*.whl . )
  mv "$stage/x/torch/include" "$dst/include"
  cp -a "$stage/x/torch/lib/libtorch_cpu.so" "$stage/x/torch/lib/libc10.so" "$dst/lib/"
  cp -a "$stage"/x/torch/lib/libgomp* "$dst/lib/" 2>/dev/null || true
  # The CUDA wheel's libtorch_cpu.so still needs these two; both load without a GPU.
  (cd "$stage/x" && python3 -m zipfile -e "$stage"/nvidia_cuda_runtime-*.whl . \
                 && python3 -m zipfile -e "$stage"/nvidia_cuda_cupti-*.whl . )
  find "$stage/x/nvidia" -name 'libcudart.so.13*' -exec cp -a {} "$dst/lib/" \;
  find "$stage/x/nvidia" -name 'libcupti.so.13*' -exec cp -a {} "$dst/lib/" \;
  ln -sf libtorch_cpu.so "$dst/lib/libtorch.so"
  echo "2.13.0" >"$dst/build-version"
  cp "$stage"/x/torch-2.13.0.dist-info/*LICENSE* "$dst/" 2>/dev/null || true
  for lib in libtorch_cpu.so libc10.so libcudart.so.13 libcupti.so.13; do
    [ -e "$dst/lib/$lib" ] || { echo "setup: $lib missing after extraction" >&2; exit 1; }
  done
  rm -rf "$stage"
  touch "$dst/.complete"
  log "libtorch: installed in $dst ($(du -sh "$dst" | cut -f1))"
}

install_mujoco() {
  local dst="$deps/mujoco"
  if [ -f "$dst/.complete" ]; then log "MuJoCo 3.17.0: present"; return; fi
  log "MuJoCo 3.17.0: downloading the PyPI wheel (once)"
  local stage="$deps/stage-mujoco"
  rm -rf "$stage" "$dst"
  pip_fetch "$stage" \
    "mujoco==3.17.0 --hash=sha256:d66928d86a2d1b601bbaa4dc11db50214d17d5301bb8afd84721313b67ff0874"
  mkdir -p "$stage/x" "$dst/lib"
  (cd "$stage/x" && python3 -m zipfile -e "$stage"/mujoco-3.17.0-*.whl . )
  cp -a "$stage/x/mujoco/libmujoco.so.3.17.0" "$dst/lib/"
  ln -sf libmujoco.so.3.17.0 "$dst/lib/libmujoco.so"
  mkdir -p "$dst/include"
  cp -a "$stage/x/mujoco/include/mujoco" "$dst/include/"
  find "$stage/x" -maxdepth 2 -iname '*LICENSE*' -exec cp -a {} "$dst/" \;
  rm -rf "$stage"
  touch "$dst/.complete"
  log "MuJoCo: installed in $dst"
}

install_debian() {
  if command -v mujoco-compile >/dev/null; then log "mujoco-compile (MuJoCo 2.2.2): present"; return; fi
  log "installing Debian package libmujoco-samples (mujoco-compile, MuJoCo 2.2.2)"
  local sudo=""; [ "$(id -u)" -eq 0 ] || sudo="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get install -y -q --no-install-recommends libmujoco-samples >/dev/null 2>&1 \
    || { $sudo apt-get update -q >/dev/null && $sudo apt-get install -y -q --no-install-recommends libmujoco-samples >/dev/null; }
  command -v mujoco-compile >/dev/null || { echo "setup: mujoco-compile not found after install" >&2; exit 1; }
}

# iceoryx2's Zenoh link tunnel (same iceoryx2 0.10 as the workspace): joins the iceoryx2 domains
# of two hosts (ARCHITECTURE.md "Beyond one machine"; tests/tests/tunnel.rs). Built once with its
# own lock file; ~10 min on 2 cores, in its own target folder so the workspace's stays untouched.
install_tunnel() {
  local dst="$deps/iox2"
  if [ -f "$dst/.complete" ] && [ -x "$dst/bin/iox2-link-tunnel-zenoh" ]; then
    log "iox2-link-tunnel-zenoh 0.10.0: present"; return
  fi
  log "iox2-link-tunnel-zenoh 0.10.0: building from crates.io (once, ~10 min on 2 cores)"
  rm -rf "$dst"
  cargo install --locked --version 0.10.0 --root "$dst" --target-dir "$deps/stage-iox2" \
    iceoryx2-integrations-zenoh-link-tunnel-cli
  rm -rf "$deps/stage-iox2"
  touch "$dst/.complete"
  log "iox2-link-tunnel-zenoh: installed in $dst/bin"
}

install_libtorch
install_mujoco
install_debian
install_tunnel
log "done"
