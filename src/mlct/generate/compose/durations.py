"""How long each action of a sequence lasts, predicted from its text.

A prompt split into actions (compose.py: "sits down and stands up, then turns slightly left")
is made part by part and chained. With equal shares a quick 45-degree turn gets as long as a
sit-down-and-stand-up, and each action is stretched or squeezed away from the tempo the model
learned. So the parts share the clip by how long each action takes, predicted from its text as
T2M's length estimator does (Guo et al., CVPR 2022, predicts a motion's length from its text).
It is fitted in the model's own text-vector space (`mlct train durations`,
train/durations.py) and stored beside the model as durations.json. A model without one splits
equally.

Version 2 (now): log seconds from a one-hidden-layer network, and a part's share of the clip
is its predicted duration plus an offset by its place in the sequence (the first, a middle or
the last part), fitted on the data's sequences: neighbouring actions overlap in the data, so a
middle part's share is shorter than its action. Version 1 (a linear map, 385 numbers, shares in
proportion to the seconds) is still read. On the benchmark's sequence test captions the parts'
cuts came 0.34 s (mean) from the data's with version 1 and 0.10 s with version 2
(docs/training.md).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from mlct.errors import MlctError, first_line
from mlct.io import write_text

FILE = "durations.json"
FORMAT, VERSIONS = "mlct-durations", (1, 2)
PLACES = ("first", "middle", "last")  # a part's place in its sequence, for the share's offset
MIN_WEIGHT = 0.05  # seconds beyond the shortest share that any part keeps (see part_weights)
# Seconds a one-action clip lasts beyond its action (the lead-in and the tail), for a file that
# does not say: the median of the procedural benchmark's single-action motions.
SINGLE_EXTRA = 0.4
# How far a clip squeezes its parts alike: the benchmark's fastest tempo is 1.15 (a motion's
# actions all done up to 1.15x faster, data/synth/build.py), so no action the model learnt
# took less than 1/1.15 of its usual time. A shorter clip takes the rest from the longest
# parts first (squeeze_longest_first).
FASTEST_TEMPO_SHARE = 1 / 1.15


@dataclass(frozen=True)
class DurationModel:
    """log(seconds) = tanh(embedding @ hidden_weight + hidden_bias) @ weight + bias, or, without
    a hidden layer (version 1), embedding @ weight + bias; in the text space of
    `text_encoder`. `offsets` (seconds, by place) turn an action's duration into its share."""

    weight: np.ndarray  # (c,) or, with a hidden layer, (h,)
    bias: float
    text_encoder: str
    fit: dict[str, Any]  # how it was fitted: data, held-out errors
    hidden_weight: np.ndarray | None = None  # (c, h)
    hidden_bias: np.ndarray | None = None  # (h,)
    offsets: Mapping[str, float] = field(default_factory=dict)  # by PLACES; none in version 1
    single_extra: float = SINGLE_EXTRA  # a one-action clip's seconds beyond its action

    @property
    def input_dim(self) -> int:
        return len(self.weight) if self.hidden_weight is None else self.hidden_weight.shape[0]

    def seconds(self, embeddings: np.ndarray) -> np.ndarray:
        """(B,) predicted durations, in seconds, of (B, c) text vectors."""
        x = np.asarray(embeddings, dtype=np.float64)
        if self.hidden_weight is not None:
            x = np.tanh(x @ self.hidden_weight + self.hidden_bias)
        return np.exp(x @ self.weight + self.bias)

    def part_weights(self, embeddings: np.ndarray, total_seconds: float, min_seconds: float
                     ) -> np.ndarray:
        """The weights split_frames shares a clip of total_seconds by, for its parts' (B, c)
        text vectors in order. Each part wants its duration plus its place's offset; a clip
        longer or shorter than their sum stretches them all alike (the tempo of each action
        changes by the same factor). split_frames gives every part min_seconds first and the
        rest in proportion to the weights, so a weight is the stretched share less that
        minimum. A clip shorter than FASTEST_TEMPO_SHARE of their sum is cut further from the
        longest parts first (`squeeze_longest_first`). Version 1 models: the durations
        themselves, as they were used."""
        if not self.offsets:
            return self.seconds(embeddings)
        wanted = self.part_seconds(embeddings)
        if total_seconds < FASTEST_TEMPO_SHARE * wanted.sum():
            shares = squeeze_longest_first(FASTEST_TEMPO_SHARE * wanted, total_seconds)
        else:
            shares = wanted * total_seconds / wanted.sum()
        return np.maximum(shares - min_seconds, MIN_WEIGHT)

    def clip_seconds(self, embeddings: np.ndarray) -> float:
        """How long a clip doing the (B, c) parts in order lasts when nobody says (generate's
        seconds="auto"): one action, its duration and the lead-in and tail around it; several,
        their shares (each duration plus its place's offset, which hold the lead-in, the
        overlaps and the tail)."""
        return float(self.part_seconds(embeddings).sum())

    def part_seconds(self, embeddings: np.ndarray) -> np.ndarray:
        """(B,) each part's own share of a clip of its natural length (see clip_seconds)."""
        seconds = self.seconds(embeddings)
        if len(seconds) == 1:
            return seconds + self.single_extra
        offsets = [self.offsets.get(p, 0.0) for p in place_names(len(seconds))]
        return np.maximum(seconds + np.array(offsets), MIN_WEIGHT)

    def to_json(self) -> dict[str, Any]:
        data: dict[str, Any] = {"format": FORMAT, "version": 1 if self.hidden_weight is None
                                and not self.offsets else 2, "text_encoder": self.text_encoder,
                                "bias": float(self.bias), "weight": _floats(self.weight)}
        if data["version"] == 2:
            data["hidden_weight"] = (None if self.hidden_weight is None else
                                     [_floats(row) for row in self.hidden_weight])
            data["hidden_bias"] = (None if self.hidden_bias is None else
                                   _floats(self.hidden_bias))
            data["offsets"] = {p: float(self.offsets.get(p, 0.0)) for p in PLACES}
            data["single_extra"] = float(self.single_extra)
        data["fit"] = self.fit
        return data

    @classmethod
    def from_json(cls, data: Any, where: str) -> DurationModel:
        try:
            if data.get("format") != FORMAT or data.get("version") not in VERSIONS:
                raise ValueError(f"not {FORMAT} version {' or '.join(map(str, VERSIONS))}")
            weight = np.asarray(data["weight"], dtype=np.float64)
            bias = float(data["bias"])
            hidden_weight = hidden_bias = None
            offsets: dict[str, float] = {}
            extra = SINGLE_EXTRA
            if data["version"] == 2:
                if data.get("hidden_weight") is not None:
                    hidden_weight = np.asarray(data["hidden_weight"], dtype=np.float64)
                    hidden_bias = np.asarray(data["hidden_bias"], dtype=np.float64)
                    if (hidden_weight.ndim != 2 or hidden_bias.shape != (hidden_weight.shape[1],)
                            or weight.shape != hidden_bias.shape):
                        raise ValueError("the hidden layer's shapes do not fit its weight")
                offsets = {p: float(data["offsets"][p]) for p in PLACES}
                extra = float(data.get("single_extra", SINGLE_EXTRA))
            arrays = [weight, np.asarray([bias, extra, *offsets.values()])]
            arrays += [] if hidden_weight is None else [hidden_weight, hidden_bias]
            if weight.ndim != 1 or not all(np.isfinite(a).all() for a in arrays):
                raise ValueError("weight must be a list of finite numbers")
            return cls(weight, bias, str(data["text_encoder"]), dict(data.get("fit", {})),
                       hidden_weight, hidden_bias, offsets, extra)
        except (AttributeError, KeyError, TypeError, ValueError) as error:
            raise MlctError(f"{where}: not a duration model ({first_line(error)})") from None

    def save(self, model_dir: str | os.PathLike) -> Path:
        path = Path(model_dir) / FILE
        # a key per line, each value on its line: readable, and 64 lines, not 25,000
        lines = [f" {json.dumps(k)}: {json.dumps(v)}" for k, v in self.to_json().items()]
        write_text(path, "{\n" + ",\n".join(lines) + "\n}\n")  # atomic
        return path


