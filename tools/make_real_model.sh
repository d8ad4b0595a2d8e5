#!/usr/bin/env bash
# The bundled model fine-tuned on real capture beside the procedural benchmark, on a CPU:
#   bash tools/make_real_model.sh WORK_DIR REAL_DATASET [REAL_DATASET ...]
# INIT: the model fine-tuned (default: the bundled one); BENCHMARK_VERSION and MOTIONS: the
# procedural benchmark beside the real data (default version 2, 4,000 motions; the bundled
# model's recipe, tools/make_bundled_model.sh, gives version 4 and 6,000).
# Each REAL_DATASET is a corpus imported with `mlct data import --corpus NAME DIR --out ...`
# (docs/real_data.md). The steps, each resumable (run it again with the same WORK_DIR):
# - the bundle's caption sets of the procedural benchmark (tools/recipe_stage.sh), merged with
#   the real datasets (their provenance.jsonl kept);
# - the autoencoder from the bundle's, every weight free (ae.freeze_encoder=false), AE_STEPS
#   (default 4,000) at lr 3e-4;
# - stage 2 from the bundle's, on the new autoencoder's latents, CM_STEPS (default 6,000) at
#   lr 2e-4;
# - the export, the durations (the benchmark's labels), the critic (the benchmark's everyday
#   captions), the text anchors (every training caption, the real ones too), and the model's
#   training_data: each corpus, its motions and license. A model trained on non-commercial data
#   (Bandai Namco's) says so whenever it is loaded.
# One thread per training: on a busy 2-core machine a two-thread run was 20x slower. Timed on
# this repository's 2-vCPU host with Bandai Namco and CMU (docs/real_data.md, "A fine-tuned
# model"): 31 min of autoencoder, 6.5 min of caption encoding, 22 min of stage 2, 14 min of
# critic and anchors, next to other work.
set -euo pipefail
work="${1:?WORK_DIR}"
shift
[ "$#" -ge 1 ] || { echo "give one or more imported real datasets" >&2; exit 2; }
source "$(dirname "$0")/recipe_stage.sh"
export OMP_NUM_THREADS=1
stamp data
caption_sets "${MOTIONS:-4000}"
[ -f "$work/mixed/provenance.jsonl" ] || mlct data merge "$work/synth_collturns" "$@" \
    --out "$work/mixed"
stamp autoencoder
DATA="$work/mixed" stage run ae --init "${INIT:-bundled}" ae.freeze_encoder=false \
    "train.ae.max_steps=${AE_STEPS:-4000}" train.ae.lr=3e-4 train.ae.precision=bf16
stamp stage 2
DATA="$work/mixed" AE="$work/run/ae" stage run cm --init "${INIT:-bundled}" text.encoder=minilm+sides \
    denoiser.dropout=0.0 "train.cm.max_steps=${CM_STEPS:-6000}" train.cm.lr=2e-4 \
    train.cm.seed=31 train.cm.precision=bf16
if [ ! -f "$work/model/text_anchors.safetensors" ]; then
    stamp export, durations, critic, text anchors
    rm -rf "$work/model"
    mlct export "$work/run" --out "$work/model" --half
    mlct train durations --data "$work/synth" --model "$work/model"
    mlct train critic --data "$work/synth_rich" --model "$work/model" --samples 8
    mlct train anchors --data "$work/mixed" --model "$work/model"
fi
record_training_data "$work/model" "$work/mixed" "{\"script\": \"tools/make_real_model.sh\",
    \"from\": \"${INIT:-the bundled model}\", \"benchmark_version\": ${BENCHMARK_VERSION:-2}}"
stamp done
echo "$work/model"
