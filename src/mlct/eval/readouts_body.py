"""Read-outs and checks of the whole-body families of benchmark version 4
(mlct.data.synth.families_body), registered with readouts.py as readouts_more.py's are.

Same conventions as mlct.eval.readouts (joints (T, 22, 3) in metres, y up, 20 fps, the person's
left and right); each check a necessary physical condition, its threshold between the family's
own ground truth and the other families' motions.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

import numpy as np

from mlct.eval.readouts import EXTRA_CHECKS, EXTRA_READINGS, Check


def body_readings(joints: np.ndarray) -> dict[str, float]:
    """The read-outs of this module as a flat {name: value} dict."""
    return {}


BODY_CHECKS: dict[str, Callable[[str, Mapping[str, Any]], list[Check]]] = {}

EXTRA_READINGS.append(body_readings)
EXTRA_CHECKS.update(BODY_CHECKS)
