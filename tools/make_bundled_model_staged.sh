#!/usr/bin/env bash
# The recipe of the bundle shipped until 2026-11-28 (docs/model_card.md, "The previous bundle"),
# kept so that model can be remade; tools/make_bundled_model.sh makes today's bundle:
#   bash tools/make_bundled_model_staged.sh [WORK_DIR] [CM_SEED]
# On 2 cores: the data 1 min, the autoencoder 40 min (10,000 steps), the consistency
# model 25-40 min (7,000 steps, the pooled MiniLM), 40-80 min of fine-tuning it with
# side-contrasted text ('minilm+sides', text/sides.py; 12,000 steps, lr 3e-4), then 24,000 more
# steps in three continuations (lr 2e-4; 70 min at 290-340 steps a minute on a free machine),
# 6,000 steps on the same motions with everyday captions added (`mlct data rephrase`; 20 min),
# the decoder retrained alone to hold still past an action's end (5,000 steps, 12 min), the
# whole autoencoder fine-tuned to decode a noisy latent (5,000 steps, 12-20 min) and 10,000
# stage-2 steps on its latents (30-40 min), the decoder again with the root's integrated path in
# its loss (3,000 steps, 6 min) and 8,000 stage-2 steps with it (30 min), the decoder once
# more with twice the latent noise (3,000 steps, 6 min) and two 10,000-step stage-2
# continuations on it (35-37 min each), a third such continuation (40 min) and one on batches
# that see the single-action claps, waves and turns three times as often (`mlct data
# oversample`, 45 min), an arm pair of 3 more latent tokens started from the body's own pair
# (10,000 steps, 50 min) and 12,000 stage-2 steps on the 6 tokens (55 min), its decoders alone
# for 12,000 more steps (55 min on one core) beside 8,000 more stage-2 steps (60 min on the
# other), the duration model (2 min) and the best-of-N critic (4 min), and last 6,000 stage-2
# steps with short, bare-verb captions added (`mlct data rephrase --vocabulary short`, 52 min),
# then 3,000 with colloquial ones, three times with three seeds (42-45 min each, one core each),
# the three runs averaged in weight space and mixed 0.7 with the model before, and the text
# anchors (seconds).
# About 13.5 h in all on a free machine (issue 14 asks for 3 h: not met), timed before the CPU
# trainer's cheaper dropout masks and fused AdamW (2026-11-28: a stage-2 step 1.15-1.29x faster,
# docs/training.md, "Dropout's random numbers on the CPU"); the whole has not been re-timed.
# Resumable: run it
# again with the same WORK_DIR after an interruption and each stage continues from its last
# checkpoint. The result is WORK_DIR/model (float16 weights); it no longer replaces the bundle.
# CM_SEED (default 0) seeds stage 2 only, for the seed spread the model card reported.
set -euo pipefail
work="${1:-mlct-bundled}"
seed="${2:-0}"
source "$(dirname "$0")/recipe_stage.sh"
caption_sets 4000  # the data and its caption sets, made once (recipe_stage.sh)
stage run ae --config small
stage run cm --config small "train.cm.seed=$seed"
# The 7,000-step model, float16 as the bundle: the fine-tune starts from what shipped before it.
[ -f "$work/model7k/config.json" ] || mlct export "$work/run" --out "$work/model7k" --half
stage sides cm --init "$work/model7k" --ae "$work/run" text.encoder=minilm+sides \
    train.cm.max_steps=12000 train.cm.lr=3e-4 "train.cm.seed=$seed"
# Three continuations of the fine-tuned model (lr 2e-4 cosine each, from the float16 export of
# the one before, as the bundle was made): 8,000, 6,000 and 10,000 steps.
[ -f "$work/model_sides/config.json" ] || mlct export "$work/sides" --out "$work/model_sides" --half
previous="$work/model_sides"
for spec in cont1:8000:0 cont2:6000:1 cont3:10000:2; do
    IFS=: read -r run steps offset <<< "$spec"
    stage "$run" cm --init "$previous" --ae "$work/run" text.encoder=minilm+sides \
        "train.cm.max_steps=$steps" train.cm.lr=2e-4 "train.cm.seed=$((seed + offset))"
    [ -f "$work/model_$run/config.json" ] || mlct export "$work/$run" --out "$work/model_$run" --half
    previous="$work/model_$run"
done
# The same motions, their training captions said in more ways (data/synth/everyday.py), and one
# more continuation on them.
DATA="$work/synth_rich" stage rich cm --init "$previous" --ae "$work/run" \
    text.encoder=minilm+sides train.cm.max_steps=6000 train.cm.lr=2e-4 "train.cm.seed=$((seed + 3))"
[ -f "$work/model_rich/config.json" ] || mlct export "$work/rich" --out "$work/model_rich" --half
# The decoder alone (encoder frozen), taught to hold the last pose past an action's end, then
# exported beside the last stage 2 (docs/training.md, "Past the end of an action").
stage hold ae --init "$work/model_rich" ae.freeze_encoder=true ae.hold_extension=0.5 \
    train.ae.max_steps=5000 train.ae.lr=3e-4
