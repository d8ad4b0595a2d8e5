"""How long each action of a sequence lasts: a linear map from the text vector to log seconds.

A prompt split into actions (compose.py: "sits down and stands up, then turns slightly left")
is made part by part and chained. With equal shares a quick 45-degree turn gets as long as a
sit-down-and-stand-up, and each action is stretched or squeezed away from the tempo the model
learned. So the parts share the clip in proportion to how long each action takes, predicted from
its text as T2M's length estimator does (Guo et al., CVPR 2022, predicts a motion's length from
its text; ours is a ridge regression, which is all 384 inputs and a few thousand captions
support). It is fitted on the single-action motions of a labelled dataset (`mlct train
durations`), in the model's own text-vector space, and stored beside the model as
durations.json (385 numbers). A model without one splits equally, as before.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from mlct.errors import MlctError, first_line
from mlct.io import write_text

FILE = "durations.json"
FORMAT, VERSION = "mlct-durations", 1
L2 = 1.0  # ridge penalty on the standardised inputs: r2 on held-out captions is flat 0.1-10


@dataclass(frozen=True)
class DurationModel:
    """log(seconds) = embedding @ weight + bias, in the text space of `text_encoder`."""

    weight: np.ndarray  # (c,)
    bias: float
    text_encoder: str
    fit: dict[str, Any]  # how it was fitted: motions, captions, held-out r2 and errors

    def seconds(self, embeddings: np.ndarray) -> np.ndarray:
        """(B,) predicted durations, in seconds, of (B, c) text vectors."""
        return np.exp(np.asarray(embeddings, dtype=np.float64) @ self.weight + self.bias)

    def to_json(self) -> dict[str, Any]:
        return {"format": FORMAT, "version": VERSION, "text_encoder": self.text_encoder,
                "bias": float(self.bias), "weight": [float(w) for w in self.weight],
                "fit": self.fit}

    @classmethod
    def from_json(cls, data: Any, where: str) -> DurationModel:
        try:
            if data.get("format") != FORMAT or data.get("version") != VERSION:
                raise ValueError(f"not {FORMAT} version {VERSION}")
            weight = np.asarray(data["weight"], dtype=np.float64)
            bias = float(data["bias"])
            if weight.ndim != 1 or not np.isfinite(weight).all() or not np.isfinite(bias):
                raise ValueError("weight must be a list of finite numbers")
            return cls(weight, bias, str(data["text_encoder"]), dict(data.get("fit", {})))
        except (AttributeError, KeyError, TypeError, ValueError) as error:
            raise MlctError(f"{where}: not a duration model ({first_line(error)})") from None

    def save(self, model_dir: str | os.PathLike) -> Path:
        path = Path(model_dir) / FILE
        write_text(path, json.dumps(self.to_json(), indent=1) + "\n")  # atomic
        return path


def read_durations(model_dir: str | os.PathLike, text_encoder: str, text_dim: int
                   ) -> DurationModel | None:
    """The model folder's duration model, None when it has none; MlctError when it is damaged
    or was fitted under another text encoder (its vectors would mean nothing here)."""
    path = Path(model_dir) / FILE
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise MlctError(f"{path}: unreadable ({first_line(error)})") from None
    model = DurationModel.from_json(data, str(path))
    if model.text_encoder != text_encoder or model.weight.shape != (text_dim,):
        raise MlctError(f"{path}: fitted for the text encoder {model.text_encoder!r} "
                        f"({model.weight.shape[0]}-d), the model uses {text_encoder!r} "
                        f"({text_dim}-d); refit it with `mlct train durations`")
    return model


def fit_durations(embeddings: np.ndarray, seconds: np.ndarray, text_encoder: str,
                  groups: np.ndarray | None = None, l2: float = L2) -> DurationModel:
    """Ridge regression of log(seconds) on (N, c) embeddings, closed form.

    groups: the motion of each caption; a fifth of the motions (never their captions apart)
    is held out to report r2 and the median error before the final fit on everything."""
    x = np.asarray(embeddings, dtype=np.float64)
    y = np.log(np.asarray(seconds, dtype=np.float64))
    if x.ndim != 2 or len(x) != len(y) or len(y) < 10:
        raise MlctError(f"need 10 or more captions with durations to fit, got {len(y)}")
    groups = np.arange(len(y)) if groups is None else np.asarray(groups)
    held = np.isin(groups, np.unique(groups)[::5])
    w, b = _ridge(x[~held], y[~held], l2)
    predicted = x[held] @ w + b
    r2 = 1.0 - np.mean((predicted - y[held]) ** 2) / np.var(y[held])
    ratio = np.exp(np.abs(predicted - y[held]))
    fit = {"captions": int(len(y)), "motions": int(len(np.unique(groups))),
           "held_out_r2": round(float(r2), 4),
           "held_out_median_error": round(float(np.median(ratio) - 1.0), 4),
           "seconds_range": [round(float(np.exp(y.min())), 3), round(float(np.exp(y.max())), 3)],
           "l2": l2}
    w, b = _ridge(x, y, l2)
    return DurationModel(w, b, text_encoder, fit)


def _ridge(x: np.ndarray, y: np.ndarray, l2: float) -> tuple[np.ndarray, float]:
    """Weights on the raw inputs of a ridge fit on standardised ones (the penalty then treats
    every dimension alike whatever its scale: the side contrast stretches a few)."""
    mean, scale = x.mean(0), x.std(0) + 1e-8
    z = (x - mean) / scale
    coef = np.linalg.solve(z.T @ z + l2 * np.eye(z.shape[1]), z.T @ (y - y.mean()))
    weight = coef / scale
    return weight, float(y.mean() - mean @ weight)


def single_action_captions(labels: Mapping[str, Mapping[str, Any]]
                           ) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(captions, seconds, motion index) of a dataset's labelled motions (labels.jsonl records
    by name) of one action and no concurrent one: each caption with the action's labelled
    duration (end - start)."""
    texts, seconds, groups = [], [], []
    for index, (_, label) in enumerate(sorted(labels.items())):
        actions = label.get("actions") or []
        if len(actions) != 1 or label.get("concurrent"):
            continue
        duration = float(actions[0]["end"]) - float(actions[0]["start"])
        for caption in label.get("captions") or []:
            texts.append(caption)
            seconds.append(duration)
            groups.append(index)
    if not texts:
        raise MlctError("no labelled single-action motions with captions (labels.jsonl of "
                        "`mlct data synth`) to fit durations on")
    return texts, np.asarray(seconds), np.asarray(groups)


def split_frames(weights: Sequence[float] | np.ndarray, frames: int, min_frames: int
                 ) -> list[int]:
    """`frames` split among parts in proportion to `weights` (their predicted durations, or
    ones for equal shares), each at least min_frames when the total allows; the shares sum to
    `frames` (largest remainders)."""
    weights = np.asarray(weights, dtype=np.float64)
    count = len(weights)
    floor = min(min_frames, frames // count)
    spare = frames - floor * count
    exact = spare * weights / weights.sum()
    share = floor + np.floor(exact).astype(int)
    # the frames that rounding down left go to the largest remainders (then the first parts)
    left = frames - int(share.sum())
    share[np.argsort(-(exact - np.floor(exact)), kind="stable")[:left]] += 1
    return [int(s) for s in share]


def describe(model: DurationModel, texts: Sequence[str], embeddings: np.ndarray) -> str:
    """One line per text with its predicted duration (for `mlct train durations`)."""
    return "\n".join(f"  {s:5.2f} s  {t}" for t, s in zip(texts, model.seconds(embeddings)))
