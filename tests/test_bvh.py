"""BVH export checked by an independent reader: bvhio parses the file and its own hierarchy
computes world positions, which must be the joints we wrote."""

from __future__ import annotations

import math

import bvhio
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mlct.data.synth.build import make_motion
from mlct.errors import MlctError
from mlct.generate.output.exports import save_motion
from mlct.generate.output.generated import GeneratedMotion
from mlct.motion.bvh import TO_CENTIMETRES, bvh_text, read_bvh, write_bvh
from mlct.motion.skeleton import HUMANML3D, KIT, Skeleton

SKELETONS = [HUMANML3D, KIT]


def bvhio_positions(path) -> tuple[list[str], np.ndarray]:
    """Joint names and (T, N, 3) world positions by bvhio's hierarchy, one frame at a time."""
    root = bvhio.readAsHierarchy(str(path))
    joints = [joint for joint, _, _ in root.layout()]
    n_frames = bvhio.readAsBvh(str(path), loadKeyFrames=False).FrameCount
    out = np.empty((n_frames, len(joints), 3))
    for frame in range(n_frames):
        root.loadPose(frame)
        out[frame] = [tuple(joint.PositionWorld) for joint in joints]
    return [joint.Name for joint in joints], out


def error_cm(path, joints: np.ndarray, skeleton: Skeleton) -> float:
    """Largest distance (cm) between bvhio's positions and our joints, matched by name."""
    names, positions = bvhio_positions(path)
    assert sorted(names) == sorted(skeleton.joint_names)
    ours = joints[:, [skeleton.index(name) for name in names]] * TO_CENTIMETRES[skeleton.unit]
    return float(np.linalg.norm(positions - ours, axis=-1).max())


