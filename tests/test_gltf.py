"""glTF/GLB and VRM Animation export, read back with pygltflib: the joints recomputed from the
file's nodes and animation samplers are the fitted skeleton's, its bones keep their length."""

from __future__ import annotations

import numpy as np
import pytest

pygltflib = pytest.importorskip("pygltflib")

from mlct.data.synth.build import make_motion  # noqa: E402
from mlct.errors import MlctError  # noqa: E402
from mlct.motion.gltf import (VRMA_EXTENSION, fit_for_gltf, read_gltf, write_glb,  # noqa: E402
                              write_vrma)
from mlct.motion.rigs import PRESETS, get_rig  # noqa: E402
from mlct.motion.skeleton import HUMANML3D, KIT  # noqa: E402


def _lengths(positions: np.ndarray, parents: tuple[int, ...]) -> np.ndarray:
    parents_ = [max(p, 0) for p in parents]
    return np.linalg.norm(positions - positions[:, parents_], axis=-1)


def _check_round_trip(path, joints, skeleton, rig) -> float:
    clip = read_gltf(path)
    fit, names = fit_for_gltf(joints, skeleton, skeleton.fps, get_rig(rig, skeleton))
    assert sorted(clip.joint_names) == sorted(names)
    order = [names.index(n) for n in clip.joint_names]
    error = float(np.linalg.norm(clip.positions - fit.positions[:, order], axis=-1).max())
    assert error < 0.01  # metres: within 1 cm of the fit (float32 keys: ~1e-7 m in practice)
    lengths = _lengths(clip.positions, clip.parents)
    assert np.abs(lengths - lengths[0]).max() < 1e-6
    assert np.allclose(clip.times, np.arange(len(joints)) / skeleton.fps, atol=1e-6)
    return error


@pytest.mark.parametrize("rig", [None, *PRESETS])
def test_glb_round_trips_through_pygltflib(rig, tmp_path):
    joints = make_motion(2, seed=0, skeleton=HUMANML3D).joints
    path = tmp_path / "m.glb"
    write_glb(path, joints, HUMANML3D, HUMANML3D.fps, rig=rig)
    assert _check_round_trip(path, joints, HUMANML3D, rig) < 1e-5
    gltf = pygltflib.GLTF2.load_binary(str(path))
    assert gltf.asset.version == "2.0"
    skin = gltf.skins[0]
    assert len(skin.joints) == HUMANML3D.n_joints and skin.inverseBindMatrices is not None
    primitive = gltf.meshes[0].primitives[0]
    assert primitive.attributes.JOINTS_0 is not None and primitive.attributes.WEIGHTS_0 is not None
    assert gltf.accessors[primitive.attributes.POSITION].min is not None  # required bounds
    expected = HUMANML3D.joint_names if rig is None else get_rig(rig, HUMANML3D).joint_names
    assert [gltf.nodes[j].name for j in skin.joints] == list(expected)


def test_glb_of_the_kit_skeleton_is_in_metres(tmp_path):
    joints = make_motion(0, seed=0, skeleton=KIT).joints  # millimetres
    path = tmp_path / "kit.glb"
    write_glb(path, joints, KIT, KIT.fps)
    _check_round_trip(path, joints, KIT, None)
    clip = read_gltf(path)
    assert 0.5 < clip.positions[..., 1].max() < 2.5  # a standing body, in metres


def test_skin_binds_the_mesh_at_the_rest_pose(tmp_path):
    """Each inverse bind matrix undoes its joint's rest world transform (from the nodes)."""
    path = tmp_path / "m.glb"
    write_glb(path, make_motion(1, seed=0, skeleton=HUMANML3D).joints, HUMANML3D, 20.0)
    gltf = pygltflib.GLTF2.load_binary(str(path))
    blob = gltf.binary_blob()
    accessor = gltf.accessors[gltf.skins[0].inverseBindMatrices]
    view = gltf.bufferViews[accessor.bufferView]
    matrices = np.frombuffer(blob, np.float32, 16 * accessor.count, view.byteOffset)
    matrices = matrices.reshape(-1, 4, 4).transpose(0, 2, 1)  # column-major
    world = np.zeros((len(gltf.skins[0].joints), 3))
    parents = {c: i for i, node in enumerate(gltf.nodes) for c in (node.children or [])}
    for joint in gltf.skins[0].joints:
        chain, node = [], joint
        while node is not None:
            chain.append(np.array(gltf.nodes[node].translation))
            node = parents.get(node)
        world[joint] = np.sum(chain, axis=0)
    assert np.allclose(matrices[:, :3, 3], -world, atol=1e-6)
    assert np.allclose(matrices[:, :3, :3], np.eye(3), atol=1e-7)
    assert world[:, 1].min() == pytest.approx(0.0, abs=1e-6)  # rest pose stands on the floor


def test_vrma_maps_vrm_humanoid_bones_to_nodes(tmp_path):
    joints = make_motion(3, seed=0, skeleton=HUMANML3D).joints
    path = tmp_path / "m.vrma"
    write_vrma(path, joints, HUMANML3D, HUMANML3D.fps)
    _check_round_trip(path, joints, HUMANML3D, "vrm")
    gltf = pygltflib.GLTF2.load_binary(str(path))
    assert gltf.extensionsUsed == [VRMA_EXTENSION]
    extension = gltf.extensions[VRMA_EXTENSION]
    assert extension["specVersion"] == "1.0"
    bones = extension["humanoid"]["humanBones"]
    for bone in ("hips", "spine", "chest", "upperChest", "neck", "head", "leftUpperArm",
                 "rightLowerLeg", "leftToes"):
        assert gltf.nodes[bones[bone]["node"]].name == bone
    assert not gltf.meshes and not gltf.skins
    # T-pose rest: the upper arms and forearms point straight out sideways.
    index = {node.name: i for i, node in enumerate(gltf.nodes)}
    forearm = np.array(gltf.nodes[index["leftLowerArm"]].translation)
    assert forearm[0] > 0 and abs(forearm[1]) < 1e-6 * np.linalg.norm(forearm) + 1e-9


def test_kit_cannot_be_retargeted_and_bad_fps_is_an_error(tmp_path):
    with pytest.raises(MlctError, match="humanml3d"):
        write_glb(tmp_path / "k.glb", make_motion(0, seed=0, skeleton=KIT).joints, KIT, 12.5,
                  rig="mixamo")
    with pytest.raises(MlctError, match="frame rate"):
        write_glb(tmp_path / "m.glb", np.zeros((3, 22, 3)), HUMANML3D, 0)
    assert not list(tmp_path.iterdir())


def test_read_gltf_refuses_a_file_that_is_not_gltf(tmp_path):
    path = tmp_path / "x.glb"
    path.write_bytes(b"not a gltf file")
    with pytest.raises(MlctError, match="x.glb"):
        read_gltf(path)
