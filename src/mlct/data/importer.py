"""`mlct data import`: a user's own motion capture and captions -> the standard dataset layout.

Input: a directory of joint positions (`.npy`, (T, J, 3) in the skeleton's joint order, y up) or
of BVH files (joints matched by name, or through a JSON map), and a captions file. Processing
is HumanML3D's: resample to the skeleton's fps (linear interpolation), cut long clips into equal
windows within the length filter (short ones are skipped and reported), `joints_to_features`
(retarget to the target skeleton, floor, facing +Z), `new_joints` recovered from the features,
caption lines with word/POS tokens, seeded splits by clip (the windows of a clip stay in one
split), Mean/Std the standard way. The dataset is built in a hidden directory and renamed into
place at the end: a failed import leaves nothing behind.

Captions (docs/custom_data.md): CSV with a header holding `name` and `caption` columns, one row
per caption (a name may repeat), or JSONL with one object per line, `{"name": ..., "caption":
"..."}` or `{"name": ..., "captions": ["...", ...]}`. The name is the motion file's stem. Every
caption describes the whole clip (each window of a cut clip gets all of its clip's captions).

Tokens: HumanML3D tags captions with spaCy (lemmas for nouns and verbs, universal POS tags).
spaCy's English model is not installable from PyPI, so captions are tagged with the procedural
benchmark's lexicon tagger, and words outside its lexicon by suffix (`-ly` adverb, `-ing`/`-ed`
verb, else noun, not lemmatized). The tokens only feed the evaluator's text encoder.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np
import torch
from tqdm import tqdm

from mlct.data.captions import SEPARATOR, format_text_line, tag_caption
from mlct.data.layout import (
    FEATURES_DIR,
    JOINTS_DIR,
    PROVENANCE_FILE,
    TEXTS_DIR,
    BadFileError,
    joints_problems,
    load_npy,
    resolve_skeleton,
)
from mlct.data.stats import standard_mean_std
from mlct.errors import MlctError
from mlct.io import atomic_dir, save_npy, write_text
from mlct.motion.features import features_to_joints, joints_to_features
from mlct.motion.floor import level_floor
from mlct.motion.kinematics import forward_kinematics
from mlct.motion.skeleton import Skeleton

DEFAULT_SPLIT = (0.8, 0.1, 0.1)
SCALE_GUESS_FILES = 20  # files read to guess the units
SCALE_TOLERANCE = 2.0  # a guessed body may be this many times shorter or taller than the rest pose
SUFFIXES = {"joints": ".npy", "bvh": ".bvh"}
# Bounds of --scale (mm to m is 1e-3, m to mm 1e3) and of the input frame rate: past them a
# clip resamples to billions of frames (0.001 fps) or its positions overflow (scale 1e300).
SCALE_RANGE = (1e-6, 1e6)
FPS_RANGE = (1.0, 10_000.0)


@dataclass
class ImportSummary:
    """What `import_dataset` wrote and what it left out."""

    path: str
    skeleton: str
    fps: float
    clips: int  # input files imported
    motions: int  # motions written (a long clip makes several windows)
    frames: int  # feature frames
    hours: float
    scale: float
    splits: dict[str, int]
    skipped_short: list[str] = field(default_factory=list)
    skipped_uncaptioned: list[str] = field(default_factory=list)
    unused_captions: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    # motion name -> its [start, stop) joint frames in its clip, resampled
    windows: dict[str, tuple[int, int]] = field(default_factory=dict)
    clip_scales: dict[str, float] = field(default_factory=dict)  # clip -> factor applied
    clip_tilts: dict[str, float] = field(default_factory=dict)  # clip -> floor tilt removed, deg


def _clean_caption(text: Any, path: Path, line: int) -> str:
    if not isinstance(text, str):
        raise BadFileError(path, f"caption {text!r} is not text", line=line)
    caption = " ".join(text.split())  # newlines and runs of spaces -> one space
    if not caption:
        raise BadFileError(path, "empty caption", line=line)
    if SEPARATOR in caption:
        raise BadFileError(path, "a caption may not contain '#' (the texts/ field separator)",
                           line=line)
    if not tag_caption(caption):
        raise BadFileError(path, f"caption {caption!r} has no words", line=line)
    return caption


def _clean_name(name: Any, path: Path, line: int) -> str:
    if not isinstance(name, str) or not name.strip():
        raise BadFileError(path, f"missing motion name (got {name!r})", line=line)
    name = name.strip()
    for suffix in SUFFIXES.values():
        if name.lower().endswith(suffix):
            name = name[: -len(suffix)]
    return name


def read_captions(path: str | os.PathLike) -> dict[str, list[str]]:
    """name -> captions from a CSV (`name`, `caption` columns) or JSONL file (module doc)."""
    path = Path(path)
    if not path.is_file():
        raise MlctError(f"{path}: no such captions file")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        pairs = _read_csv(path)
    elif suffix in (".jsonl", ".ndjson"):
        pairs = _read_jsonl(path)
    else:
        raise MlctError(f"{path}: captions must be a .csv (name,caption) or .jsonl file")
    captions: dict[str, list[str]] = {}
    for name, caption in pairs:
        captions.setdefault(name, []).append(caption)
    if not captions:
        raise MlctError(f"{path}: no captions")
    return captions


def _read_text(path: Path) -> str:
    """The file's text; utf-8-sig drops the byte-order mark that spreadsheet programs write."""
    try:
        return path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as error:
        raise BadFileError(path, f"cannot read: {error}") from None


