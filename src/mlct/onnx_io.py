"""ONNX graphs in and out: torch modules written as ONNX files, ONNX Runtime sessions read from
them. The one place torch.onnx and onnxruntime are called.

Writing uses torch.onnx's TorchScript exporter (``dynamo=False``). Why not torch 2.13's default
(torch.export-based) exporter: it needs onnxscript, another dependency, to write graphs that this
one writes with torch alone; the modules exported here are straight-line tensor code (no data-
dependent control flow), which tracing records exactly, and sizes read from an input's shape
stay symbolic along the axes named dynamic. Torch deprecates this exporter; its warning is
silenced here, in the one call.

Writing needs torch and the `onnx` package (torch.onnx serializes with it): the `[train]`
extra; running needs `onnxruntime` alone, a dependency of every install, and imports no torch
(a graph whose large weights live in a safetensors file beside it, as the shipped MiniLM's do,
is read with numpy: external_weights). Each function reports a missing library in one line.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Sequence

from mlct.errors import MlctError, first_line, require_torch

if TYPE_CHECKING:
    import onnxruntime
    import torch
    from torch import nn

OPSET = 17  # LayerNormalization is one operator from opset 17 (ONNX Runtime >= 1.14)
INSTALL = "pip install onnxruntime==1.32.0 onnx==1.23.2 (both come with every mlct install)"


def default_threads() -> int:
    """The intra-op threads when none are asked for: torch's count where torch is loaded (one
    knob, torch.set_num_threads, sets both backends alike), else what torch would take
    without importing it: $OMP_NUM_THREADS, else one per core this process may run on."""
    if "torch" in sys.modules:
        return int(sys.modules["torch"].get_num_threads())
    try:
        return max(1, int(os.environ.get("OMP_NUM_THREADS", "")))
    except ValueError:
        pass
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def export_graph(module: nn.Module, args: tuple[torch.Tensor, ...], path: str | os.PathLike,
                 inputs: Sequence[str], outputs: Sequence[str],
                 dynamic: Mapping[str, Mapping[int, str]]) -> Path:
    """Trace module(*args) and write it to path as an ONNX graph; `dynamic` names the axes
    (of inputs and outputs) left free, {"x": {0: "batch"}}; all others keep args' sizes."""
    path = Path(path)
    require_torch("writing ONNX graphs")
    import torch

    try:
        import onnx  # noqa: F401 - torch.onnx writes the file with it
    except ImportError:
        raise MlctError(f"writing ONNX graphs needs the onnx package, which is not installed: "
                        f"{INSTALL}") from None
    with warnings.catch_warnings(), torch.no_grad():
        # the exporter's deprecation notice, and the tracer's notes on the Python-side checks
        # (lengths' range, shapes) that it evaluates once on args and leaves out of the graph
        warnings.simplefilter("ignore", DeprecationWarning)
        warnings.simplefilter("ignore", torch.jit.TracerWarning)
        warnings.filterwarnings("ignore", message=".*Converting a tensor to a Python.*")
        warnings.filterwarnings("ignore", message="Constant folding")  # strided slices: kept
        torch.onnx.export(module, args, str(path), dynamo=False, opset_version=OPSET,
                          input_names=list(inputs), output_names=list(outputs),
                          dynamic_axes={k: dict(v) for k, v in dynamic.items()},
                          do_constant_folding=True)
    return path


# ONNX Runtime graph rewrites left out of every session. MatMulAddFusion turns a MatMul + Add
# into a Gemm, which takes 2-d inputs only, so around each product of a (B, S, d) input it puts
# a Reshape before and after: 160 of the bundled model's 580 operators in its 5-step batch-1
# sampler graph. Without it: 480 operators (and BiasGelu fused in their place), and the warm
# batch-1 call (5 NFE, 196 frames, 2 threads) 3 % faster, paired in one run: 5.49 -> 5.29 ms
# median (bench/paired_speed.py :matmul-add-fusion; docs/performance.md).
DISABLED_OPTIMIZERS: tuple[str, ...] = ("MatMulAddFusion",)


