"""FBX export checked by an independent reader (fbx_reader.py): the bytes parse by the published
binary layout, the skeleton and its curves are the rig's, and forward kinematics of what the
file says gives back the motion's joints."""

from __future__ import annotations

import numpy as np
import pytest
from fbx_reader import parse, read_skeleton, rigid_joints
from motion_builders import random_motion

from mlct.errors import MlctError
from mlct.motion.bvh import read_bvh, write_bvh
from mlct.motion.fbx import KTIME_PER_SECOND, fbx_bytes, write_fbx
from mlct.motion.fbx_binary import FOOTER_MAGIC, Long, Node, encode
from mlct.motion.rigfit import fit_rig
from mlct.motion.rigs import get_rig
from mlct.motion.skeleton import HUMANML3D, KIT

RIGS = [None, "mixamo", "unreal", "unity", "vrm", "smpl"]


@pytest.fixture(scope="module")
def rigid() -> np.ndarray:
    return rigid_joints(HUMANML3D, 50, seed=3)


def _frame(rig):
    """(names, axes) of the file: the rig's, or the skeleton's own in mlct's frame."""
    target = get_rig(rig, HUMANML3D)
    if target is None:
        return HUMANML3D.joint_names, np.eye(3)
    return target.joint_names, target.axes


@pytest.mark.parametrize("rig", RIGS)
def test_forward_kinematics_of_the_file_gives_back_the_motion(rig, rigid):
    clip = read_skeleton(fbx_bytes(rigid, HUMANML3D, 20.0, rig=rig))
    names, axes = _frame(rig)
    assert sorted(clip.names) == sorted(names) and len(clip.names) == 22
    order = [names.index(n) for n in clip.names]
    expected = rigid[:, order] @ axes.T * 100.0  # centimetres, the file's axes
    error_cm = np.linalg.norm(clip.positions() - expected, axis=-1).max()
    assert error_cm < 0.1  # 1 mm (measured: ~1e-5 cm, the float32 keys)
    # the hierarchy is the skeleton's, by name
    for i, parent in enumerate(clip.parents):
        own = HUMANML3D.parents[names.index(clip.names[i])]
        assert parent == (-1 if own < 0 else clip.names.index(names[own]))


def test_frames_and_clip_length_in_fbx_ticks(rigid):
    for fps, mode in ((20.0, 14), (30.0, 6), (12.5, 14)):
        clip = read_skeleton(fbx_bytes(rigid[:37], HUMANML3D, fps))
        assert len(clip.times) == 37 and clip.times[0] == 0
        assert clip.times[-1] == round(36 / fps * KTIME_PER_SECOND)  # (T - 1) / fps seconds
        assert np.all(np.diff(clip.times) > 0)
        assert clip.settings["TimeMode"][0] == mode
        assert clip.settings["CustomFrameRate"][0] == fps
        assert clip.settings["TimeSpanStop"][0] == clip.times[-1]
        top = {r.name: r for r in clip.records}
        stack = next(r for r in top["Objects"].children if r.name == "AnimationStack")
        assert stack.props()["LocalStop"][0] == clip.times[-1]


@pytest.mark.parametrize("rig, axes", [
    (None, (1, 1, 2, 1, 0, 1)),  # y up, facing +z, left +x: Maya's, Blender's default export
    ("mixamo", (1, 1, 2, 1, 0, 1)),
    ("unreal", (2, 1, 1, 1, 0, -1)),  # z up, facing +y, the character's left on -x
])
def test_global_settings_state_axes_and_centimetres(rig, axes, rigid):
    settings = read_skeleton(fbx_bytes(rigid, HUMANML3D, 20.0, rig=rig)).settings
    keys = ("UpAxis", "UpAxisSign", "FrontAxis", "FrontAxisSign", "CoordAxis", "CoordAxisSign")
    assert tuple(settings[k][0] for k in keys) == axes
    assert settings["UnitScaleFactor"][0] == 1.0  # centimetres


