"""From a script to global joint positions: clips, cross-fades, style noise, ground contact.

The ground-contact solver places the body in the world so that it is physically plausible:
the lowest contact point (ankle, ball of the foot, knee) touches the floor; the planted point
does not slide, so the root travels exactly as the stance leg pushes it (no foot skating by
construction); in flight phases the body follows the clip's clearance and keeps its velocity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mlct.data.synth.actions import Script
from mlct.data.synth.motions import ANGLE_CHANNELS, ARM_CHANNELS, Clip, Style, action_clip, \
    neutral, overlay_upper
from mlct.data.synth.rig import Rig, pose_positions, rot_y

BLEND_SECONDS = 0.4
SWITCH_MARGIN = 0.012  # metres: a new point must be this much lower to take over as the anchor


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


def concatenate(clips: list[Clip], fps: float) -> tuple[Clip, list[tuple[int, int]]]:
    """Cross-fade consecutive clips over BLEND_SECONDS; yaw continues from where it ended."""
    overlap = int(round(BLEND_SECONDS * fps))
    out = clips[0]
    segments = [(0, out.n)]
    for clip in clips[1:]:
        k = min(overlap, out.n // 2, clip.n // 2)
        w = 0.5 - 0.5 * np.cos(np.linspace(0, np.pi, k))  # 0 -> 1
        start = out.n - k
        yaw_end = out.channels["yaw"][-1]
        channels = {}
        for name, a in out.channels.items():
            b = clip.channels[name] + (yaw_end if name == "yaw" else 0.0)
            wk = w if a.ndim == 1 else w[:, None]
            mixed = (1 - wk) * a[start:] + wk * b[:k]
            channels[name] = np.concatenate([a[:start], mixed, b[k:]])
        clearance = np.concatenate([out.clearance[:start],
                                    np.maximum(out.clearance[start:], clip.clearance[:k]),
                                    clip.clearance[k:]])
        flight = np.concatenate([out.flight[:start], out.flight[start:] | clip.flight[:k],
                                 clip.flight[k:]])
        velocity = np.concatenate([out.flight_velocity[:start],
                                   np.where(clip.flight[:k, None], clip.flight_velocity[:k],
                                            out.flight_velocity[start:]),
                                   clip.flight_velocity[k:]])
        out = Clip(channels, clearance, flight, velocity)
        segments.append((start, out.n))
    return out, segments


def place_on_ground(rig: Rig, body: np.ndarray, clip: Clip) -> np.ndarray:
    """World positions (T, J, 3) from pelvis-relative positions `body` (T, J, 3)."""
    n = len(body)
    points = body[:, list(rig.contact_points)]  # (T, P, 3)
    heights = points[..., 1]
    root = np.zeros((n, 3))
    root[:, 1] = -heights.min(axis=1) + clip.clearance * rig.scale
    margin = SWITCH_MARGIN * rig.scale
    anchor = -1
    anchor_xz = np.zeros(2)
    velocity = np.zeros(2)
    heading = rot_y(clip.channels["yaw"])
    for t in range(n):
        if clip.flight[t]:
            v_body = clip.flight_velocity[t]
            if not np.isnan(v_body).any():
                # Body-frame velocity (x, z) turned into the world by the heading.
                v = heading[t] @ np.array([v_body[0], 0.0, v_body[1]]) * rig.scale
                velocity = v[[0, 2]]
            root[t, [0, 2]] = (root[t - 1, [0, 2]] if t else 0.0) + velocity
            anchor = -1
            continue
        lowest = int(np.argmin(heights[t]))
        if anchor < 0:
            # Landing (or the first frame): plant the lowest point where it is now.
            guess = root[t - 1, [0, 2]] + velocity if t else np.zeros(2)
            anchor, anchor_xz = lowest, guess + points[t, lowest, [0, 2]]
        elif heights[t, lowest] < heights[t, anchor] - margin:
            # Weight moved onto a new point: it has been planted since the previous frame, so
            # it holds the place it had then (the old point may already be lifting off).
            anchor, anchor_xz = lowest, root[t - 1, [0, 2]] + points[t - 1, lowest, [0, 2]]
        root[t, [0, 2]] = anchor_xz - points[t, anchor, [0, 2]]
        if t:
            # Take-off velocity: the mean over the last frames of stance, not the final push.
            first = max(0, t - 3)
            velocity = (root[t, [0, 2]] - root[first, [0, 2]]) / (t - first)
    return body + root[:, None, :]


def compose(script: Script, rig: Rig, style: Style, rng: np.random.Generator, fps: float,
            lead_in: float = 0.3, lead_out: float = 0.3) -> Composed:
    """Global joint positions (T, J, 3) of a script, in the skeleton's units."""
    clips = [neutral(max(2, int(round(lead_in * fps))), style)]
    for action in script.actions:
        clip = action_clip(action, rig, style, fps)
        if script.concurrent is not None:
            clip = overlay_upper(clip, script.concurrent, style, fps)
        clips.append(clip)
    clips.append(neutral(max(2, int(round(lead_out * fps))), style))
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
    positions = place_on_ground(rig, body, clip)
    # Only the clips of actions are segments; the lead-in and lead-out are idle.
    return Composed(positions, segments[1:-1])
