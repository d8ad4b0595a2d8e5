"""Look at a retargeted motion: generated joints beside the joints read back from its .glb.

For each prompt: generate, write the motion as a GLB on a rig preset (Mixamo by default: T-pose
rest, Mixamo names), read the file back with pygltflib (motion/gltf.py's `read_gltf`), map its
joints back to the HumanML3D order by name and draw both as PNG filmstrips, one above the
other, in one image. The two strips should show the same motion.

    python bench/rig_filmstrip.py --out rig_check.png
    python bench/rig_filmstrip.py --rig vrm --prompts "a person walks forward" "a person jumps"
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

import mlct
from mlct.motion.gltf import read_gltf, write_glb
from mlct.motion.render import render_motion
from mlct.motion.rigs import get_rig
from mlct.motion.skeleton import get_skeleton


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--prompts", nargs="+",
                        default=["a person walks forward", "a person jumps up twice"])
    parser.add_argument("--rig", default="mixamo")
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("rig_filmstrip.png"))
    args = parser.parse_args()

    generator = mlct.load()
    motions = generator.generate(args.prompts, seed=args.seed)
    strips = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, motion in enumerate(motions):
            skeleton = get_skeleton(motion.skeleton)
            rig = get_rig(args.rig, skeleton)
            glb = Path(tmp) / f"{i}.glb"
            write_glb(glb, motion.joints, skeleton, motion.fps, rig=rig)
            clip = read_gltf(glb)
            names = skeleton.joint_names if rig is None else rig.joint_names
            back = clip.positions[:, [clip.joint_names.index(n) for n in names]]
            error = np.linalg.norm(back - motion.joints, axis=-1)
            print(f"{motion.text!r}: {len(back)} frames, GLB joints vs generated: "
                  f"mean {error.mean() * 100:.2f} cm, max {error.max() * 100:.2f} cm")
            for joints, label in ((motion.joints, "generated"), (back, f"{args.rig} .glb")):
                png = Path(tmp) / f"{i}_{len(strips)}.png"
                render_motion(joints, png, skeleton=skeleton, title=f"{motion.text} ({label})",
                              fps=motion.fps)
                strips.append(Image.open(png).convert("RGB"))
    width = max(s.width for s in strips)
    sheet = Image.new("RGB", (width, sum(s.height for s in strips)), "white")
    y = 0
    for strip in strips:
        sheet.paste(strip, (0, y))
        y += strip.height
    sheet.save(args.out)
    print(args.out)


if __name__ == "__main__":
    main()
