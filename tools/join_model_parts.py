"""Join the two weight files tools/make_bundled_model_gpu.sh sends back into a model folder.

    python tools/join_model_parts.py FROM_DIR --out MODEL_DIR

FROM_DIR holds model_part1.safetensors (the denoiser), model_part2.safetensors (the rest),
config.json, Mean.npy and Std.npy; MODEL_DIR gets a model folder `mlct.load` reads.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

from safetensors import safe_open
from safetensors.torch import load_file, save_file


def join(source: Path, out: Path) -> Path:
    parts = [source / "model_part1.safetensors", source / "model_part2.safetensors"]
    missing = [p.name for p in parts if not p.is_file()]
    if missing:
        raise SystemExit(f"join_model_parts: {source} lacks {', '.join(missing)}")
    with safe_open(str(parts[0]), "pt") as handle:
        meta = handle.metadata()
    tensors = {}
    for part in parts:
        tensors.update(load_file(str(part)))
    out.mkdir(parents=True, exist_ok=True)
    save_file(tensors, str(out / "model.safetensors"), metadata=meta)
    for name in ("config.json", "Mean.npy", "Std.npy"):
        shutil.copy(source / name, out / name)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("source", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    print(join(args.source, args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
