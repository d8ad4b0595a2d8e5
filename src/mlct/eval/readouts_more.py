"""Read-outs and checks of the families benchmark version 3 adds: floor transitions (lie down,
get up, sit on the floor), reaching down (pick up, touch the toes), exercises in place (jumping
jacks, marching, standing on one leg) and held gestures (point, salute, hands on the hips,
crossed arms, nodding).

Same conventions as mlct.eval.readouts (joints (T, 22, 3) in metres, y up, 20 fps, the person's
left and right). The floor here is the level of the lowest joint of the body, not of the feet:
a body lying down has its feet in the air. Each check is a necessary physical condition, with
its threshold between the range of the family's own ground truth (in the comments: 300 motions
of each family, tests/test_readouts_more.py) and what the other families' motions show.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

import numpy as np

from mlct.eval.readouts import (ANKLE, EXTRA_CHECKS, EXTRA_READINGS, FPS, HEAD, NECK, PELVIS,
                                SHOULDER, SIDES, WRIST, Check, Readings, _count_entries, _count_episodes, _count_rises,
                                _other,
                                _standing, facing)

_J_SPINE3 = 9
_ELBOW = {"left": 18, "right": 19}
_ENDS = 5  # frames whose median is a clip's start or end value


def _floor_level(joints: np.ndarray) -> float:
    """Height of the floor: the 5th percentile over frames of the body's lowest joint."""
    return float(np.percentile(joints[..., 1].min(axis=1), 5))


def _end(values: np.ndarray) -> float:
    return float(np.median(values[-_ENDS:]))


def _longest(mask: np.ndarray) -> float:
    """Longest run of True, in seconds."""
    longest = run = 0
    for value in mask:
        run = run + 1 if value else 0
        longest = max(longest, run)
    return longest / FPS


def _chest_forward(joints: np.ndarray) -> np.ndarray:
    """(T, 3) unit normal of the chest, pointing out of it (horizontal when standing, up when
    lying on the back, down when lying on the front)."""
    spine = joints[:, NECK] - joints[:, PELVIS]
    across = joints[:, SHOULDER["right"]] - joints[:, SHOULDER["left"]]
    normal = np.cross(spine, across)
    return normal / np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-9)


def _tilt(joints: np.ndarray) -> np.ndarray:
    """(T,) angle (radians) of pelvis -> neck from vertical, whichever way it leans."""
    spine = joints[:, NECK] - joints[:, PELVIS]
    return np.arccos(np.clip(spine[:, 1] / np.maximum(np.linalg.norm(spine, axis=-1), 1e-9),
                             -1.0, 1.0))


def _lateral(joints: np.ndarray, joint: int) -> np.ndarray:
    """(T,) distance of `joint` towards the person's left of the neck, along the facing's left."""
    left = np.cross(np.array([0.0, 1.0, 0.0]), facing(joints))
    return np.einsum("ti,ti->t", joints[:, joint] - joints[:, NECK], left)


def _forward(joints: np.ndarray, joint: int) -> np.ndarray:
    """(T,) distance of `joint` in front of the pelvis along the body's facing."""
    return np.einsum("ti,ti->t", joints[:, joint] - joints[:, PELVIS], facing(joints))


def _head_bend(joints: np.ndarray) -> np.ndarray:
    """(T,) angle (radians) of the neck and head (top of the spine -> head) to the trunk
    (pelvis -> top of the spine), less its standing value."""
    head = joints[:, HEAD] - joints[:, _J_SPINE3]
    spine = joints[:, _J_SPINE3] - joints[:, PELVIS]
    cos = np.einsum("ti,ti->t", head, spine) / np.maximum(
        np.linalg.norm(head, axis=-1) * np.linalg.norm(spine, axis=-1), 1e-9)
    angle = np.arccos(np.clip(cos, -1.0, 1.0))
    return angle - _standing(angle)


