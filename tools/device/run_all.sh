#!/usr/bin/env bash
# One call on a lent GPU machine: set-up, the CUDA tests, like-for-like
# speed (fp32, AMP), the harness sets; records under $OUT.
#   bash tools/device/run_all.sh --out "$OUT"      # on the device machine
#   bash tools/device/run_all.sh --dry-run         # here: CPU, tiny budget
#   bash tools/device/run_all.sh --prepare ...     # here: stage what travels
# Everything is in run_all.py (standard library only: on a fresh device
# machine the OpenMMLab stack is not there yet); docs/benchmarks.md, "One
# call on a lent GPU". PYTHON picks the interpreter (default: python3,
# the device image's, which holds its CUDA PyTorch).
set -euo pipefail
exec "${PYTHON:-python3}" "$(dirname "$0")/run_all.py" "$@"
