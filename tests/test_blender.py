"""Blender imports the GLB, the BVH and the FBX and plays them (skipped where `bpy`, Blender as a
Python module, is not installed: its wheel is ~0.5 GB, so CI does not carry it; bpy 4.2 is the
one for Python 3.11)."""

from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
pytest.importorskip("pygltflib")

from fbx_reader import rigid_joints  # noqa: E402

from mlct.data.synth.build import make_motion  # noqa: E402
from mlct.motion.bvh import write_bvh  # noqa: E402
from mlct.motion.fbx import write_fbx  # noqa: E402
from mlct.motion.gltf import read_gltf, write_glb  # noqa: E402
from mlct.motion.rigs import get_rig  # noqa: E402
from mlct.motion.skeleton import HUMANML3D  # noqa: E402

pytestmark = pytest.mark.slow


def _armature_positions(frames: list[int]) -> np.ndarray:
    """(F, B, 3) world head positions of the imported armature's bones at the given frames."""
    armature = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
    out = []
    for frame in frames:
        bpy.context.scene.frame_set(frame)
        out.append([tuple(armature.matrix_world @ bone.head) for bone in armature.pose.bones])
    return np.array(out)


@pytest.mark.parametrize("rig", [None, "mixamo"])
def test_blender_imports_and_plays_the_glb(rig, tmp_path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    joints = make_motion(0, seed=0, skeleton=HUMANML3D).joints
    path = tmp_path / "m.glb"
    write_glb(path, joints, HUMANML3D, HUMANML3D.fps, rig=rig)
    bpy.ops.import_scene.gltf(filepath=str(path))
    assert any(o.type == "MESH" for o in bpy.context.scene.objects)
    action = bpy.data.actions[0]
    # the clip lasts as long as the motion (Blender resamples to its scene rate, 24 fps)
    seconds = (action.frame_range[1] - action.frame_range[0]) / bpy.context.scene.render.fps
    assert seconds == pytest.approx((len(joints) - 1) / HUMANML3D.fps, abs=0.1)
    moving = _armature_positions([1, 20])
    assert np.abs(moving[0] - moving[1]).max() > 0.01  # it plays: the bones move
    armature = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
    assert sorted(armature.pose.bones.keys()) == sorted(read_gltf(path).joint_names)


def test_blender_imports_and_plays_the_bvh(tmp_path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    joints = make_motion(0, seed=0, skeleton=HUMANML3D).joints
    path = tmp_path / "m.bvh"
    write_bvh(path, joints, HUMANML3D, HUMANML3D.fps, rig="mixamo")
    bpy.ops.import_anim.bvh(filepath=str(path), global_scale=0.01)
    armature = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
    assert "mixamorig:Hips" in armature.pose.bones
    moving = _armature_positions([1, 20])
    assert np.abs(moving[0] - moving[1]).max() > 0.01
    # the pelvis height at frame 1 is the motion's (metres after the 0.01 scale)
    hips = moving[0][list(armature.pose.bones.keys()).index("mixamorig:Hips")]
    assert abs(hips[2] - joints[0, 0, 1]) < 0.02  # Blender is z up


@pytest.mark.parametrize("rig", [None, "mixamo", "unreal"])  # unreal: a Z-up file
def test_blender_imports_and_plays_the_fbx(rig, tmp_path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    joints = rigid_joints(HUMANML3D, 45, seed=4)  # a rigid motion: the file holds it exactly
    path = tmp_path / "m.fbx"
    write_fbx(path, joints, HUMANML3D, HUMANML3D.fps, rig=rig)
    assert bpy.ops.import_scene.fbx(filepath=str(path)) == {"FINISHED"}
    armature = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
    names = HUMANML3D.joint_names if rig is None else get_rig(rig, HUMANML3D).joint_names
    assert sorted(armature.pose.bones.keys()) == sorted(names)  # 22 bones, the rig's names
    (action,) = bpy.data.actions
    assert bpy.context.scene.render.fps == HUMANML3D.fps  # from the file's frame rate
    assert tuple(action.frame_range) == (1.0, 45.0)  # one key a frame: (T - 1) / fps seconds
    # Blender is z up, facing -y, in metres: mlct's (x, y, z) is its (x, -z, y), whichever
    # axes the file states. Every bone's head at frame f is the motion's joint at f - 1.
    to_blender = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    frames = [1, 23, 45]
    bones = list(armature.pose.bones.keys())
    heads = _armature_positions(frames)[:, [bones.index(name) for name in names]]
    expected = joints[[f - 1 for f in frames]] @ to_blender.T
    assert np.abs(heads - expected).max() < 1e-3  # 1 mm (measured: ~4e-7 m)