[ -f "$work/model_hold/config.json" ] || mlct export "$work/rich" --out "$work/model_hold" --half \
    --decoder-from "$work/hold"
previous="$work/model_hold"
# The whole autoencoder again, from that model: decoding a noisy latent (ae.latent_noise), so
# that an arm's oscillation survives stage 2's error (docs/training.md, "A decoder that
# survives stage 2's error"); its latents moved, so stage 2 continues on them.
stage noise ae --init "$work/model_hold" ae.latent_noise=0.1 ae.hold_extension=0.5 \
    train.ae.max_steps=5000 train.ae.lr=3e-4
DATA="$work/synth_rich" stage noisecm cm --init "$work/model_hold" --ae "$work/noise" \
    text.encoder=minilm+sides train.cm.max_steps=10000 train.cm.lr=2e-4 "train.cm.seed=$((seed + 7))"
[ -f "$work/model_noise/config.json" ] || mlct export "$work/noisecm" --out "$work/model_noise" --half
# The decoder alone again, with the root's integrated heading and path in its loss, so that a
# turn turns by the whole angle (docs/training.md, "Turning by the angle"); the encoder is
# frozen, so the stage 2 above stays valid with it.
stage traj ae --init "$work/model_noise" ae.freeze_encoder=true ae.trajectory_weight=1.0 \
    ae.latent_noise=0.1 ae.hold_extension=0.5 train.ae.max_steps=3000 train.ae.lr=1e-4
[ -f "$work/model_traj/config.json" ] || mlct export "$work/noisecm" --out "$work/model_traj" \
    --half --decoder-from "$work/traj"
# 8,000 more stage-2 steps, with that decoder in the run (docs/training.md, "Counts").
DATA="$work/synth_rich" stage trajcm cm --init "$work/model_traj" --ae "$work/traj" \
    text.encoder=minilm+sides train.cm.max_steps=8000 train.cm.lr=2e-4 "train.cm.seed=$((seed + 9))"
[ -f "$work/model_trajcm/config.json" ] || mlct export "$work/trajcm" --out "$work/model_trajcm" --half
# The decoder alone once more, with twice the latent noise, so that a wave's later sways
# survive stage 2's error (docs/training.md, "Damped later cycles"); then two 10,000-step
# continuations of stage 2 with it (lr 2e-4 cosine each, from the float16 export before).
stage dnoise ae --init "$work/model_trajcm" ae.freeze_encoder=true ae.trajectory_weight=1.0 \
    ae.latent_noise=0.2 ae.hold_extension=0.5 train.ae.max_steps=3000 train.ae.lr=1e-4
[ -f "$work/model_dnoise/config.json" ] || mlct export "$work/trajcm" \
    --out "$work/model_dnoise" --half --decoder-from "$work/dnoise"
previous="$work/model_dnoise"
for spec in dcont1:11 dcont2:12; do
    IFS=: read -r run offset <<< "$spec"
    DATA="$work/synth_rich" stage "$run" cm --init "$previous" --ae "$work/dnoise" \
        text.encoder=minilm+sides train.cm.max_steps=10000 train.cm.lr=2e-4 \
        "train.cm.seed=$((seed + offset))"
    [ -f "$work/model_$run/config.json" ] || mlct export "$work/$run" --out "$work/model_$run" --half
    previous="$work/model_$run"
done
# A third continuation like the two above (seed + 13), then one on a rebalanced copy of the
# captioned data whose training split lists the single-action claps, waves and turns three
# times (`mlct data oversample`; docs/training.md, "Oversampling the slow families").
DATA="$work/synth_rich" stage dcont3 cm --init "$previous" --ae "$work/dnoise" \
    text.encoder=minilm+sides train.cm.max_steps=10000 train.cm.lr=2e-4 \
    "train.cm.seed=$((seed + 13))"
[ -f "$work/model_dcont3/config.json" ] || mlct export "$work/dcont3" --out "$work/model_dcont3" --half
previous="$work/model_dcont3"
DATA="$work/synth_focus" stage focus cm --init "$previous" --ae "$work/dnoise" \
    text.encoder=minilm+sides train.cm.max_steps=10000 train.cm.lr=2e-4 \
    "train.cm.seed=$((seed + 14))"
[ -f "$work/model_focus/config.json" ] || mlct export "$work/focus" --out "$work/model_focus" --half
previous="$work/model_focus"
# The arm pair (docs/training.md, "An arm pair started from the body's own pair"): 3 more
# latent tokens for the arms, started as a copy of the model's own pair restricted to the arms'
# columns, the body's encoder and tokens frozen (50 min on one core beside another job); then
# stage 2 grown onto the 6 tokens (12,000 steps on the oversampled captions, 55 min on 2 cores).
stage arms ae --init "$previous" ae.n_tokens=6 ae.arm_tokens=3 ae.arm_channels=128 \
    ae.arm_init=body ae.freeze_encoder=true train.ae.max_steps=10000 train.ae.lr=1e-3 \
    train.ae.precision=bf16
