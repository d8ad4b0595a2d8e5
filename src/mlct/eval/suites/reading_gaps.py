"""Where a reconstruction loses a family: the read-outs that differ most from the truth's.

A family's reconstructions can fail their checks with a small MPJPE: the body stands where the
truth stands and only the action's own part (a knee raised, the trunk pitched) is missing.
`ReadingGaps` collects the read-outs (`readouts.read_all`) of one-action motions, truth and
reconstruction side by side, and names, per family, the read-outs whose medians moved most
("foot_lift.left 0.24 -> 0.02"), so that a failing family says which part of the motion the
autoencoder does not draw. A move is measured in units of the reading's own spread over every
family's truths (its standard deviation), so that counts, metres, radians and seconds compare.
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any

import numpy as np

from mlct.eval.readouts import read_all

# Added to each reading's spread, so that a reading constant over the truths (spread 0) moving
# by a millimetre is not the largest gap.
FLOOR = 0.05


class ReadingGaps:
    def __init__(self) -> None:
        self._pairs: dict[str, list[tuple[dict[str, float], dict[str, float]]]] = defaultdict(list)

    def add(self, label: dict[str, Any], truth: np.ndarray, made: np.ndarray) -> None:
        """One motion's joints, truth and reconstruction; only one-action motions count."""
        if len(label["actions"]) != 1 or label.get("concurrent"):
            return
        self._pairs[label["actions"][0]["family"]].append((read_all(truth), read_all(made)))

    def largest(self, family: str, top: int = 4) -> list[tuple[str, float, float]]:
        """(reading, truth's median, reconstruction's median), the most moved first."""
        pairs = self._pairs.get(family, [])
        if not pairs:
            return []
        every_truth = [t for family_pairs in self._pairs.values() for t, _ in family_pairs]
        # a peak's time ("high_step_at") says nothing where there is no peak: left out
        keys = [k for k, v in pairs[0][0].items()
                if isinstance(v, (int, float)) and np.isfinite(v) and "_at." not in k]
        rows = []
        for key in keys:
            spread = float(np.std([t[key] for t in every_truth if np.isfinite(t[key])]))
            truth = float(np.median([t[key] for t, _ in pairs]))
            made = float(np.median([m[key] for _, m in pairs]))
            rows.append((abs(made - truth) / (spread + FLOOR), key, truth, made))
        rows.sort(reverse=True)
        return [(key, truth, made) for _, key, truth, made in rows[:top]]

    def print_for(self, families: list[str], top: int = 4) -> None:
        print("\n## read-outs the reconstructions lose (one-action motions, medians: truth -> "
              "reconstruction)")
        for family in families:
            gaps = self.largest(family, top)
            if gaps:
                print(f"{family:<17} ({len(self._pairs[family])}) " + ", ".join(
                    f"{key} {truth:.2f} -> {made:.2f}" for key, truth, made in gaps))
