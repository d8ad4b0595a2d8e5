"""`mlct generate`: prompts in, files out, batched, with a progress bar.

Three ways to call it:
- one prompt: one motion (or --num variations, seeds seed, seed + 1, ...);
- several prompts on the command line with one duration each: one continuous long motion that
  does them in order (compose/long_motion.py);
- --prompts FILE: one motion per line (times --num), generated in batches.
Every output path is checked before the model loads, so a typo costs no generation time.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Sequence

from mlct.errors import MlctError
from mlct.generate.output.exports import check_format, check_rig
from mlct.generate.compose.prompts import clean_prompt
from mlct.io import check_writable_dir

_LOG = logging.getLogger("mlct.generate")  # --verbose shows its INFO lines

if TYPE_CHECKING:
    from mlct.generate.output.generated import GeneratedMotion
    from mlct.generate.compose.generator import MotionGenerator

BATCH = 64  # motions per generate() call: big enough to batch, small enough to show progress


@dataclass
class Request:
    """What to generate: prompts (one motion each), or one long motion when `long` is set."""

    prompts: list[str]
    seconds: list[float | str] | None = None  # "auto": from the text
    lengths: list[int] | None = None
    num: int = 1
    nfe: int | None = None
    seed: int | None = None
    long: bool = False
    split_actions: bool = True  # a prompt naming actions in sequence: one part each, chained
    control: Any = None  # a generate.control.Control: path, keyframes, edit, prefix
    candidates: int | None = None  # best-of-N by the model's critic; None: the model's default
    # the first candidate this close to the critic's best (compose/critic.py); None: the model's
    critic_margin: float | None = None
    keep_going: bool = True  # locomotion longer than its natural length: chained takes
    plant_feet: bool = True  # a standing foot held where it stands (motion/foot_lock.py)
    text_anchors: bool = True  # a far prompt pulled towards the training captions' vectors
    in_place: bool = False  # the pelvis kept over its start: the engine applies root motion


def _configured(generator: Any, request: Request) -> Any:
    """The generator with the request's pipeline switches set (keep going, planted feet, text
    anchors, the critic's margin)."""
    generator.keep_going = request.keep_going
    if request.critic_margin is not None:
        from mlct.generate.compose.critic import set_margin

        set_margin(generator, request.critic_margin)
    if not request.plant_feet:
        generator.foot_lock = None
    if not request.text_anchors:
        generator.text_anchors = None
    return generator


def slug(text: str, limit: int = 40) -> str:
    """A file-name-safe form of a prompt: 'a person walks forward' -> 'a_person_walks_forward'."""
    words = re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_")
    return words[:limit].rstrip("_") or "motion"


def output_paths(names: Sequence[str], out: Path | None, out_dir: Path | None,
                 fmt: str | None) -> list[Path]:
    """One path per motion: --out FILE (indexed when there are several), or --out-dir DIR with
    names from the prompts and the --format extension."""
    if (out is None) == (out_dir is None):
        raise MlctError("give --out FILE or --out-dir DIR")
    if out is not None:
        if fmt is not None:
            raise MlctError("--format goes with --out-dir; with --out the extension names it")
        suffix = out.name[-len(check_format(out)):]  # the whole of .g1.csv, in its own case
        if out.is_dir():
            raise MlctError(f"--out {out} is a directory; name a file, or use --out-dir")
        check_writable_dir(out.parent)
        if len(names) == 1:
            return [out]
        stem = out.name[:-len(suffix)]
        return [out.with_name(f"{stem}_{i:03d}{suffix}") for i in range(len(names))]
    assert out_dir is not None
    suffix = "." + (fmt or "gif").lower().lstrip(".")
    check_format(f"motion{suffix}")
    check_writable_dir(out_dir)
    return [out_dir / f"{i:03d}_{slug(name)}{suffix}" for i, name in enumerate(names)]


