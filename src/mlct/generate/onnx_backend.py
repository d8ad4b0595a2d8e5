"""The onnx backend: MotionGenerator with its networks run by ONNX Runtime on the CPU.

    gen = mlct.load("MODEL_DIR", backend="onnx")  # after `mlct convert MODEL_DIR --onnx`

Only the three networks change (onnx_bundle.py's graphs); everything around them is the torch
backend's code: prompts, lengths, seeds, the sampler objects with their time grids, clamps and
noise (drawn from the same seeded torch.Generator), latent_scale, denormalization, joints. So the
same seed gives the same motion, up to float rounding (tests/test_onnx.py: joints within 1 mm).
"""

from __future__ import annotations

import os
import threading
from contextlib import contextmanager
from typing import Any, Iterator, Sequence

import numpy as np
import torch
from torch import Tensor

from mlct.devices import resolve_device
from mlct.errors import MlctError
from mlct.generate.bundle import read_bundle
from mlct.generate.onnx_attention import fuse_attention
from mlct.generate.onnx_bundle import DECODER_IO, DENOISER_IO, OnnxGraphs, read_onnx
from mlct.generate.onnx_decoder_halves import DecoderHalves
from mlct.generate.onnx_sampler import (COEFFICIENTS, INPUTS, consistency_feeds, fixed_batch,
                                        run_steps, sampler_model, step_coefficients)
from mlct.generate.pipeline import MotionGenerator, generators_for
from mlct.generate.samplers import ConsistencySampler
from mlct.nn.build import latent_clamp
from mlct.nn.inference import weight_dtype
from mlct.nn.masks import lengths_to_mask
from mlct.onnx_io import onnxruntime_module, session, session_from_bytes, spin_now
from mlct.text.base import TextEncoder


def _array(x: Tensor) -> np.ndarray:
    """A tensor as the contiguous array ONNX Runtime takes (no copy when it already is one)."""
    return np.ascontiguousarray(x.detach().numpy())


class OnnxDenoiser:
    """F(x_t, t, c) of denoiser.onnx, called as the samplers call the torch network."""

    def __init__(self, graph: os.PathLike, threads: int | None = None) -> None:
        self.session = session(graph, threads)

    def __call__(self, x_t: Tensor, t: Tensor, text_emb: Tensor) -> Tensor:
        """x_t (B, n, d), t (B,) or a scalar, text_emb (B, c) -> F (B, n, d), float32."""
        t = torch.as_tensor(t, dtype=torch.float32).reshape(-1).expand(x_t.shape[0])
        (inputs, outputs) = DENOISER_IO
        (f,) = self.session.run(list(outputs), dict(zip(inputs, map(_array, (
            x_t.float(), t, text_emb.float())))))
        return torch.from_numpy(f)


class OnnxDecoder:
    """The AE decoder of decoder.onnx, called as the pipeline calls the torch one.
    attention_heads: a transformer decoder's head count; given (and the onnx package there),
    its attentions run as ONNX Runtime's fused operator, mask and all (onnx_attention.py)."""

    def __init__(self, graph: os.PathLike, threads: int | None = None,
                 attention_heads: int | None = None) -> None:
        self.session = None
        if attention_heads is not None and _onnx_installed():
            import onnx

            model = onnx.load(str(graph))
            try:  # a speed-up only: a graph it cannot rewrite (or run) runs as written
                if fuse_attention(model, attention_heads, padded=True):
                    self.session = session_from_bytes(model.SerializeToString(), threads)
            except (ValueError, MlctError):
                self.session = None
        if self.session is None:
            self.session = session(graph, threads)
        shape = self.session.get_inputs()[0].shape  # ["batch", n, d]
        self.latent_shape: tuple[int, int] = (int(shape[1]), int(shape[2]))

    def decode(self, z: Tensor, lengths: Tensor, max_len: int | None = None) -> Tensor:
        """z (B, n, d), lengths (B,) -> normalized features (B, T, D), T = max_len or the
        longest; frames past an item's length are 0."""
        valid = lengths_to_mask(lengths.cpu(), max_len)  # (B, T)
        (inputs, outputs) = DECODER_IO
        (features,) = self.session.run(list(outputs), dict(zip(inputs, (
            _array(z.float()), valid.numpy()))))
        return torch.from_numpy(features)