AE="$work/arms" DATA="$work/synth_focus" stage armcm cm --init "$previous" \
    text.encoder=minilm+sides train.cm.max_steps=12000 train.cm.lr=2e-4 train.cm.precision=bf16 \
    "train.cm.seed=$((seed + 31))"
[ -f "$work/model_armcm/config.json" ] || mlct export "$work/armcm" --out "$work/model_armcm" --half
# the arm pair's two decoders trained longer on the same latents (both encoders frozen), and
# 8,000 more stage-2 steps from full-precision weights; the model takes the new decoders
stage armdec ae --init "$work/arms" ae.freeze_encoder=true train.ae.max_steps=12000 \
    train.ae.lr=5e-4 train.ae.precision=bf16
[ -f "$work/model_armcm32/config.json" ] || mlct export "$work/armcm" --out "$work/model_armcm32"
AE="$work/arms" DATA="$work/synth_focus" stage armcm2 cm --init "$work/model_armcm32" \
    text.encoder=minilm+sides train.cm.max_steps=8000 train.cm.lr=1e-4 train.cm.precision=bf16 \
    "train.cm.seed=$((seed + 32))"
[ -f "$work/model_armcm2/config.json" ] || mlct export "$work/armcm2" --out "$work/model_armcm2" \
    --half --decoder-from "$work/armdec"
previous="$work/model_armcm2"
# how long each action of a split prompt takes (generate/durations.py): seconds
[ -f "$previous/durations.json" ] || mlct train durations --data "$work/synth" --model "$previous"
# the critic of best-of-8 sampling (generate/critic.py), on the captioned-richly train split,
# also ranking the model's own 8 samples of each one-action motion by the read-outs (~4 min)
[ -f "$previous/critic.safetensors" ] || \
    mlct train critic --data "$work/synth_rich" --model "$previous" --samples 8
# Short captions (docs/training.md, "Short prompts"): 2 bare-verb captions added to each
# training motion of the oversampled data ("a woman waves"; data/synth/short.py), and 6,000
# stage-2 steps on them (lr 1e-4; 52 min on 2 cores). The model keeps the durations and the
# critic above: a critic retrained on the short-caption data cost the test captions 0.036.
AE="$work/armdec" DATA="$work/synth_short" stage shortcm cm --init "$previous" \
    text.encoder=minilm+sides train.cm.max_steps=6000 train.cm.lr=1e-4 train.cm.precision=bf16 \
    "train.cm.seed=$((seed + 33))"
[ -f "$work/model_shortcm/config.json" ] || mlct export "$work/shortcm" \
    --out "$work/model_shortcm" --half --decoder-from "$work/armdec"
# Colloquial captions (docs/training.md, "Colloquial captions"): 3 captions per training motion
# in rarer verbs, turn sizes in words, sides after their nouns and negation
# (data/synth/colloquial.py), the one-action turns and spins listed 3 more times so that turns
# keep their size; 3,000 stage-2 steps (lr 1e-4; 42 min on one core), three runs with three
# seeds. The model is their average, weight by weight, mixed 0.7 : 0.3 with the model they
# started from (tools/interpolate_models.py with the runs as TUNED: a uniform model soup, then
# WiSE-FT; docs/training.md, "Three seeds of the colloquial stage"): the gain on unseen
# phrasings with less of one seed's luck, the turns' size kept.
soup=()
for offset in 44 45 46; do  # run 44 keeps the name it had when it ran alone
    name=collcm; [ "$offset" = 44 ] || name="collcm$offset"
    AE="$work/armdec" DATA="$work/synth_collturns" stage "$name" cm --init "$work/model_shortcm" \
        text.encoder=minilm+sides train.cm.max_steps=3000 train.cm.lr=1e-4 \
        train.cm.precision=bf16 "train.cm.seed=$((seed + offset))"
    [ -f "$work/model_$name/config.json" ] || mlct export "$work/$name" \
        --out "$work/model_$name" --half --decoder-from "$work/armdec"
    soup+=("$work/model_$name")
done
rm -rf "$work/model"
python "$(dirname "$0")/interpolate_models.py" "$work/model_shortcm" "${soup[@]}" \
    --alpha 0.7 --out "$work/model"
cp "$previous/durations.json" "$previous/critic.safetensors" "$work/model/"
# the text anchors (generate/text_anchors.py): 12,000 one-action captions of the last stage's
# data, which a prompt worded unlike all of them is pulled towards before sampling, all the
# way where its 5 nearest captions' motions have one label (seconds)
mlct train anchors --data "$work/synth_collturns" --model "$work/model"
echo "$work/model"
