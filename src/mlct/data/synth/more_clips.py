"""The clip of any action: the families benchmark versions 3 (floor.py, upright.py, which build
on motions.py) and 4 (its family modules, actions.VERSION_4_MODULES) add and, for the rest,
motions.base_clip."""

from __future__ import annotations

from typing import Callable

from mlct.data.synth.floor import get_up, lie_down, pick_up, push_up, sit_floor, touch_toes
from mlct.data.synth.actions import VERSION_4_MODULES, Action
from mlct.data.synth.motions import Clip, Style, base_clip
from mlct.data.synth.rig import Rig
from mlct.data.synth.upright import UPRIGHT_CLIPS

MORE_CLIPS: dict[str, Callable[..., Clip]] = {
    "lie_down": lie_down, "get_up": get_up, "sit_floor": sit_floor, "pick_up": pick_up,
    "touch_toes": touch_toes, "push_up": push_up, **UPRIGHT_CLIPS,
    **{family: clip for module in VERSION_4_MODULES for family, clip in module.CLIPS.items()},
}


def action_clip(action: Action, rig: Rig, style: Style, fps: float) -> Clip:
    """The clip of one action, of any family."""
    if action.family in MORE_CLIPS:
        return MORE_CLIPS[action.family](rig, fps, style, **action.params)
    return base_clip(action, rig, style, fps)
