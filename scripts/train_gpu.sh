#!/usr/bin/env bash
# Train and ship a model from nothing on a machine with a GPU and the project installed (`make setup`, or the
# wheels): the data generated on every core, the training on the GPU, the weights and model card written.
# KGN-family configs (a [train] section): the PS data (about a minute on 16 cores, 8 views/s a core), then the
# training (bfloat16 autocast, parallel loading), so the 15 minutes of a lent GPU go to training. VGN's config
# (a [vgn] section, tasks/vgn_train.toml): its objects imported and its scenes labelled in physics on every
# core (about 10 s a scene a core), then the training.
#
#   scripts/train_gpu.sh CONFIG NAME [--set SECTION.NAME=VALUE ...]
#     CONFIG  a training config (tasks/train_kgnv2_multi.toml, tasks/train_kgnv2_multi_s2.toml,
#             tasks/vgn_train.toml, ...)
#     NAME    the weights' name: OUT/NAME.pt and OUT/NAME.md
#   environment: DATA (the config's data), RUN (the config's out), SCENES (1000), VIEWS (5, KGN only),
#     OBJECTS (VGN only: the data command's --objects, default its own), WORKERS (every core), DEVICE (cuda),
#     OUT (assets/weights)
#
# A KGN data folder's name picks the split: "single" in it generates single-object scenes, else multi-object.
# Everything resumes: the data generators and the training pick up what is on disk. Tested on a CPU with tiny
# settings (tests/test_scripts.py).
set -euo pipefail
CONFIG=${1:?usage: scripts/train_gpu.sh CONFIG NAME [--set SECTION.NAME=VALUE ...]}
NAME=${2:?usage: scripts/train_gpu.sh CONFIG NAME [--set SECTION.NAME=VALUE ...]}
shift 2
KGN=${KGN:-kgn-bench}
SECTION=$("${PY:-python3}" -c 'import sys, tomllib; print("vgn" if "vgn" in tomllib.load(open(sys.argv[1], "rb")) else "train")' "$CONFIG")
read_config() {  # the config's [$SECTION] value of $1
  "${PY:-python3}" -c 'import sys, tomllib; print(tomllib.load(open(sys.argv[1], "rb"))[sys.argv[2]][sys.argv[3]])' \
    "$CONFIG" "$SECTION" "$1"
}
DATA=${DATA:-$(read_config data)}
RUN=${RUN:-$(read_config out)}
WORKERS=${WORKERS:-$(nproc)}
DEVICE=${DEVICE:-cuda}
OUT=${OUT:-assets/weights}
start=$(date +%s)
if [ "$SECTION" = vgn ]; then
  objects=()
  if [ -n "${OBJECTS:-}" ]; then read -ra objects <<< "$OBJECTS"; objects=(--objects "${objects[@]}"); fi
  $KGN data vgn --scenes "${SCENES:-1000}" --out "$DATA" --workers "$WORKERS" --quiet "${objects[@]}"
  echo "data: $DATA (VGN) in $(( $(date +%s) - start )) s"
else
  MODE=multi
  case "$DATA" in *single*) MODE=single ;; esac
  $KGN data generate --mode "$MODE" --scenes "${SCENES:-1000}" --views "${VIEWS:-5}" --seed 0 --out "$DATA" \
    --workers "$WORKERS" --quiet
  echo "data: $DATA ($MODE) in $(( $(date +%s) - start )) s"
fi
$KGN train "$CONFIG" --device "$DEVICE" --quiet --set "$SECTION.data=\"$DATA\"" --set "$SECTION.out=\"$RUN\"" "$@"
echo "training: $RUN in $(( $(date +%s) - start )) s from the start"
$KGN ship "$RUN/final.pt" --name "$NAME" --out "$OUT"
echo "wrote $OUT/$NAME.pt and $OUT/$NAME.md in $(( $(date +%s) - start )) s"
