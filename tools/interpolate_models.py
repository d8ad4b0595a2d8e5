"""Weight-space interpolation of exported models of one architecture (a fine-tune and the
model it started from): every float weight becomes (1 - alpha) * BASE + alpha * TUNED.

    python tools/interpolate_models.py BASE TUNED [TUNED ...] --alpha 0.5 --out DIR

Several TUNED (fine-tunes of BASE with other seeds) are averaged first, weight by weight, into
one (a uniform "model soup", Wortsman et al. 2022), and that is mixed with BASE.

BASE and TUNED are model directories (`mlct export`; "bundled" names the bundled model). DIR
gets the first TUNED's files with model.safetensors interpolated and config.json noting where it came
from. Why: averaging a fine-tune with its start in weight space keeps much of what the
fine-tune learned and much of what it forgot (Wortsman et al. 2022, "Robust fine-tuning of
zero-shot models", WiSE-FT); here the colloquial-caption continuation gained unseen phrasings
and lost some of the size of turns (docs/training.md). Only tensors that
differ are mixed; the result is stored in TUNED's dtypes, so a float16 bundle stays float16.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

import numpy as np
from safetensors.numpy import load_file, save_file

from mlct.errors import MlctError
from mlct.io import atomic_dir


def resolve(name: str) -> Path:
    if name == "bundled":
        from mlct.generate.bundle import bundled_model_dir

        return bundled_model_dir()
    return Path(name)


def interpolate(base: Path, tuned: Path | list[Path], alpha: float, out: Path) -> int:
    """Write OUT (module docstring); returns how many tensors were mixed."""
    tuned = [tuned] if isinstance(tuned, Path) else list(tuned)
    if not 0.0 <= alpha <= 1.0:
        raise MlctError(f"--alpha must be in [0, 1], got {alpha}")
    if not tuned:
        raise MlctError("no fine-tuned model given")
    for path in (base, *tuned):
        if not (path / "model.safetensors").is_file():
            raise MlctError(f"{path}: no model.safetensors (not an exported model)")
    if out.exists():
        raise MlctError(f"{out} exists; choose another --out")
    a = load_file(str(base / "model.safetensors"))
    others = [load_file(str(path / "model.safetensors")) for path in tuned]
    for path, b in zip(tuned, others):
        if set(a) != set(b) or any(a[k].shape != b[k].shape for k in a):
            raise MlctError(f"{base} and {path} do not have the same tensors (not one architecture)")
    first = others[0]
    mixed, n = {}, 0
    for key, tensor in first.items():
        if np.issubdtype(tensor.dtype, np.floating) and not all(
                np.array_equal(a[key], b[key]) for b in others):
            soup = np.mean([b[key].astype(np.float32) for b in others], axis=0)
            mixed[key] = ((1.0 - alpha) * a[key].astype(np.float32)
                          + alpha * soup).astype(tensor.dtype)
            n += 1
        else:
            mixed[key] = tensor
    with atomic_dir(out) as work:
        for path in tuned[0].iterdir():
            if path.is_file() and path.name != "model.safetensors":
                shutil.copy2(path, work / path.name)
        save_file(mixed, str(work / "model.safetensors"))
        config = json.loads((work / "config.json").read_text(encoding="utf-8"))
        config["interpolated"] = {"base": str(base), "alpha": alpha,
                                  "tuned": str(tuned[0]) if len(tuned) == 1
                                  else [str(path) for path in tuned]}
        (work / "config.json").write_text(json.dumps(config, indent=2) + "\n", encoding="utf-8")
    return n


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("base")
    parser.add_argument("tuned", nargs="+", help="one fine-tune, or several to average first")
    parser.add_argument("--alpha", type=float, default=0.5, help="weight of TUNED (0.5)")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    try:
        n = interpolate(resolve(args.base), [resolve(t) for t in args.tuned], args.alpha,
                        args.out)
    except MlctError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(f"wrote {args.out}: {n} tensors mixed at alpha {args.alpha}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