def rigid_motion(skeleton: Skeleton, n_frames: int, seed: int, turns: float = 0.5) -> np.ndarray:
    """(T, J, 3) positions of a rigid skeleton as BVH moves one: every joint rotates all its
    children together (smooth random local rotations), the root walks and turns about y."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n_frames)[:, None]
    axes = rng.normal(size=(skeleton.n_joints, 3))
    angles = 0.6 * np.sin(2 * math.pi * (rng.uniform(0.5, 2.0, skeleton.n_joints) * t
                                         + rng.uniform(0, 1, skeleton.n_joints)))  # (T, J)
    axes = axes / np.linalg.norm(axes, axis=-1, keepdims=True)
    local = Rotation.from_rotvec((angles[..., None] * axes).reshape(-1, 3)).as_matrix()
    local = local.reshape(n_frames, skeleton.n_joints, 3, 3)
    local[:, 0] = Rotation.from_euler("y", 2 * math.pi * turns * t).as_matrix()
    world = np.empty_like(local)
    pos = np.empty((n_frames, skeleton.n_joints, 3))
    height = 0.9 * TO_CENTIMETRES["m"] / TO_CENTIMETRES[skeleton.unit]  # 0.9 m in skeleton units
    pos[:, 0] = np.concatenate([t * height, np.full_like(t, height), t * height], axis=1)
    world[:, 0] = local[:, 0]
    for joint in range(1, skeleton.n_joints):  # parents come first on both skeletons
        parent = skeleton.parents[joint]
        world[:, joint] = world[:, parent] @ local[:, joint]
        pos[:, joint] = pos[:, parent] + world[:, parent] @ skeleton.rest_offsets[joint]
    return pos


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
def test_rigid_motion_comes_back_exactly(skeleton, tmp_path):
    joints = rigid_motion(skeleton, 60, seed=1)
    path = tmp_path / "rigid.bvh"
    write_bvh(path, joints, skeleton, skeleton.fps)
    assert error_cm(path, joints, skeleton) < 0.01  # 0.1 mm: only the text's rounding


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
def test_benchmark_motion_within_one_centimetre(skeleton, tmp_path):
    # A procedural benchmark motion, processed as the datasets are (new_joints). Its pelvis and
    # upper spine are not rigid groups (the rig bends the spine above fixed hips), which a BVH
    # joint cannot show: the residual of the group fit is the error here (motion 1: 4 mm).
    joints = make_motion(1, seed=0, skeleton=skeleton).joints
    path = tmp_path / "synth.bvh"
    write_bvh(path, joints, skeleton, skeleton.fps)
    assert error_cm(path, joints, skeleton) < 1.0


@pytest.mark.parametrize("fps", [20.0, 12.5, 30.0])
def test_frame_count_and_time_round_trip(fps, tmp_path):
    joints = rigid_motion(HUMANML3D, 37, seed=2)
    path = tmp_path / "m.bvh"
    write_bvh(path, joints, HUMANML3D, fps)
    container = bvhio.readAsBvh(str(path))
    assert container.FrameCount == 37
    assert container.FrameTime == pytest.approx(1.0 / fps, rel=1e-8)
    assert len(container.Root.Keyframes) == 37


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
def test_hierarchy_channels_offsets_and_end_sites(skeleton):
    joints = rigid_motion(skeleton, 10, seed=3)
    text = bvh_text(joints, skeleton, skeleton.fps)
    head, motion = text.split("MOTION\n")
    channels = [line.split() for line in head.splitlines() if line.strip().startswith("CHANNELS")]
    assert len(channels) == skeleton.n_joints
    assert channels[0] == ["CHANNELS", "6", "Xposition", "Yposition", "Zposition",
                           "Zrotation", "Xrotation", "Yrotation"]
    assert all(c == ["CHANNELS", "3", "Zrotation", "Xrotation", "Yrotation"] for c in channels[1:])
    n_leaves = sum(j not in skeleton.parents for j in range(skeleton.n_joints))
    assert head.count("End Site") == n_leaves
    rows = motion.splitlines()[2:]
    assert len(rows) == 10 and all(len(r.split()) == 3 + 3 * skeleton.n_joints for r in rows)
    # Offsets are the bones in centimetres: the thigh (hip -> knee) of the rest pose.
    knee = skeleton.parents[skeleton.foot_left[0]]
    offset_line = head.split(f"JOINT {skeleton.joint_names[knee]}\n")[1].splitlines()[1].split()
    offset = np.array([float(v) for v in offset_line[1:]])
    expected = skeleton.bone_lengths[knee] * TO_CENTIMETRES[skeleton.unit]
    assert np.linalg.norm(offset) == pytest.approx(expected, rel=1e-3)


def test_angles_do_not_wrap_while_the_body_spins(tmp_path):
    joints = rigid_motion(HUMANML3D, 120, seed=4, turns=3.0)  # three full turns
    path = tmp_path / "spin.bvh"
    write_bvh(path, joints, HUMANML3D, HUMANML3D.fps)
    lines = path.read_text().splitlines()
    values = np.loadtxt(lines[lines.index("MOTION") + 3:])
    step = np.abs(np.diff(values[:, 3:], axis=0))
    assert step.max() < 60.0  # degrees per frame: no +-360 jumps
    assert error_cm(path, joints, HUMANML3D) < 0.01


def test_read_bvh_matches_bvhio_on_other_channel_orders(tmp_path):
    # A file unlike ours: root offset, XYZ and YXZ orders, translation channels on a child.
    text = """HIERARCHY
