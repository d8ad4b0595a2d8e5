"""Prompts worded unlike any training caption, pulled part of the way towards the nearest ones
(ours; the paper conditions on the text vector as it is).

Stage 2 learnt its text-to-latent map on the training captions' vectors. A prompt worded unlike
all of them ("a teacher at the whiteboard swings round a quarter of the way, toward her right")
lands away from those vectors, where the map was never trained, and the motion is often not the
one asked for even when the nearest training captions name the right action (held-out wording,
docs/training.md, "Far prompts pulled towards the training captions"). So before sampling, a
prompt's vector c becomes

    c' = (1 - a) c + a m,   m = the mean of its `neighbours` nearest training-caption vectors,
    a = pull * clip((near - s) / span, 0, 1),   s = its cosine with the nearest one,

so a prompt at least as close to the training captions as 95 % of unseen benchmark captions
(`near`, measured on the validation split when the anchors are made) is left as it is, and one
`span` further away is pulled by `pull`. Where the anchors know what each caption says (its
motion's label: the action, its side, angle and mode; `groups`) and all the neighbours say the
same, the pull reaches `agreed_pull` instead: "a nurse is walking down the hospital corridor"
is nearest five captions that say "a person is walking", and half a pull towards them still
stood still where the whole one walks; neighbours that differ (turns of several sizes) keep
the prompt's own say. The critic still scores the candidates against the prompt's own vector.
The anchors are the training captions' vectors (int8, one scale per row):

    MODEL_DIR/text_anchors.safetensors   "vectors" (N, c) int8, "scales" (N, 1) float16,
                                         optionally "groups" (N,) int16 (a caption's label
                                         signature, -1 where its motions' labels differ); what
                                         made them and the rule's constants in the metadata
                                         ("mlct": JSON)

The rule runs in numpy (the onnx backend's vectors are numpy arrays; the torch backend's
tensors are read as arrays and given back as tensors).
"""

from __future__ import annotations

import json
import os
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from safetensors import safe_open

from mlct.errors import MlctError, first_line
from mlct.io import atomic_path

if TYPE_CHECKING:
    from torch import Tensor

FILE = "text_anchors.safetensors"
FORMAT, VERSION = "mlct-text-anchors", 1
MEMO_ROWS = 4096  # pulled rows kept, least recently made first out