def run(load: Callable[[], MotionGenerator], request: Request, paths: Sequence[Path],
        features: bool = False, progress: bool = True, rig: str | None = None,
        notice: Callable[[str], None] | None = None) -> list[Path]:
    """Generate the request's motions and write each to its path; returns the paths.

    `load` makes the model: it is called only after every argument has been checked.
    `notice` gets one line per distinct prompt the model does not know (compose/unknown_prompts.py)."""
    from mlct.generate.seeds import MAX_SEED  # what load() imports anyway

    # Every check that needs no model comes first: a mistake costs no loading, no progress bar.
    count = len(request.prompts) * request.num  # motion (or part) i uses seed + i
    if request.seed is not None and not 0 <= request.seed <= MAX_SEED - (count - 1):
        raise MlctError(f"seeds must lie in 0..{MAX_SEED}: --seed {request.seed} with "
                        f"{count} motion(s), each using seed + i")
    for path in paths:
        if features and path.suffix.lower() != ".npy":
            raise MlctError(f"--features writes .npy files, not {path.suffix}")
        check_rig(rig, path.suffix.lower())
    for value in request.seconds or []:  # (the pipeline says the same, after loading)
        if value != "auto" and not (math.isfinite(value) and value > 0):
            raise MlctError(f"seconds must be a positive number, got {value}")
    for value in request.lengths or []:  # the upper bounds are the model's: checked by it
        if value < 1:
            raise MlctError(f"--length must be at least 1 frame, got {value}")
    if request.nfe is not None and request.nfe < 1:
        raise MlctError(f"--nfe must be at least 1 step, got {request.nfe}")
    if request.long and request.control is not None:
        raise MlctError("controls go with one prompt, not a long motion of several")
    if request.long:
        from mlct.generate.compose.long_motion import generate_long

        if request.seconds is None:
            raise MlctError("a long motion needs one duration a prompt: --seconds 3 2 2")
        if request.seconds == ["auto"]:  # one "auto" for every prompt
            request = dataclasses.replace(request, seconds=["auto"] * len(request.prompts))
        if len(request.seconds) != len(request.prompts):
            raise MlctError(f"{len(request.prompts)} prompts but {len(request.seconds)} "
                            f"durations; give one each")
        generator = _configured(load(), request)
        seconds = generator.long_part_seconds(request.prompts, request.seconds)
        started = time.perf_counter()
        motion = generate_long(generator, request.prompts, seconds, request.nfe,
                               request.seed, candidates=request.candidates)
        _LOG.info("1 motion of %d parts made in %.1f ms (backend %s; writing not counted)",
                  len(request.prompts), (time.perf_counter() - started) * 1e3,
                  generator.backend)
        if notice is not None:  # each prompt is one segment, made whole
            _tell_unknown(notice, zip(request.prompts,
                                      generator.unknown_parts(request.prompts, False)))
        (motion.in_place() if request.in_place else motion).save(paths[0], features, rig)
        return [paths[0]]
    texts = [p for p in request.prompts for _ in range(request.num)]
    seeds = None if request.seed is None else [request.seed + i for i in range(len(texts))]
    lengths = _per_text(request.lengths, request.prompts, request.num, "--length")
    seconds = _per_text(request.seconds, request.prompts, request.num, "--seconds")
    generator = _configured(load(), request)
    written = []
    told: set[str] = set()  # the prompts already said to be unknown (--num makes several)
    # The text encoder loads on first use (a CLIP one takes seconds): load it and embed the first
    # batch's prompts before the bar starts, so that the bar's first step and its ETA time
    # generation only.
    started = time.perf_counter()
    generator.encode_text(list(dict.fromkeys(clean_prompt(t) for t in texts[:BATCH])))
    text_s, making_s = time.perf_counter() - started, 0.0
    bar = _progress_bar(len(texts), progress)
    with bar:
        for start in range(0, len(texts), BATCH):
            stop = start + BATCH
            started = time.perf_counter()
            motions: Sequence[GeneratedMotion] = [m for i in range(start, min(stop, len(texts)))
                for m in generator.generate(
                    texts[i], lengths=None if lengths is None else lengths[i],
                    seconds=None if seconds is None else seconds[i], nfe=request.nfe,
                    seed=None if seeds is None else seeds[i], control=request.control)
            ] if request.control is not None else generator.generate(
                texts[start:stop], lengths=None if lengths is None else lengths[start:stop],
                seconds=None if seconds is None else seconds[start:stop], nfe=request.nfe,
                seed=None if seeds is None else seeds[start:stop],
                split_actions=request.split_actions, candidates=request.candidates)
            making_s += time.perf_counter() - started
            if notice is not None:
                told = _tell_unknown(notice, ((m.text, m.unknown_parts) for m in motions),
                                     told)
            for motion, path in zip(motions, paths[start:stop]):
                if request.in_place:
                    motion = motion.in_place()
                written.append(motion.save(path, features, rig))
                bar.update(1)
    # --verbose: what a person waits for, the text encoder apart (its first batch, above)
    _LOG.info("%d motion%s made in %.1f ms, the text encoder %.1f ms before (backend %s; "
              "writing not counted)", len(texts), "" if len(texts) == 1 else "s", making_s * 1e3,
              text_s * 1e3, generator.backend)
    return written


class _NoBar:
    """What the loop asks of a progress bar, where none is shown."""

    def __enter__(self) -> _NoBar:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def update(self, count: int = 1) -> None:
        return None


def _progress_bar(total: int, progress: bool) -> Any:
    """tqdm's bar over `total` motions; none for a single motion or without `progress` (and
    then no import of tqdm, ~15 ms of a one-off command's start)."""
    if not progress or total == 1:
        return _NoBar()
    from tqdm import tqdm

    return tqdm(total=total, unit="motion")


def _tell_unknown(notice: Callable[[str], None], judged: Any, told: set[str] | None = None
                  ) -> set[str]:
    """notice() the line of each (text, unknown parts) with parts, once per text; the texts
    told so far."""
    from mlct.generate.compose.unknown_prompts import unknown_notice

    told = set() if told is None else told
    for text, parts in judged:
        if parts and text not in told:
            told.add(text)
            notice(unknown_notice(text, tuple(parts)))
    return told


def _per_text(values: list | None, prompts: list[str], num: int, flag: str) -> list | None:
    # One value for all prompts, or one a prompt; repeated for the --num variations.
    if values is None:
        return None
    if len(values) == 1:
        values = values * len(prompts)
    if len(values) != len(prompts):
        raise MlctError(f"{flag}: {len(values)} values for {len(prompts)} prompts; "
                        f"give one, or one a prompt")
    return [v for v in values for _ in range(num)]
