#!/usr/bin/env bash
# Install the pinned cbnet_mmdet stack into a virtual environment.
#
#   bash tools/install.sh            # into ./.venv (CBNET_VENV to change)
#
# Idempotent: on a ready environment it checks and returns in seconds.
# What it pins and why:
#   torch 2.13.0      the CPU wheel here (TORCH_SPEC to override, e.g. a CUDA
#                     build on a GPU machine)
#   mmcv 2.1.0        compiled from source WITH ops (11 minutes on an idle
#                     2-core machine, 17 under load: docs/install.md; CUDA
#                     ops when nvcc and a CUDA torch are present).
#                     pip caches the built wheel, so a second environment on
#                     the same machine reuses it.
#   mmengine 0.10.7, mmdet 3.3.0
#   setuptools [77,80.9) mmcv's setup.py, openmim and MMEngine's config
#                     bases import pkg_resources (gone in 81; from 80.9 every
#                     import prints a deprecation warning); torch wants >= 77
#   openmim 0.3.9     without opendatalab/openxlab, which pin setuptools 60
set -euo pipefail

ROOT=$(cd "$(dirname "$0")/.." && pwd)
VENV=${CBNET_VENV:-$ROOT/.venv}
PY=${PYTHON:-python3}
TORCH_SPEC=${TORCH_SPEC:-torch==2.13.0}
MMCV_SPEC=mmcv==2.1.0
STAMP="$VENV/.cbnet_mmdet_stamp"

say() { printf '[install %(%H:%M:%S)T] %s\n' -1 "$*"; }

# Compile jobs for mmcv: MAX_JOBS, else every core this process may use.
# `nproc` alone honours OMP_NUM_THREADS, which tools/demo.sh (and many a
# training shell) sets to 1: mmcv then compiled with `ninja -j 1`, half
# the speed on 2 cores (found 2026-11-27 timing the demo on a fresh machine).
build_jobs() { echo "${MAX_JOBS:-$(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc)}"; }
if [ "${1:-}" = "--print-build-jobs" ]; then build_jobs; exit 0; fi

# Everything that decides what gets installed goes into the stamp.
stamp_now() {
  cat "$ROOT/tools/install.sh" "$ROOT/requirements/"*.txt "$ROOT/pyproject.toml"
  echo "$TORCH_SPEC"
}
want=$(stamp_now | sha256sum | cut -d' ' -f1)

# The project itself is installed as a regular (not editable) package:
# `mim train cbnet_mmdet` runs `<site-packages>/cbnet_mmdet/.mim/tools/
# train.py`, which an editable install does not have. Tests run from the
# source tree (`python -m pytest` puts it first on sys.path, pytest's
# `pythonpath` the projects' packages cbnet_dehaze and cbnet_serving). The
# sources go into a second stamp, so an edited tree is reinstalled
# (seconds). One install carries the five packages: the plugin, the lab,
# the tools' library and the two projects' packages.
PROJECT_STAMP="$VENV/.cbnet_mmdet_project_stamp"
project_now() {
  (cd "$ROOT" && find cbnet_mmdet cbnet_lab cbnet_tools projects configs tools \
     pyproject.toml README.md \
     -name __pycache__ -prune -o -type f -print 2>/dev/null \
     | LC_ALL=C sort | xargs sha256sum) || true
}
install_project() {
  say "cbnet_mmdet (regular install, so mim finds .mim/tools and .mim/configs)"
  "$VENV/bin/python" -m pip install --progress-bar off -q --no-deps \
    --no-build-isolation --force-reinstall "$ROOT" \
    2> >(grep -v "^WARNING: Location" >&2)
  rm -rf "$ROOT/build"
  project_now | sha256sum | cut -d' ' -f1 >"$PROJECT_STAMP"
}

