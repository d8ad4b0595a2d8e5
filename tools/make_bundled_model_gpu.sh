#!/usr/bin/env bash
# A candidate bundled model trained on a lent GPU in one device call (no package registry there;
# bench/gpu_setup.sh installs what CARRY_DIR holds): the 3-hour recipe's stages
# (tools/make_bundled_model_3h.sh) with CUDA graphs (train.*.cuda_graph=true) and more samples.
# The autoencoder sees 20,000 x 128 motions, where the CPU recipe's saw 10,000 x 32. A GPU probe
# of that shape reached 0.890 of the reconstructions at 25,000 x 128, against 0.793 (docs/
# training.md, "Stage 1's training budget"). Stage 2 sees 45,000 x 128, against 30,000 x 64.
# The data are made there as the bundle's were (synth seed 0, rephrased, claps/waves/turns
# oversampled). Precision: train.*.precision=auto, bfloat16 autocast for the autoencoders and
# fp32 for stage 2 since 2026-11-27: stage 2 in bfloat16 on an H200 diverged after ~3,000
# steps where fp32 did not (docs/training.md, "Stage 2 continued on a GPU").
#
#   bash tools/make_bundled_model_gpu.sh [CARRY_DIR]     (AE_STEPS, CM_STEPS to change the budget)
#
# Checkpoints every 5,000 steps: a stage stopped at its time limit leaves its last one, which
# the next stage and the export take up (step() carries on after a failed step).
# $OUT receives the model in two float16 files (model_part1/2.safetensors: a device call returns
# files of a limited size), its config.json, Mean.npy, Std.npy and the logs. Here, on the CPU:
#   python tools/join_model_parts.py OUT --out MODEL   (then durations and critic, as the recipes do:
#   mlct train durations --data synth4k --model MODEL; mlct train critic --data synth4k_rich
#   --model MODEL --samples 8)
# A dry run without a GPU: a stand-in nvidia-smi on PATH, DEVICE=cpu NUM=200 AE_STEPS=20
# CM_STEPS=20 SMALL_STEPS=20 BATCH=8.
set -u
cd "$(dirname "$0")/.."
final=${OUT:-/tmp/gpu_bundle}
export OUT=/tmp/gpu_bundle_logs
source bench/gpu_setup.sh "${1:-.devcarry}"
work=/tmp/gpu_bundle_work
ae_steps=${AE_STEPS:-20000}
cm_steps=${CM_STEPS:-45000}
small_steps=${SMALL_STEPS:-}  # the short decoder stages, 5,000 and 3,000 unless set (dry runs)
batch=${BATCH:-128}
on=(--device "${DEVICE:-cuda}" --quiet data.num_workers=8)
mlct() { python3 -m mlct.cli "$@"; }
step synth 120 mlct data synth --out "$work/synth" --num "${NUM:-4000}" --seed 0 --workers 16 --quiet
step rephrase 120 mlct data rephrase "$work/synth" --out "$work/synth_rich"
step oversample 60 mlct data oversample "$work/synth_rich" --out "$work/synth_focus" \
    --families clap,wave,turn --times 3
step ae 240 mlct train ae --data "$work/synth" --out "$work/run" --config small "${on[@]}" \
    train.ae.cuda_graph=true "train.ae.batch_size=$batch" "train.ae.max_steps=$ae_steps" \
    train.ae.val_every=5000 train.ae.ckpt_every=5000
# the whole autoencoder decoding a noisy latent, held past the end, with the root's path
step noise 90 mlct train ae --data "$work/synth" --out "$work/noise" --init "$work/run" "${on[@]}" \
    ae.latent_noise=0.1 ae.hold_extension=0.5 ae.trajectory_weight=1.0 \
    train.ae.cuda_graph=true "train.ae.batch_size=$batch" "train.ae.max_steps=${small_steps:-5000}" \
    train.ae.lr=3e-4 train.ae.val_every=5000 "train.ae.ckpt_every=${small_steps:-5000}"
step cm 330 mlct train cm --data "$work/synth_focus" --out "$work/cm" --config small \
    --ae "$work/noise" "${on[@]}" text.encoder=minilm+sides train.cm.cuda_graph=true \
    "train.cm.batch_size=$batch" "train.cm.max_steps=$cm_steps" train.cm.lr=4e-4 \
    train.cm.log_every=500 train.cm.val_every=5000 train.cm.ckpt_every=5000
step export 60 mlct export "$work/cm" --out "$work/model_cm" --half
# the decoder alone with twice the noise; the encoder frozen, so stage 2's latents keep
step dnoise 60 mlct train ae --data "$work/synth" --out "$work/dnoise" --init "$work/model_cm" \
    "${on[@]}" ae.freeze_encoder=true ae.trajectory_weight=1.0 ae.latent_noise=0.2 \
    ae.hold_extension=0.5 train.ae.cuda_graph=true "train.ae.batch_size=$batch" \
    "train.ae.max_steps=${small_steps:-3000}" train.ae.lr=1e-4 train.ae.val_every=5000 \
    "train.ae.ckpt_every=${small_steps:-3000}"
step model 60 mlct export "$work/cm" --out "$work/model" --half --decoder-from "$work/dnoise"
mkdir -p "$final"
python3 - "$work/model" "$final" <<'PY'
import shutil, sys
from pathlib import Path
from safetensors import safe_open
from safetensors.torch import load_file, save_file
model, final = Path(sys.argv[1]), Path(sys.argv[2])
with safe_open(str(model / "model.safetensors"), "pt") as handle:
    meta = handle.metadata()
tensors = load_file(str(model / "model.safetensors"))
first = {k: v for k, v in tensors.items() if k.startswith("denoiser.")}
rest = {k: v for k, v in tensors.items() if k not in first}
save_file(first, str(final / "model_part1.safetensors"), metadata=meta)
save_file(rest, str(final / "model_part2.safetensors"), metadata=meta)
for name in ("config.json", "Mean.npy", "Std.npy"):
    shutil.copy(model / name, final / name)
PY
for run in run noise cm dnoise; do
    cp "$work/$run/"*/log.jsonl "$final/log_$run.jsonl" 2>/dev/null
done
cat "$OUT/steps.txt" | tee "$final/steps.txt"
ls -la "$final"
