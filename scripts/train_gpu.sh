#!/usr/bin/env bash
# Train and ship a KGN-family model from nothing on a machine with a GPU and the project installed
# (`make setup`, or the wheels): the PS data generated on every core, the training on the GPU (bfloat16
# autocast, parallel loading), the weights and model card written. The KGN data takes about a minute on 16
# cores (8 views/s a core), so the 15 minutes of a lent GPU go to training.
#
#   scripts/train_gpu.sh CONFIG NAME [--set SECTION.NAME=VALUE ...]
#     CONFIG  a KGN training config (tasks/train_kgnv2_multi.toml, tasks/train_kgnv2_multi_s2.toml, ...)
#     NAME    the weights' name: OUT/NAME.pt and OUT/NAME.md
#   environment: DATA (the config's [train] data), RUN (the config's [train] out), SCENES (1000), VIEWS (5),
#     WORKERS (every core), DEVICE (cuda), OUT (assets/weights)
#
# The data folder's name picks the split: "single" in it generates single-object scenes, else multi-object.
# Everything resumes: the data generator and the training pick up what is on disk. Tested on a CPU with a tiny
# setting: DEVICE=cpu SCENES=4 ... --set train.epochs=1 --set train.limit=8 (tests/test_scripts.py).
set -euo pipefail
CONFIG=${1:?usage: scripts/train_gpu.sh CONFIG NAME [--set SECTION.NAME=VALUE ...]}
NAME=${2:?usage: scripts/train_gpu.sh CONFIG NAME [--set SECTION.NAME=VALUE ...]}
shift 2
KGN=${KGN:-kgn-bench}
read_train() {  # the config's [train] value of $1
  "${PY:-python3}" -c 'import sys, tomllib; print(tomllib.load(open(sys.argv[1], "rb"))["train"][sys.argv[2]])' "$CONFIG" "$1"
}
DATA=${DATA:-$(read_train data)}
RUN=${RUN:-$(read_train out)}
WORKERS=${WORKERS:-$(nproc)}
DEVICE=${DEVICE:-cuda}
OUT=${OUT:-assets/weights}
MODE=multi
case "$DATA" in *single*) MODE=single ;; esac
start=$(date +%s)
$KGN data generate --mode "$MODE" --scenes "${SCENES:-1000}" --views "${VIEWS:-5}" --seed 0 --out "$DATA" \
  --workers "$WORKERS" --quiet
echo "data: $DATA ($MODE) in $(( $(date +%s) - start )) s"
$KGN train "$CONFIG" --device "$DEVICE" --quiet --set "train.data=\"$DATA\"" --set "train.out=\"$RUN\"" "$@"
echo "training: $RUN in $(( $(date +%s) - start )) s from the start"
$KGN ship "$RUN/final.pt" --name "$NAME" --out "$OUT"
echo "wrote $OUT/$NAME.pt and $OUT/$NAME.md in $(( $(date +%s) - start )) s"
