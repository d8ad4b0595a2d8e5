#!/usr/bin/env bash
# The one-pass recipe of the bundled model's networks, on 2 CPU cores in bfloat16 autocast
# (tools/make_bundled_model.sh runs it, then narrows the body's decoder):
#   bash tools/make_bundled_model_3h.sh [WORK_DIR] [CM_SEED]
# - the data and every caption set (everyday, short and colloquial captions; claps, waves, turns
#   and spins oversampled), made first (tools/recipe_stage.sh: caption_sets);
# - the autoencoder on both cores: 10,000 plain steps, then 5,000 with the latent noise, the hold
#   past an action's end and the root's integrated path (with all of them from step 0 it drew no
#   clap, wave or punch);
# - then two lanes, one thread each: stage 2 on the body's 3 tokens (28,000 steps, the side-
#   contrasted text, every caption set from step 0, no dropout); beside it, the arm pair copied
#   from the body's (body encoder frozen, twice the latent noise) and its decoders trained longer
#   on the same latents;
# - stage 2 grown onto the 6 tokens, on both cores; the durations, the critic, the text anchors.
# Why each step: docs/training.md. Resumable: run it again with the same WORK_DIR and each stage
# continues from its last checkpoint. It writes WORK_DIR/model, to be measured against the
# bundle first. Step counts may be lowered for a smoke run (AE_STEPS, NOISE_STEPS, ARM_STEPS,
# ARMDEC_STEPS, CM_STEPS, CM6_STEPS, MOTIONS), and DENOISER gives stage 2's network its size as
# config overrides (default 3 x 192; "denoiser.width=256 denoiser.ff_dim=1024 denoiser.layers=5"
# is the small preset's 5 x 256).
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
