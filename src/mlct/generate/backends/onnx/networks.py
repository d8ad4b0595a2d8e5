"""The onnx backend: a model's networks run by ONNX Runtime on the CPU.

    gen = mlct.load("MODEL_DIR", backend="onnx")  # after `mlct convert MODEL_DIR --onnx`

Only the three networks change (bundle.py's graphs); everything around them is the core's and
the composer's: prompts, lengths, seeds, the sampler objects with their time grids, clamps and
noise (torch.Generator's draws, made in numpy: diffusion/torch_randn.py), latent_scale,
denormalization, joints. So the same seed gives the same motion, up to float rounding
(tests/test_onnx.py: joints within 1 mm). Batches below TORCH_MIN_BATCH are numpy around ONNX
Runtime and import no torch (the bundled model's graphs and step coefficients ship with it);
torch runs the large batches, other samplers and the controls' guidance, where installed.
The sampling of a consistency model is numpy around ONNX Runtime calls (sampler.py's feeds
and step loop, or one sampler graph); a batch of TORCH_MIN_BATCH or more goes to the torch
networks, and a sampler other than the consistency one runs its torch loop over the graphs.

Choices measured once and fixed (docs/performance.md, bench/paired_speed.py): the steps of a
small batch apart from the decoder, on one thread; a single latent decoded by its two halves
side by side; the attentions as ONNX Runtime's fused operator; batch 1 of a big sampler graph
spinning within the run while the machine is idle; the torch work around the graphs on one
thread (the constants below say why).
"""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path
import threading
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, Iterator, Sequence

import numpy as np

from mlct.config_view import latent_clamp
from mlct.errors import MlctError, require_torch
from mlct.generate.backends.base import Networks
from mlct.generate.backends.onnx.attention import fuse_attention
from mlct.generate.backends.onnx.bundle import DECODER_IO, DENOISER_IO, OnnxGraphs
from mlct.generate.backends.onnx.decoder_halves import DecoderHalves
from mlct.generate.backends.onnx.sampler import (COEFFICIENTS, INPUTS, STEPS_TABLE,
                                                 consistency_feeds, fixed_batch,
                                                 read_steps_table, run_steps, sampler_model,
                                                 step_coefficients)
from mlct.generate.samplers import ConsistencySampler
from mlct.generate.seeds import numpy_generators
from mlct.onnx_io import default_threads, session, session_from_bytes, spin_now

if TYPE_CHECKING:
    import torch
    from torch import Tensor

    from mlct.generate.backends.pytorch import TorchNetworks


def _array(x: Any) -> np.ndarray:
    """A float32 array or tensor as the contiguous array ONNX Runtime takes (no copy when it
    already is one)."""
    if isinstance(x, np.ndarray):
        return np.ascontiguousarray(x, dtype=np.float32)
    return np.ascontiguousarray(x.detach().float().cpu().numpy())


def _tensor(x: Any) -> Any:
    """An array as a torch tensor (for the torch paths); a tensor or None as it is."""
    if isinstance(x, np.ndarray):
        import torch

        return torch.from_numpy(x)
    return x


def _like(array: np.ndarray, given: Any) -> Any:
    """The result of a call as its input came: an array for an array (the core's, on this
    backend), a tensor for a tensor (a caller of the torch API: eval, controls, tests)."""
    return array if isinstance(given, np.ndarray) else _tensor(array)


def sample_loop(*args: Any, **kwargs: Any) -> Any:
    """backends/pytorch.py's sample_loop, imported when first called (it needs torch)."""
    from mlct.generate.backends.pytorch import sample_loop as loop

    return loop(*args, **kwargs)


class OnnxDenoiser:
    """F(x_t, t, c) of denoiser.onnx, called as the samplers call the torch network."""

    def __init__(self, graph: os.PathLike, threads: int | None = None) -> None:
        self.session = session(graph, threads)

    def __call__(self, x_t: Tensor, t: Tensor, text_emb: Tensor) -> Tensor:
        """x_t (B, n, d), t (B,) or a scalar, text_emb (B, c) -> F (B, n, d), float32."""
        import torch

        t = torch.as_tensor(t, dtype=torch.float32).reshape(-1).expand(x_t.shape[0])
        (inputs, outputs) = DENOISER_IO
        (f,) = self.session.run(list(outputs), dict(zip(inputs, map(_array, (
            x_t.float(), t, text_emb.float())))))
        return torch.from_numpy(f)