if [ -x "$VENV/bin/python" ] && [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$want" ] \
   && "$VENV/bin/python" -c 'import mmcv.ops, mmdet' 2>/dev/null; then
  if [ ! -f "$PROJECT_STAMP" ] || \
     [ "$(cat "$PROJECT_STAMP")" != "$(project_now | sha256sum | cut -d' ' -f1)" ]; then
    install_project
  fi
  say "environment $VENV is ready"
  exit 0
fi

if [ ! -x "$VENV/bin/python" ]; then
  say "creating virtual environment $VENV"
  "$PY" -m venv "$VENV"
fi
# shellcheck disable=SC1091
. "$VENV/bin/activate"
export PIP_DISABLE_PIP_VERSION_CHECK=1
export PIP_CONSTRAINT="$ROOT/requirements/constraints.txt"
# (the grep hides a harmless warning of this machine's pip config)
pipq() { python -m pip install --progress-bar off -q "$@" 2> >(grep -v "^WARNING: Location" >&2); }

say "build tools: setuptools>=77,<80.9, wheel"
pipq "setuptools>=77,<80.9" wheel packaging
say "PyTorch: $TORCH_SPEC"
pipq "$TORCH_SPEC"
say "NumPy and MMEngine 0.10.7"
pipq "numpy<2" mmengine==0.10.7

if python - <<'PY' 2>/dev/null
import importlib.metadata as m, mmcv.ops  # noqa
assert m.version('mmcv') == '2.1.0'
PY
then
  say "mmcv 2.1.0 with ops already installed"
else
  FORCE_CUDA=0
  if command -v nvcc >/dev/null && python -c 'import torch,sys; sys.exit(not torch.version.cuda)'; then
    FORCE_CUDA=1
  fi
  jobs=$(build_jobs)
  say "compiling $MMCV_SPEC with ops (FORCE_CUDA=$FORCE_CUDA, $jobs jobs); 11-17 min on 2 cores unless pip has it cached"
  log=$(mktemp)
  MMCV_WITH_OPS=1 FORCE_CUDA=$FORCE_CUDA MAX_JOBS=$jobs \
    python -m pip install -v --no-build-isolation "$MMCV_SPEC" >"$log" 2>&1 &
  pid=$!
  start=$SECONDS
  while kill -0 "$pid" 2>/dev/null; do
    sleep 30
    # ninja prints "[k/N] c++ ..." per source (pip -v indents it)
    n=$(grep -oE '^[[:space:]]*\[[0-9]+/[0-9]+\]' "$log" | tail -n 1 | tr -d ' []' || true)
    say "  mmcv build: $((SECONDS - start)) s, ${n:-0} sources compiled"
  done
  if ! wait "$pid"; then
    tail -n 40 "$log"
    say "mmcv build FAILED (full log: $log)"
    exit 1
  fi
  rm -f "$log"
  say "mmcv built in $((SECONDS - start)) s"
fi

say "MMDetection 3.3.0 and the runtime requirements"
pipq mmdet==3.3.0 -r "$ROOT/requirements/runtime.txt"
say "openmim 0.3.9 (without opendatalab: pip will say openmim 'requires opendatalab', as intended) and test tools"
pipq --no-deps openmim==0.3.9
pipq -r "$ROOT/requirements/tests.txt"
say "serving extra: Ray Serve (requirements/serve.txt; the serving tests need it)"
pipq -r "$ROOT/requirements/serve.txt"
install_project

python - <<'PY'
import importlib.metadata as m
import cbnet_mmdet, mmcv.ops, torch  # noqa: F401
import cbnet_dehaze, cbnet_lab, cbnet_serving, cbnet_tools  # noqa: F401
print('  ' + ', '.join(f'{p} {m.version(p)}' for p in
      ('torch', 'mmcv', 'mmengine', 'mmdet', 'cbnet_mmdet', 'setuptools',
       'numpy', 'openmim', 'ray')))
PY
stamp_now | sha256sum | cut -d' ' -f1 >"$STAMP"
say "done: activate with  . $VENV/bin/activate"
