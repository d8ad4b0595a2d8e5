#!/usr/bin/env bash
# The bundled model taught benchmark version 4 (67 families) and the commercial CMU set, on a CPU:
#   bash tools/make_broad_model.sh WORK_DIR REAL_DATASET [REAL_DATASET ...]
# INIT: the model it starts from (default: the bundled one). WITH_V2=1: stage 2 also trains on
# benchmark version 2's caption sets (4,000 motions of the 21 families, made into WORK/v2), so
# that those families keep their share of the training items. Each REAL_DATASET is a corpus
# imported with `mlct data import --corpus NAME DIR --out ...` (docs/real_data.md); for a
# bundle, only corpora whose license allows commercial use. The steps, each resumable (run it
# again with the same WORK_DIR):
# - benchmark version 4, 6,000 motions, and the bundle's caption sets of it (recipe_stage.sh);
# - the autoencoder from INIT's, every weight free: AE_STEPS (5,000) at lr 3e-4, then
#   AE2_STEPS (6,000) more at lr 5e-4, on the procedural caption set; the version-4 families
#   need the second round (read-outs of the test motions' reconstructions 0.55 after the
#   first, 0.69 after the second; docs/real_data.md);
# - stage 2 from INIT's, on the new autoencoder's latents of the procedural set merged with the
#   real datasets: CM_STEPS (22,000) at lr 2e-4;
# - the export, the durations, the critic and the text anchors, and the model's training_data.
# One thread per training (THREADS=N: N). Timed on 2 cores beside other work: 15 + 18 min of autoencoder,
# 7 min of caption encoding, 40 min of stage 2, 15 min of durations, critic and anchors.
set -euo pipefail
work="${1:?WORK_DIR}"
shift
[ "$#" -ge 1 ] || { echo "give one or more imported real datasets" >&2; exit 2; }
source "$(dirname "$0")/recipe_stage.sh"
export OMP_NUM_THREADS="${THREADS:-1}" BENCHMARK_VERSION=4
init="${INIT:-bundled}"
stamp data
caption_sets 6000
stamp autoencoder
DATA="$work/synth_collturns" stage run ae --init "$init" ae.freeze_encoder=false \
    "train.ae.max_steps=${AE_STEPS:-5000}" train.ae.lr=3e-4 train.ae.precision=bf16
stamp autoencoder, second round
DATA="$work/synth_collturns" stage run2 ae --init "$work/run/ae" ae.freeze_encoder=false \
    "train.ae.max_steps=${AE2_STEPS:-6000}" train.ae.lr=5e-4 train.ae.precision=bf16
extra=()
if [ "${WITH_V2:-0}" = 1 ]; then
    (work="$work/v2"; BENCHMARK_VERSION=2; caption_sets 4000)
    extra=("$work/v2/synth_collturns")
fi
[ -f "$work/mixed/provenance.jsonl" ] || mlct data merge "$work/synth_collturns" "${extra[@]}" \
    "$@" --out "$work/mixed"
stamp stage 2
DATA="$work/mixed" AE="$work/run2" stage run2 cm --init "$init" text.encoder=minilm+sides \
    denoiser.dropout=0.0 "train.cm.max_steps=${CM_STEPS:-22000}" train.cm.lr=2e-4 \
    train.cm.seed=31 train.cm.precision=bf16
if [ ! -f "$work/model/text_anchors.safetensors" ]; then
    stamp export, durations, critic, text anchors
    rm -rf "$work/model"
    mlct export "$work/run2" --out "$work/model" --half
    mlct train durations --data "$work/synth" --model "$work/model"
    mlct train critic --data "$work/synth_rich" --model "$work/model" --samples 8
    mlct train anchors --data "$work/mixed" --model "$work/model"
fi
with_v2=$([ "${WITH_V2:-0}" = 1 ] && echo true || echo false)
record_training_data "$work/model" "$work/mixed" "{\"script\": \"tools/make_broad_model.sh\",
    \"from\": \"$init\", \"benchmark_version\": 4, \"with_version_2\": $with_v2}"
stamp done
echo "$work/model"