def _read_csv(path: Path) -> list[tuple[str, str]]:
    reader = csv.DictReader(io.StringIO(_read_text(path), newline=""))
    fields = [f.strip().lower() for f in reader.fieldnames or []]
    if "name" not in fields or "caption" not in fields:
        raise BadFileError(path, f"the header must name the columns 'name' and 'caption' "
                                 f"(found {', '.join(fields) or 'nothing'})", line=1)
    reader.fieldnames = fields
    pairs = []
    for row in reader:
        line = reader.line_num
        if None in row or row.get("caption") is None:
            raise BadFileError(path, "row does not match the header's columns", line=line)
        pairs.append((_clean_name(row["name"], path, line),
                      _clean_caption(row["caption"], path, line)))
    return pairs


def _read_jsonl(path: Path) -> list[tuple[str, str]]:
    pairs = []
    for number, text in enumerate(_read_text(path).splitlines(), start=1):
        if not text.strip():
            continue
        try:
            record = json.loads(text)
        except json.JSONDecodeError as error:
            raise BadFileError(path, f"not JSON ({error.msg})", line=number) from None
        if not isinstance(record, dict):
            raise BadFileError(path, "each line must be a JSON object", line=number)
        name = _clean_name(record.get("name"), path, number)
        if "captions" in record and isinstance(record["captions"], list):
            texts = record["captions"]
        elif "caption" in record:
            texts = [record["caption"]]
        else:
            raise BadFileError(path, "needs 'caption' (text) or 'captions' (list of texts)",
                               line=number)
        if not texts:
            raise BadFileError(path, "empty 'captions' list", line=number)
        pairs.extend((name, _clean_caption(t, path, number)) for t in texts)
    return pairs


def _joint_map(path: str | os.PathLike | None, skeleton: Skeleton) -> dict[str, str]:
    """BVH joint name -> skeleton joint name, from a JSON object file (or names as they are)."""
    if path is None:
        return {}
    path = Path(path)
    try:
        mapping = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise MlctError(f"{path}: cannot read the joint map ({error})") from None
    if not isinstance(mapping, dict) or not all(
            isinstance(k, str) and isinstance(v, str) for k, v in mapping.items()):
        raise MlctError(f"{path}: the joint map must be a JSON object "
                        f"{{\"BVH joint\": \"{skeleton.name} joint\", ...}}")
    unknown = sorted(set(mapping.values()) - set(skeleton.joint_names))
    if unknown:
        raise MlctError(f"{path}: {', '.join(unknown)} are not {skeleton.name} joints (known: "
                        f"{', '.join(skeleton.joint_names)})")
    return mapping