# Torch's threads for the torch work around the graphs in generate(). With more, each small
# product or joint recovery starts an OpenMP parallel region, after which torch's idle OpenMP
# threads spin on the cores (libgomp's default, for milliseconds) that the next ONNX Runtime
# run wants: generate() of the bundled model, 5 s, 2 threads, best of 8 took 17.2 ms with 2
# torch threads and 12.7 with 1 (0.75x paired), best of 1 7.1 and 5.6 (docs/performance.md,
# "generate()'s own path"). The torch networks of a large batch keep all `threads`.
TORCH_GLUE_THREADS = 1
# Sampler graphs a generator builds at most: each session holds its own copy of the denoiser's
# and the decoder's weights (20 MB for the bundled model, ~180 MB at paper size); step counts
# beyond the first ones used run the step loop.
MAX_SAMPLER_GRAPHS = 3
# Batches up to this size run a sampler graph of at most ONE_THREAD_MAX_BYTES on one thread.
# At batch 1 the bundled model's ~600 operators take microseconds each on weights that stay in
# the cache, and handing part of each to a second thread (and waking it) costs more than it
# saves: 5 NFE, 2 cores, warm 5.3 -> 4.4 ms (int8 denoiser), 8.4 -> 7.6 ms (float32). A bigger
# graph streams its weights and has work enough to split: the paper-size model (68 MB in int8)
# takes 38.7 ms on two threads and 44.1 on one (docs/performance.md, 2026-11-25 17:05 UTC).
ONE_THREAD_MAX_BATCH = 1
ONE_THREAD_MAX_BYTES = 32_000_000
# Batches of at least this many latents are sampled and decoded by the torch networks (built
# once, on the first such batch, from the same weights): at large batches oneDNN's packed
# products beat ONNX Runtime's on this CPU work, at small ones ONNX Runtime's lower overhead wins
# (bundled model, 5 NFE, 196 frames, 2 threads, ms per motion ONNX Runtime / torch: batch 8
# 5.9 / 7.4, 16 5.4 / 5.9, 32 4.6 / 4.0, 64 4.6-5.2 / 3.8-4.4;
# docs/performance.md, "Backends"). The motions are the same within float
# rounding (tests/test_onnx_sampler.py). None: never.
TORCH_MIN_BATCH: int | None = 32
# A batch that runs its sampler graph on one thread (above) runs the steps alone there and the
# decoder in its own session on all `threads`: the steps' products on 4 tokens lose to a second
# thread's wake-ups, the decoder's convolutions over up to 200 frames gain from it: warm 5.44
# -> 5.29 ms paired (5 NFE, 196 frames, 2 threads; bench/paired_speed.py :one-graph). Alone, the
# decoder on two threads took 2.15 against 2.68 ms; in the pipeline the gain is smaller, as its
# weights come back to the cache after the steps (docs/performance.md).
DECODE_APART = True
# ... and a decoder with an arm pair runs its two halves side by side, one core each
# (onnx_decoder_halves.py): the bundled model's warm call 4.02 ms against 4.34 with the decoder
# as one session on two threads and 4.29 with the one-thread graph of steps and decoder (5 NFE,
# 196 frames, paired; bench/paired_speed.py :one-decoder, :one-graph).
DECODE_HALVES = True
# The sampler graph's denoiser attentions as ONNX Runtime's fused Attention operator
# (onnx_attention.py): per step ~60 standard operators per block become one, the warm batch-1
# call 0.93x (paired, bench/paired_speed.py :unfused-attention). The same for a transformer
# decoder's attentions, with their padding mask, in its session and the sampler graph, and for
# the int8 denoiser's (MultiHeadAttention after the int8 q/k/v product): the paper-size model's
# warm call 0.90x in float32, 0.91x with --int8 (paired, :unfused-attention).
FUSE_ATTENTION = True
# Where two logical CPUs stay free beside them (onnx_io.spare_cores), batch 1's steps run on
# two threads that spin between operators within the run and stop when it ends (onnx_io
# session's spin_within_run): without the wake-ups, a second thread pays for the steps' small
# products: warm 4.12 against 5.02 ms on this repository's 2-core host when nothing else runs
# (paired; bench/paired_speed.py :spinning-steps). With other work on the cores, two threads
# lose whether they spin or sleep (steps and decoder with the test suite running beside: 5.0 ms
# on one thread, 8.1 spinning within the run, 5.6 sleeping), so a machine without cores to
# spare keeps the steps on one thread (docs/performance.md).
# Batch 1 of a sampler graph over ONE_THREAD_MAX_BYTES (the paper-size model: 5 steps and the
# decoder) runs on `threads` that spin within the run while the machine is idle (onnx_io.spin_now,
# asked at every call; a second session, with its own copy of the weights, is made only when the
# machine's load changes: +362 MB of RSS for the paper-size graph in float32, +151 MB with
# --int8, kept rather than remade at each change, which takes longer than the call), or as
# `spinning_steps` says: the paper-size model's warm call 0.91x in float32, 0.84x with --int8
# against sleeping threads (paired, bench/paired_speed.py :sleeping-big-graph).
SPIN_BIG_GRAPH = True


