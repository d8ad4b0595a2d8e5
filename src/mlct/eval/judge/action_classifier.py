"""An action classifier: does a motion show what its prompt asked?

Classes come from labels.jsonl: every action family of a motion (its sequence and its concurrent
upper-body action), and for families with a side parameter (`side`, `leg`, `hand`) also
`family:value`, e.g. `kick`, `kick:left`. So "does 'kick with the left leg' produce a left kick?"
is the recall of class `kick:left` over prompts that ask for one. An imported real corpus has no
labels.jsonl: each motion's one class is then its corpus label (`action_records`).

The network is a masked 1-D temporal conv net on normalized features (B, T, D): a per-frame
projection, strided conv blocks (LayerNorm over channels, padded frames zeroed after every
layer, so a motion's prediction does not depend on what it is batched with), masked max and
mean pooling, and a sigmoid multi-label head trained with BCE. Motions of the train split are
jittered by dropping a few frames at either end (the benchmark's idle lead-in / lead-out).

    DIR/model.safetensors    weights
    DIR/classifier.json      format, version, classes, feature_dim, skeleton, sizes, training
    DIR/Mean.npy, Std.npy    the dataset's normalization statistics
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np
import torch
import torch.nn.functional as F
from safetensors.torch import load_file, save_file
from torch import Tensor, nn

from mlct.data.labels import LABELS_FILE, read_labels  # noqa: F401 - re-exported
from mlct.data.layout import (PROVENANCE_FILE, DatasetLayout, load_npy, provenance_label,
                              read_provenance)
from mlct.devices import resolve_device
from mlct.errors import MlctError, first_line
from mlct.eval.judge.evaluator_dir import prepare_target
from mlct.io import atomic_dir, read_format_json, save_npy, write_text

FORMAT = "mlct-action-classifier"
VERSION = 1
META_FILE = "classifier.json"
WEIGHTS_FILE = "model.safetensors"
SIDE_PARAMS = ("side", "leg", "hand")  # parameters that name a side of the body
THRESHOLD = 0.5
JITTER_FRAMES = 4  # at most this many frames dropped at each end of a training motion


# --- classes ---------------------------------------------------------------------------------

def action_targets(record: Mapping[str, Any]) -> set[str]:
    """The class set of a labels.jsonl record: families, plus `family:side` where one is set."""
    actions = list(record.get("actions") or [])
    if record.get("concurrent"):
        actions.append(record["concurrent"])
    targets = set()
    for action in actions:
        family = action["family"]
        targets.add(family)
        for key in SIDE_PARAMS:
            if key in action.get("params", {}):
                targets.add(f"{family}:{action['params'][key]}")
    return targets


def action_records(data_dir: str | os.PathLike) -> dict[str, dict[str, Any]]:
    """Each motion's action record, by name: labels.jsonl's where the dataset has one (a
    procedural benchmark); every other motion whose provenance carries corpus labels (an
    imported real corpus's, also inside a merge) gets one action whose family is its corpus
    label (a Bandai Namco content, CMU's description). A merge's procedural motions have
    neither when its labels.jsonl was dropped, and stay unlabelled. Why: the semantic judge of
    a real corpus can only learn what the corpus says each take shows."""
    root = Path(data_dir)
    if not (root / PROVENANCE_FILE).is_file():
        return read_labels(root)  # names labels.jsonl when it is missing too
    records = read_labels(root) if (root / LABELS_FILE).is_file() else {}
    for record in read_provenance(root):
        if record.get("labels") and record["name"] not in records:
            label = provenance_label(record)
            records[record["name"]] = {"name": record["name"], "label": label,
                                       "actions": [{"family": label, "params": {}}]}
    return records


def derive_classes(records: Iterable[Mapping[str, Any]]) -> list[str]:
    """The sorted union of the records' class sets."""
    return sorted(set().union(*(action_targets(r) for r in records)))


def multi_hot(target_sets: Sequence[set[str]], classes: Sequence[str]) -> Tensor:
    """(N, C) float 0/1 targets; a class outside `classes` raises MlctError."""
    unknown = sorted(set().union(*target_sets) - set(classes))
    if unknown:
        raise MlctError(f"classes the action classifier does not know: {', '.join(unknown)}")
    index = {k: i for i, k in enumerate(classes)}
    out = torch.zeros(len(target_sets), len(classes))
    for row, targets in enumerate(target_sets):
        out[row, [index[k] for k in targets]] = 1.0
    return out


# --- network ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class ClassifierSizes:
    """Widths of the classifier network (stored in classifier.json)."""

    hidden: int = 128  # channels of every block
    blocks: int = 4  # conv blocks; the first three halve the time axis
    kernel: int = 5  # odd: a block keeps the frames' centres
    dropout: float = 0.1

    def __post_init__(self) -> None:
        if self.hidden < 1 or self.blocks < 1 or self.kernel % 2 == 0 or not 0 <= self.dropout < 1:
            raise MlctError(f"bad classifier sizes {self}: hidden, blocks >= 1, odd kernel, "
                            f"dropout in [0, 1)")


def _mask(lengths: Tensor, steps: int) -> Tensor:
    """(B, steps) True on valid positions."""
    return torch.arange(steps, device=lengths.device)[None, :] < lengths[:, None]


class ActionNet(nn.Module):
    """Normalized features (B, T, D) and lengths (B,) -> class logits (B, C)."""

    def __init__(self, feature_dim: int, n_classes: int, sizes: ClassifierSizes) -> None:
        super().__init__()
        h = sizes.hidden
        self.strides = [2 if i < 3 else 1 for i in range(sizes.blocks)]
        self.inp = nn.Linear(feature_dim, h)
        self.convs = nn.ModuleList(nn.Conv1d(h, h, sizes.kernel, s, sizes.kernel // 2)
                                   for s in self.strides)
        self.norms = nn.ModuleList(nn.LayerNorm(h) for _ in self.strides)
        self.dropout = nn.Dropout(sizes.dropout)
        self.head = nn.Linear(2 * h, n_classes)

    def forward(self, x: Tensor, lengths: Tensor) -> Tensor:
        mask = _mask(lengths, x.shape[1])  # (B, T)
        h = F.gelu(self.inp(x)) * mask[..., None]  # (B, T, H)
        for conv, norm, stride in zip(self.convs, self.norms, self.strides):
            y = conv(h.transpose(1, 2)).transpose(1, 2)  # (B, T', H)
            lengths = (lengths + stride - 1) // stride  # frames whose centre lies inside
            mask = _mask(lengths, y.shape[1])
            y = self.dropout(F.gelu(norm(y)))
            h = (y + h if stride == 1 else y) * mask[..., None]
        neg = torch.finfo(h.dtype).min
        pooled_max = h.masked_fill(~mask[..., None], neg).amax(1)  # (B, H)
        pooled_mean = h.sum(1) / lengths[:, None].clamp(min=1)
        return self.head(torch.cat([pooled_max, pooled_mean], -1))  # (B, C)


def _pad(features: Sequence[np.ndarray | Tensor]) -> tuple[Tensor, Tensor]:
    """A list of (T, D) arrays -> zero-padded (B, T_max, D) float32 and lengths (B,)."""
    tensors = [torch.as_tensor(np.asarray(f), dtype=torch.float32) for f in features]
    lengths = torch.tensor([len(t) for t in tensors], dtype=torch.long)
    return nn.utils.rnn.pad_sequence(tensors, batch_first=True), lengths


class ActionClassifier:
    """A trained classifier: `predict` motions in real units -> class probabilities (B, C)."""

    def __init__(self, net: ActionNet, classes: Sequence[str], mean: np.ndarray, std: np.ndarray,
                 skeleton: str, sizes: ClassifierSizes, meta: Mapping[str, Any] | None = None):
        self.net = net.eval()
        self.classes = list(classes)
        self.mean = torch.as_tensor(mean, dtype=torch.float32)
        self.std = torch.as_tensor(std, dtype=torch.float32)
        self.skeleton, self.sizes, self.meta = skeleton, sizes, dict(meta or {})

    @property
    def feature_dim(self) -> int:
        return int(self.mean.shape[0])

    def check(self, feature_dim: int, skeleton: str | None = None) -> None:
        """Raise MlctError when motions of this width / skeleton are not what it was trained on."""
        if feature_dim != self.feature_dim or (skeleton is not None and skeleton != self.skeleton):
            found = f"{feature_dim}-d" + (f" {skeleton}" if skeleton else "")
            raise MlctError(f"the action classifier reads {self.feature_dim}-d {self.skeleton} "
                            f"features; the motions are {found}")

    @torch.no_grad()
    def predict(self, features: Sequence[np.ndarray | Tensor] | Tensor,
                lengths: Tensor | Sequence[int] | None = None, batch_size: int = 256) -> Tensor:
        """Probabilities (B, C) of (T, D) motions in real units (a list, or padded + lengths)."""
        if isinstance(features, Tensor) and features.ndim == 3:
            padded = features.detach().float()
            lengths_t = torch.as_tensor([padded.shape[1]] * len(padded) if lengths is None
                                        else lengths, dtype=torch.long).cpu()
        else:
            if not len(features):
                return torch.zeros(0, len(self.classes))
            if any(np.ndim(f) != 2 for f in features):
                raise MlctError("the action classifier reads (frames, features) arrays")
            for width in {np.shape(f)[1] for f in features}:
                self.check(int(width))
            padded, lengths_t = _pad(features)
        self.check(int(padded.shape[-1]))
        device = next(self.net.parameters()).device
        out = []
        for start in range(0, len(padded), batch_size):
            x, n = padded[start:start + batch_size], lengths_t[start:start + batch_size]
            x = x[:, :int(n.max())].to(device)  # (b, T, D)
            x = (x - self.mean.to(device)) / self.std.to(device)
            x = x * _mask(n.to(device), x.shape[1])[..., None]
            out.append(torch.sigmoid(self.net(x, n.to(device))).cpu())
        return torch.cat(out)

    def to(self, device: str | torch.device) -> "ActionClassifier":
        self.net.to(device)
        return self


# --- metrics ---------------------------------------------------------------------------------

def accuracy_from_probabilities(probs: Tensor | np.ndarray, classes: Sequence[str],
                                target_sets: Sequence[set[str]],
                                threshold: float = THRESHOLD) -> dict[str, Any]:
    """Per-class recall and precision at `threshold`, exact-set accuracy, mean per-class recall.

    recall[k]: of the motions whose prompt has class k, the fraction where k is detected;
    classes no prompt asks for are left out of recall and of the mean.
    """
    probs = np.asarray(probs, dtype=np.float64)
    if probs.shape != (len(target_sets), len(classes)):
        raise MlctError(f"probabilities of shape {probs.shape}, expected "
                        f"({len(target_sets)}, {len(classes)})")
    index = {k: i for i, k in enumerate(classes)}
    truth = multi_hot(target_sets, classes).numpy().astype(bool)
    detected = probs >= threshold
    hits = (detected & truth).sum(0)
    support, flagged = truth.sum(0), detected.sum(0)
    recall = {k: float(hits[i] / support[i]) for k, i in index.items() if support[i]}
    precision = {k: float(hits[i] / flagged[i]) for k, i in index.items() if flagged[i]}
    return {
        "motions": len(target_sets), "threshold": threshold,
        "exact_set_accuracy": float((detected == truth).all(1).mean()) if len(truth) else 0.0,
        "mean_recall": float(np.mean(list(recall.values()))) if recall else 0.0,
        "recall": recall, "precision": precision,
        "support": {k: int(support[i]) for k, i in index.items() if support[i]},
    }


def semantic_accuracy(classifier: ActionClassifier, features_list: Sequence[np.ndarray | Tensor],
                      target_sets: Sequence[set[str]], threshold: float = THRESHOLD
                      ) -> dict[str, Any]:
    """How often motions (real units) show the classes their prompts ask for (see above)."""
    if len(features_list) != len(target_sets):
        raise MlctError(f"{len(features_list)} motions but {len(target_sets)} target sets")
    return accuracy_from_probabilities(classifier.predict(features_list), classifier.classes,
                                       target_sets, threshold)


# --- training --------------------------------------------------------------------------------

def _split_data(layout: DatasetLayout, labels: Mapping[str, Any], split: str, skeleton: Any
                ) -> tuple[list[np.ndarray], list[set[str]]]:
    names = layout.read_split(split) if layout.split_path(split).is_file() else []
    missing = [n for n in names if n not in labels]
    if missing:
        raise MlctError(f"{layout.root / LABELS_FILE}: no record for {missing[0]} "
                        f"({len(missing)} {split} motions unlabelled)")
    return ([layout.load_features(n, skeleton) for n in names],
            [action_targets(labels[n]) for n in names])


def _batch(motions: list[Tensor], targets: Tensor, rows: list[int], generator: torch.Generator
           ) -> tuple[Tensor, Tensor, Tensor]:
    """Jittered, padded normalized motions (B, T, D), lengths (B,), targets (B, C)."""
    crops = []
    for i in rows:
        m = motions[i]
        cut = min(JITTER_FRAMES, (len(m) - 1) // 4)
        a, b = (torch.randint(0, cut + 1, (2,), generator=generator).tolist() if cut else (0, 0))
        crops.append(m[a:len(m) - b])
    x, lengths = _pad(crops)
    return x, lengths, targets[rows]


def train_action_classifier(data_dir: str | os.PathLike, out_dir: str | os.PathLike, *,
                            steps: int = 1500, batch_size: int = 64, lr: float = 2e-3,
                            seed: int = 0, device: str | torch.device | None = "cpu",
                            progress: bool = True, sizes: ClassifierSizes | None = None,
                            skeleton: str | None = None, overwrite: bool = False
                            ) -> dict[str, Any]:
    """Train on the train split of a procedural benchmark or an imported real corpus
    (`action_records`); write a self-contained `out_dir`.

    Returns a summary: losses per step, val/test semantic accuracy, seconds, and 'classifier'
    (the ActionClassifier as `load_action_classifier(out_dir)` rebuilds it).
    """
    from tqdm.auto import tqdm

    sizes = sizes or ClassifierSizes()
    if steps < 1 or batch_size < 1 or lr <= 0:
        raise MlctError(f"steps and batch_size must be >= 1 and lr > 0, got {steps}, "
                        f"{batch_size}, {lr}")
    dev = resolve_device(device)
    out = Path(out_dir)
    prepare_target(out, overwrite)
    layout = DatasetLayout.existing(data_dir)
    labels = action_records(layout.root)
    skel = layout.skeleton(skeleton)
    mean, std = layout.load_mean_std(skel)
    classes = derive_classes(labels.values())
    train_x, train_sets = _split_data(layout, labels, "train", skel)
    if not train_x:
        raise MlctError(f"{layout.split_path('train')}: no training motions")
    motions = [torch.from_numpy((m - mean) / std) for m in train_x]
    targets = multi_hot(train_sets, classes)

    generator = torch.Generator().manual_seed(seed)
    devices = [] if dev.type != "cuda" else [dev.index or 0]
    with torch.random.fork_rng(devices=devices):  # init and dropout; the caller's RNG is kept
        torch.manual_seed(seed)
        net = ActionNet(skel.feature_dim, len(classes), sizes).to(dev)
        optimizer = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=0.01)
        schedule = torch.optim.lr_scheduler.OneCycleLR(optimizer, lr, total_steps=steps,
                                                       pct_start=0.1)
        losses: list[float] = []
        order: list[int] = []
        started = time.perf_counter()
        net.train()
        bar = tqdm(range(steps), desc="action classifier", disable=not progress)
        for step in bar:
            if len(order) < batch_size:  # epochs in a seeded order, the remainder carried over
                order += torch.randperm(len(motions), generator=generator).tolist()
            rows, order = order[:batch_size], order[batch_size:]
            x, lengths, y = _batch(motions, targets, rows, generator)
            loss = F.binary_cross_entropy_with_logits(net(x.to(dev), lengths.to(dev)), y.to(dev))
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            schedule.step()
            losses.append(loss.item())
            if step % 20 == 0:
                bar.set_postfix(loss=f"{np.mean(losses[-20:]):.4f}")
        seconds = time.perf_counter() - started
    net = net.cpu().eval()
    classifier = ActionClassifier(net, classes, mean, std, skel.name, sizes)
    results = {}
    for split in ("train", "val", "test"):
        x, sets = (train_x, train_sets) if split == "train" else \
            _split_data(layout, labels, split, skel)
        if x:
            results[split] = semantic_accuracy(classifier, x, sets)
    summary = {"path": str(out), "classes": classes, "skeleton": skel.name,
               "feature_dim": skel.feature_dim, "train_motions": len(motions), "seed": seed,
               "steps": steps, "batch_size": batch_size, "lr": lr, "seconds": seconds,
               "losses": losses, "accuracy": results}
    training = {k: v for k, v in summary.items() if k not in ("path", "classes", "losses")}
    training["dataset"] = str(layout.root.resolve())
    training["final_loss"] = float(np.mean(losses[-20:]))
    classifier.meta = {"training": training}
    save_action_classifier(out, classifier)
    return summary | {"classifier": classifier}


# --- the directory ---------------------------------------------------------------------------

def save_action_classifier(out: str | os.PathLike, classifier: ActionClassifier) -> None:
    """Write `classifier` as a directory (replacing an old one only at the end)."""
    with atomic_dir(out) as work:
        state = {k: v.detach().cpu().contiguous() for k, v in classifier.net.state_dict().items()}
        save_file(state, str(work / WEIGHTS_FILE), metadata={"format": FORMAT})
        save_npy(work / "Mean.npy", classifier.mean.numpy())
        save_npy(work / "Std.npy", classifier.std.numpy())
        meta = {"format": FORMAT, "version": VERSION, "classes": classifier.classes,
                "feature_dim": classifier.feature_dim, "skeleton": classifier.skeleton,
                "sizes": asdict(classifier.sizes), "threshold": THRESHOLD,
                "side_params": list(SIDE_PARAMS), "mean": "Mean.npy", "std": "Std.npy"}
        write_text(work / META_FILE, json.dumps(meta | classifier.meta, indent=2) + "\n")


def load_action_classifier(directory: str | os.PathLike) -> ActionClassifier:
    """The ActionClassifier of a directory written by train_action_classifier."""
    root = Path(directory)
    path = root / META_FILE
    meta = read_format_json(path, FORMAT, VERSION, "an action classifier directory")
    try:
        classes, skeleton = list(meta["classes"]), str(meta["skeleton"])
        feature_dim, sizes = int(meta["feature_dim"]), ClassifierSizes(**meta["sizes"])
    except (ValueError, KeyError, TypeError, AttributeError) as error:
        raise MlctError(f"{path}: not a valid classifier description ({error})") from None
    mean, std = (load_npy(root / name) for name in ("Mean.npy", "Std.npy"))
    if mean.shape != (feature_dim,) or std.shape != (feature_dim,):
        raise MlctError(f"{root}: Mean/Std shapes {mean.shape}, {std.shape}, expected "
                        f"({feature_dim},)")
    try:
        state = load_file(str(root / WEIGHTS_FILE))
    except Exception as error:  # noqa: BLE001 - safetensors raises several kinds
        raise MlctError(f"{root / WEIGHTS_FILE}: unreadable ({type(error).__name__})") from None
    net = ActionNet(feature_dim, len(classes), sizes)
    try:
        net.load_state_dict(state)
    except RuntimeError as error:
        raise MlctError(f"{root / WEIGHTS_FILE}: weights do not fit classifier.json "
                        f"({first_line(error)})") from None
    return ActionClassifier(net, classes, mean, std, skeleton, sizes,
                            {"training": meta.get("training", {})})