def onnxruntime_module() -> Any:
    """The onnxruntime module; MlctError saying how to install it when it is missing."""
    try:
        import onnxruntime
    except ImportError:
        raise MlctError(f"the onnx backend needs ONNX Runtime, which is not installed: "
                        f"{INSTALL}") from None
    return onnxruntime


def spare_cores(threads: int) -> bool:
    """Does the machine keep at least two logical CPUs free beside `threads` busy ones? Where it
    does, a session's threads may spin within a run (session's spin_within_run); where it does
    not, spinning threads fight other work for the cores: with the test suite running beside on
    a 2-core machine, MiniLM took 8.2 ms spinning within the run against 4.1 sleeping
    (docs/performance.md). The machine's size only: a session that
    cannot change its mind later is made by this rule; spin_now also asks how busy it is."""
    return (os.cpu_count() or 1) >= threads + 2


# The busy time is counted in clock ticks (10 ms on Linux): over 0.2 s a CPU's share is read to
# 0.05, finer than the slack below. Reading it costs ~35 us, at most once per window.
LOAD_WINDOW_S = 0.2
# Background work a quiet machine does (a few hundredths of a CPU on the 2-vCPU host) must not
# stop the spinning; one other busy process must.
SPIN_SLACK_CPUS = 0.25


def _cpu_seconds() -> tuple[float, float] | None:
    """(CPU seconds every logical CPU has spent busy since boot, the hypervisor's steal
    included; CPU seconds this process has used), or None where /proc/stat is not there."""
    try:
        with open("/proc/stat", encoding="ascii") as stat:
            fields = stat.readline().split()
    except OSError:
        return None
    if len(fields) < 9 or fields[0] != "cpu":
        return None
    # user nice system idle iowait irq softirq steal (guest time is inside user already)
    ticks = [int(field) for field in fields[1:9]]
    busy = (sum(ticks) - ticks[3] - ticks[4]) / os.sysconf("SC_CLK_TCK")
    own = os.times()
    return busy, own.user + own.system


class OtherLoad:
    """How many logical CPUs other processes kept busy lately: the machine's busy time less
    this process's own, over the last window of at least LOAD_WINDOW_S (read again only when
    one has passed). None until two readings exist, and where the machine does not say."""

    def __init__(self, read: Any = _cpu_seconds) -> None:
        self._read = read
        self._last: tuple[float, float, float] | None = None
        self._load: float | None = None

    def __call__(self) -> float | None:
        now = time.monotonic()
        if self._last is not None and now - self._last[0] < LOAD_WINDOW_S:
            return self._load
        seconds = self._read()
        if seconds is None:
            return None
        if self._last is not None:
            then, busy, own = self._last
            self._load = max(0.0, (seconds[0] - busy - (seconds[1] - own)) / (now - then))
        self._last = (now, *seconds)
        return self._load


OTHER_LOAD = OtherLoad()  # the process's one meter: every caller shares its window


def spin_now(threads: int) -> bool:
    """Should `threads` intra-op threads spin within the next run? Yes when the logical CPUs
    that other processes left idle lately hold every thread (OTHER_LOAD, SPIN_SLACK_CPUS), so a
    quiet 2-core machine spins and a busy one of any size does not; spare_cores (the machine's
    size) until the meter has a reading, and where it has none. For sessions kept in both kinds
    and chosen per run (the batch-1 steps, the text encoder): on 2 quiet cores, paired with the
    rule of the machine's size (which spins nothing there), 0.90x the warm call's time and 0.88x
    the cold one's (docs/performance.md); beside other work spinning takes up to 2x."""
    if threads < 2:
        return False
    others = OTHER_LOAD()
    if others is None:
        return spare_cores(threads)
    return (os.cpu_count() or 1) - others >= threads - SPIN_SLACK_CPUS


