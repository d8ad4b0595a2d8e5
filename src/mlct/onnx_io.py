"""ONNX graphs in and out: torch modules written as ONNX files, ONNX Runtime sessions read from
them. The one place torch.onnx and onnxruntime are called.

Writing uses torch.onnx's TorchScript exporter (``dynamo=False``). Why not torch 2.13's default
(torch.export-based) exporter: it needs onnxscript, another dependency, to write graphs that this
one writes with torch alone; the modules exported here are straight-line tensor code (no data-
dependent control flow), which tracing records exactly, and sizes read from an input's shape
stay symbolic along the axes named dynamic. Torch deprecates this exporter; its warning is
silenced here, in the one call.

Writing needs the `onnx` package (torch.onnx serializes with it), running needs `onnxruntime`:
the `[onnx]` extra holds both, and each function reports a missing one in one line.
"""

from __future__ import annotations

import os
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import torch
from torch import nn

from mlct.errors import MlctError, first_line

if TYPE_CHECKING:
    import onnxruntime

OPSET = 17  # LayerNormalization is one operator from opset 17 (ONNX Runtime >= 1.14)
INSTALL = ("pip install 'mlct[onnx]' (or: pip install onnxruntime==1.32.0 onnx==1.23.2 "
           "onnx-ir==1.1.0)")


def export_graph(module: nn.Module, args: tuple[torch.Tensor, ...], path: str | os.PathLike,
                 inputs: Sequence[str], outputs: Sequence[str],
                 dynamic: Mapping[str, Mapping[int, str]]) -> Path:
    """Trace module(*args) and write it to path as an ONNX graph; `dynamic` names the axes
    (of inputs and outputs) left free, {"x": {0: "batch"}}; all others keep args' sizes."""
    path = Path(path)
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

    threads: intra-op threads; None follows torch.get_num_threads(), so one knob
    (torch.set_num_threads, OMP_NUM_THREADS) sets both backends alike. The threads sleep
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
    options.intra_op_num_threads = int(threads or torch.get_num_threads())
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
    try:
        model = path if isinstance(path, bytes) else str(path)
        return ort.InferenceSession(model, sess_options=options,
                                    providers=["CPUExecutionProvider"],
                                    disabled_optimizers=list(DISABLED_OPTIMIZERS))
    except Exception as error:  # noqa: BLE001 - onnxruntime raises its own kinds
        name = "a graph built in memory" if isinstance(path, bytes) else path
        raise MlctError(f"{name}: ONNX Runtime cannot load this graph ({first_line(error)})"
                        ) from None


def session_from_bytes(model: bytes, threads: int | None = None,
                       spin_within_run: bool | None = None) -> onnxruntime.InferenceSession:
    """session() of a serialized graph held in memory."""
    return session(model, threads, spin_within_run)
