"""Text -> latent -> motion: the one path that the CLI, the Python API and evaluation share.

    gen = mlct.load("MODEL_DIR")
    motions = gen.generate(["a person walks forward"], seconds=4, nfe=5, seed=0)
    motions[0].joints  # (T, J, 3)

Built from an inference bundle (bundle.py); needs no training code.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import os
import threading
from collections import OrderedDict
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterator, Sequence

import numpy as np
import torch
from torch import Tensor

from mlct.generate.bundle import ENCODER_PREFIXES, read_bundle
from mlct.generate.critic import Critic, check_candidates, read_critic
from mlct.generate.text_anchors import TextAnchors, read_text_anchors
from mlct.io import strip_prefix
from mlct.config import Config, config_from_dict
from mlct.devices import resolve_device
from mlct.errors import MlctError
from mlct.generate.generated import GeneratedMotion, Generation
from mlct.generate.samplers import Sampler, sampler_class
from mlct.nn.autoencoder import LatentAutoencoder
from mlct.nn.build import build_autoencoder, build_denoiser
from mlct.nn.denoiser import Denoiser
from mlct.motion.features import recover_from_ric
from mlct.motion.foot_lock import FootLock, lock_feet
from mlct.motion.skeleton import get_skeleton
from mlct.nn.inference import for_inference, weight_dtype
from mlct.generate.compose import split_actions as split_actions_of
from mlct.generate.durations import DurationModel, split_frames
from mlct.generate.compose import plain_subject, split_concurrent
from mlct.generate.prompts import clean_prompt, stated_seconds

if TYPE_CHECKING:
    from mlct.text import TextEncoder


class MotionGenerator:
    """A loaded model: text encoder (lazy), denoiser, AE decoder, schedule and sampler.

    dtype: the precision of the networks' matrix products, "float32" (default) or "bfloat16"
    (about 1.3-1.7x faster on CPUs with AVX512-BF16, joints a few mm off fp32's:
    docs/performance.md). Either way the networks run through mlct.nn.inference's layers."""

    backend = "torch"  # the name mlct.load(..., backend=) gives it (generate/backends.py)
    backend_note = "torch"  # mlct.load's: the backend and why it was chosen (--verbose)

    def __init__(self, meta: dict, tensors: dict[str, Tensor],
                 device: torch.device | str | None = None,
                 dtype: str | torch.dtype = "float32") -> None:
        try:
            self.dtype = weight_dtype(dtype)
        except ValueError as err:
            raise MlctError(str(err)) from None
        self.meta = meta
        self.config = config_from_dict(meta["config"], "model config")
        self.device = resolve_device("cpu" if device is None else device)
        self.skeleton = get_skeleton(meta["skeleton"])
        # the bundle names its sampler (config.json "sampler"); it owns steps, times, guidance
        self.sampler: Sampler = sampler_class(meta["sampler"])(self.config, self.device)
        self.ae, self.denoiser = self._networks(tensors)
        self.mean = tensors["norm.mean"].float()
        self.std = tensors["norm.std"].float()
        self._text_encoder: TextEncoder | None = None
        # how long each action of a split prompt takes (durations.json beside the weights)
        self.durations = (DurationModel.from_json(meta["durations"], "the model's durations")
                          if meta.get("durations") else None)
        self._text_memo: OrderedDict[str, Tensor] = OrderedDict()
        # best-of-N sampling (generate/critic.py): the critic beside the weights, if any, and
        # how many motions per prompt it chooses from by default
        ae = self.config.ae
        self.critic: Critic | None = (
            read_critic(meta["model_dir"], meta["text_encoder"], int(meta["text_dim"]),
                        ae.n_tokens * ae.latent_dim) if meta.get("model_dir") else None)
        self.candidates = self.critic.candidates if self.critic is not None else 1
        # a prompt worded unlike every training caption is pulled part of the way towards the
        # nearest ones before sampling (generate/text_anchors.py); None: sampled as worded
        self.text_anchors: TextAnchors | None = (
            read_text_anchors(meta["model_dir"], meta["text_encoder"], int(meta["text_dim"]))
            if meta.get("model_dir") else None)
        # the same anchors judge which prompts the model does not know (generate/unknown_prompts
        # .py: GeneratedMotion.unknown_parts); kept apart so that turning the pull off
        # (text_anchors = None, --no-text-anchors) leaves the judgement; None: no judgement
        self.known_anchors: TextAnchors | None = self.text_anchors
        # locomotion asked for longer than its natural length keeps going (generate/keep_going.py)
        self.keep_going = True
        # a list of prompts has all its samples (a sequence's parts, a body and its arms, the
        # takes of gaits that keep going) made in a few large batches (generate/batch_plan.py);
        # False: one prompt's path at a time, as before (the same motions, slower)
        self.make_ahead = True
        # a foot standing on the floor stays where it stands (motion/foot_lock.py); None: the
        # joints as decoded, their feet sliding as the data's do
        self.foot_lock: FootLock | None = FootLock()
        # parts_of_a_whole and the samples made ahead, per thread (the server's batcher)
        self._nesting = threading.local()

    def _networks(self, tensors: dict[str, Tensor]) -> tuple[Any, Any]:
        """The AE decoder and the denoiser that sample_latents and decode run: the bundle's
        modules through mlct.nn.inference's layers (another backend returns its own)."""
        ae, denoiser = bundle_networks(self.config, self.meta, tensors)
        return (for_inference(ae.to(self.device), self.dtype),
                for_inference(denoiser.to(self.device), self.dtype))

    def networks_for(self, batch: int) -> tuple[Any, Any]:
        """(decoder, denoiser) that sample and decode a batch of this size: the backend's own
        (another backend may hand large batches to networks that run them faster)."""
        return self.ae, self.denoiser

    @classmethod
    def load(cls, path: str | os.PathLike, device: torch.device | str | None = None,
             dtype: str | torch.dtype = "float32") -> MotionGenerator:
        meta, tensors = read_bundle(path)
        return cls(meta, tensors, device, dtype)

    @property
    def max_frames(self) -> int:
        return self.config.data.max_motion_length

    @property
    def default_nfe(self) -> int:
        return self.sampler.default_steps

    @property
    def text_encoder(self) -> TextEncoder:
        """The frozen text encoder, loaded on first use (it is named in the bundle, not stored)."""
        if self._text_encoder is None:
            from mlct.text import load_text_encoder

            self._text_encoder = load_text_encoder(self.meta["text_encoder"])
        return self._text_encoder

    def encode_text(self, texts: Sequence[str]) -> Tensor:
        """(B, c) frozen text embeddings. The last TEXT_MEMO_SIZE distinct texts are kept, so a
        repeated prompt skips the encoder; the memo's memory is bounded (a server sees many).
        A subject the training captions never used is read as "a person" (compose.plain_subject)."""
        texts = [plain_subject(t) for t in texts]
        found = {t: self._text_memo[t] for t in texts if t in self._text_memo}
        missing = sorted(set(texts) - set(found))
        if missing:
            found.update(zip(missing, (row.float() for row in self.text_encoder.encode(missing))))
        for text in texts:  # most recently used last; the oldest go first
            self._text_memo[text] = found[text]
            self._text_memo.move_to_end(text)
        while len(self._text_memo) > TEXT_MEMO_SIZE:
            self._text_memo.popitem(last=False)
        return torch.stack([found[t] for t in texts]).to(self.device)

    def frames_for(self, seconds: float) -> int:
        return int(round(seconds * self.skeleton.fps))

    def _lengths(self, count: int, lengths: int | Sequence[int] | None,
                 seconds: float | Sequence[float] | None, longest: int | None = None
                 ) -> list[int]:
        """Frames per text; at most the model's window, or `longest` where generate() can
        keep a gait going past it."""
        longest = self.max_frames if longest is None else longest
        if lengths is not None and seconds is not None:
            raise MlctError("give lengths (frames) or seconds, not both")
        if seconds is not None:
            secs = _numbers(seconds, count, "seconds")
            for s in secs:
                if not np.isfinite(s) or s <= 0:
                    raise MlctError(f"seconds must be a positive number, got {s}")
            lengths = [max(1, self.frames_for(min(s, 1e6))) for s in secs]
        if lengths is None:
            lengths = [min(self.max_frames, self.frames_for(DEFAULT_SECONDS))] * count
        numbers = _numbers(lengths, count, "lengths")
        if any(not np.isfinite(n) or n != int(n) for n in numbers):
            raise MlctError(f"lengths must be whole numbers of frames, got {lengths}")
        out = [int(n) for n in numbers]
        if len(out) != count:
            raise MlctError(f"{len(out)} lengths for {count} texts")
        for n in out:
            if not 1 <= n <= longest:
                raise self._too_long(n, longest)
        return out

    def longest_gait(self) -> int:
        """Frames a one-action gait may last: past the window when gaits keep going
        (generate/keep_going.py, which needs the duration model), else the window."""
        if self.keep_going and self.durations is not None:
            return self.frames_for(MAX_GAIT_SECONDS)
        return self.max_frames

    def _too_long(self, frames: int, longest: int | None = None, text: str | None = None
                  ) -> MlctError:
        """The window's one-line error; `longest` > the window when a gait may go past it;
        `text`: the prompt (or a sequence's part) it is about."""
        window = self.max_frames
        longer = ""
        if frames > window:
            longer = ("; for a longer motion give several prompts, one per part: they are "
                      "chained into one (mlct generate 'A' 'B' --seconds 5 5)")
            if longest is not None and longest > window:
                longer = (f"; a walk, a jog or another gait keeps going up to "
                          f"{longest / self.skeleton.fps:g} s{longer}")
            elif self.keep_going and self.durations is not None:
                longer = (f" for this prompt: only a gait (a walk, a jog, a run...) keeps going "
                          f"past it{longer}")
        about = f"{text!r}: " if text else ""
        return MlctError(f"{about}length {frames} frames is outside 1..{window} "
                         f"({window / self.skeleton.fps:.2f} s at {self.skeleton.fps:g} fps)"
                         f"{longer}")

    def check_nfe(self, nfe: int | None) -> int:
        """The step count to sample with (the default for None); MlctError when out of range."""
        if nfe is not None and not _is_int(nfe):
            raise MlctError(f"nfe must be a whole number of steps, got {nfe!r}")
        return self.sampler.check_steps(nfe)

    @torch.inference_mode()  # 4-6% faster than no_grad at batch 1 (docs/performance.md)
    def sample_latents(self, cond: Tensor, nfe: int | None = None,
                       seed: int | Sequence[int] | None = None, guidance: float | None = None
                       ) -> Tensor:
        """(B, n, d) latents for text embeddings cond (B, c). NFE = denoiser evaluations.

        seed: an int seeds one generator for the whole batch; a sequence seeds each item on its
        own (item i's latent is then independent of the rest of the batch); None is random."""
        batch = cond.shape[0]
        shape = (batch, *self.ae.latent_shape)
        generator = generators_for(seed)
        steps = self.check_nfe(nfe)
        uncond = self.encode_text([""]) if self.sampler.cfg else None  # (1, c) the null text
        x = self.sampler.noise(shape, generator)  # x_T (B, n, d)
        return self.sampler.sample(self.networks_for(batch)[1], x, cond, steps,
                                   generator=generator, guidance=guidance, uncond=uncond)

    @torch.inference_mode()
    def decode(self, z: Tensor, lengths: Sequence[int]) -> list[np.ndarray]:
        """Stage 2's latents (sample_latents) -> denormalized features, one (T_i, D) array per
        item."""
        lens = torch.tensor(list(lengths), device=self.device)
        z = z / self.config.schedule.latent_scale  # back to the autoencoder's latent
        feats = self.networks_for(z.shape[0])[0].decode(z, lens, max(lengths))  # normalized
        feats = (feats.float().cpu() * self.std + self.mean).numpy()
        return [feats[i, :n] for i, n in enumerate(lengths)]  # numpy views: cheap per item

    def sample_features(self, cond: Tensor, nfe: int | None, seed: int | Sequence[int] | None,
                        guidance: float | None, lengths: Sequence[int]) -> list[np.ndarray]:
        """decode(sample_latents(...)): the features of motions of `lengths` frames; a backend
        may do both in one call (the onnx backend's sampler graph)."""
        return self.decode(self.sample_latents(cond, nfe, seed, guidance), lengths)

    def best_features(self, cond: Tensor, nfe: int | None, seeds: Sequence[int],
                      guidance: float | None, lengths: Sequence[int], candidates: int
                      ) -> list[np.ndarray]:
        """sample_best's features, taken from the samples the outermost generate() made ahead
        for its whole list of prompts (generate/batch_plan.py) where it made them."""
        memo = getattr(self._nesting, "memo", None)
        if memo is None or not memo.serves(self.check_nfe(nfe), guidance, candidates):
            return self.sample_best(cond, nfe, seeds, guidance, lengths, candidates)
        found = [memo.get(row, n, s) for row, n, s in zip(cond, lengths, seeds)]
        missing = [i for i, f in enumerate(found) if f is None]
        if missing:
            made = self.sample_best(cond[missing], nfe, [seeds[i] for i in missing], guidance,
                                    [lengths[i] for i in missing], candidates)
            for i, feats in zip(missing, made):
                found[i] = feats
        return found  # type: ignore[return-value]

    def duration_vectors(self, texts: Sequence[str]) -> np.ndarray:
        """(B, c) the vectors the duration model reads: the text as the network samples from it
        (sampling_text), so that a prompt worded unlike every caption is timed as the motion
        it is pulled towards is made. Read raw, "walk around in a circle going anticlockwise"
        got 4.1 s and its circle was cut off at the 5 s floor (~250 degrees); pulled, 6.9 s
        (docs/model_card.md)."""
        return self.sampling_text(self.encode_text(list(texts))).float().cpu().numpy()

    def sampling_text(self, cond: Tensor) -> Tensor:
        """The text vectors (B, c) the network samples from: a prompt worded unlike every
        training caption pulled towards the nearest ones by the model's text anchors
        (generate/text_anchors.py), any other as it is."""
        return cond if self.text_anchors is None else self.text_anchors(cond)

    def sample_best(self, cond: Tensor, nfe: int | None, seeds: Sequence[int],
                    guidance: float | None, lengths: Sequence[int], candidates: int
                    ) -> list[np.ndarray]:
        """sample_features, each prompt the best of `candidates` latents by the critic: the
        first candidate of a seed is the plain sample of that seed, the others have seeds
        derived from it, so a motion is replayed from (text, length, nfe, seed, candidates).
        The network samples from the text vectors as the model's text anchors pull them (none:
        as given); the critic scores against `cond` itself. Always samples; best_features
        first looks in the samples made ahead."""
        sampled = self.sampling_text(cond)
        if candidates == 1 or self.critic is None:
            return self.sample_features(sampled, nfe, list(seeds), guidance, lengths)
        rows = sampled.repeat_interleave(candidates, dim=0)
        seeds_of = [(s + k * SEED_STRIDE) % (MAX_SEED + 1)
                    for s in seeds for k in range(candidates)]
        z = self.sample_latents(rows, nfe, seeds_of, guidance)  # (B * N, n, d)
        best = self.critic.best(z.float().cpu() / self.config.schedule.latent_scale,
                                torch.tensor(list(lengths)), cond.float().cpu(), candidates)
        z = z.view(len(seeds), candidates, *z.shape[1:])
        z = z[torch.arange(len(seeds), device=z.device), best.to(z.device)]
        return self.decode(z, lengths)

    def generate(self, texts: str | Sequence[str], lengths: int | Sequence[int] | None = None,
                 seconds: float | Sequence[float] | None = None, nfe: int | None = None,
                 seed: int | Sequence[int] | None = None, guidance: float | None = None,
                 split_actions: bool = True, control: Any = None,
                 candidates: int | None = None) -> Generation:
        """Motions for texts: one per text, each of its own length.

        candidates: sample this many motions per prompt (one batch) and keep the one the
        model's critic rates best (generate/critic.py); default: the model's (8 for the bundled
        model), 1 without a critic. 1 is plain sampling.

        control: a generate.control.Control (or its JSON dict): a root path, keyframes, a
        body-part edit, a prefix to continue; one text; generate/controlled.py meets it.

        split_actions: a text that names actions in sequence ("walks forward, then waves") is
        made as one motion per action, chained (generate/compose.py), when each part gets at
        least MIN_PART_SECONDS; False gives the model the whole text at once.

        seconds: per text or one for all; "auto" (or "auto" items in a list) takes the length
        from the text, by the model's duration model (auto_seconds).

        seed: an int s gives item i the seed s + i, a sequence one seed per item; either way an
        item's motion depends only on its text, length, nfe and seed, not on the rest of the
        batch (generate(["a", "b"], seed=0)[1] is generate("b", seed=1)[0], up to float
        rounding of a different batch size). None is random; the seed used is recorded.

        A list is sampled in a few large batches whatever its prompts become (a sequence's
        parts, a body and its arms, a gait's takes: generate/batch_plan.py), so pass many
        prompts in one call rather than one call each."""
        outermost = not getattr(self._nesting, "depth", 0)
        if outermost and _LOG.isEnabledFor(logging.INFO):
            self._log_reading(texts, split_actions)  # --verbose: how each prompt is read
        with self.parts_of_a_whole():
            made = self._made(texts, lengths, seconds, nfe, seed, guidance, split_actions,
                              control, candidates)
        if control is None:  # generate/controlled.py plants a motion on a path alone
            made = Generation([self.plant_feet(m) for m in made])
        if outermost:  # the whole prompt is judged once, not each part the calls inside make
            texts = [texts] if isinstance(texts, str) else list(texts)
            for motion, parts in zip(made, self.unknown_parts(texts, split_actions)):
                motion.unknown_parts = parts
        return made

    def unknown_parts(self, texts: str | Sequence[str], split_actions: bool = True
                      ) -> list[tuple[str, ...]]:
        """For each prompt, the parts of it (as generate() splits it: its actions in turn, an
        arm action done during them) that lie too far from every training caption for the
        model to know them (generate/unknown_prompts.py); () where it knows them all, or where
        the model has no text anchors to judge by. Reads the text encoder's memo without
        changing it, so that judging a prompt never changes a later motion."""
        from mlct.generate.unknown_prompts import unknown_rows

        texts = [texts] if isinstance(texts, str) else list(texts)
        clean, _ = stated_lengths([clean_prompt(t) for t in texts], split_actions)
        plans = [parts_as_made(t, split_actions) for t in clean]
        parts = [[*body, *([arms] if arms else [])] for body, arms in plans]
        distinct = list(dict.fromkeys(p for plan in parts for p in plan))
        if self.known_anchors is None or not distinct:
            return [() for _ in texts]
        unknown = dict(zip(distinct, unknown_rows(self.known_anchors,
                                                  self._judged_vectors(distinct))))
        return [tuple(p for p in plan if unknown[p]) for plan in parts]

    def _judged_vectors(self, texts: Sequence[str]) -> Tensor:
        """encode_text's vectors (B, c) for judging: from its memo where there (the vectors the
        motions were made from), else encoded now and not kept."""
        keys = [plain_subject(t) for t in texts]
        found = {k: self._text_memo[k] for k in keys if k in self._text_memo}
        missing = sorted(set(keys) - set(found))
        if missing:
            found.update(zip(missing, (row.float() for row in self.text_encoder.encode(missing))))
        return torch.stack([found[k] for k in keys])

    def reading(self, text: str, split_actions: bool = True) -> list[dict[str, Any]]:
        """How generate() reads a prompt, one dict per sample it makes: "part" (the words, as
        split from the prompt), "read_as" (as the text encoder gets them: compose.plain_subject),
        "pull" (how far the text anchors move its vector, 0 to 1), "arms" (True for an arm
        action done during the rest) and "known" (False: too far from every training caption
        for the model to know it, generate/unknown_prompts.py). A misreading shows here first
        ("a little girl in a party dress twirls" was once read as "a person dress twirls")."""
        body, arms = parts_as_made(clean_prompt(text), split_actions)
        parts = body + ([arms] if arms else [])
        vectors = self.encode_text(parts)
        pulls = (self.text_anchors.weights(vectors)[0].tolist()
                 if self.text_anchors is not None else [0.0] * len(parts))
        if self.known_anchors is not None:
            from mlct.generate.unknown_prompts import unknown_rows

            known = [not u for u in unknown_rows(self.known_anchors, vectors)]
        else:
            known = [True] * len(parts)
        return [{"part": part, "read_as": plain_subject(part), "pull": round(pull, 3),
                 "arms": k == len(body), "known": ok}
                for k, (part, pull, ok) in enumerate(zip(parts, pulls, known))]

    def _log_reading(self, texts: Any, split: bool) -> None:
        """--verbose: each prompt's reading() as one line."""
        if not isinstance(texts, (list, tuple)):
            texts = [texts]
        for text in texts:
            try:
                parts = self.reading(text, split)
            except MlctError:
                continue  # _made refuses it with its own message
            said = [f"{p['read_as']!r}" + (f" (pulled {p['pull']:.2f} towards the training "
                                             f"captions)" if p["pull"] else "")
                    + ("" if p["known"] else " (unknown to the model)")
                    for p in parts]
            body = [w for w, p in zip(said, parts) if not p["arms"]]
            arms = [w for w, p in zip(said, parts) if p["arms"]]
            _LOG.info("%r read as %s%s", text, ", then ".join(body),
                      f"; its arms as {arms[0]}" if arms else "")

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
        if _wants_auto(seconds):
            seconds = self.auto_seconds(texts, seconds, split_actions)
        elif lengths is None and seconds is None and control is None:
            seconds = self.default_seconds(texts, split_actions)
        if control is not None:
            from mlct.generate.controlled import generate_with_control

            return generate_with_control(self, texts, lengths, seconds, nfe, seed, control)
        frames = self._lengths(len(texts), lengths, seconds, self.longest_gait())
        self.check_nfe(nfe)  # before the (slow) text encoder loads
        if candidates is None:
            candidates = self.candidates
        elif check_candidates(candidates) > 1 and self.critic is None:
            raise MlctError("this model has no critic to choose among candidates (make one "
                            "with `mlct train critic`), so candidates must be 1")
        if guidance is not None and not _is_scale(guidance):  # a consistency model ignores it
            raise MlctError(f"guidance must be a number >= 0, got {guidance!r}")
        seeds = self._seeds(len(texts), seed)
        with self._made_ahead(texts, frames, seeds, split_actions, nfe, guidance, candidates):
            return self._made_each(texts, frames, seeds, split_actions, nfe, guidance,
                                   candidates)

    @contextlib.contextmanager
    def _made_ahead(self, texts: Sequence[str], frames: Sequence[int], seeds: Sequence[int],
                    split_actions: bool, nfe: int | None, guidance: float | None,
                    candidates: int) -> Iterator[None]:
        """The outermost generate() makes every sample its prompts' paths will ask for in a
        few large batches first (generate/batch_plan.py), where some prompt is more than one
        sample; the paths then read them (best_features)."""
        from mlct.generate.batch_plan import planned_samples

        # One prompt's path already makes its own samples in one call (a sequence's parts,
        # a gait's takes), so only a list is planned: a batch of 1 pays nothing for it.
        if (not self.make_ahead or len(texts) < 2
                or getattr(self._nesting, "memo", None) is not None):
            yield  # one path at a time, one prompt, or an inner call (the outer made them)
            return
        planned = planned_samples(self, texts, frames, seeds, split_actions)
        if [s.text for s in planned] == list(texts):  # one sample each: one batch already
            yield
            return
        with self.samples_ahead(planned, nfe, guidance, candidates):
            yield

    @contextlib.contextmanager
    def samples_ahead(self, samples: Sequence[Any], nfe: int | None, guidance: float | None,
                      candidates: int) -> Iterator[None]:
        """Within it, best_features reads these batch_plan.Samples, made now in a few large
        batches (added to the memo of an outer call with the same settings, else a new one)."""
        from mlct.generate.batch_plan import SampleMemo, fill

        if not self.make_ahead:
            yield
            return
        steps = self.check_nfe(nfe)
        outer = getattr(self._nesting, "memo", None)
        if outer is not None and outer.serves(steps, guidance, candidates):
            fill(self, outer, samples)
            yield
            return
        self._nesting.memo = SampleMemo(steps, guidance, candidates)
        try:
            fill(self, self._nesting.memo, samples)
            yield
        finally:
            self._nesting.memo = outer

    def _made_each(self, texts: list[str], frames: list[int], seeds: list[int],
                   split_actions: bool, nfe: int | None, guidance: float | None,
                   candidates: int) -> Generation:
        """_made's motions, prompt by prompt (their samples maybe made ahead)."""
        out: list[GeneratedMotion | None] = [None] * len(texts)
        if split_actions:
            for i, t in enumerate(texts):
                if (pair := split_concurrent(t)) is not None:
                    out[i] = self._concurrent(t, *pair, frames[i], nfe, seeds[i], guidance,
                                              candidates)
        parts_of = [split_actions_of(t) for t in texts]
        plans = parts_of if split_actions else [[t] for t in texts]
        # one action, however the caller splits ("walks, then squats" given whole is none):
        # only such a prompt may be a gait that keeps going (_keep_going)
        single = {i for i, t in enumerate(texts)
                  if len(parts_of[i]) == 1 and split_concurrent(t) is None}
        min_part = self.min_part_frames()
        whole = [i for i, (parts, n) in enumerate(zip(plans, frames)) if out[i] is None
                 and (len(parts) == 1 or n // len(parts) < min_part)]
        for i in whole:  # past the window only a one-action gait goes on (_keep_going)
            if frames[i] > self.max_frames and i not in single:
                raise self._too_long(frames[i], text=texts[i])
        if whole:
            made = self.best_features(self.encode_text([texts[i] for i in whole]), nfe,
                                      [seeds[i] for i in whole], guidance,
                                      [min(frames[i], self.max_frames) for i in whole],
                                      candidates)
            for i, feats in zip(whole, made):
                joints = recover_from_ric(torch.from_numpy(feats)).numpy()
                out[i] = GeneratedMotion(texts[i], feats, joints, self.skeleton.fps,
                                         self.skeleton.name, seeds[i])
            self._keep_going(out, [i for i in whole if i in single], frames, nfe, seeds,
                             guidance, candidates)
        for i in sorted(i for i in set(range(len(texts))) - set(whole) if out[i] is None):
            out[i] = self._chained(texts[i], plans[i], frames[i], nfe, seeds[i], guidance,
                                   candidates)
        return Generation(out)  # type: ignore[arg-type]

    @contextlib.contextmanager
    def parts_of_a_whole(self) -> Iterator[None]:
        """generate() calls inside make parts (takes, a chain's segments, a body and its arms):
        their feet stay as decoded, and the whole they make is planted once, at the end.
        Planting a planted motion again would move a foot by up to ~2 cm (a turn's pivot)."""
        self._nesting.depth = getattr(self._nesting, "depth", 0) + 1
        try:
            yield
        finally:
            self._nesting.depth -= 1

    def plant_feet(self, motion: GeneratedMotion) -> GeneratedMotion:
        """The motion with its feet held where they stand (self.foot_lock; motion/foot_lock.py),
        its features then derived from the new joints when read; as it is when foot_lock is
        None, or inside parts_of_a_whole."""
        if getattr(self._nesting, "depth", 0):
            return motion
        return self.planted(motion)

    def planted(self, motion: GeneratedMotion) -> GeneratedMotion:
        """plant_feet's work, wherever it is called from (a controlled motion's own path)."""
        if self.foot_lock is None:
            return motion
        joints = lock_feet(motion.joints, self.skeleton, self.foot_lock, motion.fps)
        return dataclasses.replace(motion, joints=joints.astype(np.float32), features=None)

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

    def default_seconds(self, texts: Sequence[str], split_actions: bool = True) -> list[float]:
        """Each text's length when neither the caller nor the prompt gives one: DEFAULT_SECONDS,
        or longer when the duration model says its actions take longer (a circle walk, a stretch,
        two actions in turn), up to the window. Never shorter: a short action is followed by
        standing, as before. Against a flat 5 s on the hand-written prompts (5 seeds): held-out 2
        0.828 -> 0.874, the other sets the same or better (docs/model_card.md)."""
        flat = min(DEFAULT_SECONDS, self.max_frames / self.skeleton.fps)  # a short window's
        if self.durations is None:
            return [flat] * len(texts)
        return [max(flat, s) for s in self.auto_seconds(texts, "auto", split_actions)]

    def auto_seconds(self, texts: Sequence[str], seconds: Any = "auto",
                     split_actions: bool = True) -> list[float]:
        """Each text's seconds, those given as "auto" predicted from the text as its parts
        would be made (DurationModel.clip_seconds: an arm action done during another lasts as
        long as the other), within MIN_PART_SECONDS and the model's window."""
        given = [seconds] * len(texts) if isinstance(seconds, str) else list(seconds)
        if len(given) != len(texts):
            raise MlctError(f"{len(given)} seconds for {len(texts)} texts")
        durations = self._duration_model()
        plans = {}  # text index -> its parts, as generate() would make them
        for i, (text, value) in enumerate(zip(texts, given)):
            if _wants_auto(value):
                plans[i] = parts_as_made(text, split_actions)[0]
        parts = [p for plan in plans.values() for p in plan]
        vectors = self.duration_vectors(parts) if parts else None
        longest = self.max_frames / self.skeleton.fps
        start = 0
        for i, plan in plans.items():  # one text-encoder call for all of them
            clip = durations.clip_seconds(vectors[start:start + len(plan)])
            given[i] = float(np.clip(clip, MIN_PART_SECONDS, longest))
            start += len(plan)
        return given

    def long_part_seconds(self, prompts: Sequence[str], seconds: Sequence[Any]) -> list[Any]:
        """The seconds of a long motion's prompts (generate_long), those given as "auto" each
        prompt's share of the whole as the duration model times a sequence's parts
        (DurationModel.part_seconds), at least MIN_PART_SECONDS."""
        if not _wants_auto(list(seconds)):
            return list(seconds)
        natural = self._duration_model().part_seconds(self.duration_vectors(prompts))
        return [max(float(n), MIN_PART_SECONDS) if _wants_auto(s) else s
                for s, n in zip(seconds, natural)]

    def _duration_model(self) -> DurationModel:
        """The model's duration model; MlctError when it has none (seconds "auto")."""
        if self.durations is None:
            raise MlctError("this model has no duration model to take seconds from the text "
                            "(make one with `mlct train durations`); give the seconds")
        return self.durations

    def _chained(self, text: str, parts: list[str], frames: int, nfe: int | None, seed: int,
                 guidance: float | None, candidates: int) -> GeneratedMotion:
        """One motion of `frames` doing parts[k] in turn, under the whole text."""
        from mlct.generate.long_motion import generate_long

        fps = self.skeleton.fps
        made = generate_long(self, parts, [n / fps for n in self.part_frames(parts, frames)],
                             nfe=nfe, seed=seed, guidance=guidance, candidates=candidates)
        return made.renamed(text)

    def min_part_frames(self) -> int:
        """The fewest frames a sequence's part may get (MIN_PART_SECONDS); a prompt whose parts
        would get fewer is made whole."""
        return self.frames_for(MIN_PART_SECONDS)

    def part_frames(self, parts: Sequence[str], frames: int) -> list[int]:
        """Each part's frames of a sequence of `frames`: its share by how long its action takes
        and its place in the sequence (durations.py; equal when the model has no duration
        model), at least MIN_PART_SECONDS where the total allows."""
        weights = (self.durations.part_weights(self.duration_vectors(parts),
                                               frames / self.skeleton.fps, MIN_PART_SECONDS)
                   if self.durations else np.ones(len(parts)))
        return split_frames(weights, frames, self.frames_for(MIN_PART_SECONDS))

    def _keep_going(self, out: list[GeneratedMotion | None], indices: Sequence[int],
                    frames: Sequence[int], nfe: int | None, seeds: Sequence[int],
                    guidance: float | None, candidates: int) -> None:
        """A one-action gait asked for clearly longer than its natural length that stopped
        early, or asked past the window (made at the window's length so far), is made again as
        takes of its natural length chained into one continuing motion (generate/keep_going.py);
        out[i] is replaced in place. A prompt past the window that is no gait raises the
        window's error. Needs the duration model."""
        from mlct.generate.batch_plan import Sample
        from mlct.generate.keep_going import names_an_end, takes_needed
        from mlct.generate.long_motion import blend_frames

        if self.durations is None or not self.keep_going:
            return
        fps = self.skeleton.fps
        for i in indices:  # past the window (made at its length so far) only a gait goes on
            if frames[i] > self.max_frames and names_an_end(out[i].text):
                raise self._too_long(frames[i], text=out[i].text)
        todo = [i for i in indices if not names_an_end(out[i].text)
                and frames[i] / fps >= MIN_PART_SECONDS]
        if not todo:
            return
        vectors = self.duration_vectors([out[i].text for i in todo])
        natural = [self.durations.clip_seconds(vector[None]) for vector in vectors]
        blend = blend_frames(fps)
        # every prompt's first takes in a few large batches (generate/batch_plan.py)
        ahead = []
        for i, seconds in zip(todo, natural):
            needed = takes_needed(out[i].joints, frames[i], self.max_frames, seconds, blend,
                                  self.skeleton)
            if needed is not None:
                ahead += [Sample(out[i].text, needed[1], (seeds[i] + k) % (MAX_SEED + 1))
                          for k in range(needed[0])]
        with self.samples_ahead(ahead, nfe, guidance, candidates):
            for i, seconds in zip(todo, natural):
                self._keep_going_one(out, i, frames[i], seconds, blend, nfe, seeds[i], guidance,
                                     candidates)

    def _keep_going_one(self, out: list[GeneratedMotion | None], i: int, frames: int,
                        natural_seconds: float, blend: int, nfe: int | None, seed: int,
                        guidance: float | None, candidates: int) -> None:
        """_keep_going for out[i]."""
        from mlct.generate.keep_going import continue_gait
        from mlct.generate.long_motion import LongMotion

        fps = self.skeleton.fps
        motion = out[i]

        def takes(count: int, take: int) -> list[np.ndarray]:
            made = self.generate([motion.text] * count, lengths=take, nfe=nfe,
                                 seed=[(seed + k) % (MAX_SEED + 1) for k in range(count)],
                                 guidance=guidance, split_actions=False, candidates=candidates)
            return [m.joints for m in made]

        kept = continue_gait(motion.joints, frames, self.max_frames, natural_seconds, blend,
                             self.skeleton, takes)
        if kept is None:
            if frames > self.max_frames:  # no gait, or its takes fell short
                raise self._too_long(frames, text=motion.text)
            return  # as the model made it
        _LOG.info("%r kept going: %d takes of %.1f s chained into %.1f s (--no-keep-going: "
                  "as the model made it)", motion.text, len(kept.takes),
                  kept.take_frames / fps, frames / fps)
        # a LongMotion, as a chain of prompts is: its seams and the takes as made; its
        # features derived from the joints when read (generated.py)
        out[i] = LongMotion(motion.text, None, kept.joints.astype(np.float32), fps,
                            self.skeleton.name, seed, seams=tuple(kept.seams),
                            texts=(motion.text,) * len(kept.takes), blend=blend,
                            segments=tuple(kept.takes))

    def _concurrent(self, text: str, body: str, arms: str, frames: int, nfe: int | None,
                    seed: int, guidance: float | None, candidates: int) -> GeneratedMotion:
        """An arm action done during another: the body made from `body` (split into its actions
        as any prompt), the arm action made from `arms` alone, standing, each the best of the
        candidates; then the arms' bones re-attached to the body, turned into its facing
        (control_fit.reattach, the body-part edit's last step). Not the edit control itself:
        its guidance pulls the arm sample toward the body, which reattach replaces anyway, and
        its candidates are chosen by that, not by the critic; on the benchmark's concurrent
        test captions the arms passed 0.843 that way, 0.899 this way (docs/training.md)."""
        # imported here: control_fit needs scipy, which a cold start must not load
        from mlct.generate.control import part_joints
        from mlct.generate.control_fit import reattach

        made = self.generate(body, lengths=frames, nfe=nfe, seed=seed, guidance=guidance,
                             candidates=candidates)[0]
        standing = self.generate(arms, lengths=frames, nfe=nfe, seed=seed, guidance=guidance,
                                 candidates=candidates)[0]
        joints = reattach(standing.joints.astype(np.float64), made.joints.astype(np.float64),
                          part_joints("arms", self.skeleton), self.skeleton)
        return GeneratedMotion(text, None, joints.astype(np.float32), self.skeleton.fps,
                               self.skeleton.name, seed)  # features derived when read

    @staticmethod
    def _seeds(count: int, seed: int | Sequence[int] | None) -> list[int]:
        if seed is None:  # random, but recorded on each motion so that it can be replayed
            return [int(s) for s in torch.randint(0, 2**31 - 1, (count,))]
        if _is_int(seed):
            seeds = [int(seed) + i for i in range(count)]  # type: ignore[arg-type]
        elif isinstance(seed, (list, tuple, np.ndarray)) and all(_is_int(s) for s in seed):
            seeds = [int(s) for s in seed]
        else:
            raise MlctError(f"seed must be a whole number or a list of them, got {seed!r}")
        if len(seeds) != count:
            raise MlctError(f"{len(seeds)} seeds for {count} texts")
        if any(not 0 <= s <= MAX_SEED for s in seeds):
            raise MlctError(f"seeds must lie in 0..{MAX_SEED} (item i uses seed + i), got {seed}")
        return seeds


def generators_for(seed: int | Sequence[int] | None) -> torch.Generator | list[torch.Generator]:
    """The noise generators of sample_latents: an int seeds one for the batch, a sequence one
    per item, None a random one."""
    if seed is None:
        generator = torch.Generator()
        generator.seed()
        return generator
    if isinstance(seed, (int, np.integer)):
        return torch.Generator().manual_seed(int(seed))
    return [torch.Generator().manual_seed(int(s)) for s in seed]


def bundle_networks(config: Config, meta: dict, tensors: dict[str, Tensor]
                    ) -> tuple[LatentAutoencoder, Denoiser]:
    """The bundle's AE (its decoder's weights) and denoiser as plain modules in eval mode;
    MlctError when the weights do not fit the config."""
    ae = build_autoencoder(config, meta["feature_dim"])
    missing, unexpected = ae.load_state_dict(strip_prefix(tensors, "decoder"), strict=False)
    if unexpected or any(not k.startswith(ENCODER_PREFIXES) for k in missing):
        raise MlctError("model weights do not match its config (decoder)")
    denoiser = build_denoiser(config, meta["text_dim"])
    try:
        denoiser.load_state_dict(strip_prefix(tensors, "denoiser"))
    except RuntimeError:
        raise MlctError("model weights do not match its config (denoiser)") from None
    return ae.eval().requires_grad_(False), denoiser.eval().requires_grad_(False)


# What the pipeline decided beyond the model's own sampling (keep-going); `mlct generate
# --verbose` prints it.
_LOG = logging.getLogger("mlct.generate")


def parts_as_made(text: str, split: bool) -> tuple[list[str], str | None]:
    """(the actions made in turn, the arm action made during them or None): how generate()
    splits a prompt, an arm action done during the rest first (compose.split_concurrent), then
    the rest's actions (compose.split_actions); (text,), None when not split."""
    pair = split_concurrent(text) if split else None
    body, arms = (text, None) if pair is None else pair
    return (split_actions_of(body) if split else [body]), arms
# The shortest share of a sequence's part: below it the blend (0.75 s) would be most of the part.
MIN_PART_SECONDS = 1.0
DEFAULT_SECONDS = 5.0  # a clip's length when neither the caller nor the prompt gives one
# A one-action gait keeps going past the model's window (generate/keep_going.py) up to this: a
# two-minute walk is 2,400 frames, ~70 takes, well under a second of sampling.
MAX_GAIT_SECONDS = 120.0
TEXT_MEMO_SIZE = 2048  # texts whose embeddings a generator keeps (LRU): <= 64 MB with tokens
SEED_STRIDE = 0x9E3779B97F4A7C15  # candidate k of seed s samples with s + k * this (mod 2^63)
MAX_SEED = 2**63 - 1  # torch.Generator.manual_seed takes 64 bits; kept signed for portability


def _is_int(value: object) -> bool:
    """A whole number given as an int (not a bool, a float or a string)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def _is_scale(value: object) -> bool:
    """A finite real number >= 0 (a guidance scale), not a bool or a string."""
    return (isinstance(value, (int, float, np.integer, np.floating))
            and not isinstance(value, (bool, np.bool_)) and bool(np.isfinite(value))
            and value >= 0)


def _numbers(value: object, count: int, name: str) -> list[float]:
    """A number for every item, or a list of them: floats; MlctError naming `name` otherwise."""
    def number(item: object) -> float:
        if isinstance(item, (bool, np.bool_)) or not isinstance(item, (int, float, np.number)):
            raise MlctError(f"{name} must be numbers, got {item!r}")
        return float(item)

    if isinstance(value, (list, tuple, np.ndarray)):
        return [number(item) for item in value]
    return [number(value)] * count


def stated_lengths(texts: Sequence[str], split_actions: bool = True
                   ) -> tuple[list[str], list[float | None]]:
    """Each prompt without a phrase that says how long ("walks forward for 20 seconds",
    prompts.stated_seconds), and the seconds it says (None: none). In a prompt of several actions
    the phrase is left where it is: whose duration it gives is not clear. generate() and the
    server's default length both read prompts this way."""
    clean, stated = [], []
    for text in texts:
        without, seconds = stated_seconds(text)
        if seconds is not None and split_actions and len(split_actions_of(without)) > 1:
            seconds = None
        clean.append(without if seconds is not None else text)
        stated.append(seconds)
    return clean, stated


def bundled_model_dir() -> Path:
    """The model shipped inside the package (docs/model_card.md): small preset, MiniLM text."""
    return Path(__file__).resolve().parent.parent / "assets" / "model"


def _wants_auto(seconds: Any) -> bool:
    """seconds="auto", or a list with an "auto" item (any case)."""
    if isinstance(seconds, str):
        if seconds.strip().lower() != "auto":
            raise MlctError(f'seconds must be a number, a list of them or "auto", '
                            f"got {seconds!r}")
        return True
    return isinstance(seconds, (list, tuple)) and any(
        isinstance(s, str) and _wants_auto(s) for s in seconds)
