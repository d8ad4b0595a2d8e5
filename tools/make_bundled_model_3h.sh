#!/usr/bin/env bash
# A one-pass recipe for the bundled model's networks, aimed at issue 14's 3 hours on 2 cores:
#   bash tools/make_bundled_model_3h.sh [WORK_DIR] [CM_SEED]
# tools/make_bundled_model.sh grew stage by stage as each change was found (~13.5 h, ~130,000
# stage-2 steps on six autoencoders). This recipe (version 6, 2026-11-29) applies what those
# stages found from the start, once each, in bfloat16 autocast, and keeps both cores busy:
# - the data and every caption set the bundle's last stage saw (everyday, short and colloquial
#   captions; claps, waves, turns and spins oversampled), made first;
# - the autoencoder in two parts on both cores: 10,000 plain steps, then 5,000 with the latent
#   noise, the hold past an action's end and the root's integrated path (with all of them from
#   step 0 it drew no clap, wave or punch: docs/training.md, "A 3-hour recipe");
# - then two lanes, one thread each: stage 2 on the body's 3 tokens with the side-contrasted
#   text and the last stage's captions from step 0; beside it, the arm pair copied from the
#   body's (body encoder frozen, twice the latent noise: docs/training.md, "An arm pair started
#   from the body's own pair") and its decoders trained longer on the same latents;
# - stage 2 grown onto the 6 tokens, on both cores; the durations, the critic, the text anchors.
# Both stage 2s run without the denoiser's dropout (version 3): a short stage 2 under-fits, and
# without it the test captions went 0.804 -> 0.916, the named side 0.820 -> 0.922, at 1.19x a step
# (docs/training.md, "Stage 2 without dropout"). Stage 2 on 3 tokens takes 28,000 steps
# (version 4): the arm lane beside it takes 64-71 min, so stage 2's thread had ~25 idle minutes
# at 18,000 steps; 28,000 fill them (65 min measured; docs/training.md, "Version 4").
# Version 5 changes only the short captions (a bare turn is a quarter turn, a bare jump is in
# place: docs/training.md, "Version 5"). Since it shipped, one colloquial hop form names the
# hopping foot, not the raised one (docs/training.md, "A hop's raised foot named in the
# captions"): this script makes that data. Version 6 (the bundle since 2026-11-29) is version
# 5 with that fix and a 3 x 192 denoiser (1.81 M parameters against 5.07 M: twice as fast to
# sample, the same held-out wording; docs/training.md, "Version 6"). Version 1 (commit eb34d51 and before: no arm pair,
# 30,000 stage-2 steps on one core) took 3.2 h of trainings and made a weaker model
# (docs/training.md, "The 3-hour recipe, finished").
# Resumable: run it again with the same WORK_DIR and each stage continues from its last
# checkpoint. Unlike make_bundled_model.sh it does not replace src/mlct/assets/model: it writes
# WORK_DIR/model, to be measured against the bundle first. Step counts may be overridden for a
# smoke run (AE_STEPS, NOISE_STEPS, ARM_STEPS, ARMDEC_STEPS, CM_STEPS, CM6_STEPS, MOTIONS), and
# DENOISER gives stage 2's network its size as config overrides; by default version 6's 3 x 192
# (DENOISER="denoiser.width=256 denoiser.ff_dim=1024 denoiser.layers=5" is the small preset's
# 5 x 256 of versions 1-5): a smaller one reads fewer bytes a sampling step (issue 17).
set -euo pipefail
work="${1:-mlct-bundled-3h}"
seed="${2:-0}"
source "$(dirname "$0")/recipe_stage.sh"
stamp data
caption_sets "${MOTIONS:-4000}"
stamp autoencoder
stage run ae --config small "train.ae.max_steps=${AE_STEPS:-10000}" train.ae.precision=bf16
stamp autoencoder, noisy latent
stage noise ae --init "$work/run" ae.latent_noise=0.1 ae.hold_extension=0.5 \
    ae.trajectory_weight=1.0 "train.ae.max_steps=${NOISE_STEPS:-5000}" train.ae.lr=3e-4 \
    train.ae.precision=bf16
stamp two lanes: stage 2 on 3 tokens, the arm pair beside it
# one thread each: two one-thread trainings side by side use the 2 cores better than one on two
# (docs/training.md, "Threads")
(
    export OMP_NUM_THREADS=1
    stage arms ae --init "$work/noise" ae.n_tokens=6 ae.arm_tokens=3 ae.arm_channels=128 \
        ae.arm_init=body ae.freeze_encoder=true ae.latent_noise=0.2 \
        "train.ae.max_steps=${ARM_STEPS:-10000}" train.ae.lr=1e-3 train.ae.precision=bf16
    # both encoders frozen (an --init of the same token count is no growth): the latents stay
    stage armdec ae --init "$work/arms" ae.freeze_encoder=true \
        "train.ae.max_steps=${ARMDEC_STEPS:-10000}" train.ae.lr=5e-4 train.ae.precision=bf16
) > "$work/arm_lane.log" 2>&1 &
arm_lane=$!
OMP_NUM_THREADS=1 stage2_on_body "$seed"
wait "$arm_lane" || { echo "the arm lane failed: $work/arm_lane.log" >&2; exit 1; }
stage2_on_all "$seed"
stamp done
echo "$work/model"
