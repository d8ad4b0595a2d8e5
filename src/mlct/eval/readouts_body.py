"""Read-outs and checks of the whole-body families of benchmark version 4
(mlct.data.synth.families_body), registered with readouts.py as readouts_more.py's are.

Same conventions as mlct.eval.readouts (joints (T, 22, 3) in metres, y up, 20 fps, the person's
left and right); each check a necessary physical condition, its threshold between the family's
own ground truth and the other families' motions.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

import numpy as np

from mlct.eval.readouts import (ANKLE, EXTRA_CHECKS, EXTRA_READINGS, FPS, KNEE, NECK, PELVIS,
                                SHOULDER, SIDES, WRIST, Check, _count_rises, _floor, _lowest_foot,
                                _other, _standing, facing)
from mlct.eval.readouts_more import (_chest_forward, _end, _floor_level, _forward, _lateral,
                                     _tilt)

HIP = {"left": 1, "right": 2}
_MOVING_SPEED = 0.25  # m/s of the pelvis over half a second: walking, however slowly


def _moving(joints: np.ndarray) -> np.ndarray:
    """(T,) whether the pelvis travels at _MOVING_SPEED or more, over the half second around."""
    lag = max(1, int(0.25 * FPS))
    ground = joints[:, PELVIS][:, [0, 2]]
    padded = np.concatenate([np.repeat(ground[:1], lag, 0), ground, np.repeat(ground[-1:], lag, 0)])
    speed = np.linalg.norm(padded[2 * lag:] - padded[:-2 * lag], axis=-1) * FPS / (2 * lag)
    return speed > _MOVING_SPEED


def _seconds(mask: np.ndarray) -> float:
    """Seconds for which `mask` holds, in all."""
    return float(np.count_nonzero(mask)) / FPS


def body_readings(joints: np.ndarray) -> dict[str, float]:
    """The read-outs of this module as a flat {name: value} dict (metres, radians, seconds,
    counts; per-side ones as 'name.left' / 'name.right'). `joints` as readouts.as_joints gives."""
    moving = _moving(joints)
    ahead = {s: _forward(joints, WRIST[s]) for s in SIDES}
    out = {s: _lateral(joints, WRIST[s]) * (1 if s == "left" else -1) for s in SIDES}
    height = {s: joints[:, WRIST[s], 1] for s in SIDES}
    shoulder = {s: joints[:, SHOULDER[s], 1] for s in SIDES}
    gap = np.linalg.norm(joints[:, WRIST["left"]] - joints[:, WRIST["right"]], axis=-1)
    pelvis, neck = joints[:, PELVIS, 1], joints[:, NECK, 1]
    both = lambda f: f("left") & f("right")  # noqa: E731
    floor = _floor_level(joints)
    r: dict[str, float] = {"start_pelvis_height": _standing(pelvis - floor),
                           "end_pelvis_height": _end(pelvis - floor)}
    # On hands and knees: both knees and both wrists near the floor, the trunk near horizontal
    # with the chest facing down.
    fours = (_tilt(joints) > 1.0) & (_chest_forward(joints)[:, 1] < -0.5) & (pelvis - floor < 0.7)
    for joint in (*KNEE.values(), *WRIST.values()):
        fours &= joints[:, joint, 1] - floor < 0.15
    r["all_fours"] = _seconds(fours)
    # Stairs: how much higher the feet end than they started (the lower foot of each frame).
    feet = np.minimum(joints[:, ANKLE["left"], 1], joints[:, ANKLE["right"], 1])
    r["feet_level_change"] = _end(feet) - _standing(feet)
    r["end_stands_tall"] = _end(pelvis - feet)
    for side in SIDES:  # stepping over: how high each knee lifts over standing, and when
        lifted = joints[:, KNEE[side], 1] - floor
        lifted = lifted - _standing(lifted)
        r[f"high_step.{side}"] = float(lifted.max())
        r[f"high_step_at.{side}"] = float(np.argmax(lifted)) / FPS
    raised = pelvis - floor
    for side in SIDES:  # limping: how far each knee bends while walking (90th percentile)
        hip, knee, ankle = (joints[:, j] for j in (HIP[side], KNEE[side], ANKLE[side]))
        thigh, shin = knee - hip, ankle - knee
        cos = np.einsum("ti,ti->t", thigh, shin) / np.maximum(
            np.linalg.norm(thigh, axis=-1) * np.linalg.norm(shin, axis=-1), 1e-9)
        bend = np.arccos(np.clip(cos, -1, 1))
        r[f"walking_knee_bend.{side}"] = float(np.percentile(bend[moving], 90)) if \
            moving.sum() > FPS else 0.0
    # Putting down: both wrists held in front of the belly before they go down to the floor,
    # and how far in front of the pelvis the nearer one ends.
    low = int(np.argmin(np.maximum(height["left"], height["right"])))
    r["held_before_low"] = _seconds(both(lambda s: (ahead[s][:low] > 0.15)
                                         & (height[s][:low] > pelvis[:low] - 0.1)))
    r["end_wrists_ahead"] = min(_end(ahead["left"]), _end(ahead["right"]))
    # Stumbling: the trunk's forward lean (radians) and how long it is over 0.25 rad.
    spine = joints[:, NECK] - joints[:, PELVIS]
    lean = np.arctan2(np.einsum("ti,ti->t", spine, facing(joints)), spine[:, 1])
    r["lean_peak"] = float(lean.max())
    r["lean_time"] = _seconds(lean > 0.25)
    # A long jump: the pelvis's horizontal travel over the longest stretch in the air.
    up = _lowest_foot(joints) > _floor(joints) + 0.05
    best = (0, 0)
    start = None
    for i, flying in enumerate(np.append(up, False)):
        if flying and start is None:
            start = i
        elif not flying and start is not None:
            best = max(best, (i - start, start))
            start = None
    length, first = best
    r["longest_flight"] = length / FPS
    r["longest_flight_travel"] = float(np.linalg.norm(
        joints[first + length - 1, PELVIS, [0, 2]] - joints[first, PELVIS, [0, 2]])) \
        if length else 0.0
    # Turning a rope: both wrists beside the hips, a little out to the sides.
    r["hands_at_hips"] = _seconds(both(lambda s: (np.abs(height[s] - pelvis) < 0.2)
                                       & (out[s] > 0.1)))
    # Sit-ups: the trunk's rises from lying (elevation 0) towards upright (pi/2).
    elevation = np.pi / 2 - _tilt(joints)
    r["trunk_rises"] = float(_count_rises(elevation, 0.8, 0.4))
    r["max_pelvis_height"] = float(raised.max())
    where = np.flatnonzero(fours)
    r["all_fours_travel"] = float(
        (joints[where[-1], PELVIS] - joints[where[0], PELVIS]) @ facing(joints)[where[0]]
        if len(where) else 0.0)
    # Carrying a box: both wrists in front of the belly, a box's width apart, while walking.
    r["carry_walk"] = _seconds(moving & (gap > 0.15) & (gap < 0.55) & both(
        lambda s: (ahead[s] > 0.15) & (ahead[s] < 0.5) & (height[s] > pelvis - 0.05)
        & (height[s] < neck - 0.12)))
    # Pushing: both arms reaching 0.4 m forward at chest height while walking.
    r["push_walk"] = _seconds(moving & (gap < 0.6) & both(
        lambda s: (ahead[s] > 0.42) & (np.abs(height[s] - shoulder[s]) < 0.25)))
    # Arms out to the sides: both wrists 0.4 m out from the neck near shoulder height.
    r["arms_out_walk"] = _seconds(moving & both(
        lambda s: (out[s] > 0.4) & (np.abs(height[s] - shoulder[s]) < 0.2)))
    return {k: float(v) for k, v in r.items()}


# ---------------------------------------------------------------------------- checks

def _busy_walk_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """carry, push, balance_walk: a walk forward with the arms held in the family's pose."""
    # GT: forward 1.3-2.5 m, the pose held while walking 3-5 s; a pick-up holds the thing
    # without walking, a walk swings the arms at the sides.
    read, what = {"carry": ("carry_walk", "both wrists in front of the belly, 0.15-0.55 m "
                            "apart"),
                  "push": ("push_walk", "both wrists 0.42 m in front at shoulder height"),
                  "balance_walk": ("arms_out_walk", "both wrists 0.4 m out to the sides at "
                                   "shoulder height")}[family]
    return [Check(f"{family}.forward", "the pelvis travels 0.8 m forward",
                  lambda r: r["forward_displacement"] > 0.8),
            Check(f"{family}.pose", f"{what} for 2 s in all while walking",
                  lambda r: r[read] >= 2.0)]


