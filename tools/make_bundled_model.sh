#!/usr/bin/env bash
# Remake the bundled model (docs/model_card.md) from scratch, on a CPU:
#   bash tools/make_bundled_model.sh [WORK_DIR] [CM_SEED]
# The one-pass recipe (tools/make_bundled_model_3h.sh: the data and its caption sets, the
# autoencoder and its arm pair, stage 2 (3 x 192) on 3 then 6 tokens, the durations, the critic
# and the text anchors), stage 2 seeded CM_SEED (default 0, the shipped seed); then the body's
# decoder narrowed to 96 channels on the frozen encoder, the arm pair's decoder kept
# (tools/make_bundled_model_narrow_decoder.sh ... 96 frozen). About 2 h 10 min from an empty
# folder on 2 CPU cores (docs/training.md, "The bundled model's recipe"). Resumable: run it
# again with the same WORK_DIR and each stage continues from its last checkpoint. The result
# replaces src/mlct/assets/model, with its ONNX graphs made again (python -m mlct.onnx_assets).
set -euo pipefail
work="${1:-mlct-bundled}"
seed="${2:-0}"
repo="$(cd "$(dirname "$0")/.." && pwd)"
bash "$(dirname "$0")/make_bundled_model_3h.sh" "$work" "$seed"
DATA="$work/synth" bash "$(dirname "$0")/make_bundled_model_narrow_decoder.sh" "$work/model" \
    "$work/narrow" 96 frozen
# where the weights came from, said in the bundle's config instead of this machine's paths
python - "$work/narrow/model/config.json" "$seed" <<'PY'
import json, sys
path, seed = sys.argv[1], int(sys.argv[2])
config = json.load(open(path))
config["decoder_from"] = ("tools/make_bundled_model_narrow_decoder.sh bundled WORK 96 frozen "
                          "(version 6's encoder and arm decoder, a 96-channel body decoder)")
config["recipe"] = {"script": "tools/make_bundled_model.sh",
                    "stages": "tools/make_bundled_model_3h.sh, version 6, then "
                              "tools/make_bundled_model_narrow_decoder.sh 96 frozen (version 7)",
                    "cm_seed": seed}
json.dump(config, open(path, "w"), indent=2)
PY
rm -rf "$repo/src/mlct/assets/model"
cp -r "$work/narrow/model" "$repo/src/mlct/assets/model"
python -m mlct.onnx_assets  # the graphs `pip install mlct` runs, made from these weights
echo "$repo/src/mlct/assets/model"