# ---------------------------------------------------------------------------------------------
# Motions
# ---------------------------------------------------------------------------------------------

def _load_joints(path: Path, skeleton: Skeleton) -> np.ndarray:
    array = load_npy(path)
    problems = joints_problems(array, skeleton.n_joints)
    if problems:
        raise BadFileError(path, "; ".join(message for _, message in problems))
    return array.astype(np.float64)


@dataclass(frozen=True)
class Between:
    """A skeleton joint the BVH rig lacks, placed on the segment between two of its joints:
    `start + at * (end - start)` (a rig with one chest bone where SMPL has two, say)."""

    start: str  # BVH joint names
    end: str
    at: float


def _load_bvh(path: Path, skeleton: Skeleton,
              mapping: dict[str, str] | tuple[dict[str, str], ...],
              between: dict[str, tuple[Between, ...]] | None = None,
              reader: Callable[[Path], Any] | None = None) -> tuple[np.ndarray, float]:
    """(T, J, 3) positions in the skeleton's joint order, in the file's units; and its fps.
    `mapping` may be several maps, one per rig naming a corpus mixes: the first under which
    every skeleton joint is found is taken. A skeleton joint no BVH joint maps to takes the
    first of its `between` places whose two joints the file has. `reader` reads a corpus's
    own format into a clip with joint_names, positions and fps."""
    from mlct.motion.bvh import read_bvh

    if reader is not None:
        clip: Any = reader(path)
    elif path.suffix.lower() == ".amc":  # CMU's own format (a corpus importer passes these)
        from mlct.motion.asf_amc import read_amc

        clip = read_amc(path)
    else:
        clip = read_bvh(path, end_sites=True)
    index = {name: i for i, name in enumerate(clip.joint_names)}
    tried = []
    for one in (mapping if isinstance(mapping, tuple) else (mapping,)):
        columns, placed, missing = _columns(path, clip.joint_names, skeleton, one, between or {})
        if not missing:
            break
        tried.append(missing)
    else:
        missing = min(tried, key=len)
        shown = ", ".join(clip.joint_names[:12]) + (" ..." if len(clip.joint_names) > 12 else "")
        raise MlctError(f"{path}: no joint for {', '.join(missing)} (its joints: {shown}); "
                        f"map them with --joint-map FILE.json")
    positions = np.empty((len(clip.positions), skeleton.n_joints, 3))
    for j, name in enumerate(skeleton.joint_names):
        if name in columns:
            positions[:, j] = clip.positions[:, columns[name]]
        else:
            place = placed[name]
            start, end = clip.positions[:, index[place.start]], clip.positions[:, index[place.end]]
            positions[:, j] = start + place.at * (end - start)
    return positions, clip.fps


def _columns(path: Path, names: tuple[str, ...], skeleton: Skeleton, mapping: dict[str, str],
             between: dict[str, tuple[Between, ...]]
             ) -> tuple[dict[str, int], dict[str, Between], list[str]]:
    """Under one map: skeleton joint -> BVH column, the joints placed between two others, and
    the skeleton joints neither finds."""
    columns: dict[str, int] = {}
    for column, name in enumerate(names):
        ours = mapping.get(name, name)
        if ours in skeleton.joint_names:
            if ours in columns:
                raise MlctError(f"{path}: joints {names[columns[ours]]} and {name} "
                                f"both map to {ours}")
            columns[ours] = column
    placed: dict[str, Between] = {}
    for name in skeleton.joint_names:
        if name not in columns:
            place = next((p for p in between.get(name, ()) if p.start in names and p.end in names),
                         None)
            if place is not None:
                placed[name] = place
    missing = [n for n in skeleton.joint_names if n not in columns and n not in placed]
    return columns, placed, missing


