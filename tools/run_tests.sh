#!/usr/bin/env bash
# The README's test command: install what is missing, then run every test.
#   bash tools/run_tests.sh [pytest args...]    e.g. -m "not slow"
#   bash tools/run_tests.sh --print-command [pytest args...]   (runs nothing)
# The suite runs in one worker process per core (pytest-xdist; each test
# file whole on one worker, so its module fixtures are built once):
# CBNET_TEST_WORKERS=N sets the number, 1 runs it in this one process.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
VENV=${CBNET_VENV:-$ROOT/.venv}
# The cores this process may use: `nproc` alone honours OMP_NUM_THREADS,
# which is set to 1 below (tools/install.sh's build_jobs, likewise).
WORKERS=${CBNET_TEST_WORKERS:-$(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc)}
case $WORKERS in
  '' | *[!0-9]* | 0)
    echo "run_tests.sh: CBNET_TEST_WORKERS must be a whole number >= 1, not '$WORKERS'" >&2
    exit 2;;
esac
CMD=("$VENV/bin/python" -m pytest -ra --durations=15)
if [ "$WORKERS" -gt 1 ]; then CMD+=(-n "$WORKERS" --dist loadfile); fi
if [ "${1:-}" = "--print-command" ]; then
  shift
  printf '%q ' "${CMD[@]}" "$@"; echo  # shell-quoted
  exit 0
fi
bash "$ROOT/tools/install.sh"
cd "$ROOT"
# One intra-op thread unless told otherwise: the tests' models are tiny, and
# on a 2-core machine two threads spin against data-loading workers and
# subprocesses (several times slower under load).
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
exec "${CMD[@]}" "$@"
