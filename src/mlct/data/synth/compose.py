"""From a script to global joint positions: clips, cross-fades, style noise, ground contact.

The ground-contact solver places the body in the world so that it is physically plausible:
the lowest contact point (ankle, ball of the foot, knee) touches the floor; the planted points
barely slide, so the root travels as the stance leg pushes it, with a bounded acceleration; in
flight phases the body follows the clip's clearance and keeps its velocity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mlct.data.synth.actions import ENDS_DOWN, STARTS_DOWN, Script
from mlct.data.synth.more_clips import action_clip
from mlct.data.synth.motions import ANGLE_CHANNELS, ARM_CHANNELS, BLEND_SECONDS, \
    GROUND_CHANNELS, Clip, Style, concatenate, held, neutral, overlay_upper  # noqa: F401
from mlct.data.synth.rig import Rig, pose_positions, rot_y

CONTACT_SOFTNESS = 0.01  # metres: a contact point this much higher than the lowest bears 1/e as much
SEAT_GRIP = 10.0  # how much more a touching seat or back holds than a touching foot or hand
MAX_ACCELERATION = 12.0  # m/s^2: bound on the root's horizontal acceleration (sprint starts reach ~10)


@dataclass
class Composed:
    """A composed motion: positions (T, J, 3) and where each action starts and ends (frames)."""

    positions: np.ndarray
    segments: list[tuple[int, int]]


def smooth_noise(rng: np.random.Generator, n: int, fps: float, scale: float,
                 cutoff_hz: float = 0.6) -> np.ndarray:
    """Low-frequency noise: a few random sinusoids below `cutoff_hz`."""
    t = np.arange(n) / fps
    freqs = rng.uniform(0.1, cutoff_hz, size=3)
    phases = rng.uniform(0, 2 * np.pi, size=3)
    weights = rng.normal(size=3) / np.sqrt(3)
    return scale * sum(w * np.sin(2 * np.pi * f * t + p) for w, f, p in zip(weights, freqs, phases))


def _ground(rig: Rig, clip: Clip, joints: tuple[int, ...]) -> np.ndarray | None:
    """(T, len(joints)) height of the ground under each joint in skeleton units: its side's
    ground channel, the mean of both for the joints of the midline; None on the flat floor."""
    left, right = (clip.channels[name] for name in GROUND_CHANNELS)
    if not (left.any() or right.any()):
        return None  # the flat floor: heights left as the very floats they always were
    sides = {j: side for side in ("left", "right") for j in (
        rig.hip[side], rig.knee[side], rig.ankle[side], *rig.foot[side], rig.shoulder[side],
        rig.elbow[side], rig.wrist[side])}
    level = {"left": left, "right": right, None: 0.5 * (left + right)}
    return np.stack([level[sides.get(j)] for j in joints], -1) * rig.scale


def place_on_ground(rig: Rig, body: np.ndarray, clip: Clip, fps: float) -> np.ndarray:
    """World positions (T, J, 3) from pelvis-relative positions `body` (T, J, 3).

    In stance the root moves opposite to the body-frame velocity of the contact points, each
    weighted by how close it is to the floor (a soft minimum over CONTACT_SOFTNESS): the
    lowest point stays planted and weight passes from heel to ball to the other foot. The
    root's horizontal acceleration is bounded by MAX_ACCELERATION; where the rig's feet ask for
    more, they slide for a frame or two. (Benchmark v1 pinned one anchor point at a time; a
    swing foot that became the lowest while still travelling forward relative to the pelvis
    threw the root 0.2 m backwards once per jog and run stride, and jog was no faster than walk.)
    """
    n = len(body)
    points = body[:, list(rig.contact_points)]  # (T, P, 3)
    heights = points[..., 1]
    ground = _ground(rig, clip, rig.contact_points)
    if ground is not None:  # stairs: each point's height over the ground under its foot
        heights = heights - ground
    root = np.zeros((n, 3))
    root[:, 1] = -heights.min(axis=1) + clip.clearance * rig.scale
    on_floor = clip.channels["floor"] > 0.5
    if on_floor.any():
        # Floor poses: the seat, back, head and hands touch the floor too, each through its
        # flesh; the seat, back and planted hands hold the body still while the legs slide out
        # or in (SEAT_GRIP), as a sitting person's weight rests on the buttocks, not the heels,
        # and the feet jump back to a plank behind the hands.
        joints, flesh = zip(*rig.floor_points.items())
        floor_points = body[:, list(joints)]
        floor_heights = floor_points[..., 1] - np.array(flesh) * rig.scale
        floor_ground = _ground(rig, clip, joints)
        if floor_ground is not None:
            floor_heights = floor_heights - floor_ground
        grip = np.array([SEAT_GRIP if j in (0, *rig.spine, *rig.wrist.values()) else 1.0
                         for j in joints])
        root[on_floor, 1] = -floor_heights[on_floor].min(axis=1) + clip.clearance[on_floor] \
            * rig.scale
    softness = CONTACT_SOFTNESS * rig.scale
    velocity = np.zeros(2)
    heading = rot_y(clip.channels["yaw"])
    previous = np.zeros(2)  # the root's last step (x, z)
    landed = True
    for t in range(1, n):
        if clip.flight[t]:
            v_body = clip.flight_velocity[t]
            if not np.isnan(v_body).any():
                # Body-frame velocity (x, z) turned into the world by the heading.
                v = heading[t] @ np.array([v_body[0], 0.0, v_body[1]]) * rig.scale
                velocity = v[[0, 2]]
            root[t, [0, 2]] = root[t - 1, [0, 2]] + velocity
            previous = velocity
            landed = False
            continue
        if not landed:
            # Touch-down frame: the body keeps its flight velocity; the feet take over after.
            root[t, [0, 2]] = root[t - 1, [0, 2]] + velocity
            previous = velocity
            landed = True
            continue
        # Soft minimum over this frame's heights: the lowest points bear the weight.
        if on_floor[t]:
            weight = np.exp(-(floor_heights[t] - floor_heights[t].min()) / softness) * grip
            slide = floor_points[t, :, [0, 2]].T - floor_points[t - 1, :, [0, 2]].T
        else:
            weight = np.exp(-(heights[t] - heights[t].min()) / softness)
            slide = points[t, :, [0, 2]].T - points[t - 1, :, [0, 2]].T  # (P, 2) body-frame motion
        weight /= weight.sum()
        step = -weight @ slide
        # The rig's feet are posed by joint angles, not by physics: around toe-off and touch-down
        # they can sweep 0.2 m in a frame. A body cannot change its speed that fast, so the
        # change of root velocity is bounded (the feet slide a little instead).
        change = step - previous
        limit = MAX_ACCELERATION * rig.scale / fps**2
        if np.linalg.norm(change) > limit:
            step = previous + change * (limit / np.linalg.norm(change))
        root[t, [0, 2]] = root[t - 1, [0, 2]] + step
        previous = step
        # Take-off velocity: the mean over the last frames of stance, not the final push.
        first = max(0, t - 3)
        velocity = (root[t, [0, 2]] - root[first, [0, 2]]) / (t - first)
    return body + root[:, None, :]


def compose(script: Script, rig: Rig, style: Style, rng: np.random.Generator, fps: float,
            lead_in: float = 0.3, lead_out: float = 0.3) -> Composed:
    """Global joint positions (T, J, 3) of a script, in the skeleton's units."""
    actions = [action_clip(action, rig, style, fps) for action in script.actions]
    if script.concurrent is not None:
        actions = [overlay_upper(clip, script.concurrent, style, fps) for clip in actions]
    # Idle lead-in and lead-out: standing, or lying still before getting up and after lying down.
    n_in, n_out = max(2, int(round(lead_in * fps))), max(2, int(round(lead_out * fps)))
    first, last = script.actions[0].family, script.actions[-1].family
    clips = [held(actions[0], 0, n_in) if first in STARTS_DOWN else neutral(n_in, style),
             *actions,
             held(actions[-1], -1, n_out) if last in ENDS_DOWN else neutral(n_out, style)]
    clip, segments = concatenate(clips, fps)
    n = clip.n
    # Natural variation: slow drifts of posture on every angle channel, a few degrees.
    for name in ANGLE_CHANNELS:
        if name != "yaw":
            clip.channels[name] = clip.channels[name] + smooth_noise(rng, n, fps, 0.03)
    for name in ARM_CHANNELS:
        if name.startswith("wrist"):
            clip.channels[name] = clip.channels[name] + np.stack(
                [smooth_noise(rng, n, fps, 0.015) for _ in range(3)], -1)
    body = pose_positions(rig, clip.channels)
    positions = place_on_ground(rig, body, clip, fps)
    # Only the clips of actions are segments; the lead-in and lead-out are idle.
    return Composed(positions, segments[1:-1])
