"""The prompt composer: what generate() makes of prompts, above the core's batches.

    gen = mlct.load("MODEL_DIR")
    motions = gen.generate(["a person walks forward"], seconds=4, nfe=5, seed=0)
    motions[0].joints  # (T, J, 3)

A prompt is split into its actions and an arm action done during them (actions.py), given
its length (lengths.py, timing.py), sampled best of N by the critic (critic.py) from text
vectors the anchors pull (text_anchors.py), kept going past its length when it is a gait
(gaits.py), chained (long_motion.py) and planted on its feet; a list of prompts has all its
samples made in a few large batches (batch_plan.py). Every sample comes from the core
(generate/core.py), one call per batch, whichever backend runs its networks.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import threading
from typing import Any, Iterator, Sequence

import numpy as np

from mlct.errors import MlctError
from mlct.generate.compose import batch_plan, gaits, parts, reading, timing
from mlct.generate.compose.actions import split_actions as split_actions_of
from mlct.generate.compose.actions import split_concurrent
from mlct.generate.compose.critic import Critic, check_candidates, read_critic
from mlct.generate.compose.durations import DurationModel, read_durations
from mlct.generate.compose.lengths import (DEFAULT_SECONDS, MIN_PART_SECONDS, frame_lengths,
                                           is_scale, longest_gait, stated_lengths, too_long,
                                           wants_auto)
from mlct.generate.compose.prompts import clean_prompt
from mlct.generate.compose.text_anchors import TextAnchors, read_text_anchors
from mlct.generate.core import MotionCore
from mlct.generate.output.generated import GeneratedMotion, Generation
from mlct.generate.seeds import Sampling, item_seeds
from mlct.motion.foot_lock import FootLock, lock_feet


class MotionGenerator:
    """A loaded model: the core (its networks on one backend, sampler, text memo) and what
    generate() does with prompts around it: durations, critic, text anchors, keep going,
    planted feet."""

    def __init__(self, core: MotionCore) -> None:
        self.core = core
        meta = core.meta
        self.backend = core.networks.name  # mlct.load(..., backend=)'s name (generate/load.py)
        self.backend_note = self.backend  # mlct.load's: the backend and why (--verbose)
        # how long each action of a split prompt takes (durations.json beside the weights)
        self.durations: DurationModel | None = (
            read_durations(meta["model_dir"], meta["text_encoder"], int(meta["text_dim"]))
            if meta.get("model_dir") else None)
        # best-of-N sampling (critic.py): the critic beside the weights, if any, and how many
        # motions per prompt it chooses from by default
        ae = self.config.ae
        self.critic: Critic | None = (
            read_critic(meta["model_dir"], meta["text_encoder"], int(meta["text_dim"]),
                        ae.n_tokens * ae.latent_dim, core.networks.critic_graph(),
                        threads=1) if meta.get("model_dir") else None)
        self.candidates = self.critic.candidates if self.critic is not None else 1
        # a prompt worded unlike every training caption is pulled part of the way towards the
        # nearest ones before sampling (text_anchors.py); None: sampled as worded
        self.text_anchors: TextAnchors | None = (
            read_text_anchors(meta["model_dir"], meta["text_encoder"], int(meta["text_dim"]))
            if meta.get("model_dir") else None)
        # the same anchors judge which prompts the model does not know (unknown_prompts.py:
        # GeneratedMotion.unknown_parts); kept apart so that turning the pull off
        # (text_anchors = None, --no-text-anchors) leaves the judgement; None: no judgement
        self.known_anchors: TextAnchors | None = self.text_anchors
        # locomotion asked for longer than its natural length keeps going (keep_going.py)
        self.keep_going = True
        # a foot standing on the floor stays where it stands (motion/foot_lock.py); None: the
        # joints as decoded, their feet sliding as the data's do
        self.foot_lock: FootLock | None = FootLock()
        # parts_of_a_whole and the samples made ahead, per thread (the server's batcher)
        self.nesting = threading.local()

    # -- the core's, as a loaded model shows them ----------------------------------------------
    networks = property(lambda self: self.core.networks)
    config = property(lambda self: self.core.config)
    meta = property(lambda self: self.core.meta)
    skeleton = property(lambda self: self.core.skeleton)
    device = property(lambda self: self.core.device)
    dtype = property(lambda self: self.core.networks.dtype)  # the products' precision
    sampler = property(lambda self: self.core.sampler)
    max_frames = property(lambda self: self.core.max_frames)
    default_nfe = property(lambda self: self.core.default_nfe)
    text_encoder = property(lambda self: self.core.networks.text_encoder())
    ae = property(lambda self: self.core.networks.decoder)  # .decode(z, lengths, max_len)
    denoiser = property(lambda self: self.core.networks.denoiser)  # F(x_t, t, c)
    mean = property(lambda self: self.core.networks.mean)
    std = property(lambda self: self.core.networks.std)

    def frames_for(self, seconds: float) -> int:
        return self.core.frames_for(seconds)

    def check_nfe(self, nfe: int | None) -> int:
        return self.core.check_nfe(nfe)

    def encode_text(self, texts: Sequence[str]) -> Any:
        return self.core.encode_text(texts)

    def sample_latents(self, cond: Any, nfe: int | None = None, seed: Any = None,
                       guidance: float | None = None) -> Any:
        return self.core.sample_latents(cond, nfe, seed, guidance)

    def decode(self, z: Any, lengths: Sequence[int]) -> list[np.ndarray]:
        return self.core.decode(z, lengths)

    def sample_features(self, cond: Any, nfe: int | None, seed: Any, guidance: float | None,
                        lengths: Sequence[int]) -> list[np.ndarray]:
        return self.core.sample_features(cond, nfe, seed, guidance, lengths)

    # -- what the composer's modules do with a loaded model ------------------------------------
    def _lengths(self, count: int, lengths: Any, seconds: Any, longest: int | None = None
                 ) -> list[int]:
        return frame_lengths(self, count, lengths, seconds, longest)

    def longest_gait(self) -> int:
        return longest_gait(self)

    def default_seconds(self, texts: Sequence[str], split_actions: bool = True) -> list[float]:
        return timing.default_seconds(self, texts, split_actions)

    def auto_seconds(self, texts: Sequence[str], seconds: Any = "auto",
                     split_actions: bool = True) -> list[float]:
        return timing.auto_seconds(self, texts, seconds, split_actions)

    def long_part_seconds(self, prompts: Sequence[str], seconds: Sequence[Any]) -> list[Any]:
        return timing.long_part_seconds(self, prompts, seconds)

    def part_frames(self, parts: Sequence[str], frames: int) -> list[int]:
        return timing.part_frames(self, parts, frames)

    def unknown_parts(self, texts: Any, split_actions: bool = True) -> list[tuple[str, ...]]:
        return reading.unknown_parts(self, texts, split_actions)

    def reading(self, text: str, split_actions: bool = True) -> list[dict[str, Any]]:
        return reading.reading(self, text, split_actions)

    def sampling_text(self, cond: Any) -> Any:
        """The text vectors (B, c) the network samples from: a prompt worded unlike every
        training caption pulled towards the nearest ones by the model's text anchors
        (text_anchors.py), any other as it is."""
        return cond if self.text_anchors is None else self.text_anchors(cond)

    def sample_best(self, cond: Any, seeds: Sequence[int], lengths: Sequence[int],
                    how: Sampling) -> list[np.ndarray]:
        """The features of one batch, each prompt the best of `candidates` latents by the
        critic (the first candidate of a seed is the plain sample of that seed), so a motion is
        replayed from (text, length, nfe, seed, candidates): one call of the core. The network
        samples from the text vectors as the model's text anchors pull them (none: as given);
        the critic scores against `cond` itself. Always samples; batch_plan.best_features
        first looks in the samples made ahead."""
        critic = self.critic

        def choose(z: Any, count: int) -> Any:  # (B * N, n, d) -> (B,)
            return critic.best(z, list(lengths), cond, count)

        return self.core.features(self.sampling_text(cond), seeds, lengths, how,
                                  choose if critic is not None else None)

    # -- generate() ------------------------------------------------------------------------------
    def generate(self, texts: str | Sequence[str], lengths: int | Sequence[int] | None = None,
                 seconds: float | Sequence[float] | None = None, nfe: int | None = None,
                 seed: int | Sequence[int] | None = None, guidance: float | None = None,
                 split_actions: bool = True, control: Any = None,
                 candidates: int | None = None) -> Generation:
        """Motions for texts: one per text, each of its own length.

        candidates: sample this many motions per prompt (one batch) and keep the one the
        model's critic rates best (critic.py); default: the model's (8 for the bundled model),
        1 without a critic. 1 is plain sampling.

        control: a generate.control.schema.Control (or its JSON dict): a root path,
        keyframes, a body-part edit, a prefix to continue; one text; control/controlled.py
        meets it.

        split_actions: a text that names actions in sequence ("walks forward, then waves") is
        made as one motion per action, chained (actions.py), when each part gets at least
        MIN_PART_SECONDS; False gives the model the whole text at once.

        seconds: per text or one for all; "auto" (or "auto" items in a list) takes the length
        from the text, by the model's duration model (auto_seconds).

        seed: an int s gives item i the seed s + i, a sequence one seed per item; either way an
        item's motion depends only on its text, length, nfe and seed, not on the rest of the
        batch (generate(["a", "b"], seed=0)[1] is generate("b", seed=1)[0], up to float
        rounding of a different batch size). None is random; the seed used is recorded.

        A list is sampled in a few large batches whatever its prompts become (a sequence's
        parts, a body and its arms, a gait's takes: batch_plan.py), so pass many prompts in
        one call rather than one call each."""
        with self.core.networks.running():  # the onnx backend's torch threads
            outermost = not getattr(self.nesting, "depth", 0)
            if outermost and reading.LOG.isEnabledFor(logging.INFO):
                reading.log_reading(self, texts, split_actions)  # --verbose: its reading
            with self.parts_of_a_whole():
                made = self._made(texts, lengths, seconds, nfe, seed, guidance, split_actions,
                                  control, candidates)
            if control is None:  # control/controlled.py plants a motion on a path alone
                made = Generation([self.plant_feet(m) for m in made])
            if outermost:  # the whole prompt is judged once, not each part made inside
                texts = [texts] if isinstance(texts, str) else list(texts)
                for motion, found in zip(made, self.unknown_parts(texts, split_actions)):
                    motion.unknown_parts = found
            return made

    def _made(self, texts: str | Sequence[str], lengths: Any, seconds: Any, nfe: int | None,
              seed: Any, guidance: float | None, split_actions: bool, control: Any,
              candidates: int | None) -> Generation:
        """generate()'s motions before their feet are planted."""
        if isinstance(texts, str):
            texts = [texts]
        if not isinstance(texts, (list, tuple)):
            raise MlctError(f"texts must be a string or a list of strings, not "
                            f"{type(texts).__name__}")
        texts = [clean_prompt(t, f"text {i + 1}" if len(texts) > 1 else "")
                 for i, t in enumerate(texts)]
        if not texts:
            return Generation([])
        clean, stated = stated_lengths(texts, split_actions)
        if any(n is not None for n in stated):
            return self._stated(texts, clean, stated, lengths, seconds, nfe, seed, guidance,
                                split_actions, control, candidates)
        if wants_auto(seconds):
            seconds = self.auto_seconds(texts, seconds, split_actions)
        elif lengths is None and seconds is None and control is None:
            seconds = self.default_seconds(texts, split_actions)
        if control is not None:
            from mlct.generate.control.controlled import generate_with_control

            return generate_with_control(self, texts, lengths, seconds, nfe, seed, control)
        frames = self._lengths(len(texts), lengths, seconds, self.longest_gait())
        self.check_nfe(nfe)  # before the (slow) text encoder loads
        if candidates is None:
            candidates = self.candidates
        elif check_candidates(candidates) > 1 and self.critic is None:
            raise MlctError("this model has no critic to choose among candidates (make one "
                            "with `mlct train critic`), so candidates must be 1")
        if guidance is not None and not is_scale(guidance):  # a consistency model ignores it
            raise MlctError(f"guidance must be a number >= 0, got {guidance!r}")
        seeds = item_seeds(len(texts), seed)
        how = Sampling(self.check_nfe(nfe), guidance, candidates)  # every batch of the call's
        with batch_plan.made_ahead(self, texts, frames, seeds, split_actions, how):
            return self._made_each(texts, frames, seeds, split_actions, how)

    def _made_each(self, texts: list[str], frames: list[int], seeds: list[int],
                   split_actions: bool, how: Sampling) -> Generation:
        """_made's motions, prompt by prompt (their samples maybe made ahead)."""
        out: list[GeneratedMotion | None] = [None] * len(texts)
        if split_actions:
            for i, t in enumerate(texts):
                if (pair := split_concurrent(t)) is not None:
                    out[i] = parts.concurrent(self, t, *pair, frames[i], seeds[i], how)
        parts_of = [split_actions_of(t) for t in texts]
        plans = parts_of if split_actions else [[t] for t in texts]
        # one action, however the caller splits ("walks, then squats" given whole is none):
        # only such a prompt may be a gait that keeps going (gaits.py)
        single = {i for i, t in enumerate(texts)
                  if len(parts_of[i]) == 1 and split_concurrent(t) is None}
        min_part = self.frames_for(MIN_PART_SECONDS)
        whole = [i for i, (plan, n) in enumerate(zip(plans, frames)) if out[i] is None
                 and (len(plan) == 1 or n // len(plan) < min_part)]
        for i in whole:  # past the window only a one-action gait goes on (gaits.py)
            if frames[i] > self.max_frames and i not in single:
                raise too_long(self, frames[i], text=texts[i])
        if whole:
            made = batch_plan.best_features(self, self.encode_text([texts[i] for i in whole]),
                                            [seeds[i] for i in whole],
                                            [min(frames[i], self.max_frames) for i in whole],
                                            how)
            for i, feats in zip(whole, made):
                out[i] = GeneratedMotion(texts[i], feats, self.core.joints(feats),
                                         self.skeleton.fps, self.skeleton.name, seeds[i])
            gaits.keep_going(self, out, [i for i in whole if i in single], frames, seeds, how)
        for i in sorted(i for i in set(range(len(texts))) - set(whole) if out[i] is None):
            out[i] = parts.chained(self, texts[i], plans[i], frames[i], seeds[i], how)
        return Generation(out)  # type: ignore[arg-type]

    def _stated(self, texts: list[str], clean: list[str], stated: list[float | None],
                lengths: Any, seconds: Any, nfe: int | None, seed: Any, guidance: float | None,
                split_actions: bool, control: Any, candidates: int | None) -> Generation:
        """generate() for prompts that say how long: the model reads them without the phrase
        (it never saw one in a caption), whose seconds give the clip's length unless the caller
        gave lengths or seconds ("auto" for all counts as not given). The motions keep the
        prompts as written."""
        if lengths is None and (seconds is None or isinstance(seconds, str)):
            fallback = ([seconds] * len(clean) if seconds is not None else
                        self.default_seconds(clean, split_actions) if control is None
                        else [DEFAULT_SECONDS] * len(clean))
            seconds = [f if n is None else n for n, f in zip(stated, fallback)]
        made = self.generate(clean, lengths=lengths, seconds=seconds, nfe=nfe, seed=seed,
                             guidance=guidance, split_actions=split_actions, control=control,
                             candidates=candidates)
        return Generation([m.renamed(t) for m, t in zip(made, texts)])

    @contextlib.contextmanager
    def parts_of_a_whole(self) -> Iterator[None]:
        """generate() calls inside make parts (takes, a chain's segments, a body and its arms):
        their feet stay as decoded, and the whole they make is planted once, at the end.
        Planting a planted motion again would move a foot by up to ~2 cm (a turn's pivot)."""
        self.nesting.depth = getattr(self.nesting, "depth", 0) + 1
        try:
            yield
        finally:
            self.nesting.depth -= 1

    def plant_feet(self, motion: GeneratedMotion) -> GeneratedMotion:
        """The motion with its feet held where they stand (self.foot_lock; motion/foot_lock.py),
        its features then derived from the new joints when read; as it is when foot_lock is
        None, or inside parts_of_a_whole."""
        if getattr(self.nesting, "depth", 0):
            return motion
        return self.planted(motion)

    def planted(self, motion: GeneratedMotion) -> GeneratedMotion:
        """plant_feet's work, wherever it is called from (a controlled motion's own path)."""
        if self.foot_lock is None:
            return motion
        joints = lock_feet(motion.joints, self.skeleton, self.foot_lock, motion.fps)
        return dataclasses.replace(motion, joints=joints.astype(np.float32), features=None)
