#!/usr/bin/env bash
# The README's test command: install what is missing, then run every test.
#   bash tools/run_tests.sh [pytest args...]    e.g. -m "not slow"
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
bash "$ROOT/tools/install.sh"
VENV=${CBNET_VENV:-$ROOT/.venv}
cd "$ROOT"
# One intra-op thread unless told otherwise: the tests' models are tiny, and
# on a 2-core machine two threads spin against data-loading workers and
# subprocesses (several times slower under load).
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
exec "$VENV/bin/python" -m pytest -ra --durations=15 "$@"
