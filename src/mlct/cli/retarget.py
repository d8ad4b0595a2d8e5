"""`mlct retarget FILE.npy --out x.glb --rig mixamo`: a motion file already made (joints or
features .npy, e.g. from `mlct generate --out x.npy` or a dataset) as a rig file: .bvh, .glb,
.fbx, .vrma or .npz, or the Unitree G1 robot's joint angles (.g1.csv, .g1.npz), through the same
writer as `mlct generate` (docs/export.md)."""

from __future__ import annotations

import argparse
from pathlib import Path

from mlct.cli.parser import Commands
from mlct.errors import MlctError

SUFFIXES = (".bvh", ".glb", ".fbx", ".vrma", ".npz", ".g1.csv", ".g1.npz")


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from mlct.generate.output.exports import ROBOT_FORMATS, check_rig, save_motion
    from mlct.generate.output.generated import GeneratedMotion
    from mlct.io import check_writable_dir
    from mlct.motion.motion_npy import load_motion_npy

    name = args.out.name.lower()
    suffix = next((f for f in ROBOT_FORMATS if name.endswith(f)), args.out.suffix.lower())
    if suffix not in SUFFIXES:
        raise MlctError(f"--out {args.out.name}: retarget writes {', '.join(SUFFIXES)} files")
    check_rig(args.rig, suffix)
    check_writable_dir(args.out.parent)
    if args.fps is not None and not args.fps > 0:
        raise MlctError(f"--fps must be positive, got {args.fps}")
    joints, skeleton = load_motion_npy(args.file, args.skeleton)
    motion = GeneratedMotion(text=args.file.stem, features=np.zeros((len(joints), 0)),
                             joints=joints, fps=args.fps or skeleton.fps, skeleton=skeleton.name)
    print(save_motion(motion, args.out, rig=args.rig))
    return 0


def add_parser(commands: Commands) -> None:
    retarget = commands.add_parser(
        "retarget", help="a joints/features .npy as a rig file (BVH, GLB, FBX, VRMA, NPZ) or G1 "
        "angles")
    retarget.add_argument("file", type=Path, help="features (T x 263/251) or joints (T x J x 3) .npy")
    retarget.add_argument("--out", required=True, type=Path,
                          help="OUT.bvh, .glb, .fbx, .vrma, .npz, .g1.csv or .g1.npz")
    retarget.add_argument("--rig", default=None,
                          help="for .bvh/.glb/.fbx: mixamo, unreal, unity, vrm, smpl or "
                               "FILE.json")
    retarget.add_argument("--skeleton", default=None, help="humanml3d or kit (default: from shape)")
    retarget.add_argument("--fps", type=float, default=None, help="default: the skeleton's fps")
    retarget.set_defaults(func=run)
