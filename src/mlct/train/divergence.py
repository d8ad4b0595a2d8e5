"""A run whose gradient norm leaves its early range: warned about, or stopped where asked.

Why: stage 2 in bfloat16 on a GPU trained normally for ~3,000 steps, then its gradient norm
rose from ~20 to thousands and to infinity while the loss stayed finite, so nothing stopped it
and 37,000 more steps trained a model that stands still (docs/training.md). Clipping hides such a
run from the loss curve for a while; the norm does
not. Over the 40 healthy runs logged in docs/logs the largest logged norm was 7.9x the median
of the run's first five; the diverged ones reached 351x and infinity. A factor of 30 sits
between the two.
"""

from __future__ import annotations

import math
import statistics

FACTOR = 30.0  # a logged norm this many times the early median counts as leaving the range
EARLY_LOGS = 5  # the early range: the median of this many first logged norms


class DivergenceWatch:
    """Fed each logged gradient norm; says once when one is non-finite or FACTOR times the
    median of the run's first EARLY_LOGS (counted from this process's start: a resumed run
    measures its range again)."""

    def __init__(self, factor: float | None = None, early_logs: int | None = None) -> None:
        self.factor = FACTOR if factor is None else factor
        self.early_logs = EARLY_LOGS if early_logs is None else early_logs
        self.early: list[float] = []
        self.tripped = False

    def check(self, step: int, grad_norm: float) -> str | None:
        """The warning's text the first time `grad_norm` leaves the range, else None."""
        if self.tripped:
            return None
        if len(self.early) < self.early_logs:
            if math.isfinite(grad_norm):
                self.early.append(grad_norm)
                return None
        reference = statistics.median(self.early) if self.early else float("nan")
        if math.isfinite(grad_norm) and not grad_norm > self.factor * reference:
            return None
        self.tripped = True
        return (f"the gradient norm is {grad_norm:.4g} at step {step}, more than "
                f"{self.factor:g}x its early median {reference:.3g}: the run is probably "
                f"diverging")