class OnnxDecoder:
    """The AE decoder of decoder.onnx, called as the pipeline calls the torch one.
    attention_heads: a transformer decoder's head count; given (and the onnx package there),
    its attentions run as ONNX Runtime's fused operator, mask and all (backends/onnx/attention.py)."""

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
        import torch

        from mlct.nn.masks import lengths_to_mask

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
# rounding (tests/test_onnx_sampler.py).
TORCH_MIN_BATCH = 32
# A batch that runs its sampler graph on one thread (above) runs the steps alone there and the
# decoder in its own session on all `threads`: the steps' products on 4 tokens lose to a second
# thread's wake-ups, the decoder's convolutions over up to 200 frames gain from it: warm 5.44
# -> 5.29 ms paired (5 NFE, 196 frames, 2 threads; bench/paired_speed.py :one-graph). Alone, the
# decoder on two threads took 2.15 against 2.68 ms; in the pipeline the gain is smaller, as its
# weights come back to the cache after the steps (docs/performance.md).
# ... and a decoder with an arm pair runs its two halves side by side, one core each
# (backends/onnx/decoder_halves.py): the bundled model's warm call 4.02 ms against 4.34 with the decoder
# as one session on two threads and 4.29 with the one-thread graph of steps and decoder (5 NFE,
# 196 frames, paired; bench/paired_speed.py :one-decoder, :one-graph).
# The sampler graph's denoiser attentions as ONNX Runtime's fused Attention operator
# (backends/onnx/attention.py): per step ~60 standard operators per block become one, the warm batch-1
# call 0.93x (paired, bench/paired_speed.py :unfused-attention). The same for a transformer
# decoder's attentions, with their padding mask, in its session and the sampler graph, and for
# the int8 denoiser's (MultiHeadAttention after the int8 q/k/v product): the paper-size model's
# warm call 0.90x in float32, 0.91x with --int8 (paired, :unfused-attention).
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