def more_readings(joints: np.ndarray) -> dict[str, float]:
    """The read-outs of this module as a flat {name: value} dict (metres, radians, seconds,
    counts; per-side ones as 'name.left' / 'name.right'). `joints` as readouts.as_joints gives."""
    floor = _floor_level(joints)
    pelvis = joints[:, PELVIS, 1] - floor
    tilt = _tilt(joints)
    r: dict[str, float] = {
        "start_pelvis_height": _standing(pelvis), "end_pelvis_height": _end(pelvis),
        "start_torso_tilt": _standing(tilt), "end_torso_tilt": _end(tilt),
        "end_chest_up": _end(_chest_forward(joints)[:, 1]),
        "end_feet_ahead": _end(0.5 * (_forward(joints, ANKLE["left"])
                                      + _forward(joints, ANKLE["right"]))),
        "head_nods": float(_count_rises(_head_bend(joints), 0.25, 0.12)),
    }
    # Going down to the floor: seconds from the pelvis 0.1 m under its start to within 0.1 m of
    # its end (inf unless it ends 0.3 m lower); a fall (benchmark version 4) is quicker.
    start, end = r["start_pelvis_height"], r["end_pelvis_height"]
    left, arrived = np.flatnonzero(pelvis < start - 0.1), np.flatnonzero(pelvis < end + 0.1)
    r["descent_time"] = float((arrived[0] - left[0]) / FPS) if start - end > 0.3 and len(left) \
        else float("inf")
    # Push-ups: chest dips while the body is prone (chest facing down) on planted hands.
    hands_down = np.maximum(joints[:, WRIST["left"], 1], joints[:, WRIST["right"], 1]) - floor
    prone = (_chest_forward(joints)[:, 1] < -0.5) & (tilt > 1.0) & (hands_down < 0.12)
    chest = np.where(prone, joints[:, _J_SPINE3, 1] - floor, np.inf)
    r["prone_hold"] = _longest(prone)
    r["push_ups"] = float(_count_entries(chest, 0.3, 0.38))
    ankle_gap = np.linalg.norm(joints[:, ANKLE["left"]] - joints[:, ANKLE["right"]], axis=-1)
    head = joints[:, HEAD, 1]
    arms_up = np.minimum(joints[:, WRIST["left"], 1], joints[:, WRIST["right"], 1]) > head
    # A jumping jack's opening: feet 12 cm further apart than standing and both hands overhead.
    r["jack_openings"] = float(_count_episodes((ankle_gap > _standing(ankle_gap) + 0.12)
                                               & arms_up, min_gap=3))
    shoulder_y = {s: joints[:, SHOULDER[s], 1] for s in SIDES}
    lateral = {s: _lateral(joints, WRIST[s]) for s in SIDES}
    elbow_out = {s: np.abs(_lateral(joints, _ELBOW[s])) for s in SIDES}
    hip_level = {s: np.abs(joints[:, WRIST[s], 1] - joints[:, PELVIS, 1]) < 0.15 for s in SIDES}
    chest_level = {s: (joints[:, WRIST[s], 1] < joints[:, NECK, 1])
                   & (joints[:, WRIST[s], 1] > joints[:, PELVIS, 1] + 0.15) for s in SIDES}
    r["hands_on_hips_hold"] = _longest(
        hip_level["left"] & hip_level["right"] & (elbow_out["left"] > 0.3)
        & (elbow_out["right"] > 0.3) & (np.abs(lateral["left"]) < 0.3)
        & (np.abs(lateral["right"]) < 0.3))
    # Crossed: each wrist on the far side of the midline, at chest height.
    r["arms_crossed_hold"] = _longest((lateral["left"] < -0.05) & (lateral["right"] > 0.05)
                                      & chest_level["left"] & chest_level["right"])
    down = pelvis < _standing(pelvis) - 0.15
    for s in SIDES:
        # A lunge: how far this ankle is ahead of the other while the pelvis is down.
        split = np.einsum("ti,ti->t", joints[:, ANKLE[s]] - joints[:, ANKLE[_other(s)]],
                          facing(joints))
        r[f"lunge_split.{s}"] = float(split[down].max()) if down.any() else 0.0
        ankle = joints[:, ANKLE[s], 1]
        lifted = ankle - _standing(ankle)
        wrist = joints[:, WRIST[s]]
        r[f"min_wrist_height.{s}"] = float(wrist[:, 1].min() - floor)
        # Holding what it picked up: after its lowest point the wrist stays in front of the
        # body while the body is back up.
        low = int(np.argmin(wrist[:, 1]))
        up = pelvis[low:] > _standing(pelvis) - 0.1
        r[f"carry_hold.{s}"] = _longest(up & (_forward(joints, WRIST[s])[low:] > 0.15))
        r[f"foot_up_hold.{s}"] = _longest(lifted > 0.15)
        r[f"ankle_lifts.{s}"] = float(_count_rises(lifted, 0.15, 0.07))
        # Pointing: the wrist well out in front at shoulder height.
        r[f"point_hold.{s}"] = _longest((_forward(joints, WRIST[s]) > 0.4)
                                        & (np.abs(wrist[:, 1] - shoulder_y[s]) < 0.2))
        # A salute: the hand at the brow with the elbow raised out to the side (GT: 0.2 m above
        # the shoulder); a hand held to the mouth or the ear (drink, phone_call of benchmark
        # version 4) keeps the elbow 0.08-0.19 m below it.
        r[f"salute_hold.{s}"] = _longest(
            (np.linalg.norm(wrist - joints[:, HEAD], axis=-1) < 0.2)
            & (joints[:, _ELBOW[s], 1] > shoulder_y[s] - 0.02))
    return {k: float(v) for k, v in r.items()}