@dataclass(frozen=True)
class TextAnchors:
    """Training-caption vectors and the pull rule of the module docstring."""

    vectors: Any  # (N, c) float32, as the model's text encoder gives them (array or tensor)
    near: float  # cosine at or above which a prompt is left alone
    span: float  # how much further below `near` the pull reaches `pull`
    pull: float  # the largest share of the neighbours' mean, in [0, 1]
    neighbours: int = 5
    info: dict[str, Any] | None = None
    groups: Any = None  # (N,) each caption's label signature, -1: unknown or mixed
    agreed_pull: float = 1.0  # the largest share where every neighbour has the same group

    def __post_init__(self) -> None:
        if self.vectors.ndim != 2 or len(self.vectors) < self.neighbours:
            raise MlctError(f"text anchors need at least {self.neighbours} vectors, "
                            f"got {tuple(self.vectors.shape)}")
        if not (0.0 <= self.pull <= 1.0 and self.span > 0.0 and self.neighbours >= 1
                and 0.0 <= self.agreed_pull <= 1.0):
            raise MlctError(f"text anchors: pull and agreed_pull must be in [0, 1], span > 0 "
                            f"and neighbours >= 1, got {self.pull}, {self.agreed_pull}, "
                            f"{self.span}, {self.neighbours}")
        if self.groups is not None and tuple(self.groups.shape) != (len(self.vectors),):
            raise MlctError(f"text anchors: {len(self.vectors)} vectors but groups of shape "
                            f"{tuple(self.groups.shape)}")
        rows = _array(self.vectors)
        object.__setattr__(self, "_rows", rows)
        # the unit vectors as (c, N) columns: one product gives every prompt's cosines
        object.__setattr__(self, "_columns", _unit_columns(rows))
        object.__setattr__(self, "_groups", None if self.groups is None
                           else np.asarray(_array(self.groups, None), np.int64))
        object.__setattr__(self, "_memo", OrderedDict())  # row bytes -> (nearest, pulled row)
        object.__setattr__(self, "_lock", threading.Lock())  # the server's threads share it

    def weights(self, cond: Any) -> tuple[np.ndarray, np.ndarray]:
        """(a (B,), m (B, c)): each row's pull and its neighbours' mean (zeros where a is 0:
        a row near the captions needs no neighbours). Arrays, or tensors for a tensor."""
        pull, mean, _ = self._rule(_array(cond))
        return _like(pull, cond), _like(mean, cond)

    def _rule(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """weights' (a, m) and each row's cosine with its nearest caption s (B,)."""
        sims = _unit(rows) @ self._columns  # (B, N)
        nearest = sims.max(axis=1)
        ramp = np.clip((self.near - nearest) / self.span, 0.0, 1.0)
        pull = (self.pull * ramp).astype(np.float32)
        mean = np.zeros((len(sims), self._rows.shape[1]), np.float32)
        far = np.flatnonzero(ramp > 0)
        if len(far):
            # the `neighbours` nearest, nearest first (torch.topk's order)
            top = np.argsort(-sims[far], axis=1, kind="stable")[:, :self.neighbours]  # (F, k)
            mean[far] = self._rows[top].mean(axis=1)
            if self._groups is not None:
                groups = self._groups[top]  # (F, k)
                agreed = (groups >= 0).all(axis=1) & (groups == groups[:, :1]).all(axis=1)
                pull[far] = np.where(agreed, self.agreed_pull * ramp[far], pull[far])
        return pull, mean, nearest

    def nearest(self, cond: Any) -> np.ndarray:
        """(B,) each row's cosine with its nearest training caption: how far the prompt lies
        from everything the model was trained on (generate/compose/unknown_prompts.py reads it).
        An array, or a tensor for a tensor."""
        return _like(np.array([near for near, _ in self._entries(_array(cond))], np.float32),
                     cond)

    def __call__(self, cond: Any) -> Any:
        """cond (B, c) -> the pulled vectors, an array for an array, a tensor of cond's dtype
        and device for a tensor."""
        rows = _array(cond)
        out = np.stack([row for _, row in self._entries(rows)])
        if np.array_equal(out, rows):
            return cond
        if isinstance(cond, np.ndarray):
            return out
        return _like(out, cond).to(dtype=cond.dtype, device=cond.device)

    def _entries(self, rows: np.ndarray) -> list[tuple[float, np.ndarray]]:
        """(nearest cosine, pulled row) of each row (B, c). A row seen before is taken from a
        memo (MEMO_ROWS): the 12,000 cosines cost ~0.4 ms a prompt on one thread (2 BLAS
        threads beside the graphs' on 2 busy cores took 10-25 ms), 5 % of a warm batch-1
        generate(), which asks for both: the pull before sampling, the judgement after."""
        keys = [row.tobytes() for row in rows]
        memo: OrderedDict[bytes, tuple[float, np.ndarray]] = self._memo  # type: ignore
        with self._lock:  # type: ignore[attr-defined]
            found = [memo.get(k) for k in keys]
        missing = [i for i, f in enumerate(found) if f is None]
        if missing:
            pull, mean, nearest = self._rule(rows[missing])
            made = (1.0 - pull[:, None]) * rows[missing] + pull[:, None] * mean
            with self._lock:  # type: ignore[attr-defined]
                for i, row, near in zip(missing, made, nearest):
                    found[i] = memo[keys[i]] = (float(near), row)
                while len(memo) > MEMO_ROWS:
                    memo.popitem(last=False)
        return found  # type: ignore[return-value]


def _array(x: Any, dtype: Any = np.float32) -> np.ndarray:
    """A tensor or array as a numpy array (of dtype; None: as it is)."""
    if not isinstance(x, np.ndarray):
        x = x.detach().cpu().numpy()
    return x if dtype is None else np.asarray(x, dtype)


def _like(array: np.ndarray, given: Any) -> Any:
    """An array for an array, a tensor for a tensor."""
    if isinstance(given, np.ndarray):
        return array
    import torch

    return torch.from_numpy(array)


def _unit(rows: np.ndarray) -> np.ndarray:
    """Rows scaled to unit length (F.normalize's: a zero row stays zero)."""
    return rows / np.maximum(np.linalg.norm(rows, axis=1, keepdims=True), 1e-12)


def _unit_columns(rows: np.ndarray, block: int = 512) -> np.ndarray:
    """_unit(rows).T as a C-contiguous (c, N) array, made a block of rows at a time: no (N, c)
    temporary (the same values; 12,000 anchors in ~0.6x the time, at every model load)."""
    columns = np.empty((rows.shape[1], len(rows)), rows.dtype)
    for start in range(0, len(rows), block):
        columns[:, start:start + block] = _unit(rows[start:start + block]).T
    return columns


def int8_rows(vectors: Tensor) -> tuple[Tensor, Tensor]:
    """(N, c) -> int8 rows (N, c) and float16 scales (N, 1), as the file stores them; rows *
    scales gives the vectors back within half a step."""
    import torch

    vectors = torch.as_tensor(vectors).float()
    scales = (vectors.abs().amax(dim=1, keepdim=True) / 127.0).clamp(min=1e-12).half()
    return torch.round(vectors / scales.float()).clamp(-127, 127).to(torch.int8), scales


def save_text_anchors(model_dir: str | os.PathLike, anchors: TextAnchors, text_encoder: str
                      ) -> Path:
    """Write MODEL_DIR/text_anchors.safetensors atomically: int8 rows, a float16 scale each."""
    import torch
    from safetensors.torch import save

    vectors = torch.as_tensor(anchors.vectors).float()
    rows, scales = int8_rows(vectors)
    # the rule and the format last: anchors read from a file carry the old ones in their info
    info = {**(anchors.info or {}), "format": FORMAT, "version": VERSION,
            "text_encoder": text_encoder, "text_dim": int(vectors.shape[1]), "near": anchors.near,
            "span": anchors.span, "pull": anchors.pull, "neighbours": anchors.neighbours}
    tensors = {"vectors": rows.contiguous(), "scales": scales.contiguous()}
    if anchors.groups is not None:
        groups = torch.as_tensor(anchors.groups)
        if int(groups.max()) > torch.iinfo(torch.int16).max:
            raise MlctError(f"text anchors: {int(groups.max()) + 1} label groups, more "
                            f"than the file's int16 holds")
        tensors["groups"] = groups.to(torch.int16).contiguous()
        info["agreed_pull"] = anchors.agreed_pull
    else:
        info.pop("agreed_pull", None)
    path = Path(model_dir) / FILE
    with atomic_path(path) as tmp:
        tmp.write_bytes(save(tensors, metadata={"mlct": json.dumps(info)}))
    return path


def read_text_anchors(model_dir: str | os.PathLike, text_encoder: str, text_dim: int
                      ) -> TextAnchors | None:
    """The model folder's anchors, None when it has none; MlctError when the file is damaged
    or was made with another text encoder."""
    path = Path(model_dir) / FILE
    if not path.is_file():
        return None
    try:
        with safe_open(str(path), framework="numpy") as f:
            info = json.loads((f.metadata() or {})["mlct"])
            rows, scales = f.get_tensor("vectors"), f.get_tensor("scales")
            groups = f.get_tensor("groups") if "groups" in f.keys() else None
        if info.get("format") != FORMAT or info.get("version") != VERSION:
            raise ValueError(f"not {FORMAT} version {VERSION}")
        if rows.dtype != np.int8 or rows.ndim != 2 or tuple(scales.shape) != (len(rows), 1):
            raise ValueError(f"vectors {tuple(rows.shape)} {rows.dtype}, scales "
                             f"{tuple(scales.shape)}")
        if groups is not None and (groups.dtype != np.int16
                                   or tuple(groups.shape) != (len(rows),)):
            raise ValueError(f"groups {tuple(groups.shape)} {groups.dtype}")
        vectors = np.multiply(rows, scales.astype(np.float32), dtype=np.float32)  # one pass
        rule = (float(info["near"]), float(info["span"]), float(info["pull"]),
                int(info["neighbours"]))
        agreed_pull = float(info.get("agreed_pull", rule[2]))
    except Exception as error:  # safetensors, json and the checks raise several kinds
        raise MlctError(f"{path}: not text anchors ({first_line(error)})") from None
    if info["text_encoder"] != text_encoder or vectors.shape[1] != text_dim:
        raise MlctError(f"{path}: made with the text encoder {info['text_encoder']!r} "
                        f"({vectors.shape[1]}-d), the model uses {text_encoder!r} ({text_dim}-d); "
                        f"remake them with `mlct train anchors`")
    near, span, pull, neighbours = rule
    return TextAnchors(vectors, near, span, pull, neighbours, info,
                       None if groups is None else groups.astype(np.int64), agreed_pull)
