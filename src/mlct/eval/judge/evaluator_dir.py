"""A self-contained evaluator directory, as `train_evaluator` writes it and anyone reloads it.

    DIR/finest.tar           the three state dicts in the official key layout (Evaluator.save:
                             'text_encoder', 'movement_encoder', 'motion_encoder', 'epoch', plus
                             mean/std), so Evaluator.load_official reads it too at official sizes
    DIR/Mean.npy, Std.npy    the evaluator's own normalization statistics
    DIR/learned_words.npz    learned word vectors (vocabulary "learned"), or
    DIR/glove/our_vab_*      a copy of the GloVe files it was trained with (vocabulary "glove")
    DIR/meta.json            format, version, feature_dim, network sizes, vocabulary, and what
                             the writer adds (training run, normalization rule)

The directory is built beside its final name and renamed into place: a reader never sees a
half-written one.
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import asdict
from pathlib import Path
from typing import Any, Mapping

import torch

from mlct.data.layout import load_npy
from mlct.errors import MlctError
from mlct.eval.judge.evaluator import (
    NETWORK_KEYS,
    UNIT_LENGTH,
    Evaluator,
    EvaluatorSizes,
    build_networks,
    load_state_checked,
)
from mlct.eval.judge.learned_words import LearnedWordVectors
from mlct.eval.judge.word_vectors import UNKNOWN_WORD, WordVectorizer
from mlct.io import atomic_dir, read_format_json, save_npy, write_text
from mlct.motion.skeleton import get_skeleton, skeleton_for_dim

FORMAT = "mlct-evaluator-dir"
VERSION = 1
META_FILE = "meta.json"
CHECKPOINT_FILE = "finest.tar"
WORDS_FILE = "learned_words.npz"
GLOVE_DIR = "glove"
GLOVE_PREFIX = "our_vab"
GLOVE_FILES = tuple(f"{GLOVE_PREFIX}_{kind}" for kind in ("data.npy", "words.pkl", "idx.pkl"))


def prepare_target(out: Path, overwrite: bool) -> None:
    """Fail early (one line) when `out` cannot become the evaluator directory."""
    if out.exists() and not out.is_dir():
        raise MlctError(f"{out} exists and is not a directory")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise MlctError(f"{out} exists and is not empty: choose a new directory or pass "
                        f"overwrite=True")
    out.parent.mkdir(parents=True, exist_ok=True)
    if not os.access(out.parent, os.W_OK):
        raise MlctError(f"cannot write to {out.parent}")


def write_evaluator_dir(out: str | os.PathLike, evaluator: Evaluator, sizes: EvaluatorSizes, *,
                        glove_dir: str | os.PathLike | None = None,
                        states: Mapping[str, Mapping[str, Any]] | None = None,
                        meta: Mapping[str, Any] | None = None) -> None:
    """Write `evaluator` as DIR (replacing an old one only at the end).

    A LearnedWordVectors vectorizer is saved; a GloVe one is copied from `glove_dir`. `states`
    are extra torch files (name -> dict); `meta` entries are added to meta.json.
    """
    out = Path(out)
    vectorizer = evaluator.vectorizer
    if vectorizer is None:
        raise MlctError("an evaluator directory needs the evaluator's word vectors")
    learned = isinstance(vectorizer, LearnedWordVectors)
    if not learned and glove_dir is None:
        raise MlctError("a GloVe evaluator needs glove_dir, to copy its vectors")
    with atomic_dir(out) as work:  # an old directory is replaced only at the end
        evaluator.save(work / CHECKPOINT_FILE)
        for name, state in (states or {}).items():
            torch.save(dict(state), work / name)
        save_npy(work / "Mean.npy", evaluator.mean.cpu().numpy())
        save_npy(work / "Std.npy", evaluator.std.cpu().numpy())
        if isinstance(vectorizer, LearnedWordVectors):
            vectorizer.save(work / WORDS_FILE)
        else:
            assert glove_dir is not None
            (work / GLOVE_DIR).mkdir()
            for name in GLOVE_FILES:
                shutil.copyfile(Path(glove_dir) / name, work / GLOVE_DIR / name)
        core = {"format": FORMAT, "version": VERSION, "feature_dim": evaluator.feature_dim,
                "unit_length": UNIT_LENGTH, "sizes": asdict(sizes),
                "vocabulary": "learned" if learned else "glove",
                "word_vectors": WORDS_FILE if learned else f"{GLOVE_DIR}/{GLOVE_PREFIX}_*",
                "mean": "Mean.npy", "std": "Std.npy"}
        write_text(work / META_FILE, json.dumps(core | dict(meta or {}), indent=2) + "\n")


def read_evaluator_meta(directory: str | os.PathLike) -> dict[str, Any]:
    """meta.json of an evaluator directory, checked (format, version); MlctError otherwise."""
    return read_format_json(Path(directory) / META_FILE, FORMAT, VERSION,
                            "an evaluator directory of train_evaluator")


def load_evaluator_dir(directory: str | os.PathLike) -> Evaluator:
    """The Evaluator of an evaluator directory: networks, its Mean/Std, its word vectors."""
    root = Path(directory)
    meta = read_evaluator_meta(root)
    try:
        sizes = EvaluatorSizes(**meta["sizes"])
        feature_dim = int(meta["feature_dim"])
        vocabulary = meta["vocabulary"]
    except (KeyError, TypeError, ValueError) as error:
        raise MlctError(f"{root / META_FILE}: bad or missing entry ({error!r})") from None
    mean, std = (load_npy(root / name) for name in ("Mean.npy", "Std.npy"))
    source = root / CHECKPOINT_FILE
    try:
        state = torch.load(source, map_location="cpu", weights_only=True)
    except Exception as error:  # noqa: BLE001 - any unreadable file gets the same one line
        first = (str(error).strip().splitlines() or [""])[0]
        raise MlctError(f"{source}: not a readable weights-only torch checkpoint "
                        f"({type(error).__name__}: {first})") from None
    if not isinstance(state, dict):
        raise MlctError(f"{source}: expected a dict with {', '.join(NETWORK_KEYS)}")
    networks = build_networks(feature_dim, sizes)
    for key in NETWORK_KEYS:
        if key not in state:
            raise MlctError(f"{source}: key {key!r} is missing")
        load_state_checked(networks[key], state[key], key, source)
    if vocabulary == "learned":
        vectorizer: WordVectorizer = LearnedWordVectors.load(root / WORDS_FILE)
    elif vocabulary == "glove":
        vectorizer = WordVectorizer(root / GLOVE_DIR, GLOVE_PREFIX)
    else:
        raise MlctError(f"{root / META_FILE}: unknown vocabulary {vocabulary!r} (learned, glove)")
    dim = vectorizer[f"{UNKNOWN_WORD}/OTHER"][0].shape[0]
    if dim != sizes.word:
        raise MlctError(f"{root}: {dim}-d word vectors, the text encoder reads {sizes.word}")
    epoch = state.get("epoch", 0)
    return Evaluator(networks, mean, std, vectorizer, epoch=epoch if isinstance(epoch, int) else 0)


def import_official_evaluator(checkpoint: str | os.PathLike, mean: str | os.PathLike,
                              std: str | os.PathLike, glove_dir: str | os.PathLike,
                              out: str | os.PathLike, skeleton: str | None = None,
                              overwrite: bool = False) -> Path:
    """Turn Guo et al.'s files into an evaluator directory, weights and statistics unchanged.

    checkpoint: text-to-motion's `checkpoints/<t2m|kit>/text_mot_match/model/finest.tar`;
    mean/std: `checkpoints/<t2m|kit>/Comp_v6_KLD01/meta/{mean,std}.npy` (the evaluator's own,
    not the dataset's); glove_dir: the `our_vab_{data.npy,words.pkl,idx.pkl}` directory.
    The skeleton defaults to the one whose feature width the mean has (263 humanml3d, 251 kit).
    """
    out = Path(out)
    prepare_target(out, overwrite)
    for name in GLOVE_FILES:
        if not (Path(glove_dir) / name).is_file():
            raise MlctError(f"{glove_dir}: {name} is missing (GloVe files of text-to-motion)")
    evaluator = Evaluator.load_official(checkpoint, glove_dir, mean=load_npy(mean),
                                        std=load_npy(std))
    try:
        skel = (get_skeleton(skeleton) if skeleton is not None
                else skeleton_for_dim(evaluator.feature_dim))
    except ValueError as error:
        raise MlctError(str(error)) from None
    if skel.feature_dim != evaluator.feature_dim:
        raise MlctError(f"the evaluator reads {evaluator.feature_dim}-d features, the "
                        f"{skel.name} skeleton has {skel.feature_dim}")
    write_evaluator_dir(out, evaluator, EvaluatorSizes(), glove_dir=glove_dir,
                        meta={"skeleton": skel.name, "source": "official",
                              "checkpoint": str(Path(checkpoint).resolve())})
    return out