REFERENCE_POSE_FRAMES = 3  # leading frames looked at for a conversion's T-pose
# After a reference pose, a conversion may blend into the capture over a few frames faster than
# a body moves (arms falling 15 degrees a frame at 120 fps, ~30 m/s at the wrist): those go too,
# up to BLEND_SECONDS, while a joint moves more than BLEND_LEGS leg lengths a second (~7 m/s).
BLEND_SECONDS = 0.25
BLEND_LEGS = 8.0


def drop_reference_pose(positions: np.ndarray, skeleton: Skeleton, fps: float) -> np.ndarray:
    """The clip without its leading T-pose frames and the blend out of them: many BVH
    conversions start with the rig's reference pose, arms straight out to the sides, which is
    not part of the motion. A frame is one when both wrists are within 15 degrees of level with
    their shoulders and each arm is nearly straight."""
    names = skeleton.joint_names
    first = 0
    for frame in positions[:REFERENCE_POSE_FRAMES]:
        straight = True
        for side in ("left", "right"):
            shoulder, elbow, wrist = (frame[names.index(f"{side}_{j}")]
                                      for j in ("shoulder", "elbow", "wrist"))
            reach = wrist - shoulder
            arm = np.linalg.norm(elbow - shoulder) + np.linalg.norm(wrist - elbow)
            level = abs(reach[1]) < np.sin(np.radians(15)) * np.linalg.norm(reach)
            straight &= bool(level and np.linalg.norm(reach) > 0.95 * arm)
        if not straight:
            break
        first += 1
    if first:
        limit = BLEND_LEGS * _leg_length(positions, skeleton) / fps  # per frame
        steps = np.linalg.norm(np.diff(positions, axis=0), axis=-1).max(axis=-1)
        stop = min(len(steps), first + int(BLEND_SECONDS * fps))
        while first < stop and steps[first] > limit:
            first += 1
    return positions[first:] if first < len(positions) - 1 else positions


def resample(positions: np.ndarray, source_fps: float, target_fps: float) -> np.ndarray:
    """(T, J, 3) at source_fps -> the same time span at target_fps, linearly interpolated."""
    if math.isclose(source_fps, target_fps, rel_tol=1e-6) or len(positions) < 2:
        return positions
    duration = (len(positions) - 1) / source_fps
    n_frames = int(math.floor(duration * target_fps + 1e-9)) + 1
    at = np.arange(n_frames) * (source_fps / target_fps)  # fractional source frames
    first = np.minimum(np.floor(at).astype(int), len(positions) - 2)
    weight = (at - first)[:, None, None]
    return (1.0 - weight) * positions[first] + weight * positions[first + 1]


def windows(n_frames: int, skeleton: Skeleton) -> list[tuple[int, int]]:
    """[start, stop) joint-frame windows of a clip whose feature lengths (stop - start - 1) fall
    in the length filter: equal windows as long as allowed; [] when the clip is too short."""
    n_features = n_frames - 1
    if n_features < skeleton.min_frames:
        return []
    longest = skeleton.max_frames - 1
    count = math.ceil(n_features / longest)
    length = n_features // count
    return [(i * length, i * length + length + 1) for i in range(count)]


def _rest_height(skeleton: Skeleton) -> float:
    """Vertical extent of the skeleton's rest pose, in its units: what a body should measure."""
    local = torch.zeros(skeleton.n_joints, 4, dtype=torch.float64)
    local[:, 0] = 1.0
    rest = forward_kinematics(local, torch.zeros(3, dtype=torch.float64),
                              skeleton.rest_offsets, skeleton).numpy()
    return float(np.ptp(rest[:, 1]))


def guess_scale(heights: list[float], skeleton: Skeleton) -> float:
    """The power of ten that brings the median body height (file units) to the rest pose's."""
    height = float(np.median(heights))
    target = _rest_height(skeleton)
    if not height > 0:
        raise MlctError("cannot guess the units: the bodies have no height; pass --scale")
    scale = 10.0 ** round(math.log10(target / height))
    if not 1 / SCALE_TOLERANCE <= height * scale / target <= SCALE_TOLERANCE:
        raise MlctError(f"cannot guess the units: bodies measure {height:.4g} units from the "
                        f"lowest to the highest joint, no power of ten makes that a "
                        f"{target:.4g} {skeleton.unit} body; pass --scale (to {skeleton.unit})")
    return scale


