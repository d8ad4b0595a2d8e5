#!/usr/bin/env bash
# Stage 2 of tools/make_bundled_model_3h.sh alone, on the autoencoder of an existing bundle:
#   bash tools/make_bundled_model_3h_stage2.sh MODEL_DIR WORK_DIR [CM_SEED]
# For a retraining that changes only stage 2 (captions, the denoiser's size, a seed) when the
# recipe's stage-1 runs are not at hand: tools/autoencoder_from_bundle.py writes MODEL_DIR's
# autoencoder back as the recipe's `noise` (3 body tokens) and `armdec` (6 tokens) runs, and the
# recipe's stage 2 follows (stage2_on_body and stage2_on_all in tools/recipe_stage.sh, which the
# recipe calls too) with the arm lane already done. The caption sets are made if absent.
# DENOISER as in the recipe (default: version 6's 3 x 192). The bundle of version 6 was made so,
# on version 5's bundle:
#   bash tools/make_bundled_model_3h_stage2.sh V5_BUNDLE WORK 0
set -euo pipefail
bundle="$1"
work="$2"
seed="${3:-0}"
source "$(dirname "$0")/recipe_stage.sh"
stamp data
caption_sets "${MOTIONS:-4000}"
[ -f "$work/armdec/ae/checkpoints/latest" ] ||
    python "$(dirname "$0")/autoencoder_from_bundle.py" "$bundle" "$work"
stamp stage 2 on 3 tokens
stage2_on_body "$seed"
stage2_on_all "$seed"
stamp done
echo "$work/model"