def _crawl_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """crawl: down on the hands and knees, forward on them, back up."""
    # GT: on all fours 3.4-4.6 s, 0.4-0.8 m forward meanwhile; a push-up's plank keeps the
    # knees up and stays put.
    return [Check("crawl.all_fours", "both knees and wrists within 0.15 m of the floor, the "
                  "chest facing down, for 2 s in all", lambda r: r["all_fours"] >= 2.0),
            Check("crawl.forward", "0.3 m forward on all fours",
                  lambda r: r["all_fours_travel"] > 0.3),
            Check("crawl.stands", "starts standing and ends within 0.1 m of that height",
                  lambda r: r["start_pelvis_height"] > 0.7
                  and r["end_pelvis_height"] > r["start_pelvis_height"] - 0.1)]


def _stairs_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """walk_downstairs, walk_upstairs: forward, the feet end a flight lower (higher), upright."""
    # GT: the feet end 0.68 m lower (higher), 0.9-1.1 m forward; on the flat floor they end
    # where they started, within a few centimetres.
    down = family == "walk_downstairs"
    return [Check(f"{family}.forward", "the pelvis travels 0.4 m forward",
                  lambda r: r["forward_displacement"] > 0.4),
            Check(f"{family}.level", f"the feet end 0.35 m {'lower' if down else 'higher'} "
                  "than they started",
                  lambda r: (-1 if down else 1) * r["feet_level_change"] > 0.35),
            Check(f"{family}.upright", "ends standing: the pelvis 0.75 m over the lower ankle",
                  lambda r: r["end_stands_tall"] > 0.75)]


