#!/usr/bin/env bash
# What the arm costs (issue 42, item 4): each detector on the same GIGA rounds (same seed, objects, placement,
# camera and noise), executed by the floating hand and by the 7-DoF arm, both with the benchmark's 20 cm gripper
# (the arm cannot carry the Panda hand) and the detector's best candidate as predicted (selector "top").
# The arm adds IK, the arm's own collisions, reach, and the carry to the bin.
#   RUNS=runs/arm_vs_floating bash results/calibration/arm_vs_floating.sh [task ...]
# Each run resumes; the table: .venv/bin/python results/calibration/arm_vs_floating_table.py "$RUNS".
set -euo pipefail
RUNS=${RUNS:-runs/arm_vs_floating}
TASKS=${*:-giga_pile giga_packed}
DETECTORS=${DETECTORS:-oracle vgn antipodal kgnv2 random}
for task in $TASKS; do
  for det in $DETECTORS; do
    K="kgn-bench run tasks/$task.toml --detector $det --workers 1 --quiet --set execution.gripper=default"
    $K --out "$RUNS/$task/floating/$det"
    $K --out "$RUNS/$task/arm/$det" --set execution.hand=arm
  done
done
