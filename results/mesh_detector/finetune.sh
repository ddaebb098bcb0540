#!/usr/bin/env bash
# A fine-tuned kgnv2_mesh candidate against the shipped one (issue 44), with measure.sh's seeds: Table I on both
# PS test splits, the four-look primitive views (plain and textured), single real objects, real clearance and
# the label-free physics check on real-object scenes. Needs what measure.sh needs; every step resumes.
#   bash results/mesh_detector/finetune.sh runs/train_kgnv2_mesh_ft     # writes runs/mesh_detector/finetune/<run>
set -euo pipefail
RUN=${1:?the fine-tuning run folder}
W=$RUN/final.pt
OUT=${RUNS:-runs}/mesh_detector/finetune/$(basename "$RUN")
APP=${RUNS:-runs}/mesh_detector/appearance
mkdir -p "$OUT"
for d in ps_multi ps_single; do
  [ -f "$OUT/vision_$d/vision.json" ] || kgn-bench eval vision --weights "$W" --data "data/$d" --split test --quiet \
    --out "$OUT/vision_$d"
done
for look in plain tex; do
  [ -f "$OUT/look_$look/vision.json" ] || kgn-bench eval vision --weights "$W" --data "$APP/$look" --split train \
    --quiet --out "$OUT/look_$look"
done
[ -f "$OUT/physics_real/physics.json" ] || kgn-bench eval physics --weights "$W" --data data/real_multi --views 250 \
  --quiet --out "$OUT/physics_real"
for task in single_real multi_real; do
  [ -f "$OUT/$task/summary.json" ] || FINETUNED_WEIGHTS=$W PYTHONPATH=results/mesh_detector kgn-bench run \
    "tasks/$task.toml" --detector finetuned:make --workers "${WORKERS:-2}" --quiet --out "$OUT/$task"
done