class OnnxNetworks(Networks):
    """The text encoder, denoiser and decoder of a model as ONNX graphs (CPU, float32).

    threads: ONNX Runtime's intra-op threads per graph; None: torch.get_num_threads() when
    loaded. The torch work around the graphs in generate() (the critic, the joints, the feet:
    small tensors) runs on one torch thread, so that no OpenMP thread of torch's spins on a
    core the graphs' threads want (TORCH_GLUE_THREADS, `running`)."""

    name = "onnx"
    numpy = True

    def __init__(self, meta: dict, tensors: dict[str, Any], graphs: OnnxGraphs,
                 threads: int | None = None) -> None:
        super().__init__(meta, "cpu")
        self.graphs, self.threads = graphs, int(threads or default_threads())
        # float32, as the graph's; tensors are numpy arrays (bundle.read_bundle(numpy=True))
        # or torch tensors
        self._mean, self._std = _array(tensors["norm.mean"]), _array(tensors["norm.std"])
        self.clamp = latent_clamp(self.config)
        self.decoder = OnnxDecoder(graphs.decoder, self.threads, self._decoder_heads())
        self.denoiser = OnnxDenoiser(graphs.denoiser, self.threads)
        self.graph_sessions = SamplerGraphs(self)
        self._spinning: bool | None = None  # `spinning`; None: the machine's load decides
        self._halves: DecoderHalves | None | bool = False  # False: not made yet
        self._single_decodes = 0  # decode() calls with one latent
        self._tensors = tensors  # the torch networks of large batches are built from them
        self._torch: TorchNetworks | None = None

    def resolve_device(self, device: Any) -> Any:
        return "cpu"  # the CPU, said without torch (mlct.load checks the device asked for)

    @property
    def dtype(self) -> Any:
        """The graphs' products' precision: torch.float32."""
        import torch

        return torch.float32

    @property
    def mean(self) -> Tensor:
        """The feature mean as a tensor, for the torch networks of a large batch."""
        return _tensor(self._mean)

    @property
    def std(self) -> Tensor:
        return _tensor(self._std)

    def critic_graph(self) -> Any:
        """The graphs' critic.onnx when they have one made from the model's critic.safetensors
        (the shipped graphs: onnx_assets.py), else None."""
        name = (self.graphs.manifest.get("graphs") or {}).get("critic")
        if not name or not self.meta.get("model_dir"):
            return None
        from mlct.shipped import CRITIC_WEIGHTS, file_digest

        weights = Path(self.meta["model_dir"]) / "critic.safetensors"
        graph = Path(self.graphs.denoiser).parent / name
        if not (graph.is_file() and weights.is_file()
                and (self.graphs.shipped  # (the tests check the package's digests)
                     or self.graphs.manifest.get(CRITIC_WEIGHTS) == file_digest(weights))):
            return None
        return graph

    def text_encoder(self) -> Any:
        """text_encoder.onnx with the MiniLM tokenizer, loaded on first use."""
        if self._text_encoder is None:
            from mlct.text.minilm_onnx import OnnxMiniLMEncoder

            self._text_encoder = OnnxMiniLMEncoder(self.graphs.text_encoder,
                                                   self.meta["text_encoder"], self.threads)
            self._text_encoder.spinning = self._spinning
        return self._text_encoder

    def running(self) -> Any:
        """generate()'s torch work on TORCH_GLUE_THREADS threads (the torch networks of a
        large batch on `threads`)."""
        return torch_glue(TORCH_GLUE_THREADS)

    @property
    def torch_min_batch(self) -> int | None:
        """The smallest batch the torch networks run (TORCH_MIN_BATCH; `mlct generate -v`);
        None without torch: every batch runs on the graphs."""
        return TORCH_MIN_BATCH if _torch_installed() else None

    def large(self, batch: int) -> bool:
        """Does a batch this size go to the torch networks (TORCH_MIN_BATCH, where torch is
        installed)?"""
        return batch >= TORCH_MIN_BATCH and _torch_installed()

    def torch_networks(self) -> TorchNetworks:
        """The torch networks of large batches, built from the same weights on first use."""
        if self._torch is None:
            from mlct.generate.backends.pytorch import TorchNetworks

            tensors = {k: _tensor(v) for k, v in self._tensors.items()}
            self._torch = TorchNetworks(self.meta, tensors, "cpu", "float32")
        return self._torch

    def _networks_for(self, batch: int) -> tuple[Any, Any]:
        """(decoder, denoiser): the ONNX graphs, or for a large batch the torch networks."""
        if not self.large(batch):
            return self.decoder, self.denoiser
        nets = self.torch_networks()
        return nets.decoder, nets.denoiser

    def latents(self, cond: Any, steps: int, seed: int | Sequence[int] | None,
                guidance: float | None, uncond: Any) -> Any:
        """A consistency model's latents without per-step torch glue: the noise and
        coefficients once (sampler.consistency_feeds), then, from the second call with a step
        count, the steps' graph in one call (SamplerGraphs.steps), before it one denoiser call
        and a few numpy operations per step. A large batch goes to the torch networks, on all
        `threads`; another sampler runs its own loop over the graphs. Latents as a numpy array
        (B, n, d), or a tensor from the torch paths."""
        large = self.large(cond.shape[0])
        if not isinstance(self.sampler, ConsistencySampler) or large:
            require_torch(f"the {self.meta['sampler']} sampler on the onnx backend")
            import torch

            with torch_threads(self.threads if large else None), torch.inference_mode():
                return sample_loop(self.sampler, self._networks_for(cond.shape[0])[1],
                                   self.decoder.latent_shape, _tensor(cond), steps, seed,
                                   guidance, _tensor(uncond))
        return _like(self._latents(self.graph_sessions.steps(steps, cond.shape[0]), cond, steps,
                                   seed), cond)

    def _latents(self, session: Any | None, cond: Any, steps: int,
                 seed: int | Sequence[int] | None) -> np.ndarray:
        """x_0 of a consistency model by the steps' session, or by the step loop when None."""
        feeds = self._feeds(cond, steps, seed)
        text = _array(cond)
        if session is None:
            return run_steps(self.denoiser.session, feeds, text, self.clamp)
        (latent,) = session.run(["latent"], {"x": feeds["x"], "noise": feeds["noise"],
                                             "text": text})
        return latent

    def features(self, cond: Tensor, steps: int, seed: int | Sequence[int] | None,
                 guidance: float | None, uncond: Tensor | None, lengths: Sequence[int]
                 ) -> list[np.ndarray]:
        """Sampling and decoding in one ONNX Runtime call: the sampler graph of this step count
        (sampler.py), built in memory at the second call with it (one-off commands never pay
        the build, a server or a batch loop does once) when the onnx package is installed;
        otherwise the latents, then the decoder."""
        large = self.large(cond.shape[0])
        chosen = None if large else self.graph_sessions.sampler(steps, cond.shape[0])
        if chosen is None and isinstance(self.sampler, ConsistencySampler) and not large:
            # the step loop (this call is counted)
            return self.decode(self._latents(None, cond, steps, seed), lengths)
        if chosen is None:
            return self.decode(self.latents(cond, steps, seed, guidance, uncond), lengths)
        session, apart = chosen
        feeds = self._feeds(cond, steps, seed)
        feeds["text"] = _array(cond)
        feeds["valid"] = np.arange(max(lengths)) < np.array(lengths)[:, None]  # (B, T)
        if not apart:
            # times and coef are the graph's own constants
            (features,) = session.run(["features"], {k: feeds[k] for k in INPUTS
                                                      if k not in COEFFICIENTS})
        else:  # the steps on one thread, then the decoder on all (the graph's own arithmetic)
            (latent,) = session.run(["latent"], {k: feeds[k] for k in ("x", "noise", "text")})
            features = self._decoded(latent, feeds["valid"])
        return [features[i, :n] for i, n in enumerate(lengths)]

    def _decoded(self, latent: np.ndarray, valid: np.ndarray, halves: bool = True
                 ) -> np.ndarray:
        """Features in real units (B, T, D) of sampled latents (B, n, d) by the decoder's
        session: a single latent's by its halves side by side, one core each, whose join
        undoes the normalization (decoder_halves.py)."""
        latent = latent / np.float32(self.config.schedule.latent_scale)
        cut = self._decoder_halves() if halves and latent.shape[0] == 1 else None
        if cut is not None:  # side by side where a second core is idle, else one after the other
            return cut(latent, valid, side_by_side=self.spin(2))
        (inputs, outputs) = DECODER_IO
        (normalized,) = self.decoder.session.run(list(outputs),
                                                 dict(zip(inputs, (latent, valid))))
        return normalized * self._std + self._mean

    def _feeds(self, cond: Any, steps: int, seed: int | Sequence[int] | None
               ) -> dict[str, np.ndarray]:
        shape = (cond.shape[0], *self.decoder.latent_shape)
        return consistency_feeds(self.sampler, shape, numpy_generators(seed), steps,
                                 self.graph_sessions.coefficients(steps))

    def decode(self, z: Any, lengths: Sequence[int]) -> list[np.ndarray]:
        """The decoder's; a single latent, from the second one on, through the decoder's
        halves side by side (decoder_halves.py), as `features` decodes one: generate()'s
        chosen candidate. (Cutting the halves takes ~70 ms: a one-off command's single
        decode keeps the whole decoder.)"""
        if z.shape[0] == 1:
            self._single_decodes += 1
        if self.large(z.shape[0]):
            import torch

            from mlct.generate.backends.pytorch import decode_with

            with torch_threads(self.threads), torch.inference_mode():
                return decode_with(self._networks_for(z.shape[0])[0], _tensor(z), lengths,
                                   self.config, self.mean, self.std, self.device)
        valid = np.arange(max(lengths)) < np.array(lengths)[:, None]
        halves = z.shape[0] == 1 and self._single_decodes >= 2
        features = self._decoded(_array(z), valid, halves)
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

    def spin(self, threads: int) -> bool:
        """Do `threads` threads spin within this run: as `spinning` says, or (None) while
        the machine has idle logical CPUs for them (onnx_io.spin_now)?"""
        return self._spinning if self._spinning is not None else spin_now(threads)

    def _decoder_halves(self) -> DecoderHalves | None:
        """The decoder cut in its two halves (decoder_halves.py), made on first use; None
        without an arm pair or without the onnx package."""
        if self._halves is False:
            self._halves = DecoderHalves.of(self.graphs.decoder, self._mean, self._std)
        return self._halves

    def _decoder_heads(self) -> int | None:
        """The transformer decoder's head count, for its fused attention; None: a convolutional
        decoder (no attention)."""
        ae = self.config.ae
        return ae.heads if ae.architecture == "transformer" else None


