"""Join the weight files a GPU recipe sends back into a model folder.

    python tools/join_model_parts.py FROM_DIR --out MODEL_DIR
    python tools/join_model_parts.py FROM_DIR --base MODEL --out MODEL_DIR

FROM_DIR holds model_part1.safetensors (the denoiser), model_part2.safetensors (the rest),
config.json, Mean.npy and Std.npy (tools/make_bundled_model_gpu.sh); MODEL_DIR gets a model
folder `mlct.load` reads. With --base, FROM_DIR holds only denoiser.safetensors and config.json
(bench/gpu_stage2_continue.sh: stage 2 continued on a frozen model) and everything else (the
autoencoder and decoders, Mean/Std, durations, critic) is the base model's, as is the config's
provenance of the decoder.
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


def join_onto(source: Path, base: Path, out: Path) -> Path:
    """The continued denoiser of `source` in a copy of the model folder `base`."""
    import json

    if not (source / "denoiser.safetensors").is_file():
        raise SystemExit(f"join_model_parts: {source} lacks denoiser.safetensors")
    with safe_open(str(base / "model.safetensors"), "pt") as handle:
        meta = handle.metadata()
    tensors = {k: v for k, v in load_file(str(base / "model.safetensors")).items()
               if not k.startswith("denoiser.")}
    tensors.update(load_file(str(source / "denoiser.safetensors")))
    out.mkdir(parents=True, exist_ok=True)
    for name in ("Mean.npy", "Std.npy", "durations.json", "critic.safetensors"):
        if (base / name).is_file():
            shutil.copy(base / name, out / name)
    save_file(tensors, str(out / "model.safetensors"), metadata=meta)
    config = json.loads((source / "config.json").read_text())
    kept = json.loads((base / "config.json").read_text())
    config["decoder_from"] = kept.get("decoder_from")  # the run there named its 1-step copy
    config["config"]["ae"] = kept["config"]["ae"]
    (out / "config.json").write_text(json.dumps(config, indent=2) + "\n")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("source", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--base", type=Path, default=None,
                        help="a model folder whose all but the denoiser the result keeps")
    args = parser.parse_args(argv)
    if args.base is not None:
        print(join_onto(args.source, args.base, args.out))
    else:
        print(join(args.source, args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