def session(path: str | os.PathLike | bytes, threads: int | None = None,
            spin_within_run: bool | None = None) -> onnxruntime.InferenceSession:
    """An ONNX Runtime CPU session of the graph at path, every graph optimization on.

    threads: intra-op threads; None: default_threads() (torch's count where torch is loaded). The threads sleep
    between operators instead of spinning (ONNX Runtime's default): on a 2-core machine busy
    with other work, the bundled model's warm batch-1 median at 2 threads was 116 ms spinning
    and 35 ms not (1 thread: 20 and 21 ms; docs/performance.md).
    spin_within_run: the threads spin between operators during a run and stop when it ends
    (`session.force_spinning_stop`), so they take no core between calls; None: when there are
    threads to wake and cores to spare (spare_cores). Measured on 2 quiet cores, spinning
    within the run against sleeping: MiniLM 3.04 / 3.70 ms, the paper-size model's 5 steps and
    decoder 50.4 / 57.1 ms (docs/performance.md)."""
    ort = onnxruntime_module()
    OTHER_LOAD()  # a first reading, so that the first run has a window to judge by (spin_now)
    options = ort.SessionOptions()
    options.intra_op_num_threads = int(threads or default_threads())
    if spin_within_run is None:
        count = options.intra_op_num_threads
        spin_within_run = count > 1 and spare_cores(count)
    options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    options.log_severity_level = 3  # errors only: no notes on stderr
    options.add_session_config_entry("session.intra_op.allow_spinning",
                                     "1" if spin_within_run else "0")
    if spin_within_run:
        options.add_session_config_entry("session.force_spinning_stop", "1")
    # int8 weights dequantized in the graph (export-web's 'int8-weights' text encoder) are
    # computed as written, in float32, as ONNX Runtime Web computes them: left on, the native
    # build fuses DequantizeLinear + MatMul into MatMulNBits, whose arithmetic moved MiniLM's
    # vectors 3e-3 from the page's (1e-7 with this set). Graphs without such pairs are unchanged.
    options.add_session_config_entry("session.disable_quant_qdq", "1")
    weights: list[Any] = []
    model: str | bytes = path if isinstance(path, bytes) else str(path)
    if not isinstance(path, bytes) and weights_recipe(path).is_file():
        names, weights, folder = _recipe_weights(path)
        options.add_external_initializers(names, weights)
        # the rest ONNX Runtime reads from the weights file itself: a graph read from memory
        # finds its external data in this folder (one read from its path, only beside it)
        options.add_session_config_entry("session.model_external_initializers_file_folder_path",
                                         str(folder))
        model = Path(path).read_bytes()
    try:
        made = ort.InferenceSession(model, sess_options=options,
                                    providers=["CPUExecutionProvider"],
                                    disabled_optimizers=list(DISABLED_OPTIMIZERS))
        made._mlct_weights = weights  # the arrays the session reads stay alive with it
        return made
    except Exception as error:  # noqa: BLE001 - onnxruntime raises its own kinds
        name = "a graph built in memory" if isinstance(path, bytes) else path
        raise MlctError(f"{name}: ONNX Runtime cannot load this graph ({first_line(error)})"
                        ) from None


def session_from_bytes(model: bytes, threads: int | None = None,
                       spin_within_run: bool | None = None) -> onnxruntime.InferenceSession:
    """session() of a serialized graph held in memory."""
    return session(model, threads, spin_within_run)


# A graph's large weights read from a safetensors file instead of the graph (the shipped MiniLM:
# its one copy of the weights, assets/minilm/model.safetensors, serves the torch encoder and the
# graph). An initializer that is a tensor of the file as it is stands in the graph as ONNX
# external data at the tensor's offset in the file, which ONNX Runtime reads itself; so does a
# product's weight that is a tensor's transpose, its MatMul made a FusedMatMul that transposes
# it (transB: the same packed weights, the same results to the bit). GRAPH.weights.json names
# the file, and says of each other initializer (stored as external data with no file) which
# tensors it is built from in numpy: several, transposed or not, concatenated along an axis
# (the fused attention's query, key and value). Version 1 built every initializer in numpy;
# reading the file in ONNX Runtime instead of handing it 90 MB of arrays took the shipped text
# encoder's session from ~115 to ~50 ms of CPU (docs/performance.md, "Cold start").
WEIGHTS_FORMAT, WEIGHTS_VERSION = "mlct-onnx-weights", 2
WEIGHTS_VERSIONS = (1, 2)  # what the loader reads


def weights_recipe(graph: str | os.PathLike) -> Path:
    """The file that says where the graph's large weights come from (may not exist)."""
    graph = Path(graph)
    return graph.with_name(graph.stem + ".weights.json")