class SamplerGraphs:
    """The sampler graphs of an OnnxNetworks (sampler.py: the step loop of one step count as
    one graph, with the decoder or without) and their sessions, built when first worth it."""

    def __init__(self, nets: OnnxNetworks) -> None:
        self.nets = nets
        self.fused: dict[int, Any] = {}  # step count -> its sampler graph (bytes, or None)
        # (step count, threads, batch 1, steps apart from the decoder, spinning) -> session
        self.sessions: dict[tuple[int, int, bool, bool, bool], Any] = {}
        self.calls: dict[int, int] = {}  # step count -> sampling calls with it
        self.steps_only: dict[int, bytes] = {}  # step count -> its graph without the decoder
        self._coefficients: dict[int, dict[str, np.ndarray]] = {}  # steps -> times, coef
        self._onnx: bool | None = None  # is the onnx package there (None: not asked yet)

    def coefficients(self, steps: int) -> dict[str, np.ndarray]:
        """step_coefficients of this step count, computed once, or read from the table the
        graphs carry (sampler.STEPS_TABLE: the bundled model's, made when they were)."""
        if steps not in self._coefficients:
            table = self.nets.graphs.text_encoder.parent / STEPS_TABLE
            found = read_steps_table(table, steps) if table.is_file() else None
            if found is None:
                require_torch("the step coefficients of a model whose graphs carry none")
                found = step_coefficients(self.nets.sampler, steps)
            self._coefficients[steps] = found
        return self._coefficients[steps]

    def sampler(self, steps: int, batch: int) -> tuple[Any, bool] | None:
        """The sampler graph's session for `steps` steps at this batch size, and whether it
        leaves the decoding to the decoder's session; or None: not a consistency model, the
        first call with this step count, MAX_SAMPLER_GRAPHS built already, or no onnx package
        to build the graph with. A small batch of a small graph runs its steps on one thread
        apart from the decoder (on all `threads`), anything else on `threads`."""
        nets = self.nets
        if not isinstance(nets.sampler, ConsistencySampler):
            return None
        self.calls[steps] = self.calls.get(steps, 0) + 1
        built = sum(graph is not None for graph in self.fused.values())
        if steps not in self.fused and self.calls[steps] >= 2 and built < MAX_SAMPLER_GRAPHS:
            if not self._has_onnx():  # the graph is assembled with the onnx package
                self.fused[steps] = None
                return None
            self.fused[steps] = self._graph(steps, with_decoder=True)
        graph = self.fused.get(steps)
        if graph is None:
            return None
        small = batch <= ONE_THREAD_MAX_BATCH and len(graph) <= ONE_THREAD_MAX_BYTES
        if small and nets.threads > 1:
            if steps not in self.steps_only:
                self.steps_only[steps] = self._graph(steps, with_decoder=False)
            return self._steps_session(steps, batch), True
        threads = 1 if small else nets.threads
        # batch 1 of a graph too big for one thread (paper size) spins within the run while the
        # machine is idle, as the small graph's steps do
        spin = batch == 1 and threads > 1 and nets.spin(threads)
        key = (steps, threads, batch == 1, False, spin)
        if key not in self.sessions:
            # batch 1, the size a person waits on, gets a graph of fixed shapes (fewer operators)
            # (not spinning: onnx_io.session decides by the machine's size)
            self.sessions[key] = session_from_bytes(fixed_batch(graph, 1) if batch == 1
                                                    else graph, threads, spin or None)
        return self.sessions[key], False

    def steps(self, steps: int, batch: int) -> Any | None:
        """The session of the steps alone (the sampler graph without the decoder) for
        latents: the best-of-N candidates of generate() (batch N a prompt), guidance, the
        latents a caller decodes itself. Built at the second call with this step count, as
        the sampler graph is, and only for a graph of at most ONE_THREAD_MAX_BYTES (a
        paper-size one keeps the step loop rather than another copy of its weights). None
        otherwise: then the step loop runs (run_steps), the same arithmetic."""
        self.calls[steps] = self.calls.get(steps, 0) + 1
        if steps not in self.steps_only:
            if self.calls[steps] < 2 or len(self.steps_only) >= MAX_SAMPLER_GRAPHS:
                return None
            if not self._has_onnx():
                return None
            self.steps_only[steps] = self._graph(steps, with_decoder=False)
        if len(self.steps_only[steps]) > ONE_THREAD_MAX_BYTES:
            return None
        return self._steps_session(steps, batch)

    def _steps_session(self, steps: int, batch: int) -> Any:
        """The session of the built steps-only graph at this batch size: batch 1 on one thread,
        or on two spinning within the run where two logical CPUs are idle; a larger batch on
        `threads`, spinning while the machine is idle (onnx_io.spin_now) unless `spinning`
        says."""
        nets = self.nets
        if batch == 1:
            spin = nets.threads > 1 and nets.spin(2)
            threads = 2 if spin else 1
        else:
            threads = nets.threads
            spin = threads > 1 and nets.spin(threads)
        key = (steps, threads, batch == 1, True, spin)
        if key not in self.sessions:
            graph = self.steps_only[steps]
            # batch 1, the size a person waits on, gets a graph of fixed shapes (fewer operators)
            self.sessions[key] = session_from_bytes(fixed_batch(graph, 1) if batch == 1
                                                    else graph, threads, spin)
        return self.sessions[key]

    def _has_onnx(self) -> bool:
        """Is the onnx package there, asked once (Python does not remember a failed import,
        and the candidates' path asks at every call)?"""
        if self._onnx is None:
            self._onnx = _onnx_installed()
        return self._onnx

    def _graph(self, steps: int, with_decoder: bool) -> bytes:
        """sampler.sampler_model of this model and step count, serialized."""
        nets = self.nets
        return sampler_model(nets.graphs.denoiser,
                             nets.graphs.decoder if with_decoder else None, steps,
                             clamp=nets.clamp, latent_scale=nets.config.schedule.latent_scale,
                             mean=nets._mean, std=nets._std,
                             coefficients=self.coefficients(steps),
                             attention_heads=nets.config.denoiser.heads,
                             decoder_heads=nets._decoder_heads()).SerializeToString()


def check_device_and_dtype(device: torch.device | str | None, dtype: str | torch.dtype) -> None:
    """A one-line MlctError unless the onnx backends can run there: the CPU, float32 (said
    before any graph is made into the cache: backends.py); "cpu" and "float32" are checked
    without torch."""
    if (device is None or (isinstance(device, str) and device.strip().lower() == "cpu")) and (
            dtype == "float32"):
        return
    require_torch(f"device {device!r} or dtype {dtype!r}")
    import torch

    from mlct.devices import resolve_device
    from mlct.nn.inference import weight_dtype

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


def _torch_installed() -> bool:
    """Can torch be imported (asked without importing it)?"""
    try:
        return "torch" in sys.modules or importlib.util.find_spec("torch") is not None
    except ImportError:  # a finder that refuses it
        return False


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
    torch = sys.modules.get("torch")
    if count is None or torch is None:  # torch not loaded: nothing of it runs (or spins)
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
    import torch

    before = torch.get_num_threads()
    if count is None or count == before:
        yield
        return
    torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(before)
