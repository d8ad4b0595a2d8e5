"""The consistency sampler without per-step overhead on the onnx backend.

Two ways, both fed by consistency_feeds (the noise and the per-step coefficients, computed by
the torch sampler's own functions and drawn from the same seeded generators in the same order,
so the motions are the torch backend's up to float rounding; tests/test_onnx_sampler.py):

- run_steps: one denoiser.onnx call per step and the update of Algorithm 2 in float32 numpy
  (any step count, nothing to build);
- sampler_model: the whole K-step sampler and the decoder as one ONNX graph, one ONNX Runtime
  call per batch. It is assembled in memory from denoiser.onnx and decoder.onnx (the onnx
  package; nothing is traced again): the denoiser's nodes once per step, unrolled, all of them
  reading one copy of its weights, then x0 / latent_scale through the decoder's nodes and the
  normalization undone:

    inputs  x (B, n, d)        x_T, the sampler's first noise
            noise (K, B, n, d) the re-noising noise after each step (the last one unused)
            text (B, c)        the condition
            times (K,)         the step times, T first
            coef (K, 4)        per step c_skip(t_k), c_out(t_k), alpha(t_k+1), sigma(t_k+1)
            valid (B, T) bool  the frames to decode
    outputs features (B, T, D) denormalized features; latent (B, n, d) the sampled x_0

  Unrolled rather than an ONNX Loop: with ONNX Runtime 1.32 the Loop ran the same steps
  ~1.4x slower than separate calls (its body's products were slower), the unrolled graph
  ~10% faster than them (docs/performance.md).
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from mlct.diffusion.torch_randn import TorchRandn
from mlct.generate.backends.onnx.attention import fuse_attention

if TYPE_CHECKING:
    from mlct.diffusion.samplers import Generators

INPUTS = ("x", "noise", "text", "times", "coef", "valid")
COEFFICIENTS = ("times", "coef")  # inputs, or constants when sampler_model gets them
OUTPUTS = ("features", "latent")


def sampler_model(denoiser: str | os.PathLike, decoder: str | os.PathLike | None, steps: int,
                  *, clamp: float | None, latent_scale: float, mean: np.ndarray, std: np.ndarray,
                  coefficients: dict[str, np.ndarray] | None = None,
                  attention_heads: int | None = None, decoder_heads: int | None = None) -> Any:
    """The sampler graph of `steps` steps (above), an onnx.ModelProto, from denoiser.onnx
    (x_t, t, text -> f) and decoder.onnx (latent, valid -> features); the clamp, latent_scale
    and the feature mean and std are the bundle's, baked in as constants. decoder None: the
    steps alone (inputs x, noise, text and the coefficients; output latent), for a caller that
    decodes in a session of its own (backends/onnx/networks.py: the decoder on more threads).

    coefficients: step_coefficients' times and coef, baked in as constants instead of inputs
    (they depend on the step count alone): ONNX Runtime then folds the denoiser's time terms
    (its sinusoid and time projections) into constants once, not per call.
    attention_heads: the denoiser's head count; given, its self-attentions become ONNX
    Runtime's fused Attention operator (backends/onnx/attention.py), a graph only ONNX Runtime runs.
    decoder_heads: the same for a transformer decoder's attentions, with their padding mask."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    den = onnx.load(str(denoiser))
    if attention_heads is not None:
        fuse_attention(den, attention_heads)
    f32 = TensorProto.FLOAT

    def const(name: str, value: np.ndarray) -> onnx.NodeProto:
        return helper.make_node("Constant", [], [name], value=numpy_helper.from_array(value, name))

    nodes = [const(name, np.asarray(value, np.float32))
             for name, value in (coefficients or {}).items()]
    nodes += [const("zero", np.array([0], np.int64)), const("one", np.array([1], np.int64)),
             helper.make_node("Shape", ["x"], ["shape"]),
             helper.make_node("Slice", ["shape", "zero", "one"], ["batch"])]  # (1,)
    if clamp is not None:
        nodes += [const("lo", np.array(-clamp, np.float32)),
                  const("hi", np.array(clamp, np.float32))]
    x = "x"
    for k in range(steps):  # unrolled: the denoiser's nodes once per step, its weights shared
        p = f"s{k}/"
        nodes += [const(p + "k", np.array(k, np.int64)),
                  helper.make_node("Gather", ["times", p + "k"], [p + "t"]),
                  helper.make_node("Expand", [p + "t", "batch"], [p + "t_b"]),
                  helper.make_node("Gather", ["coef", p + "k"], [p + "coef"])]
        nodes += _renamed(den.graph, p, {"x_t": x, "t": p + "t_b", "text": "text"},
                          shared={i.name: "den/" + i.name for i in den.graph.initializer})
        for j, name in enumerate(("skip", "out", "alpha", "sigma")):
            nodes += [const(f"{p}j{j}", np.array(j, np.int64)),
                      helper.make_node("Gather", [p + "coef", f"{p}j{j}"], [p + name])]
        x0 = "latent" if k == steps - 1 else p + "x0"
        nodes += [helper.make_node("Mul", [p + "skip", x], [p + "sx"]),
                  helper.make_node("Mul", [p + "out", p + den.graph.output[0].name], [p + "of"]),
                  helper.make_node("Add", [p + "sx", p + "of"],
                                   [p + "s" if clamp is not None else x0])]
        if clamp is not None:
            nodes.append(helper.make_node("Clip", [p + "s", "lo", "hi"], [x0]))
        if k + 1 < steps:  # re-noise to the next time
            nodes += [helper.make_node("Gather", ["noise", p + "k"], [p + "noise"]),
                      helper.make_node("Mul", [p + "alpha", x0], [p + "ax"]),
                      helper.make_node("Mul", [p + "sigma", p + "noise"], [p + "sn"]),
                      helper.make_node("Add", [p + "ax", p + "sn"], [p + "x"])]
            x = p + "x"
    latent = helper.make_tensor_value_info
    n, d = (int(v.dim_value) for v in den.graph.input[0].type.tensor_type.shape.dim[1:])
    c = int(den.graph.input[2].type.tensor_type.shape.dim[1].dim_value)
    inputs = [latent("x", f32, ["batch", n, d]), latent("noise", f32, ["steps", "batch", n, d]),
              latent("text", f32, ["batch", c]), latent("times", f32, ["steps"]),
              latent("coef", f32, ["steps", 4])]
    outputs = [latent("latent", f32, ["batch", n, d])]
    initializers = _renamed_initializers(den.graph, "den/")
    if decoder is not None:
        dec = onnx.load(str(decoder))
        if decoder_heads is not None:
            fuse_attention(dec, decoder_heads, padded=True)
        nodes += [const("latent_scale", np.array(latent_scale, np.float32)),
                  helper.make_node("Div", ["latent", "latent_scale"], ["ae_latent"])]
        nodes += _renamed(dec.graph, "dec/", {"latent": "ae_latent", "valid": "valid"})
        nodes += [const("std", np.asarray(std, np.float32)),
                  const("mean", np.asarray(mean, np.float32)),
                  helper.make_node("Mul", ["dec/" + dec.graph.output[0].name, "std"],
                                   ["scaled"]),
                  helper.make_node("Add", ["scaled", "mean"], ["features"])]
        inputs.append(latent("valid", TensorProto.BOOL, ["batch", "frames"]))
        feature_dim = int(np.asarray(mean).shape[-1])
        outputs.insert(0, latent("features", f32, ["batch", "frames", feature_dim]))
        initializers = _renamed_initializers(dec.graph, "dec/") + initializers
    graph = helper.make_graph(
        nodes, "mlct_sampler", [i for i in inputs if i.name not in (coefficients or {})],
        outputs, initializer=initializers)
    model = helper.make_model(graph, opset_imports=list(den.opset_import),
                              producer_name="mlct")
    model.ir_version = den.ir_version
    return model


