#!/usr/bin/env bash
# Rebuild the bundled model (docs/model_card.md) from scratch, on a CPU:
#   bash tools/make_bundled_model.sh [WORK_DIR] [CM_SEED]
# About 80 minutes on 2 cores: the data 1 min, the autoencoder 40 min (10,000 steps), the
# consistency model 35-40 min (7,000 steps). Resumable: run it again with the same WORK_DIR after an
# interruption and each stage continues from its last checkpoint. The result replaces
# src/mlct/assets/model (float16 weights). CM_SEED (default 0) seeds stage 2 only, for the
# seed spread the model card reports.
set -euo pipefail
work="${1:-mlct-bundled}"
seed="${2:-0}"
repo="$(cd "$(dirname "$0")/.." && pwd)"
stage() {  # stage NAME ARGS...: train, or resume when the stage already has checkpoints
    local name="$1"; shift
    if ls "$work/run/$name/checkpoints"/step-* >/dev/null 2>&1; then
        mlct train "$name" --data "$work/synth" --out "$work/run" --resume
    else
        mlct train "$name" --data "$work/synth" --out "$work/run" --config small "$@"
    fi
}
[ -f "$work/synth/synth.json" ] || mlct data synth --out "$work/synth" --num 4000 --seed 0 --workers 2
stage ae
stage cm "train.cm.seed=$seed"
mlct export "$work/run" --out "$work/model" --half
rm -rf "$repo/src/mlct/assets/model"
cp -r "$work/model" "$repo/src/mlct/assets/model"
echo "$repo/src/mlct/assets/model"