LEGS = "legs"  # scale each clip so that its legs measure the skeleton's (corpora of mixed units)


def _leg_length(positions: np.ndarray, skeleton: Skeleton) -> float:
    """Median over frames of hip-knee-ankle length, both legs averaged (the positions' units)."""
    total = 0.0
    for side in ("left", "right"):
        hip, knee, ankle = (positions[:, skeleton.joint_names.index(f"{side}_{j}")]
                            for j in ("hip", "knee", "ankle"))
        total += float(np.median(np.linalg.norm(knee - hip, axis=-1) +
                                 np.linalg.norm(ankle - knee, axis=-1)))
    return total / 2


def leg_scale(positions: np.ndarray, skeleton: Skeleton) -> float:
    """The factor that gives the clip's legs the skeleton's rest length: units and body size at
    once, so that a clip's speeds are those of a body of the skeleton's size."""
    rest = np.asarray(skeleton.rest_offsets)
    target = sum(float(np.linalg.norm(rest[skeleton.joint_names.index(f"left_{j}")]))
                 for j in ("knee", "ankle"))
    length = _leg_length(positions, skeleton)
    if not length > 0:
        raise MlctError("the clip's legs have no length: cannot scale it")
    return target / length


def _height(positions: np.ndarray) -> float:
    """Median over frames of the vertical extent of the joints."""
    return float(np.median(np.ptp(positions[..., 1], axis=-1)))


# ---------------------------------------------------------------------------------------------
# The import
# ---------------------------------------------------------------------------------------------

