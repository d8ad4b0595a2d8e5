"""The training step replayed from one CUDA graph (`train.<stage>.cuda_graph=true`).

Why: at the paper's sizes a stage-2 step (the frozen encoder, the online denoiser on 2B items,
the target denoiser, the backward pass, clipping, AdamW, the EMA) issues thousands of small
kernels, and the host's microseconds per launch, not the GPU, set the pace: on an H200 the GPU
was busy 24-31% of the time (docs/training.md, "On a GPU"). Captured once, the whole step is one
launch.

What a graph needs, and how the step provides it:
- fixed shapes and addresses: the motions live on the device (train/resident.py) and a batch
  arrives as (B,) item indices, first frames and lengths copied into fixed buffers; the motion
  keeps its whole padded width (stages.longest) and the text comes as rows of the run's table;
- nothing read on the host inside the step: AdamW keeps its step count on the device
  (capturable) and reads its learning rate from a device tensor, which the loop's scheduler
  value is copied into before each replay; the EMA target skips AveragedModel's first-call
  test (stages.update_ema_in_graph), the eager warm-up steps having made that first call;
- lazy set-ups done before the capture: the first `warmup` steps run eagerly on a side stream.

The loss is still read after every step (the loop stops on a non-finite one, as before; the
read costs the GPU only the gap between two replays). On other devices (and in the tests) the
same fixed-shape step runs without a graph.
"""

from __future__ import annotations

import contextlib
from typing import Any, Callable

import torch
from torch import Tensor, nn

from mlct.train.resident import ResidentMotions

Terms = dict[str, Tensor]


def optimizer_update(model: nn.Module, optimizer: torch.optim.Optimizer, loss: Tensor,
                     grad_clip: float) -> Tensor:
    """Backward, gradient-norm clipping and one optimizer step; returns the norm before
    clipping (a device tensor: reading it waits for the device)."""
    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    grad_norm = torch.nn.utils.clip_grad_norm_(model.parameters(), grad_clip)
    optimizer.step()
    return grad_norm


def restore_optimizer(optimizer: torch.optim.Optimizer, state: dict[str, Any]) -> None:
    """optimizer.load_state_dict, keeping this run's `capturable`: a checkpoint written with
    or without CUDA graphs resumes either way (the step counts move to the device or back)."""
    flags = [group.get("capturable", False) for group in optimizer.param_groups]
    optimizer.load_state_dict(state)
    for group, capturable in zip(optimizer.param_groups, flags):
        group["capturable"] = capturable
        for parameter in group["params"]:
            slot = optimizer.state.get(parameter, {})
            if isinstance(slot.get("step"), Tensor):
                where = parameter.device if capturable else torch.device("cpu")
                slot["step"] = slot["step"].to(device=where, dtype=torch.float32)


class CapturedStep:
    """stage.loss, optimizer_update and the stage's after-step update, on a batch of choices
    (batches.collate_choices), replayed from one CUDA graph after `warmup` eager steps."""

    def __init__(self, stage: Any, model: nn.Module, optimizer: torch.optim.Optimizer,
                 motions: ResidentMotions, grad_clip: float,
                 autocast: Callable[[], contextlib.AbstractContextManager],
                 warmup: int = 3) -> None:
        self.stage, self.model, self.optimizer = stage, model, optimizer
        self.motions, self.grad_clip, self.autocast = motions, grad_clip, autocast
        self.device = motions.flat.device
        self.graphed = self.device.type == "cuda"
        self.warmup = warmup
        self.eager_steps = 0  # steps run before the capture (a test reads it)
        self._inputs: dict[str, Tensor] | None = None
        self._graph: Any = None
        self._outputs: tuple[Terms, Tensor] | None = None
        # AdamW's learning rates as device tensors, which the captured step reads
        self._lrs = [torch.tensor(float(g["lr"]), device=self.device)
                     for g in optimizer.param_groups]

    def __call__(self, choices: dict[str, Any]) -> tuple[Terms, Tensor]:
        """One training step on `choices`; returns the loss terms and the gradient norm (the
        graph's own buffers when replayed: read them before the next call)."""
        self._fill(choices)
        if not self.graphed:
            return self._step(in_graph=False)
        if self._graph is None and self.eager_steps < self.warmup:
            self.eager_steps += 1
            return self._on_side_stream()
        if self._graph is None:
            self._capture()
        for tensor, group in zip(self._lrs, self.optimizer.param_groups):
            tensor.fill_(float(group["lr"]))  # the scheduler's value for this step
        self._graph.replay()
        return self._outputs

    def _fill(self, choices: dict[str, Any]) -> None:
        text = getattr(self.stage, "text", None)  # the latent stages' caption table
        fresh = {key: choices[key] for key in ("index", "start", "length")}
        if text is not None:
            fresh["text_rows"] = text.rows(choices["caption"])
        if self._inputs is None:
            self._inputs = {key: value.to(self.device) for key, value in fresh.items()}
            return
        if fresh["length"].shape != self._inputs["length"].shape:
            raise ValueError(f"a captured step takes batches of {len(self._inputs['length'])}, "
                             f"not {len(fresh['length'])}")
        for key, value in fresh.items():
            self._inputs[key].copy_(value, non_blocking=True)

    def _step(self, in_graph: bool) -> tuple[Terms, Tensor]:
        inputs = self._inputs
        batch = {"motion": self.motions.gather(inputs["index"], inputs["start"], inputs["length"]),
                 "length": inputs["length"], "static": True}
        if "text_rows" in inputs:
            batch["text_rows"] = inputs["text_rows"]
        with self.autocast():
            terms = self.stage.loss(self.model, batch)
        grad_norm = optimizer_update(self.model, self.optimizer, terms["loss"], self.grad_clip)
        # detached: a loss kept by the caller would keep this step's autograd graph alive into
        # the next one, whose backward then runs on another stream (torch warns of it)
        terms = {**terms, "loss": terms["loss"].detach()}
        if in_graph:
            self.stage.after_step_in_graph()
        else:
            self.stage.after_step()
        return terms, grad_norm

    def _on_side_stream(self) -> tuple[Terms, Tensor]:
        # as torch.cuda.graphs advises: lazy set-ups (cuBLAS workspaces, AdamW's state) happen
        # in eager steps on a side stream before the capture
        current = torch.cuda.current_stream(self.device)
        side = torch.cuda.Stream(device=self.device)
        side.wait_stream(current)
        with torch.cuda.stream(side):
            out = self._step(in_graph=False)
        current.wait_stream(side)
        return out

    def _capture(self) -> None:
        groups = self.optimizer.param_groups
        floats = [group["lr"] for group in groups]
        self.optimizer.zero_grad(set_to_none=True)  # the gradients get the graph's memory
        graph = torch.cuda.CUDAGraph()
        try:
            for group, tensor in zip(groups, self._lrs):
                group["lr"] = tensor  # AdamW reads the rate from this tensor in the graph
            with torch.cuda.graph(graph):
                self._outputs = self._step(in_graph=True)
        finally:
            for group, value in zip(groups, floats):
                group["lr"] = value  # the scheduler and the checkpoint keep plain floats
        self._graph = graph
