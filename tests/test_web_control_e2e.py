"""The page's controls in headless Chromium: draw a path on the floor view, generate, and the
motion's root follows the drawn path; pin a pose and it is kept at its frame. Like
tests/test_web_e2e.py (whose fixtures it reuses): Debian's chromium and playwright, or skipped.
MLCT_WEB_CONTROL_SCREENSHOT=PATH keeps the page's screenshot (docs/img/web_control.png).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from test_web_e2e import browser, page, url  # noqa: F401  (fixtures)

pytestmark = pytest.mark.slow  # a browser against a live server


def _distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """(N,) distance of each (x, z) point to the polyline (K, 2)."""
    a, b = line[:-1], line[1:]  # (K-1, 2)
    ab = b - a
    t = ((points[:, None] - a) * ab).sum(-1) / np.maximum((ab ** 2).sum(-1), 1e-12)
    closest = a + np.clip(t, 0, 1)[..., None] * ab  # (N, K-1, 2)
    return np.linalg.norm(points[:, None] - closest, axis=-1).min(axis=1)


def test_draw_a_path_and_the_motion_walks_it(page, tmp_path):  # noqa: F811
    box = page.locator("#floor").bounding_box()
    # a curve on the floor view: from near the centre up (+z) and to the right (+x)
    strokes = [(0.5, 0.55), (0.5, 0.45), (0.53, 0.35), (0.6, 0.27), (0.7, 0.22), (0.8, 0.2)]
    page.mouse.move(box["x"] + box["width"] * strokes[0][0], box["y"] + box["height"] * strokes[0][1])
    page.mouse.down()
    for u, v in strokes[1:]:
        page.mouse.move(box["x"] + box["width"] * u, box["y"] + box["height"] * v, steps=5)
    page.mouse.up()
    waypoints = np.array(page.evaluate("window.mlctControl.waypoints()"))
    assert len(waypoints) >= 5
    assert waypoints[-1, 0] > waypoints[0, 0] + 1 and waypoints[-1, 1] > waypoints[0, 1] + 1
    length = np.linalg.norm(np.diff(waypoints, axis=0), axis=1).sum()
    seconds = float(page.input_value("#seconds"))  # grown to walk the path at 0.45 m/s
    assert seconds == pytest.approx(min(9.8, np.ceil(length / 0.45 * 10) / 10), abs=0.11)
    page.fill("#prompt", "a person walks forward")
    page.press("#prompt", "Enter")
    page.wait_for_function("window.mlct.firstFrameMs.length === 2", timeout=60_000)
    joints = np.array(page.evaluate("window.mlct.state.motion.joints"))
    root = joints[:, 0][:, [0, 2]]
    assert np.linalg.norm(root[0] - waypoints[0]) < 0.05  # starts where the path starts
    assert np.linalg.norm(root[-1] - waypoints[-1]) < 0.05  # and ends where it ends
    assert _distance_to_polyline(root, waypoints).max() < 0.15  # on the path in between
    assert "error" not in (page.get_attribute("#status", "class") or "")

    # the screenshot: paused half-way along the drawn path
    page.click("#play")
    page.locator("#scrub").fill("40")
    page.wait_for_function("window.mlct.state.frame === 40", timeout=5_000)
    page.wait_for_timeout(300)  # control.js redraws the floor view on the next frames
    shot = tmp_path / "web_control.png"
    page.screenshot(path=str(shot))
    if os.environ.get("MLCT_WEB_CONTROL_SCREENSHOT"):
        target = Path(os.environ["MLCT_WEB_CONTROL_SCREENSHOT"])
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(shot, target)

    # pin the pose at frame 30, then generate from another prompt: the pose stays at frame 30
    page.locator("#scrub").fill("30")
    page.wait_for_function("window.mlct.state.frame === 30", timeout=5_000)
    pinned = joints[30]
    page.click("#pin-pose")
    page.click("#clear-path")
    page.fill("#prompt", "a person waves with the right hand")
    page.press("#prompt", "Enter")
    page.wait_for_function("window.mlct.firstFrameMs.length === 3", timeout=60_000)
    again = np.array(page.evaluate("window.mlct.state.motion.joints"))
    assert np.linalg.norm(again[30] - pinned, axis=-1).max() < 0.01
    assert "frame 30" in page.inner_text("#pins")