# ---------------------------------------------------------------------------- checks

def _floor_checks(family: str) -> list[Check]:
    """lie_down, get_up, sit_floor: where the pelvis and the torso are at the ends."""
    # GT lying: pelvis 0.12-0.2 m above the floor, torso 1.5-1.6 rad from vertical, chest up;
    # sitting: pelvis 0.15-0.25 m, torso 0.4-0.6 rad, the ankles 0.8 m ahead of the pelvis.
    standing = [Check(f"{family}.starts_standing", "the pelvis starts over 0.7 m up",
                      lambda r: r["start_pelvis_height"] > 0.7)]
    if family == "lie_down":
        return standing + [
            Check("lie_down.low", "the pelvis ends within 0.3 m of the floor",
                  lambda r: r["end_pelvis_height"] < 0.3),
            Check("lie_down.flat", "the torso ends over 1.2 rad (70 degrees) from vertical",
                  lambda r: r["end_torso_tilt"] > 1.2),
            Check("lie_down.on_back", "the chest ends facing up",
                  lambda r: r["end_chest_up"] > 0.7),
            # GT: 0.9-1.2 s from the pelvis 0.1 m down to lying; falling backwards 0.35-0.6 s.
            Check("lie_down.controlled", "lowers itself, not falls: 0.75 s or more from the "
                  "pelvis 0.1 m down to lying", lambda r: r["descent_time"] >= 0.75)]
    if family == "sit_floor":
        return standing + [
            Check("sit_floor.low", "the pelvis ends within 0.3 m of the floor",
                  lambda r: r["end_pelvis_height"] < 0.3),
            Check("sit_floor.upright", "the torso ends within 0.9 rad of vertical (sitting up, "
                  "not lying)", lambda r: r["end_torso_tilt"] < 0.9),
            Check("sit_floor.legs_out", "the ankles end over 0.5 m in front of the pelvis",
                  lambda r: r["end_feet_ahead"] > 0.5)]
    return [Check("get_up.starts_lying", "the pelvis starts within 0.3 m of the floor with the "
                  "torso over 1.2 rad from vertical",
                  lambda r: r["start_pelvis_height"] < 0.3 and r["start_torso_tilt"] > 1.2),
            Check("get_up.stands", "the pelvis ends over 0.75 m up with the torso within 0.35 "
                  "rad of vertical",
                  lambda r: r["end_pelvis_height"] > 0.75 and r["end_torso_tilt"] < 0.35)]


