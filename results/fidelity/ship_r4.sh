#!/usr/bin/env bash
# Ship one recipe-4 model and re-measure what it feeds (issue 43, items 4-5). Run from the repository root with the
# project's environment active, after the model's training has written its final.pt:
#
#   bash results/fidelity/ship_r4.sh kgnv2_single     # runs/train_kgnv2_single_r4 → assets/weights/kgnv2_single.pt
#   bash results/fidelity/ship_r4.sh kgnv2            # runs/train_kgnv2_multi_r4  → assets/weights/kgnv2.pt
#   bash results/fidelity/ship_r4.sh kgn_single       # runs/train_kgn_single_r4   → assets/weights/kgn_single.pt
#   bash results/fidelity/ship_r4.sh kgn              # runs/train_kgn_multi_r4    → assets/weights/kgn.pt
#   bash results/fidelity/ship_r4.sh kgnv2_sbranch_single   # Table II's scale-branch model, the same recipe
#
# Steps: the weights and model card (kgn-bench ship); Table I and Table II on the full PS test splits (each model's
# evaluation is cached in results/vision/ by the weights' hash, so only the new model is evaluated); Table I old
# beside new against the commit given as BEFORE (default HEAD: commit the shipped weights after this script);
# for the multi-split models, which the closed loop runs, the error decomposition into results/fidelity/errors_<name>.
# The closed-loop rows and the CI baselines follow the multi-split models (printed at the end: they take about an
# hour and rewrite results/benchmark.* and results/ci_baseline*.json).
set -euo pipefail
NAME=${1:?kgnv2_single, kgnv2, kgn_single, kgn or kgnv2_sbranch_single}
case "$NAME" in
  kgnv2_single|kgn_single|kgnv2_sbranch_single) RUN=runs/train_${NAME}_r4 ;;
  kgnv2|kgn) RUN=runs/train_${NAME}_multi_r4 ;;
  *) echo "ship_r4.sh: unknown model '$NAME' (kgnv2_single, kgnv2, kgn_single, kgn or kgnv2_sbranch_single)" >&2; exit 2 ;;
esac
[ -f "$RUN/final.pt" ] || { echo "ship_r4.sh: $RUN/final.pt does not exist: the training has not finished" >&2; exit 1; }
BEFORE=${BEFORE:-HEAD}
OUT=results/fidelity/r4
mkdir -p "$OUT"

kgn-bench ship "$RUN/final.pt" --name "$NAME"
kgn-bench experiment table1 > /dev/null
kgn-bench experiment table2 > /dev/null
python results/fidelity/table1_compare.py "git:$BEFORE" results/vision_table1.json --old-label "before" \
  --new-label "recipe 4" > "$OUT/table1_before_after.md"
python results/fidelity/compare_histories.py "$NAME=$RUN/history.jsonl" > "$OUT/${NAME}_history.md"
if [ "$NAME" = kgnv2 ] || [ "$NAME" = kgn ]; then
  kgn-bench eval errors --weights "$NAME" --data data/ps_multi --split test --out "results/fidelity/errors_$NAME"
fi
echo "shipped $NAME; Table I before/after: $OUT/table1_before_after.md; curves: $OUT/${NAME}_history.md"
echo "before committing: set config_stem=\"$(basename "$RUN")\" on the model(s) of weights $NAME in kgn_bench/eval/experiments.py"
echo "  (tests/test_experiments.py checks it against the checkpoint) and list the weights in docs/dataset-training.md"
if [ "$NAME" = kgnv2 ] || [ "$NAME" = kgn ]; then
  echo "next: kgn-bench benchmark --out results --workers 2 (closed-loop rows), make ci-baselines, kgn-bench perf detector --variant $NAME"
fi