def safetensors_header_digest(path: str | os.PathLike) -> str:
    """The sha256 of a safetensors file's header (names, dtypes, shapes, offsets): a cheap
    check, at every load, that it is the file a recipe was made for (its size is the other);
    the tests compare the whole file's sha256."""
    with open(path, "rb") as f:
        size = int.from_bytes(f.read(8), "little")
        return hashlib.sha256(f.read(size)).hexdigest()


def external_weights(graph: str | os.PathLike) -> tuple[list[str], list[Any]]:
    """(names, OrtValues) of the graph's initializers that its recipe (weights_recipe) builds
    with numpy from the safetensors file it names; MlctError when that file is missing or
    another. The file is mapped, not read: a tensor taken as it is is a view of the page cache,
    the transposed and joined ones are copies. (The initializers the graph reads from the file
    itself, ONNX Runtime reads: session.)"""
    names, values, _ = _recipe_weights(graph)
    return names, values


def _recipe_weights(graph: str | os.PathLike) -> tuple[list[str], list[Any], Path]:
    """external_weights' names and OrtValues, and the folder of the weights file."""
    import numpy as np
    import onnxruntime as ort

    recipe_path = weights_recipe(graph)
    try:
        recipe = json.loads(recipe_path.read_text(encoding="utf-8"))
        source = (recipe_path.parent / recipe["safetensors"]).resolve()
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise MlctError(f"{recipe_path}: cannot read the graph's weights recipe "
                        f"({first_line(error)})") from None
    if recipe.get("format") != WEIGHTS_FORMAT or recipe.get("version") not in WEIGHTS_VERSIONS:
        raise MlctError(f"{recipe_path}: not a {WEIGHTS_FORMAT} recipe of version "
                        f"{' or '.join(map(str, WEIGHTS_VERSIONS))}")
    if not source.is_file():
        raise MlctError(f"{graph}: its weights file {source} is missing; reinstall mlct")
    if (source.stat().st_size != recipe.get("size")
            or safetensors_header_digest(source) != recipe.get("header_sha256")):
        raise MlctError(f"{graph}: {source} is not the weights file the graph was made for")
    tensors = mapped_safetensors(source)
    names, values = [], []
    for entry in recipe["initializers"]:
        parts = [tensors[key].T if transpose else tensors[key] for key, transpose in entry["parts"]]
        array = parts[0] if len(parts) == 1 else np.concatenate(parts, axis=entry["axis"])
        names.append(entry["name"])
        values.append(ort.OrtValue.ortvalue_from_numpy(np.ascontiguousarray(array)))
    return names, values, source.parent


_SAFETENSORS_DTYPES = {"F32": "<f4", "F16": "<f2", "I64": "<i8", "I32": "<i4", "I8": "i1"}


def mapped_safetensors(path: str | os.PathLike) -> dict[str, Any]:
    """A safetensors file's tensors as read-only numpy views of the file mapped in memory (the
    format: an 8-byte little-endian header size, a JSON header of dtype, shape and byte
    offsets per tensor, then the data)."""
    import numpy as np

    data = np.memmap(path, dtype=np.uint8, mode="r")
    size = int.from_bytes(data[:8].tobytes(), "little")
    header = json.loads(data[8:8 + size].tobytes())
    start = 8 + size
    out = {}
    for name, info in header.items():
        if name == "__metadata__" or info["dtype"] not in _SAFETENSORS_DTYPES:
            continue
        begin, end = info["data_offsets"]
        out[name] = data[start + begin:start + end].view(_SAFETENSORS_DTYPES[info["dtype"]]
                                                         ).reshape(info["shape"])
    return out


