#!/usr/bin/env bash
# Remake the bundled model (docs/model_card.md) from scratch, on a CPU:
#   bash tools/make_bundled_model.sh WORK_DIR CMU_DATASET [CMU_DATASET ...]
# 1. The procedural model (about 2 h 10 min on 2 CPU cores): the one-pass recipe
#    (tools/make_bundled_model_3h.sh: benchmark version 2 and its caption sets, the autoencoder
#    and its arm pair, stage 2 on 3 then 6 tokens, the durations, the critic, the text anchors),
#    then the body's decoder narrowed to 96 channels (tools/make_bundled_model_narrow_decoder.sh).
# 2. That model fine-tuned on benchmark version 4 (64 families, 6,000 motions) beside real CMU
#    capture (tools/make_real_model.sh; about 70 min): the CMU_DATASETs are imported with
#    `mlct data import --corpus cmu|cmu-expmap` and merged (docs/real_data.md). Only data whose
#    license allows commercial use goes in: the benchmark and CMU.
# CM_SEED (default 0) seeds stage 2. Resumable: run it again with the same WORK_DIR and each
# stage continues from its last checkpoint. The result replaces src/mlct/assets/model, with its
# ONNX graphs made again (python -m mlct.onnx_assets).
set -euo pipefail
work="${1:?WORK_DIR}"
shift
[ "$#" -ge 1 ] || { echo "give the imported CMU dataset(s)" >&2; exit 2; }
seed="${CM_SEED:-0}"
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
INIT="$work/narrow/model" BENCHMARK_VERSION=4 MOTIONS=6000 \
    bash "$(dirname "$0")/make_real_model.sh" "$work/real" "$@"
python - "$work/real/model/config.json" "$seed" <<'PY'
import json, sys
path, seed = sys.argv[1], int(sys.argv[2])
config = json.load(open(path))
config["recipe"] = {"script": "tools/make_bundled_model.sh", "cm_seed": seed,
                    "stages": "tools/make_bundled_model_3h.sh and "
                              "tools/make_bundled_model_narrow_decoder.sh 96 frozen (the "
                              "procedural model), then tools/make_real_model.sh on benchmark "
                              "version 4 and CMU capture"}
json.dump(config, open(path, "w"), indent=2)
PY
rm -rf "$repo/src/mlct/assets/model"
cp -r "$work/real/model" "$repo/src/mlct/assets/model"
python -m mlct.onnx_assets  # the graphs `pip install mlct` runs, made from these weights
echo "$repo/src/mlct/assets/model"