def place_names(count: int) -> list[str]:
    """The place of each of `count` parts: first, middle ..., last (a lone part is "first")."""
    return [PLACES[0] if i == 0 else PLACES[2] if i == count - 1 else PLACES[1]
            for i in range(count)]


def _floats(values: np.ndarray) -> list[float]:
    """float32's precision is all a duration needs, and keeps the file a third the size."""
    return [float(f"{v:.7g}") for v in np.asarray(values, dtype=np.float64)]


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
    if model.text_encoder != text_encoder or model.input_dim != text_dim:
        raise MlctError(f"{path}: fitted for the text encoder {model.text_encoder!r} "
                        f"({model.input_dim}-d), the model uses {text_encoder!r} "
                        f"({text_dim}-d); refit it with `mlct train durations`")
    return model


def squeeze_longest_first(wanted: np.ndarray, total_seconds: float) -> np.ndarray:
    """Shares of a clip of total_seconds, shorter than the parts' `wanted` seconds (sum), with
    the time taken from the longest parts first: every part longer than a common cap is cut to
    it, the shorter ones keep their own length, and the cap is where the shares sum to the clip.

    Why not squeeze all alike: an action of a count (waves, claps, jumps) or of an angle (a
    turn) needs its own time for it (the benchmark's waves take 2.2-3.6 s, its walks 3.8-5.7 s),
    where a walk or a jog is as good shorter, only going less far. Squeezed alike, "a person
    walks, then waves" in 5 s gave the wave 1.8 s, less than any wave of the data, and it
    swayed too few times (docs/training.md). Down to equal shares when the clip is shorter
    than that. part_weights uses it
    only past the data's own tempo range: within it the data's cuts agree better with parts
    squeezed alike."""
    wanted = np.asarray(wanted, dtype=np.float64)
    levels = np.sort(wanted)
    count = len(levels)
    # Parts at or under levels[k] keep their length; the count - k longer ones share the rest.
    below = 0.0
    for k in range(count):
        cap = (total_seconds - below) / (count - k)
        if cap <= levels[k]:
            return np.minimum(wanted, cap)
        below += levels[k]
    return wanted * total_seconds / wanted.sum()  # not shorter after all: alike


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