def _reach_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """pick_up, touch_toes: the hands go down to the floor and the body comes back up."""
    back_up = Check(f"{family}.back_up", "the pelvis ends within 0.1 m of its starting height "
                    "(standing again)",
                    lambda r: r["end_pelvis_height"] > r["start_pelvis_height"] - 0.1)
    if family == "touch_toes":
        # GT: both wrists 0.1-0.2 m above the floor with the pelvis 0.1 m lower at most and the
        # knees straight; a squat or pick-up reaches down by bending the knees (knees 0.4 m up).
        return [Check("touch_toes.hands_down", "both wrists come within 0.25 m of the floor",
                      lambda r: max(r["min_wrist_height.left"], r["min_wrist_height.right"])
                      < 0.25),
                Check("touch_toes.straight_legs", "starts standing and the pelvis sinks less "
                      "than 0.2 m", lambda r: r["start_pelvis_height"] > 0.7
                      and r["pelvis_drop"] < 0.2),
                Check("touch_toes.fold", "the torso folds over 1.2 rad (70 degrees) forward",
                      lambda r: r["torso_pitch"] > 1.2),
                back_up]
    hand = params.get("hand", "both")
    # GT: the pelvis sinks 0.45-0.6 m (a deep squat); a toe touch keeps it up, bending over.
    checks = [back_up, Check("pick_up.bends_knees", "starts standing and the pelvis sinks over "
                             "0.25 m", lambda r: r["start_pelvis_height"] > 0.7
                             and r["pelvis_drop"] > 0.25)]
    for side in SIDES if hand == "both" else (hand,):
        # GT: the reaching wrist 0.1-0.2 m above the floor (the fingers on it); then held in
        # front of the belly.
        checks += [Check(f"pick_up.{side}_down", f"the {side} wrist comes within 0.22 m of the "
                         "floor", lambda r, s=side: r[f"min_wrist_height.{s}"] < 0.22),
                   Check(f"pick_up.{side}_holds", f"once up again, the {side} wrist is held "
                         "0.15 m in front of the pelvis for 0.5 s",
                         lambda r, s=side: r[f"carry_hold.{s}"] >= 0.5)]
    if hand != "both":  # GT: the free hand rests on the knee, 0.1 m higher or more
        other = _other(hand)
        checks.append(Check(f"pick_up.{other}_not_down", f"the {other} wrist stays 0.07 m "
                            f"higher than the {hand} one",
                            lambda r: r[f"min_wrist_height.{other}"]
                            > r[f"min_wrist_height.{hand}"] + 0.07))
    return checks


def _in_place_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """jumping_jack, march_in_place, one_leg_stand: the legs work, the body stays put."""
    # Stepping in place while turning (turn, spin) or walking a circle back to the start
    # lifts the feet too: a pose held in place neither travels nor turns.
    put = Check(f"{family}.in_place", "the pelvis travels less than 0.8 m and turns less than "
                "45 degrees", lambda r: r["pelvis_path"] < 0.8
                and abs(r["heading_change"]) < np.radians(45))
    if family == "jumping_jack":
        count = params.get("count")
        return [put, Check("jumping_jack.opens", "feet apart with both hands overhead at least "
                           "twice", lambda r: r["jack_openings"] >= 2)] + (
            [Check("jumping_jack.count", f"{count} openings",
                   lambda r: r["jack_openings"] == count)] if count else [])
    if family == "march_in_place":
        # GT: each ankle lifts 0.2-0.35 m three times, never both off the floor.
        return [put, Check("march_in_place.knees_up", "each ankle lifts 0.15 m at least twice",
                           lambda r: min(r["ankle_lifts.left"], r["ankle_lifts.right"]) >= 2),
                Check("march_in_place.no_flight", "both feet 2 cm up in at most 3 frames",
                      lambda r: r["flight_frames"] <= 3)]
    leg = params.get("leg")
    sides = (leg,) if leg else SIDES

    def stands_on(r: Readings, s: str) -> bool:  # GT: the free ankle up 0.25 m for 2.6-3.4 s
        return r[f"foot_up_hold.{_other(s)}"] >= 1.5 and r[f"foot_lift.{s}"] < 0.08

    return [put, Check("one_leg_stand.leg", f"stands on the {leg or 'one'} leg: the other ankle "
                       "held 0.15 m up for 1.5 s while it stays down",
                       lambda r: any(stands_on(r, s) for s in sides)),
            Check("one_leg_stand.no_hop", "the standing foot stays on the floor",
                  lambda r: r["airborne_frames"] <= 1)]


def _lunge_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """lunge: the named foot steps well ahead, the body sinks onto the back knee, each time."""
    # GT: the front ankle 0.8-0.95 m ahead while down, the back knee 0.15-0.25 m over the floor,
    # down 0.5 s each time; a kneel stays down 1.3 s or more, a squat keeps the feet level.
    leg, count = params.get("leg"), params.get("count")
    sides = (leg,) if leg else SIDES

    def lunges(r: Readings, s: str) -> bool:
        return r[f"lunge_split.{s}"] > 0.5 and r[f"knee_clearance.{_other(s)}"] < 0.3

    checks = [Check("lunge.split", f"the {leg or 'one'} ankle 0.5 m ahead of the other while "
                    "the pelvis is down, the back knee within 0.3 m of the floor",
                    lambda r: any(lunges(r, s) for s in sides)),
              Check("lunge.drop", "the pelvis sinks over 0.2 m and comes straight back up "
                    "(down under 1 s at a time)",
                    lambda r: r["pelvis_drop"] > 0.2 and r["low_hold"] < 1.0),
              Check("lunge.grounded", "a foot always on the floor (at most 1 frame 5 cm up)",
                    lambda r: r["airborne_frames"] <= 1)]
    if count:
        checks.append(Check("lunge.count", f"{count} lunges", lambda r: r["pelvis_dips"] == count))
    return checks


