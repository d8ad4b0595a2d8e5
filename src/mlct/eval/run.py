"""`mlct eval`: models x (NFE, guidance) configurations under the standard protocol, one report.

Which numbers a configuration takes:
- a consistency (MLCT) model samples with each of `nfe` (default: its own, 5); its guidance w
  was trained in (one network pass per step), so `guidance` does not apply to it;
- a DDIM (diffusion baseline) model samples with each of `ddim_steps` (default: its own, 50)
  and each classifier-free guidance scale of `guidance` (default: its own, 7.5); its NFE is the
  step count, each step running the denoiser on cond and uncond (2 x steps network passes).
An axis given for a kind of model that is not among the models is an error, not a no-op.
"""

from __future__ import annotations

import platform
import sys
import time
from dataclasses import asdict
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Sequence

import torch

from mlct.cpu_features import kernel_dtype
from mlct.generate.bundle import read_bundle
from mlct.devices import resolve_device
from mlct.errors import MlctError
from mlct.eval.protocol import Log, ProtocolConfig, check_model, open_protocol
from mlct.generate.compose.generator import MotionGenerator
from mlct.generate.load import torch_generator
from mlct.generate.samplers import sampler_class

REPORT_FORMAT = "mlct-eval-report"
REPORT_VERSION = 1
CHOICES = [
    "The real side (one seeded caption and crop per test item) is embedded once and reused by "
    "every replication and configuration; replication r reshuffles the groups with seed + r.",
    "Generated and Real rows share the items' text embeddings; FID compares with the real "
    "embeddings of the same kept items, so Real's FID is 0 up to rounding.",
    "Each generation takes its item's caption and ground-truth (cropped) length; batch b of "
    "replication r samples with a seed derived from (seed + r, b).",
    "Generated and real features are normalized by the evaluator's own Mean/Std.",
    "Diversity takes 300 pairs, or kept - 1 on a split that keeps 300 items or fewer.",
    "NFE counts denoiser evaluations (sampling steps); DDIM with CFG runs two network passes "
    "per step. AITS: batch 1, text encoding + sampling + decoding, after warm-up, loading "
    "excluded.",
]


def _labels(models: Sequence[Path]) -> list[str]:
    """Short row names: the directory names, the full paths where two names collide."""
    names = [m.name or str(m) for m in models]
    return [name if names.count(name) == 1 else str(m) for name, m in zip(names, models)]


def _grid(gen: MotionGenerator, steps: dict[str, Sequence[int] | None],
          guidance: Sequence[float] | None) -> list[tuple[int | None, float | None]]:
    """The (steps, guidance) configurations of one model; None means the model's default.
    steps: the step counts asked for, by the option that sweeps them (Sampler.steps_option);
    a guidance scale is a sampling choice for a sampler with classifier-free guidance only."""
    sampler = gen.sampler
    scales = (guidance or [None]) if sampler.cfg else [None]
    return [(n, g) for n in (steps[sampler.steps_option] or [None]) for g in scales]


def run_evaluation(models: Sequence[str | Path], data_dir: str | Path,
                   evaluator_dir: str | Path, *, nfe: Sequence[int] | None = None,
                   ddim_steps: Sequence[int] | None = None,
                   guidance: Sequence[float] | None = None, split: str = "test",
                   config: ProtocolConfig = ProtocolConfig(),
                   device: str | torch.device | None = None, log: Log | None = None,
                   command: str | None = None,
                   classifier_dir: str | Path | None = None,
                   dtype: str = "float32") -> dict[str, Any]:
    """Evaluate every configuration of every model and the Real row; the report as a dict.

    Every input is checked (files, widths, skeletons, lengths, step counts) before the real
    side is embedded or anything is generated. With classifier_dir (an action classifier of a
    procedural benchmark) every row also gets the semantic accuracy. dtype: the models'
    matrix-product precision (MotionGenerator), to check a reduced precision's metrics.
    """
    log = log or (lambda message: None)
    started = time.perf_counter()
    dev = resolve_device(device)
    paths = [Path(m) for m in models]
    if not paths:
        raise MlctError("no model to evaluate (pass --model MODEL_DIR)")
    bundles = [read_bundle(p) for p in paths]
    samplers = {sampler_class(meta.get("sampler")) for meta, _ in bundles}
    steps = {"nfe": nfe, "ddim_steps": ddim_steps}  # by Sampler.steps_option
    if nfe and not any(s.steps_option == "nfe" for s in samplers):
        raise MlctError("--nfe sets the steps of consistency (MLCT) models; none was given "
                        "(a DDIM model's steps are --ddim-steps)")
    for given, flag, applies in (
            (ddim_steps, "--ddim-steps", any(s.steps_option == "ddim_steps" for s in samplers)),
            (guidance, "--guidance", any(s.cfg for s in samplers))):
        if given and not applies:
            raise MlctError(f"{flag} applies to DDIM (diffusion) models only; a consistency "
                            f"model's guidance w is set at training (consistency.guidance)")
    protocol = open_protocol(data_dir, evaluator_dir, split, config, dev, log,
                             models=[(p, meta) for p, (meta, _) in zip(paths, bundles)],
                             classifier_dir=classifier_dir)
    dataset = protocol.dataset
    dtype = str(kernel_dtype(dtype, dev)).removeprefix("torch.")  # the report says what ran
    gens = [torch_generator(meta, tensors, dev, dtype) for meta, tensors in bundles]
    grids = [_grid(g, steps, guidance) for g in gens]
    for path, gen, grid in zip(paths, gens, grids):
        check_model(protocol, gen, [count for count, _ in grid], path)

    cfg = protocol.config
    log(f"{len(dataset)} items in {split!r}, {protocol.kept} kept per replication, "
        f"{cfg.reps} replications, device {dev}")
    real = protocol.evaluate_real()
    rows = []
    total = sum(len(grid) for grid in grids)
    for path, label, gen, grid in zip(paths, _labels(paths), gens, grids):
        for count, scale in grid:
            method = f"{label} ({gen.sampler.describe(scale)})"
            log(f"[{len(rows) + 1}/{total}] {method}, NFE {gen.check_nfe(count)}")
            rows.append(protocol.evaluate(gen, count, scale, method=method, model=str(path)))
    return {
        "format": REPORT_FORMAT, "version": REPORT_VERSION,
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "command": command if command is not None else " ".join(sys.argv),
        "config": {
            "data": str(Path(data_dir)), "split": split, "items": len(dataset),
            "kept_per_replication": protocol.kept, "skeleton": dataset.skeleton.name,
            "evaluator": str(Path(evaluator_dir)), "models": [str(p) for p in paths],
            "classifier": None if classifier_dir is None else str(Path(classifier_dir)),
            "nfe": list(nfe) if nfe else None,
            "ddim_steps": list(ddim_steps) if ddim_steps else None,
            "guidance": list(guidance) if guidance else None, "device": str(dev),
            "dtype": dtype,
            "protocol": asdict(cfg), "choices": CHOICES,
            "versions": _versions(),
        },
        "real": real.to_dict(),
        "rows": [row.to_dict() for row in rows],
        "seconds": time.perf_counter() - started,
    }


def _versions() -> dict[str, str]:
    from mlct import __version__

    return {"mlct": __version__, "torch": torch.__version__, "python": platform.python_version()}