class OnnxMotionGenerator(MotionGenerator):
    """A loaded model whose text encoder, denoiser and decoder are ONNX graphs (CPU, float32).

    threads: ONNX Runtime's intra-op threads per graph; None: torch.get_num_threads() when
    loaded. The torch work around the graphs in generate() (the critic, the joints, the feet:
    small tensors) runs on one torch thread, so that no OpenMP thread of torch's spins on a
    core the graphs' threads want (TORCH_GLUE_THREADS, `torch_glue_threads`)."""

    backend = "onnx"

    def __init__(self, meta: dict, tensors: dict[str, Tensor], graphs: OnnxGraphs,
                 device: torch.device | str | None = None, dtype: str | torch.dtype = "float32",
                 threads: int | None = None, fused: bool = True) -> None:
        check_device_and_dtype(device, dtype)
        self.graphs, self.threads = graphs, int(threads or torch.get_num_threads())
        self.fused = fused
        self._fused: dict[int, Any] = {}  # step count -> its sampler graph (bytes, or None)
        # (step count, threads, batch 1, steps apart from the decoder, spinning) -> session
        self._sessions: dict[tuple[int, int, bool, bool, bool], Any] = {}
        self._calls: dict[int, int] = {}  # step count -> sampling calls with it
        self._coefficients: dict[int, dict[str, np.ndarray]] = {}  # step count -> its times, coef
        self.torch_min_batch = TORCH_MIN_BATCH
        self.decode_apart = DECODE_APART
        self.decode_halves = DECODE_HALVES
        self._spinning: bool | None = None  # `spinning`; None: the machine's load decides
        # the attentions of the sampler graph and of a transformer decoder as ONNX Runtime's
        # fused operator (onnx_attention.py)
        self.fuse_attention = FUSE_ATTENTION
        self.spin_big_graph = SPIN_BIG_GRAPH
        self.torch_glue_threads: int | None = TORCH_GLUE_THREADS  # None: torch's, untouched
        self._halves: DecoderHalves | None | bool = False  # False: not made yet
        self._single_decodes = 0  # decode() calls with one latent
        self._steps_only: dict[int, bytes] = {}  # step count -> its graph without the decoder
        self._onnx: bool | None = None  # is the onnx package there (None: not asked yet)
        self._tensors = tensors  # the torch networks of large batches are built from them
        self._torch_networks: tuple[Any, Any] | None = None
        super().__init__(meta, tensors, "cpu", "float32")
        self.clamp = latent_clamp(self.config)
        self._mean, self._std = self.mean.numpy(), self.std.numpy()  # float32, as the graph's

    def _networks(self, tensors: dict[str, Tensor]) -> tuple[OnnxDecoder, OnnxDenoiser]:
        return (OnnxDecoder(self.graphs.decoder, self.threads, self._decoder_heads()),
                OnnxDenoiser(self.graphs.denoiser, self.threads))

    def _large(self, batch: int) -> bool:
        return self.torch_min_batch is not None and batch >= self.torch_min_batch

    def networks_for(self, batch: int) -> tuple[Any, Any]:
        """The ONNX graphs, or for a batch of torch_min_batch or more the torch networks."""
        if not self._large(batch):
            return self.ae, self.denoiser
        if self._torch_networks is None:
            self._torch_networks = MotionGenerator._networks(self, self._tensors)
        return self._torch_networks

    @torch.inference_mode()
    def sample_latents(self, cond: Tensor, nfe: int | None = None,
                       seed: int | Sequence[int] | None = None, guidance: float | None = None
                       ) -> Tensor:
        """As the torch backend's, for a consistency model without its per-step torch glue:
        the noise and coefficients once (onnx_sampler.consistency_feeds), then, from the second
        call with a step count, the steps' graph in one call (_steps_session), before it one
        denoiser call and a few numpy operations per step. A large batch goes to the torch
        networks, on all `threads`."""
        if not isinstance(self.sampler, ConsistencySampler) or self._large(cond.shape[0]):
            with torch_threads(self.threads if self._large(cond.shape[0]) else None):
                return super().sample_latents(cond, nfe, seed, guidance)
        session = self._steps_session(self.check_nfe(nfe), cond.shape[0]) if self.fused else None
        return self._latents(session, cond, nfe, seed)

    def _latents(self, session: Any | None, cond: Tensor, nfe: int | None,
                 seed: int | Sequence[int] | None) -> Tensor:
        """x_0 of a consistency model by the steps' session, or by the step loop when None."""
        feeds = self._feeds(cond, nfe, seed)
        text = _array(cond.float())
        if session is None:
            return torch.from_numpy(run_steps(self.denoiser.session, feeds, text, self.clamp))
        (latent,) = session.run(["latent"], {"x": feeds["x"], "noise": feeds["noise"],
                                             "text": text})
        return torch.from_numpy(latent)

    def sample_features(self, cond: Tensor, nfe: int | None, seed: int | Sequence[int] | None,
                        guidance: float | None, lengths: Sequence[int]) -> list[np.ndarray]:
        """Sampling and decoding in one ONNX Runtime call: the sampler graph of this step count
        (onnx_sampler.py), built in memory at the second call with it (one-off commands never
        pay the build, a server or a batch loop does once) when `fused` and the onnx package is
        installed; otherwise sample_latents, then the decoder."""
        chosen = (self._sampler_session(self.check_nfe(nfe), cond.shape[0])
                  if self.fused and not self._large(cond.shape[0]) else None)
        if chosen is None and isinstance(self.sampler, ConsistencySampler) \
                and not self._large(cond.shape[0]):  # the step loop (this call is counted)
            return self.decode(self._latents(None, cond, nfe, seed), lengths)
        if chosen is None:
            return super().sample_features(cond, nfe, seed, guidance, lengths)
        session, apart = chosen
        feeds = self._feeds(cond, nfe, seed)
        feeds["text"] = _array(cond.float())
        feeds["valid"] = np.arange(max(lengths)) < np.array(lengths)[:, None]  # (B, T)
        if not apart:
            # times and coef are the graph's own constants
            (features,) = session.run(["features"], {k: feeds[k] for k in INPUTS
                                                      if k not in COEFFICIENTS})
        else:  # the steps on one thread, then the decoder on all (the graph's own arithmetic)
            (latent,) = session.run(["latent"], {k: feeds[k] for k in ("x", "noise", "text")})
            features = self._decoded(latent, feeds["valid"])
        return [features[i, :n] for i, n in enumerate(lengths)]

    def _decoded(self, latent: np.ndarray, valid: np.ndarray) -> np.ndarray:
        """Features in real units (B, T, D) of sampled latents (B, n, d) by the decoder's
        session: a single latent's by its halves side by side, one core each, whose join
        undoes the normalization (onnx_decoder_halves.py)."""
        latent = latent / np.float32(self.config.schedule.latent_scale)
        halves = self._decoder_halves() if latent.shape[0] == 1 else None
        if halves is not None:
            return halves(latent, valid)
        (inputs, outputs) = DECODER_IO
        (normalized,) = self.ae.session.run(list(outputs), dict(zip(inputs, (latent, valid))))
        return normalized * self._std + self._mean

    def _feeds(self, cond: Tensor, nfe: int | None, seed: int | Sequence[int] | None
               ) -> dict[str, np.ndarray]:
        shape = (cond.shape[0], *self.ae.latent_shape)
        steps = self.check_nfe(nfe)
        return consistency_feeds(self.sampler, shape, generators_for(seed), steps,
                                 self._step_coefficients(steps))

    def _step_coefficients(self, steps: int) -> dict[str, np.ndarray]:
        """step_coefficients of this step count, computed once."""
        if steps not in self._coefficients:
            self._coefficients[steps] = step_coefficients(self.sampler, steps)
        return self._coefficients[steps]

    def _sampler_session(self, steps: int, batch: int) -> tuple[Any, bool] | None:
        """The sampler graph's session for `steps` steps at this batch size, and whether it
        leaves the decoding to the decoder's session (DECODE_APART); or None: not a
        consistency model, the first call with this step count, MAX_SAMPLER_GRAPHS built
        already, or no onnx package to build the graph with. A small batch of a small graph
        runs on one thread, anything else on `threads`."""
        if not isinstance(self.sampler, ConsistencySampler):
            return None
        self._calls[steps] = self._calls.get(steps, 0) + 1
        built = sum(graph is not None for graph in self._fused.values())
        if steps not in self._fused and self._calls[steps] >= 2 and built < MAX_SAMPLER_GRAPHS:
            if not self._has_onnx():  # the graph is assembled with the onnx package
                self._fused[steps] = None
                return None
            self._fused[steps] = self._sampler_graph(steps, with_decoder=True)
        graph = self._fused.get(steps)
        if graph is None:
            return None
        small = batch <= ONE_THREAD_MAX_BATCH and len(graph) <= ONE_THREAD_MAX_BYTES
        if small and self.decode_apart and self.threads > 1:
            if steps not in self._steps_only:
                self._steps_only[steps] = self._sampler_graph(steps, with_decoder=False)
            return self._steps_graph_session(steps, batch), True
        threads = 1 if small else self.threads
        # batch 1 of a graph too big for one thread (paper size) spins within the run while the
        # machine is idle, as the small graph's steps do (SPIN_BIG_GRAPH)
        spin = batch == 1 and threads > 1 and self.spin_big_graph and self._spin(threads)
        key = (steps, threads, batch == 1, False, spin)
        if key not in self._sessions:
            # batch 1, the size a person waits on, gets a graph of fixed shapes (fewer operators)
            # (not spinning: onnx_io.session decides by the machine's size)
            self._sessions[key] = session_from_bytes(fixed_batch(graph, 1) if batch == 1
                                                     else graph, threads, spin or None)
        return self._sessions[key], False

    def _steps_session(self, steps: int, batch: int) -> Any | None:
        """The session of the steps alone (the sampler graph without the decoder) for
        sample_latents: the best-of-N candidates of generate() (batch N a prompt), guidance,
        the latents a caller decodes itself. Built at the second call with this step count, as
        the sampler graph is, and only for a graph of at most ONE_THREAD_MAX_BYTES (a
        paper-size one keeps the step loop rather than another copy of its weights). None
        otherwise: then the step loop runs (run_steps), the same arithmetic. Batch 1 runs as
        sample_features' steps do; a larger batch on `threads` threads, spinning within the run
        while the machine is idle (onnx_io.spin_now; both kinds are small)."""
        self._calls[steps] = self._calls.get(steps, 0) + 1
        if steps not in self._steps_only:
            if self._calls[steps] < 2 or len(self._steps_only) >= MAX_SAMPLER_GRAPHS:
                return None
            if not self._has_onnx():
                return None
            self._steps_only[steps] = self._sampler_graph(steps, with_decoder=False)
        if len(self._steps_only[steps]) > ONE_THREAD_MAX_BYTES:
            return None
        return self._steps_graph_session(steps, batch)

    def _steps_graph_session(self, steps: int, batch: int) -> Any:
        """The session of the built steps-only graph at this batch size: batch 1 on one thread,
        or on two spinning within the run (_spinning_steps); a larger batch on `threads`,
        spinning while the machine is idle (onnx_io.spin_now) unless `spinning_steps` says."""
        if batch == 1:
            spin = self.threads > 1 and self._spinning_steps()
            threads = 2 if spin else 1
        else:
            threads = self.threads
            spin = threads > 1 and self._spin(threads)
        key = (steps, threads, batch == 1, True, spin)
        if key not in self._sessions:
            graph = self._steps_only[steps]
            # batch 1, the size a person waits on, gets a graph of fixed shapes (fewer operators)
            self._sessions[key] = session_from_bytes(fixed_batch(graph, 1) if batch == 1
                                                     else graph, threads, spin)
        return self._sessions[key]

    def decode(self, z: Tensor, lengths: Sequence[int]) -> list[np.ndarray]:
        """As the torch backend's; a single latent, from the second one on, through the
        decoder's halves side by side (onnx_decoder_halves.py), as sample_features decodes one:
        generate()'s chosen candidate. (Cutting the halves takes ~70 ms: a one-off command's
        single decode keeps the whole decoder.)"""
        if z.shape[0] == 1:
            self._single_decodes += 1
        if z.shape[0] != 1 or self._single_decodes < 2 or self._decoder_halves() is None:
            with torch_threads(self.threads if self._large(z.shape[0]) else None):
                return super().decode(z, lengths)
        valid = np.arange(max(lengths)) < np.array(lengths)[:, None]
        features = self._decoded(_array(z.float()), valid)
        return [features[i, :n] for i, n in enumerate(lengths)]

    @property
    def spinning(self) -> bool | None:
        """Whether the steps' and the text encoder's threads spin within their runs: None (the
        default) while the machine is idle (onnx_io.spin_now), or forced either way. A server
        sets False while requests overlap (serve/batcher.py): its own threads then work beside
        the model's, which the load meter, counting other processes, does not see."""
        return self._spinning

    @spinning.setter
    def spinning(self, value: bool | None) -> None:
        self._spinning = value
        if self._text_encoder is not None and hasattr(self._text_encoder, "spinning"):
            self._text_encoder.spinning = value

    # the older name (benches and tests force the steps' choice by it): the same one value,
    # so that the text encoder never keeps a choice the steps no longer make
    spinning_steps = spinning

    def _spinning_steps(self) -> bool:
        """Do batch 1's steps run on two threads that spin within the run (`spinning_steps`;
        None: when `threads` >= 2 and the machine has two idle logical CPUs for them now,
        onnx_io.spin_now)? Asked at every call: both sessions are small."""
        return self.threads >= 2 and self._spin(2)

    def _spin(self, threads: int) -> bool:
        """Do `threads` threads spin within this run: as `spinning_steps` says, or (None) while
        the machine has idle logical CPUs for them (onnx_io.spin_now)?"""
        return self._spinning if self._spinning is not None else spin_now(threads)

    def _decoder_halves(self) -> DecoderHalves | None:
        """The decoder cut in its two halves (onnx_decoder_halves.py), made on first use; None
        without an arm pair, without the onnx package, or with `decode_halves` off."""
        if not self.decode_halves:
            return None
        if self._halves is False:
            self._halves = DecoderHalves.of(self.graphs.decoder, self._mean, self._std)
        return self._halves

    def _has_onnx(self) -> bool:
        """Is the onnx package there, asked once per generator (Python does not remember a
        failed import, and the candidates' path asks at every call)?"""
        if self._onnx is None:
            self._onnx = _onnx_installed()
        return self._onnx

    def _decoder_heads(self) -> int | None:
        """The transformer decoder's head count, for its fused attention; None: a convolutional
        decoder (no attention) or `fuse_attention` off."""
        ae = self.config.ae
        return ae.heads if self.fuse_attention and ae.architecture == "transformer" else None

    def _sampler_graph(self, steps: int, with_decoder: bool) -> bytes:
        """onnx_sampler.sampler_model of this model and step count, serialized."""
        return sampler_model(self.graphs.denoiser,
                             self.graphs.decoder if with_decoder else None, steps,
                             clamp=self.clamp, latent_scale=self.config.schedule.latent_scale,
                             mean=self._mean, std=self._std,
                             coefficients=self._step_coefficients(steps),
                             attention_heads=self.config.denoiser.heads
                             if self.fuse_attention else None,
                             decoder_heads=self._decoder_heads()).SerializeToString()

    def generate(self, *args: Any, **kwargs: Any) -> Any:
        """MotionGenerator.generate, its torch work on TORCH_GLUE_THREADS threads (the torch
        networks of a large batch on `threads`)."""
        with torch_glue(self.torch_glue_threads):
            return super().generate(*args, **kwargs)

    @property
    def text_encoder(self) -> TextEncoder:
        """text_encoder.onnx with the MiniLM tokenizer, loaded on first use."""
        if self._text_encoder is None:
            from mlct.text.minilm_onnx import OnnxMiniLMEncoder

            self._text_encoder = OnnxMiniLMEncoder(self.graphs.text_encoder,
                                                   self.meta["text_encoder"], self.threads)
            self._text_encoder.spinning = self._spinning
        return self._text_encoder

    @classmethod
    def load(cls, path: str | os.PathLike, device: torch.device | str | None = None,
             dtype: str | torch.dtype = "float32", threads: int | None = None,
             graphs: str | os.PathLike | None = None) -> OnnxMotionGenerator:
        """graphs: the folder of the ONNX graphs (default: path/onnx)."""
        onnxruntime_module()  # its absence first: the fix for it comes before converting
        meta, tensors = read_bundle(path)
        return cls(meta, tensors, read_onnx(path, meta["text_encoder"], graphs), device, dtype,
                   threads)