def _gesture_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """point, salute, hands_on_hips, cross_arms, nod: a pose of the arms or head, held."""
    hand = params.get("hand")
    if family in ("point", "salute"):
        read = "point_hold" if family == "point" else "salute_hold"
        what = ("held 0.4 m in front of the pelvis at shoulder height" if family == "point"
                else "held within 0.2 m of the head, the elbow raised to the shoulder")
        sides = (hand,) if hand else SIDES
        checks = [Check(f"{family}.hand", f"the {hand or 'one'} wrist {what} for 1 s",
                        lambda r: any(r[f"{read}.{s}"] >= 1.0 for s in sides))]
        if hand:  # GT: the other wrist hangs 0.6 m below the head
            other = _other(hand)
            checks.append(Check(f"{family}.{other}_down", f"the {other} wrist stays 0.3 m below "
                                "the head", lambda r: r[f"wrist_height.{other}"] < -0.3))
        return checks
    if family == "hands_on_hips":
        # A pose stood in: lunges are often done with the hands on the hips too.
        return [Check("hands_on_hips.hold", "both wrists at hip height with the elbows 0.3 m "
                      "out for 1 s", lambda r: r["hands_on_hips_hold"] >= 1.0),
                Check("hands_on_hips.standing", "the pelvis sinks less than 0.1 m",
                      lambda r: r["pelvis_drop"] < 0.1)]
    if family == "cross_arms":
        return [Check("cross_arms.hold", "each wrist past the midline at chest height for 1 s",
                      lambda r: r["arms_crossed_hold"] >= 1.0)]
    count = params.get("count")  # nod
    checks = [Check("nod.head", "the head tips forward at least twice",
                    lambda r: r["head_nods"] >= 2),
              Check("nod.body_still", "standing (the pelvis 0.7 m up), the torso leans less "
                    "than 0.3 rad and the pelvis sinks less than 0.1 m",
                    lambda r: r["start_pelvis_height"] > 0.7 and r["torso_pitch"] < 0.3
                    and r["pelvis_drop"] < 0.1)]
    if count:
        checks.append(Check("nod.count", f"{count} nods", lambda r: r["head_nods"] == count))
    return checks


def _push_up_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """push_up: down from standing onto the hands, chest dips, back up."""
    # GT: prone on the hands 2.5 s or more, the chest joint from 0.45 m down to 0.2 m each time.
    count = params.get("count")
    checks = [Check("push_up.plank", "prone on both hands (chest down, wrists within 0.12 m of "
                    "the floor) for 1.5 s", lambda r: r["prone_hold"] >= 1.5),
              Check("push_up.dips", "the chest dips under 0.3 m at least twice",
                    lambda r: r["push_ups"] >= 2),
              Check("push_up.stands", "starts standing and ends within 0.1 m of that height",
                    lambda r: r["start_pelvis_height"] > 0.7
                    and r["end_pelvis_height"] > r["start_pelvis_height"] - 0.1)]
    if count:
        checks.append(Check("push_up.count", f"{count} push-ups",
                            lambda r: r["push_ups"] == count))
    return checks


MORE_CHECKS: dict[str, Callable[[str, Mapping[str, Any]], list[Check]]] = {
    "lie_down": lambda f, p: _floor_checks(f), "get_up": lambda f, p: _floor_checks(f),
    "sit_floor": lambda f, p: _floor_checks(f), "pick_up": _reach_checks,
    "touch_toes": _reach_checks, "jumping_jack": _in_place_checks,
    "march_in_place": _in_place_checks, "one_leg_stand": _in_place_checks,
    "point": _gesture_checks, "salute": _gesture_checks, "hands_on_hips": _gesture_checks,
    "cross_arms": _gesture_checks, "nod": _gesture_checks, "push_up": _push_up_checks,
    "lunge": _lunge_checks,
}

EXTRA_READINGS.append(more_readings)
EXTRA_CHECKS.update(MORE_CHECKS)
