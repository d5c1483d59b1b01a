#!/usr/bin/env bash
# The README's first command: from nothing to a trained, evaluated, drawn
# CBNet on the bundled (generated) Cityscapes-like data, on CPU.
#
#   bash tools/demo.sh
#
# Steps: install the pinned stack (tools/install.sh), generate the
# benchmark preset's dataset (seeded, so the same every time), train the
# demo config (the demo CBNet, 320 steps at half the images' side) with
# `mim train cbnet_mmdet`, evaluate the checkpoint on clear and foggy val
# (AP, AP50, mIoU and their drop), draw predictions on clear and foggy
# images. Outputs go to work_dirs/demo/.
# Knobs: DEMO_EPOCHS (default: the config's 8), DEMO_NUM_TRAIN/DEMO_NUM_VAL
# (default 200/50; other sizes are generated into their own folder),
# DEMO_WORK_DIR (default work_dirs/demo).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
# One intra-op thread: on a 2-core machine with a data-loading worker beside
# the trainer, torch's default of 2 threads spins and runs several times
# slower (measured 18.5 s vs 2.6 s per demo step under load).
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
step() { printf '\n[demo %(%H:%M:%S)T] %s\n' -1 "$*"; }
start=$SECONDS

step "1/5 installing the pinned stack (first time: ~15 min, mostly mmcv)"
bash tools/install.sh
# shellcheck disable=SC1091
. "${CBNET_VENV:-$ROOT/.venv}/bin/activate"

CONFIG=configs/demo/cbnet_mit-b0_nasfpn_1xb4-8e_cityscapes-like-bench.py
WORK=${DEMO_WORK_DIR:-work_dirs/demo}
# the benchmark preset: 200 train / 50 val 256x512 images, the
# folder compare_recipes.py --preset bench reads too; smaller sets (the
# knobs) go to their own folder, so the benchmark's data is never replaced
DATA=data/cityscapes_like_bench
sizes=()
data_opts=()
if [ -n "${DEMO_NUM_TRAIN:-}${DEMO_NUM_VAL:-}" ]; then
  NUM_TRAIN=${DEMO_NUM_TRAIN:-200}
  NUM_VAL=${DEMO_NUM_VAL:-50}
  DATA=data/cityscapes_like_bench_$NUM_TRAIN-$NUM_VAL
  sizes=(--num-train "$NUM_TRAIN" --num-val "$NUM_VAL")
  ann=$DATA/annotations/instancesonly_filtered_gtFine_val.json
  data_opts=("train_dataloader.dataset.dataset.data_root=$DATA/"
             "val_dataloader.dataset.data_root=$DATA/"
             "test_dataloader.dataset.data_root=$DATA/"
             "val_evaluator.0.ann_file=$ann" "val_evaluator.1.ann_file=$ann"
             "test_evaluator.0.ann_file=$ann" "test_evaluator.1.ann_file=$ann")
fi
step "2/5 generating the benchmark preset's 256x512 images into $DATA (kept if already there)"
python tools/misc/generate_cityscapes_like.py "$DATA" --preset bench \
  "${sizes[@]}" --nproc 2 --convert --reuse

step "3/5 training with: mim train cbnet_mmdet $CONFIG (at half the images' side)"
extra=("${data_opts[@]}")
if [ -n "${DEMO_EPOCHS:-}" ]; then
  extra+=("train_cfg.max_epochs=$DEMO_EPOCHS"
          "train_cfg.val_interval=$DEMO_EPOCHS"
          "param_scheduler.1.end=$DEMO_EPOCHS"
          "default_hooks.checkpoint.interval=$DEMO_EPOCHS")
fi
opts=()
[ ${#extra[@]} -eq 0 ] || opts=(--cfg-options "${extra[@]}")
mim train cbnet_mmdet "$CONFIG" --work-dir "$WORK" "${opts[@]}"
CKPT=$(cat "$WORK/last_checkpoint")

step "4/5 evaluating $CKPT on clear and foggy val (beta 0.01, 0.02)"
data_cfg=()
[ ${#data_opts[@]} -eq 0 ] || data_cfg=(--cfg-options "${data_opts[@]}")
python tools/analysis_tools/ap_drop.py "$CONFIG" "$CKPT" \
  --betas 0.01 0.02 --out-dir "$WORK/ap_drop" "${data_cfg[@]}"

step "5/5 drawing predictions (clear | beta 0.01 | beta 0.02) from the score the evaluation paints masks from (printed)"
python tools/misc/draw_predictions.py "$CONFIG" "$CKPT" \
  $(ls "$DATA"/leftImg8bit/val/*/*_leftImg8bit.png | head -n 2) \
  --betas 0.01 0.02 --out "$WORK/predictions.png"

step "done in $(( (SECONDS - start) / 60 )) min: table $WORK/ap_drop/ap_drop.md, picture $WORK/predictions.png"
cat "$WORK/ap_drop/ap_drop.md"