def fixed_batch(model: bytes, batch: int) -> bytes:
    """The serialized sampler graph with its batch dimension fixed: with every shape known,
    ONNX Runtime folds the shape arithmetic of the attention's reshapes into constants (the
    batch-1 graph of the bundled model: ~1,500 -> ~1,000 operators after its optimizations)."""
    import onnx

    proto = onnx.ModelProto.FromString(model)
    for value in [*proto.graph.input, *proto.graph.output]:
        for dim in value.type.tensor_type.shape.dim:
            if dim.dim_param == "batch":
                dim.Clear()
                dim.dim_value = batch
    return proto.SerializeToString()


def _renamed(graph: object, prefix: str, inputs: dict[str, str],
             shared: dict[str, str] | None = None) -> list:
    """graph's nodes with every value name prefixed, except its inputs, which become
    inputs[name] (values of the enclosing graph)."""
    import copy

    def name(value: str) -> str:
        if not value:
            return value
        return inputs.get(value) or (shared or {}).get(value) or prefix + value

    out = []
    for i, node in enumerate(graph.node):  # type: ignore[attr-defined]
        node = copy.deepcopy(node)
        # a quantized graph leaves some nodes unnamed: names must be unique in the whole graph
        node.name = prefix + (node.name or f"node{i}")
        node.input[:] = [name(v) for v in node.input]
        node.output[:] = [name(v) for v in node.output]
        out.append(node)
    return out


def _renamed_initializers(graph: object, prefix: str) -> list:
    import copy

    out = []
    for tensor in graph.initializer:  # type: ignore[attr-defined]
        tensor = copy.deepcopy(tensor)
        tensor.name = prefix + tensor.name
        out.append(tensor)
    return out


