"""How far the int8 denoiser (backend onnx-int8) moves the joints from float32 ONNX's.

    python bench/quality.py int8 --data SYNTH [--model DIR] [--limit N] [--plans fiiii,ffiii] [--floor]

The same seeds through both (seed 0 each, one sample, no split into actions): the benchmark's
test captions at their real lengths, then the 42 hand-written paraphrases at 5 s. Prints the
joints' distance (mean, median, 99th percentile, largest), the root-relative pose's, and how many
motions move more than 1 cm on average, in the joints and in the pose (root-relative), and how
far the root's end point moved against the length of its path.

--plans: which of the 5 steps need float32? Each plan names a denoiser per step, f (float32)
or i (int8), e.g. fiiii: the first step in float32, the rest in int8. A plan runs the step loop
(onnx_sampler.run_steps) of the float32 conversion with the int8 denoiser's session at its i
steps, and is compared with float32 on the test captions.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

import mlct
from mlct.data.layout import DatasetLayout
from mlct.generate.backends.onnx.convert import convert_to_onnx
from mlct.eval.suites.common import prompt_file
from mlct.generate.bundle import bundled_model_dir



# Prompts per generate() call: under the onnx backends' TORCH_MIN_BATCH, so that every batch
# runs the graphs under test, not the float32 torch networks that large batches go to.
BATCH = 16


def joints(gen: mlct.MotionGenerator, texts: list[str], lengths: list[int]) -> list[np.ndarray]:
    out = []
    for k in range(0, len(texts), BATCH):
        part = slice(k, k + BATCH)
        out += [m.joints for m in gen.generate(texts[part], lengths=lengths[part],
                                               seed=[0] * len(texts[part]), candidates=1,
                                               split_actions=False)]
    return out


def report(what: str, a: list[np.ndarray], b: list[np.ndarray]) -> None:
    dist = np.concatenate([np.linalg.norm(x - y, axis=-1).ravel() for x, y in zip(a, b)])
    pose = np.concatenate([np.linalg.norm((x - x[:, :1]) - (y - y[:, :1]), axis=-1).ravel()
                           for x, y in zip(a, b)])
    per = np.array([np.linalg.norm(x - y, axis=-1).mean() for x, y in zip(a, b)])
    per_pose = np.array([np.linalg.norm((x - x[:, :1]) - (y - y[:, :1]), axis=-1).mean()
                         for x, y in zip(a, b)])
    # where the root ends against how far it went: a drift of the trajectory, not the pose
    drift = np.array([np.linalg.norm(x[-1, 0] - y[-1, 0]) for x, y in zip(a, b)])
    path = np.array([np.linalg.norm(np.diff(y[:, 0], axis=0), axis=-1).sum() for y in a])
    share = drift / np.maximum(path, 1e-6)
    mm = 1000
    print(f"{what}: joints mean {dist.mean() * mm:.1f} mm, median {np.median(dist) * mm:.1f}, "
          f"p99 {np.percentile(dist, 99) * mm:.0f}, largest {dist.max() * mm:.0f}; root-relative "
          f"pose mean {pose.mean() * mm:.1f}, largest {pose.max() * mm:.0f}; motions moving "
          f"> 1 cm on average: {(per > 0.01).sum()} of {len(per)} ({(per > 0.01).mean():.1%}), "
          f"in the pose {(per_pose > 0.01).sum()} ({(per_pose > 0.01).mean():.1%}); the root's "
          f"end point moved {drift.mean() * mm:.1f} mm on average, {np.median(share):.2%} of "
          f"its path (median; largest {share.max():.1%})")


class StepPlan:
    """A denoiser session for the step loop that runs step k on plan[k % len(plan)]'s session:
    'f' the float32 one, 'i' the int8 one. run_steps calls it once per step, in order."""

    def __init__(self, plan: str, float32: object, int8: object) -> None:
        self.sessions = [{"f": float32, "i": int8}[c] for c in plan]
        self.calls = 0

    def run(self, outputs: list[str], feeds: dict) -> list:
        session = self.sessions[self.calls % len(self.sessions)]
        self.calls += 1
        return session.run(outputs, feeds)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--model", type=Path, default=None, help="default: the bundled model")
    parser.add_argument("--limit", type=int, default=None, help="first N test motions")
    parser.add_argument("--plans", default="", help="step plans of f and i, comma-separated")
    parser.add_argument("--floor", action="store_true",
                        help="also the float32 torch backend against float32 onnx: the distance "
                             "that is float rounding alone")


def run(args: argparse.Namespace) -> None:
    layout = DatasetLayout.existing(args.data)
    names = layout.read_split("test")[: args.limit]
    captions = [layout.read_texts(n)[0].caption for n in names]
    lengths = [min(len(layout.load_features(n)), 196) for n in names]
    paraphrases = [p["text"] for p in prompt_file(args.prompt_dir, "seen")["paraphrases"]]
    with tempfile.TemporaryDirectory() as tmp:
        model = args.model or bundled_model_dir()
        dirs = [convert_to_onnx(model, Path(tmp) / name, read_only=True, int8=int8)
                for name, int8 in (("f32", False), ("i8", True))]
        gens = [mlct.load(d, backend=backend) for d, backend in zip(dirs, ("onnx", "onnx-int8"))]
        plans = [p for p in args.plans.split(",") if p]
        steps = gens[0].check_nfe(None)
        for plan in plans:
            if set(plan) - set("fi") or len(plan) != steps:
                args.error(f"--plans: {plan!r} is not one f or i per step ({steps} steps)")
        float32 = joints(gens[0], captions, lengths)
        report(f"{len(names)} test captions", float32, joints(gens[1], captions, lengths))
        if args.floor:
            torch_backend = mlct.load(model, backend="torch")
            report(f"float32 torch against onnx, {len(names)} test captions", float32,
                   joints(torch_backend, captions, lengths))
        for plan in plans:
            mixed = mlct.load(dirs[0], backend="onnx")
            # the step loop (run_steps), as where the onnx package is missing: no sampler graph
            # of the steps, whose denoiser calls the plan chooses
            mixed.networks.graph_sessions._onnx = False
            mixed.denoiser.session = StepPlan(plan, mixed.denoiser.session,
                                              gens[1].denoiser.session)
            report(f"plan {plan}, {len(names)} test captions", float32,
                   joints(mixed, captions, lengths))
        five = [gens[0].frames_for(5.0)] * len(paraphrases)
        report(f"{len(paraphrases)} paraphrases, 5 s", *(joints(g, paraphrases, five)
                                                         for g in gens))