def externalize_weights(graph: str | os.PathLike, source: str | os.PathLike,
                        relative_to_graph: str, min_size: int = 4096) -> Path:
    """Rewrite the graph at `graph` so that each initializer of min_size elements or more that
    is a tensor of the safetensors file `source` (or its transpose, or a concatenation of such)
    is read from that file at load instead of stored in the graph (the recipe above): a tensor
    as it is, or a transposed one that only MatMuls take as their weight (those made
    FusedMatMuls with transB), as external data at its offset in the file; any other from the
    recipe written beside the graph, checked by rebuilding every such initializer.
    relative_to_graph: the source's path from the graph's folder, as the recipe records it.
    Returns the recipe."""
    import numpy as np
    import onnx
    from onnx import TensorProto, helper, numpy_helper
    from safetensors.numpy import load_file

    graph, source = Path(graph), Path(source)
    tensors = load_file(str(source))
    with open(source, "rb") as f:  # where each tensor's bytes lie in the file
        size = int.from_bytes(f.read(8), "little")
        header = json.loads(f.read(size))
    known: dict[bytes, tuple[str, bool]] = {}
    for key, array in tensors.items():
        known.setdefault(_fingerprint(array), (key, False))
        if array.ndim == 2:
            known.setdefault(_fingerprint(array.T), (key, True))

    def pieces(array: np.ndarray) -> tuple[list[tuple[str, bool]], int] | None:
        if _fingerprint(array) in known:
            return [known[_fingerprint(array)]], 0
        for axis in range(array.ndim):
            for count in (3, 2, 4):
                if array.shape[axis] % count:
                    continue
                found = [known.get(_fingerprint(part))
                         for part in np.split(array, count, axis=axis)]
                if all(found):
                    return found, axis  # type: ignore[return-value]
        return None

    model = onnx.load(str(graph))
    users: dict[str, list[Any]] = {}
    for node in model.graph.node:
        for name in set(node.input):
            users.setdefault(name, []).append(node)
    entries = []
    for init in model.graph.initializer:
        array = numpy_helper.to_array(init)
        if array.size < min_size or (found := pieces(array)) is None:
            continue
        parts, axis = found
        rebuilt = [tensors[k].T if t else tensors[k] for k, t in parts]
        rebuilt = rebuilt[0] if len(rebuilt) == 1 else np.concatenate(rebuilt, axis=axis)
        if rebuilt.dtype != array.dtype or not np.array_equal(rebuilt, array):
            raise MlctError(f"{graph.name}: {init.name} rebuilt from {source.name} differs")
        key, transposed = parts[0]
        products = users.get(init.name, [])
        in_file = len(parts) == 1 and (not transposed or (products and all(
            node.op_type == "MatMul" and node.domain in ("", "ai.onnx")
            and list(node.input).index(init.name) == 1 for node in products)))
        location, offset = "weights.unused", 0
        if in_file:
            for node in products if transposed else []:  # x @ w.T, the weight as it is stored
                node.op_type, node.domain = "FusedMatMul", "com.microsoft"
                node.attribute.append(helper.make_attribute("transB", 1))
            if transposed:
                del init.dims[:]
                init.dims.extend(tensors[key].shape)
            location, offset = source.name, 8 + size + header[key]["data_offsets"][0]
        else:
            entries.append({"name": init.name, "axis": axis, "parts": [list(p) for p in parts]})
        init.ClearField("raw_data")
        for field in ("float_data", "int32_data", "int64_data", "double_data"):
            init.ClearField(field)
        init.data_location = TensorProto.EXTERNAL
        del init.external_data[:]
        for name, value in (("location", location), ("offset", str(offset)),
                            ("length", str(array.nbytes))):
            item = init.external_data.add()
            item.key, item.value = name, value
    if not any(o.domain == "com.microsoft" for o in model.opset_import) and any(
            node.domain == "com.microsoft" for node in model.graph.node):
        model.opset_import.append(helper.make_opsetid("com.microsoft", 1))
    onnx.save(model, str(graph))
    recipe = {"format": WEIGHTS_FORMAT, "version": WEIGHTS_VERSION,
              "safetensors": relative_to_graph, "size": source.stat().st_size,
              "header_sha256": safetensors_header_digest(source), "initializers": entries}
    path = weights_recipe(graph)
    path.write_text(json.dumps(recipe, indent=1) + "\n", encoding="utf-8")
    return path


def _fingerprint(array: Any) -> bytes:
    """The identity of an array's values, shape and dtype, for matching weights."""
    import numpy as np

    contiguous = np.ascontiguousarray(array)
    digest = hashlib.sha256(contiguous.tobytes())
    digest.update(f"{contiguous.dtype} {contiguous.shape}".encode())
    return digest.digest()
