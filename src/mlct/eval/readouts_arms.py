"""Read-outs and checks of the arm, gesture and sports families of benchmark version 4
(mlct.data.synth.families_arms), registered with readouts.py as readouts_more.py's are.

Same conventions as mlct.eval.readouts (joints (T, 22, 3) in metres, y up, 20 fps, the person's
left and right); positions of the hands are taken relative to the neck, in the body's frame at
the window's first frame (forward, left), so that a torso turning with a swing does not turn
the frame with it. Each check is a necessary physical condition, with its threshold between the
range of the family's own ground truth (in the comments: the 300 motions of each family that
bench/quality.py ground-truth measures) and what the other families' motions show.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

import numpy as np

from mlct.eval.readouts import (ANKLE, EXTRA_CHECKS, EXTRA_READINGS, FPS, HEAD, L_HIP, NECK,
                                PELVIS, R_HIP, SHOULDER, SIDES, WRIST, Check, Readings,
                                _count_episodes, _initial_axes, _other, _reversals,
                                _torso_angles)

_ELBOW = {"left": 18, "right": 19}
_NONE = 99.0  # seconds: what a timing read-out says when the motion never does it


def _longest(mask: np.ndarray) -> float:
    """Longest run of True, in seconds."""
    longest = run = 0
    for value in mask:
        run = run + 1 if value else 0
        longest = max(longest, run)
    return longest / FPS


def _whip(start: np.ndarray, end: np.ndarray) -> float:
    """Seconds from a frame in `start` to the first later frame in `end`, the shortest such
    wait over the clip (a wind-up then a strike); _NONE if no `end` frame follows a `start` one."""
    best, last = _NONE, None
    for i in range(len(start)):
        if start[i]:
            last = i
        elif end[i] and last is not None:
            best = min(best, (i - last) / FPS)
    return best


def _twist(joints: np.ndarray) -> np.ndarray:
    """(T,) angle (radians, left-positive) of the shoulder line from the hip line, seen from
    above: the upper body turned on the hips."""
    def angle(a: int, b: int) -> np.ndarray:
        d = joints[:, a] - joints[:, b]
        return np.arctan2(d[:, 0], d[:, 2])
    diff = angle(SHOULDER["right"], SHOULDER["left"]) - angle(R_HIP, L_HIP)
    return np.angle(np.exp(1j * diff))


def arms_readings(joints: np.ndarray) -> dict[str, float]:
    """The read-outs of this module as a flat {name: value} dict (metres, radians, seconds,
    counts; per-side ones as 'name.left' / 'name.right'), in the body's frame at the first
    frame, relative to the neck."""
    forward, left = _initial_axes(joints)
    neck = joints[:, NECK]
    head = joints[:, HEAD]
    pelvis_y = joints[:, PELVIS, 1]
    r: dict[str, float] = {}
    fwd, lat, up, rel = {}, {}, {}, {}
    for s in SIDES:
        rel[s] = joints[:, WRIST[s]] - neck
        fwd[s] = rel[s] @ forward
        lat[s] = rel[s] @ left
        up[s] = joints[:, WRIST[s], 1] - joints[:, SHOULDER[s], 1]
    gap = np.linalg.norm(joints[:, WRIST["left"]] - joints[:, WRIST["right"]], axis=-1)
    together = gap < 0.15
    mid = 0.5 * (rel["left"] + rel["right"])
    mid_lat = mid @ left
    mid_y = 0.5 * (joints[:, WRIST["left"], 1] + joints[:, WRIST["right"], 1]) - pelvis_y
    r["grip_hold"] = _longest(together)
    # Two-handed swings: the gripped hands from the right side to the left side.
    r["grip_swing"] = _whip(together & (mid_lat < -0.08), together & (mid_lat > 0.12))
    r["grip_low"] = float(mid_y[together].min()) if together.any() else _NONE
    r["grip_front_height"] = (float(np.median(mid_y[together & (np.abs(mid_lat) < 0.12)]))
                              if (together & (np.abs(mid_lat) < 0.12)).any() else -_NONE)
    r["grip_right"] = float(-mid_lat[together].min()) if together.any() else -_NONE
    r["grip_left"] = float(mid_lat[together].max()) if together.any() else -_NONE
    twist = _twist(joints)
    r["twist_left"], r["twist_right"] = float(twist.max()), float(-twist.min())
    pitch = _torso_angles(joints)[0]
    r["lean_back"] = float(-pitch.min())
    # Both hands overhead and together (a two-handed shot).
    over = (joints[:, WRIST["left"], 1] > head[:, 1] + 0.05) & (
        joints[:, WRIST["right"], 1] > head[:, 1] + 0.05)
    r["hands_up_together"] = _longest(over & (gap < 0.32))
    out_both = ((np.abs(lat["left"]) > 0.4) & (np.abs(lat["right"]) > 0.4)
                & (np.abs(up["left"]) < 0.2) & (np.abs(up["right"]) < 0.2))
    r["arms_out_hold"] = _longest(out_both)
    speed = np.linalg.norm(np.diff(joints[:, [WRIST["left"], WRIST["right"]]], axis=0),
                           axis=-1).max(axis=1) * FPS
    r["peak_wrist_speed"] = float(speed.max())
    both_front = (fwd["left"] > 0.35) & (fwd["right"] > 0.35)
    r["both_push"] = float(_count_episodes(both_front, min_gap=4))
    # Pelvis over the feet, sideways: swaying.
    feet = 0.5 * (joints[:, ANKLE["left"]] + joints[:, ANKLE["right"]])
    r["hip_sway"] = float(_reversals((joints[:, PELVIS] - feet) @ left, 0.025))
    r["roll_sway"] = float(_reversals(_torso_angles(joints)[1], 0.06))
    mouth = head + 0.09 * forward - np.array([0.0, 0.06, 0.0])
    for s in SIDES:
        sign = 1.0 if s == "left" else -1.0
        cocked = (up[s] > -0.02) & (fwd[s] < -0.08)
        r[f"throw_whip.{s}"] = _whip(cocked, (fwd[s] > 0.25) & (up[s] > -0.3))
        # A forehand: back at its own side behind the shoulders, then across in front.
        back = (sign * lat[s] > 0.3) & (fwd[s] < 0.05) & (gap > 0.35)
        r[f"forehand_whip.{s}"] = _whip(back, (sign * lat[s] < 0.02) & (fwd[s] > 0.1))
        r[f"at_mouth_hold.{s}"] = _longest(np.linalg.norm(joints[:, WRIST[s]] - mouth, axis=-1)
                                           < 0.11)
        ear = head + sign * 0.1 * left - np.array([0.0, 0.07, 0.0])
        r[f"at_ear_hold.{s}"] = _longest(np.linalg.norm(joints[:, WRIST[s]] - ear, axis=-1)
                                         < 0.08)
        elbow_low = joints[:, _ELBOW[s], 1] < joints[:, SHOULDER[s], 1] - 0.12
        r[f"elbow_low_hold.{s}"] = _longest(elbow_low & (up[s] > -0.05))
        front = (fwd[s] > 0.3) & (np.abs(up[s]) < 0.25)
        r[f"circle_lat.{s}"] = float(_reversals(lat[s][front], 0.06))
        r[f"circle_up.{s}"] = float(_reversals(up[s][front], 0.06))
        out = (np.abs(lat[s]) > 0.4) & (np.abs(up[s]) < 0.2)
        r[f"arm_out_hold.{s}"] = _longest(out)
        r[f"out_circles.{s}"] = float(_reversals(up[s][out], 0.05))
        level = np.abs(up[s]) < 0.2
        r[f"sweep_level.{s}"] = float(_reversals(lat[s][level], 0.12))
        waist = (joints[:, WRIST[s], 1] > pelvis_y) & (up[s] < -0.05) & (fwd[s] > 0.1)
        r[f"curls.{s}"] = float(_reversals(fwd[s][waist], 0.06))
        low = joints[:, WRIST[s], 1] < pelvis_y + 0.15
        r[f"pats.{s}"] = float(_reversals(joints[:, WRIST[s], 1][low], 0.05))
        r[f"pulls.{s}"] = float(_reversals(fwd[s][(up[s] < 0.05) & (up[s] > -0.4)], 0.1))
        r[f"wrist_below_shoulder.{s}"] = float(-up[s].max())
    return {k: float(v) for k, v in r.items()}


# ---------------------------------------------------------------------------- checks

def _sides(params: Mapping[str, Any]) -> tuple[str, ...]:
    hand = params.get("hand")
    return (hand,) if hand else SIDES


def _one_hand(family: str, params: Mapping[str, Any], name: str, what: str,
              test: Callable[[Readings, str], bool], idle: bool = True) -> list[Check]:
    """A check of the named hand (either, unnamed), and with `idle` that the other hangs: its
    wrist stays 0.3 m below the head (readouts.wrist_height)."""
    hand = params.get("hand")
    sides = _sides(params)
    checks = [Check(f"{family}.{name}", f"the {hand or 'one'} {what}",
                    lambda r: any(test(r, s) for s in sides))]
    if hand and idle:
        other = _other(hand)
        checks.append(Check(f"{family}.{other}_down", f"the {other} wrist stays 0.3 m below the "
                            "head", lambda r: r[f"wrist_height.{other}"] < -0.3))
    return checks


_IN_PLACE = ("the pelvis travels less than 0.8 m", lambda r: r["pelvis_path"] < 0.8)


def _in_place(family: str) -> Check:
    return Check(f"{family}.in_place", *_IN_PLACE)


def _swing_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """throw, golf_swing, bat_swing, tennis_swing: a fast strike of the arm(s) in place."""
    if family == "throw":
        # GT: 0.05-0.1 s from the wound-up hand (above the shoulder, behind the neck) to out in
        # front; the peak wrist speed 8.6-11.5 m/s; the hands never nearer than 0.27 m. A bat
        # swing's hands (together) take 0.25 s.
        def whips(r: Readings, s: str) -> bool:
            return r[f"throw_whip.{s}"] < 0.2
        return _one_hand(family, params, "whip", "hand winds up above the shoulder behind the "
                         "neck and is out 0.25 m in front within 0.2 s", whips, idle=False) + [
            Check("throw.fast", "a wrist moves faster than 6 m/s",
                  lambda r: r["peak_wrist_speed"] > 6.0),
            Check("throw.one_hand", "the hands stay 0.2 m apart", lambda r: r["min_hand_gap"]
                  > 0.2)] + ([Check(f"throw.{_other(params['hand'])}_still",
                                    f"the {_other(params['hand'])} hand does not throw",
                                    lambda r: r[f"throw_whip.{_other(params['hand'])}"] >= 0.5)]
                             if params.get("hand") else [])
    if family == "tennis_swing":
        # GT: 0.2-0.25 s from the racket hand back at its side (0.3 m out, behind the neck,
        # the hands 0.35 m apart) to across the midline in front; peak wrist speed 7.7-10 m/s.
        hand = params.get("hand")
        checks = _one_hand(family, params, "forehand", "hand swings from back at its own side "
                           "to across the front within 0.5 s",
                           lambda r, s: r[f"forehand_whip.{s}"] < 0.5, idle=False)
        checks.append(Check("tennis_swing.fast", "a wrist moves faster than 5 m/s",
                            lambda r: r["peak_wrist_speed"] > 5.0))
        if hand:
            other = _other(hand)
            checks.append(Check(f"tennis_swing.{other}_still", f"the {other} hand makes no "
                                "forehand", lambda r: r[f"forehand_whip.{other}"] >= 0.5))
        return checks + [_in_place(family)]
    gripped = Check(f"{family}.grip", "both hands within 0.15 m of each other (on the club or "
                    "bat) for 1.5 s", lambda r: r["grip_hold"] >= 1.5)
    if family == "golf_swing":
        # GT: the gripped hands from the right side to the left in 0.3-0.75 s, down to the
        # pelvis's height (-0.03 to -0.01 m) on the way; the torso bent 0.44-0.49 rad forward.
        return [gripped, Check("golf_swing.through", "the gripped hands go from the right side "
                               "to the left within 1 s", lambda r: r["grip_swing"] < 1.0),
                Check("golf_swing.low", "the gripped hands come down within 0.1 m of the "
                      "pelvis's height", lambda r: r["grip_low"] < 0.1),
                Check("golf_swing.bent", "the torso bends over 0.3 rad forward",
                      lambda r: r["torso_pitch"] > 0.3), _in_place(family)]
    # bat_swing. GT: right to left in 0.15-0.2 s; in front the hands 0.22-0.26 m above the
    # pelvis, never below 0.19 m; the torso within 0.1 rad of upright.
    return [gripped, Check("bat_swing.through", "the gripped hands go from the right side to "
                           "the left within 0.45 s", lambda r: r["grip_swing"] < 0.45),
            Check("bat_swing.level", "the gripped hands stay 0.1 m above the pelvis",
                  lambda r: r["grip_low"] > 0.1),
            Check("bat_swing.upright", "the torso leans less than 0.25 rad forward",
                  lambda r: r["torso_pitch"] < 0.25), _in_place(family)]


def _head_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """drink, phone_call: a hand held at the mouth or the ear."""
    if family == "drink":
        # GT: the wrist within 0.11 m of the mouth for 1.1-1.75 s, the elbow 0.12 m below the
        # shoulder meanwhile (a salute holds the elbow out at shoulder height, 0.4 s at most).
        def drinks(r: Readings, s: str) -> bool:
            return 0.7 <= r[f"at_mouth_hold.{s}"] < 2.4 and r[f"elbow_low_hold.{s}"] >= 0.8
        return _one_hand(family, params, "to_mouth", "wrist held within 0.11 m of the mouth for "
                         "0.7-2.4 s, the elbow down", drinks)
    # phone_call. GT: the wrist within 0.08 m of the jaw below the ear for 2.85-3.75 s.
    return _one_hand(family, params, "at_ear", "wrist held beside the jaw for 2 s",
                     lambda r, s: r[f"at_ear_hold.{s}"] >= 2.0) + [_in_place(family)]


def _circle_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """wash_window, arm_circles, direct_traffic, beckon, dribble: a hand's repeated path."""
    if family == "wash_window":
        # GT: 8 reversals sideways and 8-9 up and down of the wrist out in front at shoulder
        # height; a clap or punch reverses 5 ways at most in one of the two.
        checks = _one_hand(family, params, "circles", "wrist circles 0.3 m in front at shoulder "
                           "height: 6 reversals sideways and 6 up and down",
                           lambda r, s: r[f"circle_lat.{s}"] >= 6 and r[f"circle_up.{s}"] >= 6)
        return checks + [_in_place(family)]
    if family == "arm_circles":
        # GT: both arms out at shoulder height 4.3-5.5 s, 13 up-and-down reversals each; a
        # balancing walk holds them out still while travelling.
        return [Check("arm_circles.out", "both wrists 0.4 m out at shoulder height for 2.5 s",
                      lambda r: r["arms_out_hold"] >= 2.5),
                Check("arm_circles.circling", "each wrist, out, reverses up and down 8 times",
                      lambda r: min(r["out_circles.left"], r["out_circles.right"]) >= 8),
                _in_place(family)]
    if family == "direct_traffic":
        # GT: the waving wrist 7-9 reversals sideways at shoulder height; the other held out.

        def directs(r: Readings, s: str) -> bool:
            return r[f"sweep_level.{s}"] >= 5 and r[f"arm_out_hold.{_other(s)}"] >= 1.5
        return _one_hand(family, params, "wave_on", "arm sweeps sideways at shoulder height 5 "
                         "times while the other is held out at its side for 1.5 s", directs,
                         idle=False) + [_in_place(family)]
    if family == "beckon":
        # GT: 9 forward-and-back reversals of the wrist at waist height; jogs and pulls on a
        # rope do it with both hands. Standing: the pelvis rises 0.018 m at most; a jump rope's
        # hops lift it 0.14 m, its hands circling at the hips reversing forward and back too
        # (6-7 times one of them, 1-3 the other).
        def beckons(r: Readings, s: str) -> bool:
            return r[f"curls.{s}"] >= 6 and r[f"curls.{_other(s)}"] <= 3
        return _one_hand(family, params, "curls", "forearm curls in and out 6 times at waist "
                         "height (the other not)", beckons) + [
            Check("beckon.standing", "the pelvis rises less than 0.06 m (no hopping)",
                  lambda r: r["pelvis_rise"] < 0.06), _in_place(family)]
    # dribble. GT: 13-15 up-and-down reversals of the wrist at hip height; a walk's swinging
    # hands do it up to 12 times, both of them.
    def dribbles(r: Readings, s: str) -> bool:
        return r[f"pats.{s}"] >= 10 and r[f"pats.{_other(s)}"] <= 4
    return _one_hand(family, params, "pats", "hand pats down 10 times at hip height (the "
                     "other not)", dribbles, idle=False) + [_in_place(family)]


