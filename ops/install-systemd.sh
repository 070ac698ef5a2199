#!/usr/bin/env bash
# Renders the systemd units of the stack (from [stack] in the config, by `mta systemd`) for this
# checkout and installs them.
#   ./ops/install-systemd.sh [--dest DIR] [--config FILE] [--user USER] [--bin DIR]
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
[ -x "$bin/mta" ] || { echo "install-systemd: $bin/mta missing: build with cargo build --release --workspace --bins" >&2; exit 1; }
exec "$bin/mta" systemd --dest "$dest" --config "$config" --user "$user" --bin "$bin"
