#!/usr/bin/env bash
# How much VGN gains from data (issue 42): VGN trained on the first N scenes of data/vgn (tasks/vgn_train.toml with
# vgn.max_scenes = N; 10 % of them held out), then GIGA's rounds (seed 0, 100 a task) with each run's weights
# (results/calibration/vgn_runs.py names the runs). GIGA trains on about 33k scenes a scene type; we have 1000.
#   bash results/calibration/vgn_data_volume.sh 100 300     # 1000: tasks/vgn_train.toml's own run, runs/train_vgn
#   ANY=1 bash results/calibration/vgn_data_volume.sh 300   # the rotation towards any yaw that held (_any)
# Every step resumes. The table: kgn-bench report runs/vgn_runs --out results/calibration/vgn_data_volume
set -euo pipefail
RUNS=${RUNS:-runs}
sizes=("$@")
[ ${#sizes[@]} -eq 0 ] && sizes=(100 300)
for n in "${sizes[@]}"; do
  set_args=()
  if [ "$n" = 1000 ]; then name=s1000; out=$RUNS/train_vgn; else
    name=s$n; out=$RUNS/train_vgn_s$n; set_args+=(--set "vgn.max_scenes=$n"); fi
  if [ -n "${ANY:-}" ]; then
    name=${name}_any; out=${out}_any; set_args+=(--set vgn.rotation_target=any_holding); fi
  kgn-bench train tasks/vgn_train.toml --threads 1 --set "vgn.out=$out" "${set_args[@]}"
  for task in giga_pile giga_packed; do
    PYTHONPATH=results/calibration VGN_RUNS=$RUNS kgn-bench run "tasks/$task.toml" --detector "vgn_runs:$name" \
      --workers 1 --quiet --out "$RUNS/vgn_runs/$task/$name"
  done
done