def test_rest_pose_is_the_rigs_standing_on_the_floor(rigid):
    clip = read_skeleton(fbx_bytes(rigid, HUMANML3D, 20.0, rig="unreal"))
    target = get_rig("unreal", HUMANML3D)
    rest = np.zeros_like(clip.rest)  # rest world positions: every Lcl Rotation 0
    for j in range(22):  # the file lists parents before children
        parent = clip.parents[j]
        rest[j] = clip.rest[j] + (rest[parent] if parent >= 0 else 0.0)
    assert rest[:, 2].min() == pytest.approx(0.0, abs=1e-9)  # z up: the lowest joint on the floor
    upper = clip.names.index("upperarm_l")
    lower = clip.names.index("lowerarm_l")
    bone = (rest[lower] - rest[upper]) @ target.axes  # back in mlct's frame
    assert bone / np.linalg.norm(bone) == pytest.approx(target.rest_directions[18], abs=1e-6)
    top = {r.name: r for r in clip.records}
    bind = next(r for r in top["Objects"].children if r.name == "Pose")
    assert len(bind.all("PoseNode")) == 23  # the Null and every joint
    matrix = bind.all("PoseNode")[-1].first("Matrix").values[0]
    assert len(matrix) == 16 and matrix[15] == 1.0


@pytest.mark.parametrize("rig", [None, "mixamo", "unreal"])
def test_the_fbx_and_the_bvh_of_one_motion_agree(rig, tmp_path):
    # A motion the rigid fit cannot hold exactly (its spine groups bend): both files hold the
    # same fitted skeleton, moved the same way.
    joints = random_motion(HUMANML3D, 40, seed=1)
    write_bvh(tmp_path / "m.bvh", joints, HUMANML3D, 20.0, rig=rig)
    bvh = read_bvh(tmp_path / "m.bvh")
    clip = read_skeleton(fbx_bytes(joints, HUMANML3D, 20.0, rig=rig))
    to_cm = 1.0 if rig is None else 100.0 / get_rig(rig, HUMANML3D).per_metre  # BVH units
    order = [bvh.joint_names.index(n) for n in clip.names]
    error_cm = np.linalg.norm(clip.positions() - bvh.positions[:, order] * to_cm, axis=-1).max()
    assert error_cm < 0.005  # the BVH text's rounding (1e-4 cm, 1e-4 degrees)
    target = get_rig(rig, HUMANML3D)
    fit = fit_rig(joints, HUMANML3D, None if target is None else target.rest_directions)
    assert np.abs(fit.positions - joints).max() > 0.01  # the fit is not exact here: 1 cm


def test_kit_millimetres_become_centimetres():
    joints = rigid_joints(KIT, 20, seed=0)
    clip = read_skeleton(fbx_bytes(joints, KIT, KIT.fps))
    order = [KIT.joint_names.index(n) for n in clip.names]
    assert np.abs(clip.positions() - joints[:, order] / 10.0).max() < 0.01


def test_the_container_parses_in_both_versions_and_ends_in_the_footer(rigid):
    for version in (7400, 7500):
        data = fbx_bytes(rigid, HUMANML3D, 20.0, version=version)
        got, records, footer = parse(data)
        assert got == version
        assert [r.name for r in records][:2] == ["FBXHeaderExtension", "FileId"]
        assert {"GlobalSettings", "Documents", "Definitions", "Objects", "Connections",
                "Takes"} <= {r.name for r in records}
        assert footer.endswith(FOOTER_MAGIC)
        assert footer[-140:-136] == version.to_bytes(4, "little")  # then 120 zero bytes
        assert (len(data) - len(FOOTER_MAGIC) - 120 - 4) % 16 == 0  # the version is aligned
    objects = next(r for r in records if r.name == "Objects")
    curve = next(r for r in objects.children if r.name == "AnimationCurve")
    assert curve.first("KeyTime").compressed == [True]  # zlib (400 bytes), and it reads back
    assert fbx_bytes(rigid, HUMANML3D, 20.0) == fbx_bytes(rigid, HUMANML3D, 20.0)  # no clock


