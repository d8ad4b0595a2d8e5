"""The clip makers of the families benchmark version 3 adds, by family (motions.action_clip
dispatches here: these modules build on motions.py, so it cannot import them at its top)."""

from __future__ import annotations

from typing import Callable

from mlct.data.synth.floor import get_up, lie_down, pick_up, push_up, sit_floor, touch_toes
from mlct.data.synth.motions import Clip
from mlct.data.synth.upright import UPRIGHT_CLIPS

MORE_CLIPS: dict[str, Callable[..., Clip]] = {
    "lie_down": lie_down, "get_up": get_up, "sit_floor": sit_floor, "pick_up": pick_up,
    "touch_toes": touch_toes, "push_up": push_up, **UPRIGHT_CLIPS,
}