def _step_over_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """step_over: walking forward, the named ankle lifts knee-high, then the other one."""
    # GT: the leading knee 0.2-0.3 m over its standing height, the other 0.1-0.2 m; a walk lifts a
    # knee 0.05 m, marching in place stays put, stairs end on another level.
    leg = params.get("leg")
    sides = (leg,) if leg else SIDES

    def over(r: Mapping[str, float], s: str) -> bool:
        o = _other(s)
        return (r[f"high_step.{s}"] > 0.15 and r[f"high_step.{o}"] > 0.1
                and 0.1 < r[f"high_step_at.{o}"] - r[f"high_step_at.{s}"] < 1.5)

    return [Check("step_over.forward", "the pelvis travels 0.8 m forward on level ground, never "
                  "airborne", lambda r: r["forward_displacement"] > 0.8
                  and abs(r["feet_level_change"]) < 0.1 and r["airborne_frames"] <= 2),
            Check("step_over.high_step", f"the {leg or 'one'} knee lifts 0.15 m, then the other "
                  "0.1 m within 1.5 s", lambda r: any(over(r, s) for s in sides))]


def _fall_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """fall_forward, fall_backward: from standing to lying in a second or so."""
    # GT: down in 0.35-0.6 s (readouts_more's descent_time); lying down takes 0.9 s or more.
    # Forward ends on the front (chest down), backward on the back (chest up).
    front = family == "fall_forward"
    return [Check(f"{family}.starts_standing", "the pelvis starts over 0.7 m up",
                  lambda r: r["start_pelvis_height"] > 0.7),
            Check(f"{family}.quick", "the pelvis goes from 0.1 m under standing to its lying "
                  "height in under 0.75 s", lambda r: r["descent_time"] < 0.75),
            Check(f"{family}.lies", "ends lying: the pelvis within 0.35 m of the floor, the "
                  "torso over 1.1 rad from vertical",
                  lambda r: r["end_pelvis_height"] < 0.35 and r["end_torso_tilt"] > 1.1),
            Check(f"{family}.side", f"the chest ends facing {'down' if front else 'up'}",
                  lambda r: (-1 if front else 1) * r["end_chest_up"] > 0.5)]


def _sit_ups_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """sit_ups: lying on the back, the trunk rises towards upright and back, count times."""
    # GT: the trunk from 1.4 rad to 0.3 rad from vertical each time, the pelvis 0.1-0.2 m up.
    count = params.get("count")
    checks = [Check("sit_ups.lying", "starts lying: the pelvis within 0.3 m of the floor, the "
                    "torso over 1.2 rad from vertical", lambda r: r["start_pelvis_height"] < 0.3
                    and r["start_torso_tilt"] > 1.2),
              Check("sit_ups.stays_down", "the pelvis stays within 0.35 m of the floor",
                    lambda r: r["max_pelvis_height"] < 0.35),
              Check("sit_ups.rises", "the trunk rises within 0.77 rad of upright at least twice",
                    lambda r: r["trunk_rises"] >= 2)]
    if count:
        checks.append(Check("sit_ups.count", f"{count} sit-ups",
                            lambda r: r["trunk_rises"] == count))
    return checks


def _limp_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """limp: a walk forward whose named knee bends far less than the other."""
    # GT: the hurt knee bends ~0.45 times as far as the good one; a walk's knees within 15 %.
    side = params.get("side")
    sides = (side,) if side else SIDES

    def favours(r: Mapping[str, float], s: str) -> bool:
        return r[f"walking_knee_bend.{s}"] < 0.7 * r[f"walking_knee_bend.{_other(s)}"]

    return [Check("limp.forward", "the pelvis travels 0.8 m forward",
                  lambda r: r["forward_displacement"] > 0.8),
            Check("limp.stiff_leg", f"walking, the {side or 'one'} knee bends less than 0.7 "
                  "times as far as the other", lambda r: any(favours(r, s) for s in sides))]


