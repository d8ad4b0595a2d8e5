"""The quality suites: does the model do what its text says? One runner over mlct.eval.suites.

    python bench/quality.py SUITE [options]      # python bench/quality.py SUITE --help
    python bench/quality.py motion --data SYNTH --seeds 5 --classifier CLF   # the benchmark
    python bench/quality.py paraphrases --seeds 5                             # hand-written sets

Suites: motion, paraphrases, sides, examples, short, turns, feet, keep-going, int8, real
(bench/README.md: what each prints and how long it takes). The hand-written prompt sets are
bench/data's; `motion --ae RUN` also takes a training run's autoencoder.
"""

from __future__ import annotations

import argparse
import importlib
from pathlib import Path
from typing import Callable

import numpy as np

from mlct.eval.suites import SUITES

PROMPT_DIR = Path(__file__).resolve().parent / "data"


def load_autoencoder(path: Path) -> Callable[[np.ndarray], np.ndarray]:
    """features (T, D) in real units -> the autoencoder's reconstruction (T, D); path: a
    training run, an AE checkpoint, or a model folder (its encoder and decoder)."""
    import torch

    if (path / "config.json").is_file():  # a model folder: the autoencoder it generates with
        from mlct.config import config_from_dict
        from mlct.generate.bundle import bundle_autoencoder_state, read_bundle
        from mlct.nn.build import build_autoencoder
        meta, tensors = read_bundle(path)
        ae = build_autoencoder(config_from_dict(meta["config"], "model config"),
                               int(meta["feature_dim"]))
        ae.load_state_dict(bundle_autoencoder_state(tensors, path))
        ae.eval().requires_grad_(False)
        mean, std = tensors["norm.mean"].float(), tensors["norm.std"].float()
    else:
        from mlct.train.stages import find_autoencoder, load_frozen_autoencoder
        ae, norm, _ = load_frozen_autoencoder(find_autoencoder(path, None), torch.device("cpu"))
        mean, std = norm.mean, norm.std

    def run(x: np.ndarray) -> np.ndarray:
        xt = (torch.from_numpy(np.asarray(x)).float()[None] - mean) / std
        with torch.no_grad():
            recon, _ = ae(xt, torch.tensor([len(x)]), None, 0.0)
        return (recon[0] * std + mean).numpy()
    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--prompt-dir", type=Path, default=PROMPT_DIR,
                        help="the hand-written prompt sets (default: bench/data)")
    commands = parser.add_subparsers(dest="suite", required=True, metavar="SUITE")
    for name, module_name in SUITES.items():
        module = importlib.import_module(f"mlct.eval.suites.{module_name}")
        doc = module.__doc__ or ""
        sub = commands.add_parser(name, help=doc.split("\n")[0], description=doc,
                                  formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(sub)
        sub.set_defaults(run=module.run, error=sub.error, load_autoencoder=load_autoencoder)
    args = parser.parse_args()
    args.run(args)


if __name__ == "__main__":
    main()
