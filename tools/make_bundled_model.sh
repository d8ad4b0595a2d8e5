#!/usr/bin/env bash
# Rebuild the bundled model (docs/model_card.md) from scratch, on a CPU:
#   bash tools/make_bundled_model.sh [WORK_DIR]
# About 35 minutes on 2 cores: the data 1 min, the autoencoder 15 min, the consistency model
# 17 min. The result replaces src/mlct/assets/model (float16 weights, 11 MB).
set -euo pipefail
work="${1:-mlct-bundled}"
repo="$(cd "$(dirname "$0")/.." && pwd)"
mlct data synth --out "$work/synth" --num 2000 --seed 0 --workers 2
mlct train ae --data "$work/synth" --out "$work/run" --config small   # stage 1, 2,500 steps
mlct train cm --data "$work/synth" --out "$work/run" --config small   # stage 2, 3,000 steps
mlct export "$work/run" --out "$work/model" --half
rm -rf "$repo/src/mlct/assets/model"
cp -r "$work/model" "$repo/src/mlct/assets/model"
echo "$repo/src/mlct/assets/model"
