#!/usr/bin/env bash
# How much VGN gains from data (issue 42): VGN trained on the first N scenes of data/vgn (tasks/vgn_train.toml with
# vgn.max_scenes = N; 10 % of them held out) for EPOCHS epochs (default 90, the config's), then GIGA's rounds
# (seed 0, 100 a task) with each run's weights (results/calibration/vgn_runs.py names the runs s<N>_e<E>).
# GIGA trains on about 33k scenes a scene type; data/vgn has 1000.
#   bash results/calibration/vgn_data_volume.sh 300 600 1000
#   ANY=1 bash results/calibration/vgn_data_volume.sh 300      # the rotation towards any yaw that held (_any)
#   NOAUG=1 bash results/calibration/vgn_data_volume.sh 300    # without the k*90 rotation augmentation (_noaug)
# Every step resumes. Each run's summary: runs/vgn_runs/<task>/<name>/summary.md.
set -euo pipefail
RUNS=${RUNS:-runs}
EPOCHS=${EPOCHS:-90}
sizes=("$@")
[ ${#sizes[@]} -eq 0 ] && sizes=(300 600 1000)
for n in "${sizes[@]}"; do
  name=s${n}_e$EPOCHS
  set_args=(--set "vgn.max_scenes=$n" --set "vgn.epochs=$EPOCHS")
  if [ -n "${ANY:-}" ]; then name=${name}_any; set_args+=(--set vgn.rotation_target=any_holding); fi
  if [ -n "${NOAUG:-}" ]; then name=${name}_noaug; set_args+=(--set vgn.augment=false); fi
  kgn-bench train tasks/vgn_train.toml --threads 1 --set "vgn.out=$RUNS/train_vgn_$name" "${set_args[@]}"
  for task in giga_pile giga_packed; do
    PYTHONPATH=results/calibration VGN_RUNS=$RUNS kgn-bench run "tasks/$task.toml" --detector "vgn_runs:$name" \
      --workers 1 --quiet --out "$RUNS/vgn_runs/$task/$name"
  done
done