def _put_down_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """put_down: holding something in front, both hands down to the floor, up empty-handed."""
    # GT: held 0.9-1.3 s, the wrists 0.1-0.2 m over the floor, ending by the thighs.
    return [Check("put_down.holds", "both wrists in front of the belly for 0.5 s before they "
                  "go down", lambda r: r["held_before_low"] >= 0.5),
            Check("put_down.down", "both wrists come within 0.22 m of the floor, the pelvis "
                  "sinks over 0.25 m", lambda r: max(r["min_wrist_height.left"],
                                                   r["min_wrist_height.right"]) < 0.22
                  and r["pelvis_drop"] > 0.25),
            Check("put_down.empty_handed", "ends standing with the hands no longer in front "
                  "(a wrist within 0.12 m of the pelvis's plane)",
                  lambda r: r["end_wrists_ahead"] < 0.12
                  and r["end_pelvis_height"] > r["start_pelvis_height"] - 0.1)]


def _jump_rope_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """jump_rope: small two-footed hops in place, the hands by the hips, count of them."""
    # GT: hops 8-12 cm (the pelvis rises under 0.15 m), the hands by the hips 2-3 s; a jump in
    # place rises 0.25 m with the arms swinging, a hop lifts one foot.
    count = params.get("count")
    checks = [Check("jump_rope.in_place", "the pelvis travels less than 0.6 m",
                    lambda r: r["pelvis_path"] < 0.6),
              Check("jump_rope.small_hops", "three hops or more on both feet, the pelvis rising "
                    "less than 0.2 m", lambda r: r["airborne_episodes"] >= 3
                    and r["pelvis_rise"] < 0.2
                    and abs(r["foot_lift.left"] - r["foot_lift.right"]) < 0.05),
              Check("jump_rope.hands", "both wrists by the hips for 1.5 s in all",
                    lambda r: r["hands_at_hips"] >= 1.5)]
    if count:
        checks.append(Check("jump_rope.count", f"{count} hops",
                            lambda r: r["airborne_episodes"] == count))
    return checks


def _stumble_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """stumble: walking, the trunk pitches forward briefly, and it walks on upright."""
    # GT: the lean peaks at 0.39-0.61 rad and is over 0.25 rad for 0.25-0.4 s; a walk leans
    # under 0.15 rad, pushing leans 0.3 rad the whole way, a fall goes down.
    return [Check("stumble.forward", "the pelvis travels 1 m forward",
                  lambda r: r["forward_displacement"] > 1.0),
            Check("stumble.lurch", "the trunk pitches over 0.35 rad forward, for less than "
                  "1.2 s", lambda r: r["lean_peak"] > 0.35 and 0 < r["lean_time"] < 1.2),
            Check("stumble.recovers", "stays on its feet (the pelvis sinks less than 0.25 m) "
                  "and ends standing", lambda r: r["pelvis_drop"] < 0.25
                  and r["end_pelvis_height"] > r["start_pelvis_height"] - 0.1)]


def _long_jump_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """long_jump: a run-up, one long flight forward, landing on the feet."""
    # GT: in the air 0.55 s (the feet 5 cm up), the pelvis 1.5-2.0 m further meanwhile, the
    # run-up 2.7-4 m/s; a run's flights last 0.1 s, a jump forward covers 0.5 m, stairs end on
    # another level.
    return [Check("long_jump.run_up", "the pelvis reaches 2.5 m/s (over a second)",
                  lambda r: r["peak_speed"] > 2.5),
            Check("long_jump.flight", "one flight of 0.25 s or more covering 1 m, on level ground",
                  lambda r: r["longest_flight"] >= 0.25 and r["longest_flight_travel"] > 1.0
                  and abs(r["feet_level_change"]) < 0.1),
            Check("long_jump.lands", "ends standing", lambda r: r["end_pelvis_height"]
                  > r["start_pelvis_height"] - 0.1)]


BODY_CHECKS: dict[str, Callable[[str, Mapping[str, Any]], list[Check]]] = {
    "crawl": _crawl_checks, "walk_downstairs": _stairs_checks, "walk_upstairs": _stairs_checks,
    "step_over": _step_over_checks, "fall_forward": _fall_checks, "fall_backward": _fall_checks,
    "sit_ups": _sit_ups_checks, "limp": _limp_checks, "put_down": _put_down_checks,
    "jump_rope": _jump_rope_checks, "stumble": _stumble_checks,
    "long_jump": _long_jump_checks, "carry": _busy_walk_checks, "push": _busy_walk_checks,
    "balance_walk": _busy_walk_checks,
}

EXTRA_READINGS.append(body_readings)
EXTRA_CHECKS.update(BODY_CHECKS)
