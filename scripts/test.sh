#!/usr/bin/env bash
# The test suite, as CI runs it. Installs what the third-party cross-checks need — a
# Python venv with pyarrow, mcap and rerun-sdk (pinned to the crate's rerun), and
# Debian's Chromium for the report's browser check — and runs every Rust test, optimised.
set -euo pipefail
cd "$(dirname "$0")/.."

# A full disk fails the build, the venv or Chromium's install in ways that do not say so:
# say it first. Measured on a fresh clone (session 43): the release build 1.8 GiB under
# target/, cargo's registry 0.45 GiB, the venv 0.85 GiB, Chromium 0.35 GiB with its
# libraries; with room for the tests' temporary runs, about 4 GiB.
free_kib=$(df -Pk . 2>/dev/null | awk 'NR == 2 { print $4 }' || true)
case "$free_kib" in
  '' | *[!0-9]*) ;; # df gave no figure: nothing to say
  *)
    if [ "$free_kib" -lt $((4 * 1024 * 1024)) ]; then
      echo "scripts/test.sh: warning: only $((free_kib / 1024)) MiB free on the disk" \
        "of $PWD; the build and the test set-up need about 4 GiB" >&2
    fi
    ;;
esac

# The build is most of CI's time and needs both cores; what the cross-checks need comes
# over the network. Start the build first and set those up beside it.
cargo test --release --workspace --no-run &
build_pid=$!
trap 'kill "$build_pid" 2>/dev/null || true' EXIT

if ! .venv/bin/python -c "import pyarrow, mcap, mcap_ros2, rerun, duckdb, websocket" 2>/dev/null; then
  python3 -m venv .venv
  .venv/bin/pip install --quiet --disable-pip-version-check -r tests/python/requirements.txt
fi
export UNZ_PYTHON="$PWD/.venv/bin/python"
# rerun-sdk asks once whether it may send analytics; it may not.
RERUN_ANALYTICS=0 .venv/bin/rerun analytics disable >/dev/null 2>&1 || true

if ! command -v chromium >/dev/null; then
  SUDO=""
  if [ "$(id -u)" != 0 ]; then SUDO=sudo; fi
  $SUDO apt-get install -y --no-install-recommends chromium >/dev/null \
    || { $SUDO apt-get update >/dev/null && $SUDO apt-get install -y --no-install-recommends chromium >/dev/null; }
fi
export UNZ_CHROMIUM="$(command -v chromium)"

# The build's own status: a failed build fails here, with cargo's errors above.
wait "$build_pid"
trap - EXIT

cargo test --release --workspace
