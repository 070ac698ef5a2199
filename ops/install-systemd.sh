#!/usr/bin/env bash
# Renders the systemd units in ops/systemd/ for this checkout and installs them.
#   ./ops/install-systemd.sh [--dest DIR] [--config FILE] [--user USER]
# Default DEST is /etc/systemd/system (then: systemctl daemon-reload && systemctl start mtanet.target).
# With --dest elsewhere it only renders (used by the tests to verify the units).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
dest=/etc/systemd/system; config="$root/ops/mtanet.toml"; user=$(id -un); bin="$root/target/release"
while [ $# -gt 0 ]; do
  case "$1" in
    --dest) dest=$2; shift 2 ;;
    --config) config=$(cd "$(dirname "$2")" && pwd)/$(basename "$2"); shift 2 ;;
    --user) user=$2; shift 2 ;;
    --bin) bin=$2; shift 2 ;;
    *) echo "install-systemd: unknown option $1" >&2; exit 2 ;;
  esac
done
for b in mta-simulator mta-predictor mta-trainer; do
  [ -x "$bin/$b" ] || { echo "install-systemd: $bin/$b missing: build with cargo build --release --workspace --bins" >&2; exit 1; }
done
mkdir -p "$dest"
for f in "$root"/ops/systemd/*.service.in; do
  out="$dest/$(basename "${f%.in}")"
  sed -e "s|@BIN@|$bin|g" -e "s|@CONFIG@|$config|g" -e "s|@USER@|$user|g" "$f" >"$out"
  echo "installed $out"
done
cp "$root/ops/systemd/mtanet.target" "$dest/"
echo "installed $dest/mtanet.target"
