"""The rig formats through the one writer (generate/output/exports.py): the Python API, the CLI's
--rig, and the one-line errors for a rig a format cannot take."""

from __future__ import annotations

import numpy as np
import pytest

from mlct.cli import main
from mlct.data.synth.build import make_motion
from mlct.errors import MlctError
from mlct.generate.output.exports import check_rig, export_bytes, save_motion
from mlct.generate.output.generated import GeneratedMotion
from mlct.motion.bvh import read_bvh
from mlct.motion.skeleton import HUMANML3D


@pytest.fixture(scope="module")
def motion() -> GeneratedMotion:
    synth = make_motion(5, seed=0, skeleton=HUMANML3D)
    return GeneratedMotion("a person walks", synth.features, synth.joints, 20.0, "humanml3d", 3)


def test_save_every_rig_format(motion, tmp_path):
    bvh = motion.save(tmp_path / "m.bvh", rig="mixamo")
    assert read_bvh(bvh).joint_names[0] == "mixamorig:Hips"
    npz = np.load(motion.save(tmp_path / "m.npz"))
    assert npz["poses"].shape == (len(motion.joints), 156)
    pytest.importorskip("pygltflib")
    from mlct.motion.gltf import read_gltf

    assert read_gltf(motion.save(tmp_path / "m.glb", rig="unreal")).joint_names[0] == "pelvis"
    clip = read_gltf(save_motion(motion, tmp_path / "m.vrma", rig="vrm"))
    assert clip.joint_names[0] == "hips" and "VRMC_vrm_animation" in clip.extensions
    data = export_bytes(motion, ".glb", rig="mixamo")  # the server's download
    assert data[:4] == b"glTF" and b"mixamorig:LeftUpLeg" in data


@pytest.mark.parametrize("rig, suffix, words", [
    ("mixamo", ".gif", "applies to .bvh, .glb"), ("mixamo", ".npz", ".npz is always smpl"),
    ("unreal", ".vrma", ".vrma is always vrm"), ("maya", ".glb", "unknown rig 'maya'"),
    ("missing.json", ".bvh", "cannot read"),
])
def test_a_rig_a_format_cannot_take_is_a_one_line_error(motion, tmp_path, rig, suffix, words):
    with pytest.raises(MlctError, match=words.replace(".", r"\.")):
        check_rig(rig, suffix)
    with pytest.raises(MlctError):
        save_motion(motion, tmp_path / f"m{suffix}", rig=rig)
    assert not list(tmp_path.iterdir())


def test_cli_refuses_a_bad_rig_before_loading_the_model(tmp_path, capsys):
    assert main(["generate", "a person walks", "--out", str(tmp_path / "m.gif"),
                 "--rig", "mixamo"]) == 2
    assert "--rig applies to" in capsys.readouterr().err
    assert main(["generate", "a person walks", "--out", str(tmp_path / "m.glb"),
                 "--rig", "nope"]) == 2
    assert not list(tmp_path.iterdir())


def test_retarget_command_writes_a_rig_file_from_a_joints_npy(motion, tmp_path, capsys):
    np.save(tmp_path / "walk.npy", motion.joints)
    out = tmp_path / "walk.bvh"
    assert main(["retarget", str(tmp_path / "walk.npy"), "--out", str(out), "--rig", "unreal"]) == 0
    assert read_bvh(out).joint_names[0] == "pelvis" and "thigh_l" in read_bvh(out).joint_names
    np.save(tmp_path / "features.npy", motion.features)  # features work too
    assert main(["retarget", str(tmp_path / "features.npy"), "--out", str(tmp_path / "f.npz")]) == 0
    assert np.load(tmp_path / "f.npz")["poses"].shape[0] == len(motion.joints)
    capsys.readouterr()
    assert main(["retarget", str(tmp_path / "walk.npy"), "--out", str(tmp_path / "w.gif")]) == 2
    assert "retarget writes" in capsys.readouterr().err
    assert main(["retarget", str(tmp_path / "nope.npy"), "--out", str(tmp_path / "w.glb")]) == 2
    assert "no such file" in capsys.readouterr().err