def parse_split(text: str) -> tuple[float, float, float]:
    """'0.8,0.1,0.1' -> train, val, test fractions (non-negative, summing to 1)."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    return check_split(values, text)


def check_split(values: tuple[float, ...], given: Any = None) -> tuple[float, float, float]:
    """The fractions if they are three non-negative numbers summing to 1; MlctError otherwise."""
    if len(values) != 3 or not all(math.isfinite(v) and v >= 0 for v in values) or not \
            math.isclose(sum(values), 1.0, abs_tol=1e-6):
        shown = values if given is None else given
        raise MlctError(f"--split must be three fractions train,val,test summing to 1 "
                        f"(e.g. 0.8,0.1,0.1), got {shown!r}")
    return values  # type: ignore[return-value]


def split_clips(clips: list[str], fractions: tuple[float, float, float],
                seed: int) -> dict[str, list[str]]:
    """Seeded shuffle of the clips into train/val/test by the fractions (test takes the rest)."""
    order = np.random.default_rng(seed).permutation(len(clips))
    shuffled = [clips[i] for i in order]
    n_train = int(round(fractions[0] * len(clips)))
    n_val = min(int(round(fractions[1] * len(clips))), len(clips) - n_train)
    return {"train": shuffled[:n_train], "val": shuffled[n_train:n_train + n_val],
            "test": shuffled[n_train + n_val:]}


def _motion_files(directory: Path, suffix: str) -> dict[str, Path]:
    if not directory.is_dir():
        raise MlctError(f"{directory}: no such directory")
    files = {p.name[: -len(suffix)]: p for p in sorted(directory.iterdir())
             if p.name.lower().endswith(suffix) and not p.name.startswith(".") and p.is_file()}
    if not files:
        raise MlctError(f"{directory}: no {suffix} files")
    return files


def _short_list(names: list[str], limit: int = 10) -> str:
    shown = ", ".join(names[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")


def import_dataset(out: str | os.PathLike, captions: str | os.PathLike | dict[str, list[str]], *,
                   joints_dir: str | os.PathLike | None = None,
                   bvh_dir: str | os.PathLike | dict[str, Path] | None = None,
                   skeleton: str | Skeleton = "humanml3d",
                   joint_map: str | os.PathLike | dict[str, str] | tuple[dict[str, str], ...]
                   | None = None,
                   between: dict[str, tuple[Between, ...]] | None = None,
                   provenance: dict[str, dict[str, Any]] | None = None,
                   reader: Callable[[Path], Any] | None = None,
                   scale: float | str | None = None,
                   fps: float | None = None, split: tuple[float, float, float] = DEFAULT_SPLIT,
                   seed: int = 0, skip_uncaptioned: bool = False, overwrite: bool = False,
                   level: bool = True, progress: bool = False) -> ImportSummary:
    """Import joints (.npy) or BVH files with their captions as a dataset at `out` (module doc).

    `scale` multiplies the input positions into the skeleton's units (m for humanml3d, mm for
    kit); None guesses a power of ten from the body height. `fps` is the input's frame rate;
    None takes the BVH Frame Time, or the skeleton's fps for .npy. `scale="legs"` scales each
    clip by its leg length instead (`leg_scale`). `level` turns each clip so that the floor its
    feet stand on is horizontal, where it is tilted by a few degrees (motion/floor.py).
    A corpus importer (mlct.data.corpora) passes its files, captions and joint map as
    mappings, the joints its rig lacks as `between`, and each clip's `provenance` (source,
    license, labels), written per motion to provenance.jsonl; a corpus whose files are neither
    BVH nor AMC passes its `reader`.
    """
    if (joints_dir is None) == (bvh_dir is None):
        raise MlctError("give one source: --joints DIR or --bvh DIR")
    skel = resolve_skeleton(skeleton)
    assert skel is not None
    kind = "joints" if joints_dir is not None else "bvh"
    if isinstance(bvh_dir, dict):
        files = dict(sorted(bvh_dir.items()))
    else:
        files = _motion_files(Path(joints_dir if joints_dir is not None else bvh_dir),
                              SUFFIXES[kind])
    if scale == LEGS:
        per_clip, scale = True, None
    else:
        per_clip = False
    for name, value, (low, high) in (("--scale", scale, SCALE_RANGE), ("--fps", fps, FPS_RANGE)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise MlctError(f"{name} must be a positive number, got {value}")
        if value is not None and not low <= value <= high:
            raise MlctError(f"{name} {value:g} is outside {low:g}..{high:g}")
    if seed < 0:
        raise MlctError(f"--seed must be a non-negative integer, got {seed}")
    split = check_split(tuple(split))
    out = Path(out)
    if out.exists() and (not out.is_dir() or (any(out.iterdir()) and not overwrite)):
        raise MlctError(f"{out} exists and is not an empty directory: choose a new one or pass "
                        f"--overwrite")
    if joint_map is not None and kind != "bvh":
        raise MlctError("--joint-map is for --bvh input (.npy joints are in the skeleton's order)")
    texts = captions if isinstance(captions, dict) else read_captions(captions)
    mapping = joint_map if isinstance(joint_map, (dict, tuple)) else _joint_map(joint_map, skel)

    summary = ImportSummary(path=str(out), skeleton=skel.name, fps=skel.fps, clips=0,
                            motions=0, frames=0, hours=0.0, scale=1.0, splits={})
    uncaptioned = [name for name in files if name not in texts]
    if uncaptioned and not skip_uncaptioned:
        raise MlctError(f"{len(uncaptioned)} motion file(s) have no caption in {captions}: "
                        f"{_short_list(uncaptioned)} (caption them or pass --skip-uncaptioned)")
    summary.skipped_uncaptioned = uncaptioned
    summary.unused_captions = sorted(set(texts) - set(files))
    files = {name: path for name, path in files.items() if name in texts}
    if not files:
        raise MlctError("no motion file has a caption: nothing to import")

    loaded: dict[Path, tuple[np.ndarray, float]] = {}  # the files read for the units guess

    def load(path: Path) -> tuple[np.ndarray, float]:
        """(positions in file units, fps) of one file."""
        if path in loaded:
            return loaded.pop(path)
        if kind == "bvh":
            positions, file_fps = _load_bvh(path, skel, mapping, between, reader)
            positions = drop_reference_pose(positions, skel, fps or file_fps)
            if fps is None and not FPS_RANGE[0] <= file_fps <= FPS_RANGE[1]:
                raise MlctError(f"{path}: its Frame Time makes {file_fps:g} fps, outside "
                                f"{FPS_RANGE[0]:g}..{FPS_RANGE[1]:g} (--fps overrides it)")
            return positions, fps or file_fps
        return _load_joints(path, skel), fps or skel.fps

    if per_clip:
        summary.notes.append("each clip scaled so that its legs measure the skeleton's")
    elif scale is None:
        sample = list(files.values())[:SCALE_GUESS_FILES]
        loaded.update((path, load(path)) for path in sample)
        scale = guess_scale([_height(positions) for positions, _ in loaded.values()], skel)
        summary.notes.append(f"--scale not given: positions x {scale:g} to {skel.unit}, guessed "
                             f"from the body height of {len(sample)} file(s)")
    summary.scale = scale if scale is not None else float("nan")

    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # tiny per-clip tensors: threads cost more than they give
    try:
        with atomic_dir(out) as work:
            for sub in (FEATURES_DIR, JOINTS_DIR, TEXTS_DIR):
                (work / sub).mkdir()
            members = _write_motions(work, files, texts, load, skel, scale, summary, level,
                                     progress)
            _write_splits(work, members, split, seed, summary)
            if provenance is not None:
                _write_provenance(work, members, provenance, summary)
            mean, std, constant = standard_mean_std(_features(work, members), skel)
            save_npy(work / "Mean.npy", mean)
            save_npy(work / "Std.npy", std)
            summary.notes.extend(f"feature group {g!r} is constant: its std is set to 1"
                                 for g in constant)
            source = joints_dir if joints_dir is not None else bvh_dir
            if isinstance(source, dict):
                source = os.path.commonpath([str(p) for p in source.values()])
            info = {"source": str(source),
                    "kind": kind, "skeleton": skel.name,
                    "captions": "made by the corpus importer" if isinstance(captions, dict)
                    else str(captions),
                    "fps": skel.fps, "scale": LEGS if per_clip else scale, "split": list(split), "seed": seed,
                    "clips": {clip: names for clip, names in members.items()},
                    "skipped_short": summary.skipped_short,
                    "skipped_uncaptioned": summary.skipped_uncaptioned}
            write_text(work / "import.json", json.dumps(info, indent=2) + "\n")
    finally:
        torch.set_num_threads(threads)
    summary.hours = summary.frames / skel.fps / 3600.0
    return summary


def _write_motions(work: Path, files: dict[str, Path], texts: dict[str, list[str]], load: Any,
                   skel: Skeleton, scale: float | None, summary: ImportSummary, level: bool,
                   progress: bool) -> dict[str, list[str]]:
    """Process and write every clip; returns clip -> names of its motions. A `scale` of None
    scales each clip by its legs (`leg_scale`); `level` takes a tilted floor out of the whole
    clip before it is cut into windows (a window may travel too little to show the tilt)."""
    members: dict[str, list[str]] = {}
    taken: dict[str, str] = {}  # motion name -> clip it came from
    for clip, path in tqdm(files.items(), disable=not progress, desc="import", unit="clip"):
        positions, file_fps = load(path)
        factor = leg_scale(positions, skel) if scale is None else scale
        summary.clip_scales[clip] = factor
        positions = resample(positions * factor, file_fps, skel.fps)
        if level:
            positions, tilt = level_floor(positions, skel)
            summary.clip_tilts[clip] = math.degrees(tilt)
        spans = windows(len(positions), skel)
        if not spans:
            summary.skipped_short.append(clip)
            continue
        width = max(2, len(str(len(spans) - 1)))
        names = [clip] if len(spans) == 1 else [f"{clip}_{i:0{width}d}" for i in range(len(spans))]
        lines = "".join(format_text_line(c, tag_caption(c)) + "\n" for c in texts[clip])
        for name, (start, stop) in zip(names, spans):
            if name in taken:
                raise MlctError(f"{path}: its motion {name} clashes with {taken[name]}'s; "
                                f"rename one of the files")
            taken[name] = clip
            summary.windows[name] = (start, stop)
            try:
                features = joints_to_features(positions[start:stop], skel).features
            except MlctError as error:
                raise MlctError(f"{path}: {error}") from None
            np.save(work / FEATURES_DIR / f"{name}.npy", features)
            np.save(work / JOINTS_DIR / f"{name}.npy", features_to_joints(features))
            (work / TEXTS_DIR / f"{name}.txt").write_text(lines, encoding="utf-8")
            summary.frames += len(features)
        members[clip] = names
        summary.clips += 1
        summary.motions += len(names)
    if not members:
        raise MlctError(f"every clip is shorter than the {skel.name} length filter "
                        f"({skel.min_frames} frames at {skel.fps:g} fps): nothing to import")
    return members


def _write_splits(work: Path, members: dict[str, list[str]], split: tuple[float, float, float],
                  seed: int, summary: ImportSummary) -> None:
    by_clip = split_clips(sorted(members), split, seed)
    names = {part: sorted(n for clip in clips for n in members[clip])
             for part, clips in by_clip.items()}
    for part, part_names in names.items():
        write_text(work / f"{part}.txt", "".join(f"{n}\n" for n in part_names))
    write_text(work / "train_val.txt", "".join(f"{n}\n" for n in
                                               sorted(names["train"] + names["val"])))
    write_text(work / "all.txt", "".join(f"{n}\n" for clip in sorted(members)
                                         for n in members[clip]))
    summary.splits = {part: len(part_names) for part, part_names in names.items()}


def _write_provenance(work: Path, members: dict[str, list[str]],
                      provenance: dict[str, dict[str, Any]], summary: ImportSummary) -> None:
    """One JSON line per motion: its clip, its window of the clip ([start, stop) joint frames at
    the skeleton's fps) and the clip's provenance record."""
    lines = []
    for clip, names in members.items():
        for name in names:
            record = {"name": name, "clip": clip, "window": list(summary.windows[name]),
                      "scale": round(summary.clip_scales[clip], 6),
                      "floor_tilt_deg": round(summary.clip_tilts.get(clip, 0.0), 3),
                      **provenance.get(clip, {})}
            lines.append(json.dumps(record, sort_keys=True) + "\n")
    write_text(work / PROVENANCE_FILE, "".join(lines))


def _features(work: Path, members: dict[str, list[str]]) -> Iterator[np.ndarray]:
    for clip_names in members.values():
        for name in clip_names:
            yield np.load(work / FEATURES_DIR / f"{name}.npy")


def format_summary(summary: ImportSummary) -> str:
    """The lines `mlct data import` prints."""
    lines = list(summary.notes)
    lines.append(f"imported {summary.clips} clip(s) as {summary.motions} motion(s), "
                 f"{summary.frames:,} frames at {summary.fps:g} fps ({summary.hours:.3f} hours, "
                 f"{summary.skeleton}) to {summary.path}; splits " +
                 ", ".join(f"{k} {v}" for k, v in summary.splits.items()))
    tilted = {clip: deg for clip, deg in summary.clip_tilts.items() if deg > 0}
    if tilted:
        lines.append(f"levelled the floor of {len(tilted)} clip(s), by up to "
                     f"{max(tilted.values()):.1f} degrees (floor_tilt_deg in provenance.jsonl "
                     f"where the dataset has one)")
    if summary.skipped_short:
        lines.append(f"skipped {len(summary.skipped_short)} clip(s) shorter than the length "
                     f"filter: {_short_list(summary.skipped_short)}")
    if summary.skipped_uncaptioned:
        lines.append(f"skipped {len(summary.skipped_uncaptioned)} uncaptioned file(s): "
                     f"{_short_list(summary.skipped_uncaptioned)}")
    if summary.unused_captions:
        lines.append(f"{len(summary.unused_captions)} caption name(s) match no file: "
                     f"{_short_list(summary.unused_captions)}")
    return "\n".join(lines)