def consistency_feeds(sampler: Any, shape: Sequence[int], generator: Generators, steps: int,
                      coefficients: dict[str, np.ndarray] | None = None
                      ) -> dict[str, np.ndarray]:
    """x, noise, times and coef (above) of a run of the ConsistencySampler `sampler`: its times,
    its coefficient functions, and the noise drawn as sample_latents and sample_consistency draw
    it (x_T, then one draw per re-noising, from the same generators in the same order).
    coefficients: step_coefficients(sampler, steps), when the caller kept them (they are the
    same for every call with this step count; computing them is ~30 torch operations)."""
    shape = tuple(shape)
    coefficients = coefficients or step_coefficients(sampler, steps)
    noise = np.zeros((steps, *shape), np.float32)
    if _numpy_stream(generator):  # seeds.numpy_generators: torch's draws, without torch
        draws = _draws(shape, generator, steps)  # x_T, then one per re-noising: (K, B, n, d)
        noise[:steps - 1] = draws[1:]
        return {"x": draws[0], "noise": noise, **coefficients}
    from mlct.diffusion.samplers import draw_noise

    x = sampler.noise(shape, generator)
    for k in range(1, steps):  # float32 on the CPU, as the times the torch sampler passes
        noise[k - 1] = draw_noise(shape, generator, x).numpy()
    return {"x": x.numpy(), "noise": noise, **coefficients}


def _numpy_stream(generator: Any) -> bool:
    return isinstance(generator, TorchRandn) or (
        isinstance(generator, list) and all(isinstance(g, TorchRandn) for g in generator))


def _draws(shape: tuple[int, ...], generator: TorchRandn | list[TorchRandn], count: int
           ) -> np.ndarray:
    """`count` successive N(0, I) draws of `shape`, (count, *shape), as draw_noise draws each:
    one stream for the batch, or one per item (whose draws follow one another in its own)."""
    if isinstance(generator, list):
        if len(generator) != shape[0]:
            raise ValueError(f"{len(generator)} generators for a batch of {shape[0]}")
        return np.stack([g.randn_many(shape[1:], count) for g in generator], axis=1)
    return generator.randn_many(shape, count)


def step_coefficients(sampler: Any, steps: int) -> dict[str, np.ndarray]:
    """times (K,) and coef (K, 4) of a `steps`-step run of the ConsistencySampler `sampler`
    (above): the same for every call with this step count. Torch computes them (the
    sampler's own functions); the shipped graphs carry them for every step count
    (STEPS_TABLE), so that the bundled model samples without torch."""
    import torch

    from mlct.diffusion.consistency import c_out, c_skip

    times = sampler.times(steps)
    zero = times.new_zeros(1)
    nxt = times[1:]
    coef = torch.stack([c_skip(times, sampler.eta, sampler.time_scale),
                        c_out(times, sampler.eta, sampler.time_scale),
                        torch.cat([sampler.schedule.alpha(nxt), zero]),
                        torch.cat([sampler.schedule.sigma(nxt), zero])], dim=1)
    return {"times": times.float().numpy(), "coef": coef.float().numpy()}


STEPS_TABLE = "consistency_steps.npz"  # beside the graphs: times_K, coef_K for each K


def write_steps_table(sampler: Any, path: str | os.PathLike) -> None:
    """step_coefficients of every step count the sampler takes, into one .npz file."""
    table = {}
    for steps in range(1, sampler.max_steps + 1):
        found = step_coefficients(sampler, steps)
        table[f"times_{steps}"], table[f"coef_{steps}"] = found["times"], found["coef"]
    np.savez(path, **table)


def read_steps_table(path: str | os.PathLike, steps: int) -> dict[str, np.ndarray] | None:
    """write_steps_table's coefficients of this step count; None where it has none."""
    with np.load(path) as table:
        if f"times_{steps}" not in table:
            return None
        return {"times": table[f"times_{steps}"], "coef": table[f"coef_{steps}"]}


def run_steps(denoiser: Any, feeds: dict[str, np.ndarray], text: np.ndarray,
              clamp: float | None) -> np.ndarray:
    """The sampler graph's loop on the host, one denoiser.onnx call per step (any step count,
    no graph to build): the same arithmetic in float32 numpy. Returns x_0 (B, n, d)."""
    x, coef = feeds["x"], feeds["coef"]
    batch = np.ones(x.shape[0], np.float32)
    x0 = x
    for k, t in enumerate(feeds["times"]):
        (f,) = denoiser.run(["f"], {"x_t": x, "t": batch * t, "text": text})
        skip, out, alpha, sigma = coef[k]
        x0 = skip * x + out * f
        if clamp is not None:
            x0 = np.clip(x0, -clamp, clamp)
        if k + 1 < len(coef):
            x = alpha * x0 + sigma * feeds["noise"][k]
    return x0