def test_values_of_every_type_round_trip():
    arrays = [np.arange(300, dtype=t) for t in (np.float32, np.float64, np.int32, np.int64)]
    node = Node("Root", [True, 7, Long(2**40), 1.5, np.float32(0.25), "é", b"\x00\x01", *arrays],
                [Node("Leaf", [1]), Node("Empty")])
    _, (back,), _ = parse(encode([node]))
    assert back.values[:7] == [1, 7, 2**40, 1.5, 0.25, "é", b"\x00\x01"]
    for a, b in zip(arrays, back.values[7:]):
        np.testing.assert_array_equal(a, b)
    assert [c.name for c in back.children] == ["Leaf", "Empty"]
    with pytest.raises(TypeError):
        encode([Node("Bad", [object()])])


@pytest.mark.parametrize("fps", [0, -20.0, float("nan"), "fast"])
def test_bad_frame_rates_are_one_line_errors(fps, rigid):
    with pytest.raises(MlctError, match="positive frame rate"):
        fbx_bytes(rigid, HUMANML3D, fps)


def test_bad_joints_and_rigs_are_one_line_errors_and_write_nothing(rigid, tmp_path):
    bad = rigid.copy()
    bad[3, 4, 1] = np.nan
    with pytest.raises(MlctError, match="FBX export: the joints contain NaN"):
        write_fbx(tmp_path / "m.fbx", bad, HUMANML3D, 20.0)
    with pytest.raises(MlctError, match="unknown rig 'maya'"):
        write_fbx(tmp_path / "m.fbx", rigid, HUMANML3D, 20.0, rig="maya")
    with pytest.raises(MlctError, match="this motion is kit"):
        write_fbx(tmp_path / "m.fbx", rigid_joints(KIT, 5, 0), KIT, 12.5, rig="mixamo")
    assert not list(tmp_path.iterdir())


def test_one_frame_is_a_clip_of_length_zero(rigid):
    clip = read_skeleton(fbx_bytes(rigid[:1], HUMANML3D, 20.0))
    assert list(clip.times) == [0]
    order = [HUMANML3D.joint_names.index(n) for n in clip.names]
    assert np.abs(clip.positions()[0] - rigid[0, order] * 100.0).max() < 0.01


def test_save_motion_cli_and_server_bytes_write_the_fbx(rigid, tmp_path, capsys):
    from mlct.cli import main
    from mlct.generate.output.exports import check_rig, export_bytes, save_motion
    from mlct.generate.output.generated import GeneratedMotion

    motion = GeneratedMotion("a person walks", np.zeros((len(rigid), 263)), rigid, 20.0,
                             "humanml3d", 0)
    path = save_motion(motion, tmp_path / "m.FBX", rig="unreal")  # the extension picks it
    assert read_skeleton(path.read_bytes()).names[0] == "pelvis"
    assert export_bytes(motion, ".fbx", rig="mixamo") == fbx_bytes(rigid, HUMANML3D, 20.0,
                                                                      rig="mixamo")
    check_rig("vrm", ".fbx")  # every preset
    np.save(tmp_path / "walk.npy", rigid)
    assert main(["retarget", str(tmp_path / "walk.npy"), "--out", str(tmp_path / "w.fbx"),
                 "--rig", "mixamo"]) == 0
    assert read_skeleton((tmp_path / "w.fbx").read_bytes()).names[0] == "mixamorig:Hips"


def test_cli_refuses_a_bad_rig_for_an_fbx_before_loading_the_model(tmp_path, capsys,
                                                                  monkeypatch):
    import mlct
    from mlct.cli import main

    def no_model(*args, **kwargs):
        raise AssertionError("the model was loaded")

    monkeypatch.setattr(mlct, "load", no_model)
    for rig, words in (("maya", "unknown rig 'maya'"), ("missing.json", "cannot read")):
        capsys.readouterr()
        assert main(["generate", "a person walks", "--out", str(tmp_path / "m.fbx"),
                     "--rig", rig]) == 2
        err = capsys.readouterr().err
        assert words in err and len(err.strip().splitlines()) == 1
    assert not list(tmp_path.iterdir())