ROOT hips
{
  OFFSET 1.0 2.0 3.0
  CHANNELS 6 Xposition Yposition Zposition Xrotation Yrotation Zrotation
  JOINT chest
  {
    OFFSET 0.0 10.0 0.0
    CHANNELS 6 Xposition Yposition Zposition Yrotation Xrotation Zrotation
    JOINT head
    {
      OFFSET 0.0 5.0 1.0
      CHANNELS 3 Xrotation Yrotation Zrotation
      End Site
      {
        OFFSET 0.0 3.0 0.0
      }
    }
  }
  JOINT leg
  {
    OFFSET 2.0 -8.0 0.0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 0.0 -9.0 0.0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.0083333
0 90 0 10 20 30 0 12 1 40 -50 60 5 6 7 -70 80 -90
1 91 2 -10 25 -30 0.5 11 0 -40 50 -60 170 -6 7 70 -80 90
2 92 4 100 -20 130 -0.5 10 -1 140 -150 160 -5 60 -70 0 0 0
"""
    path = tmp_path / "other.bvh"
    path.write_text(text)
    clip = read_bvh(path)
    names, expected = bvhio_positions(path)
    assert list(clip.joint_names) == names == ["hips", "chest", "head", "leg"]
    assert clip.parents == (-1, 0, 1, 0)
    assert clip.fps == pytest.approx(120.0, rel=1e-4)
    np.testing.assert_allclose(clip.positions, expected, atol=1e-4)


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
def test_read_bvh_gives_back_our_joints(skeleton, tmp_path):
    joints = rigid_motion(skeleton, 30, seed=5)
    path = tmp_path / "ours.bvh"
    write_bvh(path, joints, skeleton, skeleton.fps)
    clip = read_bvh(path)
    order = [clip.joint_names.index(name) for name in skeleton.joint_names]
    back = clip.positions[:, order] / TO_CENTIMETRES[skeleton.unit]
    np.testing.assert_allclose(back, joints, atol=1e-3 / TO_CENTIMETRES[skeleton.unit])
    assert [clip.parents[i] for i in order][1:] == [
        order[p] for p in skeleton.parents[1:]]


@pytest.mark.parametrize("bad, message", [
    (np.full((5, 22, 3), np.nan), "NaN or inf"),
    (np.zeros((5, 21, 3)), "shape"),
    (np.zeros((0, 22, 3)), "shape"),
    (np.zeros((5, 22)), "shape"),
])
def test_bad_joints_are_one_line_errors_and_write_nothing(bad, message, tmp_path):
    path = tmp_path / "bad.bvh"
    with pytest.raises(MlctError, match=message) as info:
        write_bvh(path, bad, HUMANML3D, 20.0)
    assert "\n" not in str(info.value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("fps", [0.0, -20.0, float("nan")])
def test_bad_fps_is_an_error(fps):
    with pytest.raises(MlctError, match="frame rate"):
        bvh_text(rigid_motion(HUMANML3D, 5, seed=0), HUMANML3D, fps)


def test_unreadable_bvh_is_one_line_error(tmp_path):
    path = tmp_path / "broken.bvh"
    path.write_text("HIERARCHY\nROOT a\n{\n  OFFSET 0 0\n")
    with pytest.raises(MlctError, match="not a readable BVH") as info:
        read_bvh(path)
    assert "\n" not in str(info.value)


def test_save_motion_writes_bvh(tmp_path):
    joints = rigid_motion(HUMANML3D, 20, seed=6).astype(np.float32)
    motion = GeneratedMotion(text="a person turns", features=np.zeros((20, 263), np.float32),
                             joints=joints, fps=20.0, skeleton="humanml3d")
    path = save_motion(motion, tmp_path / "turn.bvh")
    assert error_cm(path, joints, HUMANML3D) < 0.01


@pytest.mark.parametrize("content", [b"", b"   \n", b"not a bvh at all\n",
                                     b"HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n"])
def test_read_bvh_refuses_empty_or_truncated_files_in_one_line(tmp_path, content):
    """An empty .bvh made bvhio's parser loop forever (`mlct data import --bvh` hung)."""
    path = tmp_path / "bad.bvh"
    path.write_bytes(content)
    with pytest.raises(MlctError) as info:
        read_bvh(path)
    assert "bad.bvh" in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("rig", ["mixamo", "unreal", "unity", "vrm", "smpl"])
def test_rig_presets_name_turn_and_scale_the_skeleton(rig, tmp_path):
    from mlct.motion.rigfit import fit_rig
    from mlct.motion.rigs import get_rig

    joints = make_motion(0, seed=0, skeleton=HUMANML3D).joints
    path = tmp_path / f"{rig}.bvh"
    write_bvh(path, joints, HUMANML3D, HUMANML3D.fps, rig=rig)
    clip = read_bvh(path)
    target = get_rig(rig, HUMANML3D)
    assert clip.joint_names[0] == target.joint_names[0]
    assert sorted(clip.joint_names) == sorted(target.joint_names)
    fit = fit_rig(joints, HUMANML3D, target.rest_directions)
    expected = fit.positions @ target.axes.T * target.per_metre
    order = [target.joint_names.index(n) for n in clip.joint_names]
    unit_cm = 100.0 / target.per_metre  # centimetres per file unit
    error_cm = np.linalg.norm(clip.positions - expected[:, order], axis=-1).max() * unit_cm
    assert error_cm < 0.01  # the fitted skeleton, to the text's rounding
    lengths = np.linalg.norm(clip.positions[:, 1:] - clip.positions[:, list(clip.parents[1:])],
                             axis=-1)
    assert np.abs(lengths - lengths[0]).max() * unit_cm < 1e-3  # rounding of 1e-4 units
    head = clip.positions[:, clip.joint_names.index(target.joint_names[15])]
    up = 2 if rig == "unreal" else 1
    assert 1.2 < head[:, up].mean() * unit_cm / 100.0 < 2.0  # a standing head, metres, up


def test_rig_from_a_json_file(tmp_path):
    import json

    spec = {"name": "mine", "joints": {n: f"b_{n}" for n in HUMANML3D.joint_names},
            "rest": "A", "up": "z", "forward": "-y", "unit": "cm"}
    (tmp_path / "mine.json").write_text(json.dumps(spec))
    path = tmp_path / "m.bvh"
    write_bvh(path, rigid_motion(HUMANML3D, 20, seed=5), HUMANML3D, 20.0,
              rig=tmp_path / "mine.json")
    clip = read_bvh(path)
    assert clip.joint_names[0] == "b_pelvis"
    assert clip.positions[:, clip.joint_names.index("b_head"), 2].mean() > 100.0  # z up, cm
    spec["joints"].pop("head")
    (tmp_path / "bad.json").write_text(json.dumps(spec))
    with pytest.raises(MlctError, match="missing: head"):
        write_bvh(tmp_path / "n.bvh", rigid_motion(HUMANML3D, 5, seed=5), HUMANML3D, 20.0,
                  rig=tmp_path / "bad.json")
    with pytest.raises(MlctError, match="unknown rig"):
        bvh_text(rigid_motion(HUMANML3D, 5, seed=5), HUMANML3D, 20.0, rig="blender")
    assert not (tmp_path / "n.bvh").exists()


def test_euler_angles_are_scipys_and_rebuild_the_turn():
    """The writer's own ZXY decomposition (no scipy at import) against scipy's, and at gimbal
    lock, where any split is right, the turn it rebuilds."""
    from mlct.motion.bvh import euler_zxy_degrees

    turns = Rotation.random(2000, random_state=0)
    np.testing.assert_allclose(euler_zxy_degrees(turns.as_matrix()),
                               turns.as_euler("ZXY", degrees=True), atol=1e-8)
    locked = Rotation.from_euler("ZXY", [[30, 90, 20], [-70, -90, 45], [0, 90, 0]], degrees=True)
    angles = euler_zxy_degrees(locked.as_matrix())
    assert np.allclose(np.abs(angles[:, 1]), 90) and np.all(angles[:, 2] == 0)
    rebuilt = Rotation.from_euler("ZXY", angles, degrees=True).as_matrix()
    np.testing.assert_allclose(rebuilt, locked.as_matrix(), atol=1e-9)
