#!/usr/bin/env bash
# From GIGA's setting to this harness's hard tier, one change at a time, for the GPD-style `antipodal`:
#   A  giga_pile as published: floating Panda hand (8 cm), selector top          (kgn-bench benchmark tasks/benchmark_giga.toml)
#   B  A with the benchmark's 20 cm gripper, still floating
#   C  B with the raw selector (the paper's checks on the observed cloud)
#   D  C executed by the arm (IK, pre-grasp 10 cm, lift, carry to the bin)
#   E  the hard tier's pile: primitives, our box and camera, the arm, raw       (runs/pinned/pile/antipodal)
# Each run resumes; results/calibration/decompose.md tabulates them (kgn-bench report of the five folders).
set -euo pipefail
RUNS=${RUNS:-runs/calib}
K="kgn-bench run tasks/giga_pile.toml --detector antipodal --workers 1 --quiet"
$K --out $RUNS/B_wide_gripper --set execution.gripper=default
$K --out $RUNS/C_raw_selector --set execution.gripper=default --set selector.mode=raw
$K --out $RUNS/D_arm --set execution.gripper=default --set execution.hand=arm --set selector.mode=raw
