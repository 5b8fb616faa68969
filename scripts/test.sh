#!/usr/bin/env bash
# The test suite, as CI runs it. Installs what the third-party cross-checks need
# (a Python venv with pyarrow and mcap) and runs every Rust test, optimised.
set -euo pipefail
cd "$(dirname "$0")/.."

if ! .venv/bin/python -c "import pyarrow, mcap" 2>/dev/null; then
  python3 -m venv .venv
  .venv/bin/pip install --quiet --disable-pip-version-check -r tests/python/requirements.txt
fi
export UNZ_PYTHON="$PWD/.venv/bin/python"

cargo test --release --workspace