def check_device_and_dtype(device: torch.device | str | None, dtype: str | torch.dtype) -> None:
    """A one-line MlctError unless the onnx backends can run there: the CPU, float32 (said
    before any graph is made into the cache: backends.py)."""
    if device is not None and resolve_device(device).type != "cpu":
        raise MlctError(f"the onnx backend runs on the CPU, not {device!r}; use "
                        f"backend='torch' (--backend torch) for a GPU")
    try:
        float32 = weight_dtype(dtype) == torch.float32
    except ValueError as err:
        raise MlctError(str(err)) from None
    if not float32:
        raise MlctError(f"the onnx backend runs float32 graphs; dtype {dtype!r} is the "
                        f"torch backend's (--backend torch)")


def _onnx_installed() -> bool:
    """Is the onnx package there (the sampler graphs are assembled with it)?"""
    try:
        import onnx  # noqa: F401
    except ImportError:
        return False
    return True


_GLUE_LOCK = threading.Lock()
_glue = {"active": 0, "saved": 0}  # generate() calls inside torch_glue, torch's count before


@contextmanager
def torch_glue(count: int | None) -> Iterator[None]:
    """Torch on `count` threads while any generate() of the onnx backend runs (None: as it is);
    the first to enter saves torch's count and the last to leave puts it back, so calls from
    several threads at once leave it as they found it. The count is the process's: torch work
    of another thread during a generate() runs on `count` threads too."""
    if count is None:
        yield
        return
    with _GLUE_LOCK:
        if _glue["active"] == 0:
            _glue["saved"] = torch.get_num_threads()
            torch.set_num_threads(count)
        _glue["active"] += 1
    try:
        yield
    finally:
        with _GLUE_LOCK:
            _glue["active"] -= 1
            if _glue["active"] == 0:
                torch.set_num_threads(_glue["saved"])


@contextmanager
def torch_threads(count: int | None) -> Iterator[None]:
    """torch.set_num_threads(count) for the block, then back as it was; None: as it is."""
    before = torch.get_num_threads()
    if count is None or count == before:
        yield
        return
    torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(before)