def _body_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """look_around, shoot_basketball, sway, pull_rope, tai_chi."""
    if family == "look_around":
        # GT: the shoulders turn 0.51-0.72 rad on the hips each way; a punch turns 0.36 one way
        # with the fists up.
        return [Check("look_around.turns", "the shoulders turn 0.35 rad on the hips to each "
                      "side", lambda r: min(r["twist_left"], r["twist_right"]) > 0.35),
                Check("look_around.arms_down", "both wrists stay 0.3 m below the shoulders",
                      lambda r: min(r["wrist_below_shoulder.left"],
                                    r["wrist_below_shoulder.right"]) > 0.3),
                Check("look_around.facing", "the body turns less than 20 degrees",
                      lambda r: abs(r["heading_change"]) < np.radians(20))]
    if family == "shoot_basketball":
        # GT: both wrists over the head 0.18 m apart for 0.6-0.75 s; 5 frames of flight.
        # Sit-ups (lying, the hands behind the head) hold the hands past the head too.
        return [Check("shoot_basketball.standing", "starts standing: the pelvis 0.7 m up",
                      lambda r: r["start_pelvis_height"] > 0.7),
                Check("shoot_basketball.release", "both wrists over the head within 0.32 m of "
                      "each other for 0.3 s", lambda r: r["hands_up_together"] >= 0.3),
                Check("shoot_basketball.jump", "both feet off the floor at least 2 frames",
                      lambda r: r["flight_frames"] >= 2), _in_place(family)]
    if family == "sway":
        # GT: 8-10 reversals of the pelvis sideways over the feet and 8-9 of the torso's roll;
        # a circle walk's pelvis reverses, its torso does not.
        return [Check("sway.hips", "the pelvis shifts sideways over the feet 6 times",
                      lambda r: r["hip_sway"] >= 6),
                Check("sway.lean", "the torso rolls side to side 6 times",
                      lambda r: r["roll_sway"] >= 6),
                Check("sway.feet_down", "neither ankle lifts over 0.08 m",
                      lambda r: max(r["foot_lift.left"], r["foot_lift.right"]) < 0.08),
                Check("sway.arms_down", "both wrists stay 0.3 m below the shoulders",
                      lambda r: min(r["wrist_below_shoulder.left"],
                                    r["wrist_below_shoulder.right"]) > 0.3)]
    if family == "pull_rope":
        # GT: leaning back 0.26-0.34 rad, 9 reversals forward and back of each wrist.
        return [Check("pull_rope.lean_back", "the torso leans back over 0.18 rad",
                      lambda r: r["lean_back"] > 0.18),
                Check("pull_rope.pulls", "each wrist pulls in and reaches out 6 times",
                      lambda r: min(r["pulls.left"], r["pulls.right"]) >= 6),
                Check("pull_rope.standing", "the pelvis sinks less than 0.25 m",
                      lambda r: r["pelvis_drop"] < 0.25), _in_place(family)]
    # tai_chi. GT: two pushes of both hands 0.35 m out in front, the wrists never faster than
    # 0.43-0.51 m/s, on knees bent 0.06 m.
    return [Check("tai_chi.pushes", "both hands pushed 0.35 m out in front twice",
                  lambda r: r["both_push"] >= 2),
            Check("tai_chi.slow", "no wrist faster than 1 m/s",
                  lambda r: r["peak_wrist_speed"] < 1.0),
            Check("tai_chi.knees", "the pelvis sinks 0.03 m or more",
                  lambda r: r["pelvis_drop"] > 0.03), _in_place(family)]


ARMS_CHECKS: dict[str, Callable[[str, Mapping[str, Any]], list[Check]]] = {
    **dict.fromkeys(("throw", "golf_swing", "bat_swing", "tennis_swing"), _swing_checks),
    **dict.fromkeys(("drink", "phone_call"), _head_checks),
    **dict.fromkeys(("wash_window", "arm_circles", "direct_traffic", "beckon", "dribble"),
                    _circle_checks),
    **dict.fromkeys(("look_around", "shoot_basketball", "sway", "pull_rope", "tai_chi"),
                    _body_checks),
}

EXTRA_READINGS.append(arms_readings)
EXTRA_CHECKS.update(ARMS_CHECKS)
