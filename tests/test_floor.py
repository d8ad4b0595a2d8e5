"""Levelling a tilted capture floor (motion/floor.py, applied by `mlct data import`): a walk on a
floor tilted by a few degrees is turned back level, a level walk is left as it is, and so are
the motions whose floor rises for real (stairs) or that do not travel far enough to tell."""

from __future__ import annotations

import numpy as np
import pytest

from mlct.data.importer import import_dataset
from mlct.eval.readouts import flight_frames
from mlct.eval.suites.ground_truth import motion
from mlct.motion.floor import floor_gradient, level_floor, support_points
from mlct.motion.skeleton import HUMANML3D as SK


def tilted(joints: np.ndarray, degrees: float, heading: float = 0.0) -> np.ndarray:
    """`joints` on a floor rising `degrees` towards `heading` (radians about +y from +z)."""
    slope = np.tan(np.radians(degrees))
    direction = np.array([np.sin(heading), np.cos(heading)])
    rise = (joints[..., [0, 2]] @ direction) * slope
    out = joints.copy()
    out[..., 1] += rise  # a shear: exact for the floor, within 0.1 % of a turn for the body
    return out


@pytest.fixture(scope="module")
def walk() -> np.ndarray:
    return motion("walk", {"speed": "normal"}, seed=3)


def support_spread(joints: np.ndarray) -> float:
    heights = support_points(joints, SK)[:, 1]
    return float(heights.max() - heights.min())


@pytest.mark.parametrize("degrees, heading", [(1.5, 0.0), (3.0, 0.0), (2.0, 0.4)])
def test_a_walk_on_a_tilted_floor_is_turned_level(walk, degrees, heading):
    # the walk goes along +z; heading 0.4 rad tilts the floor partly across it too, and only
    # the part along the travel can be read
    steep = tilted(walk, degrees, heading)
    assert support_spread(steep) > 0.05  # the feet end 8-17 cm above where they started
    gradient = floor_gradient(steep, SK)
    assert gradient is not None
    along = np.tan(np.radians(degrees)) * np.cos(heading)
    assert gradient[1] == pytest.approx(along, abs=0.003)
    level, tilt = level_floor(steep, SK)
    assert np.degrees(tilt) == pytest.approx(np.degrees(np.arctan(np.linalg.norm(gradient))))
    assert support_spread(level) < 0.015
    # the body is turned, not deformed: bone lengths stay
    bones = [(0, 3), (3, 6), (1, 4), (4, 7), (2, 5), (5, 8)]
    for a, b in bones:
        before = np.linalg.norm(steep[:, a] - steep[:, b], axis=-1)
        after = np.linalg.norm(level[:, a] - level[:, b], axis=-1)
        np.testing.assert_allclose(after, before, atol=1e-9)


def test_a_level_walk_stays_as_it_is(walk):
    level, tilt = level_floor(walk, SK)
    assert np.degrees(tilt) < 0.2
    assert np.abs(level - walk).max() < 0.01


def test_stairs_and_motions_in_place_keep_their_floor():
    stairs = motion("walk_upstairs", {}, seed=0)
    assert floor_gradient(stairs, SK) is None  # rises ~30 degrees: the terrain's own
    same, tilt = level_floor(stairs, SK)
    assert tilt == 0.0 and same is stairs
    wave = motion("wave", {"hand": "right", "count": 3}, seed=0)
    assert floor_gradient(tilted(wave, 2.0), SK) is None  # it does not travel: nothing to read


def test_the_importer_levels_a_tilted_walk_and_says_so(tmp_path, walk):
    src = tmp_path / "joints"
    src.mkdir()
    np.save(src / "walk.npy", tilted(walk, 2.0).astype(np.float32))
    captions = tmp_path / "captions.csv"
    captions.write_text("name,caption\nwalk,a person walks forward\n", encoding="utf-8")
    flights = {}
    for level in (True, False):
        out = tmp_path / f"out_{level}"
        summary = import_dataset(out, captions, joints_dir=src, scale=1.0, fps=SK.fps,
                                 split=(1.0, 0.0, 0.0), level=level)
        joints = np.load(out / "new_joints" / "walk.npy")
        flights[level] = flight_frames(joints)
        if level:
            assert summary.clip_tilts["walk"] == pytest.approx(2.0, abs=0.2)
        else:
            assert "walk" not in summary.clip_tilts
    # levelled, the walk keeps a foot on the floor; as captured it reads as one in flight
    assert flights[True] <= 3 < flights[False]
