"""Does a model's motion follow its text? Kinematic read-outs of generated motions per prompt.

    python bench/text_following.py MODEL_DIR [--nfe 4] [--seeds 0 1] [--render DIR]

For each prompt (phrased as the procedural benchmark phrases them) it prints, over the seeds:
the root displacement along the body's initial facing (fwd) and to its left (side), the range
of the pelvis height (jumps and squats move it), and the peak heights above the floor of the
wrists and feet (waves, arm raises and kicks lift them). A model that ignores the text prints
the same row for every prompt. `--render` also writes a PNG filmstrip per prompt (first seed).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import mlct
from mlct.motion.render import render_motion

PROMPTS = [
    ("a person walks forward at a brisk pace.", 4.0),
    ("the woman walks backward at a steady pace.", 4.0),
    ("a person runs straight ahead.", 4.0),
    ("the man steps sideways to the left three times.", 3.0),
    ("a figure turns right by 45 degrees.", 3.0),
    ("the woman waves the right hand back and forth two times.", 3.0),
    ("the person puts both their arms up in the air.", 3.0),
    ("a person squats down three times.", 4.0),
    ("the man jumps two times straight up.", 3.3),
    ("a person does a single left kick.", 2.4),
    ("a person kicks out with the right foot.", 2.4),
    ("the woman stands quietly.", 3.0),
]


def readouts(joints: np.ndarray, names: tuple[str, ...]) -> dict[str, float]:
    """Kinematic summary of (T, J, 3) joints, y up."""
    index = {name: i for i, name in enumerate(names)}
    root = joints[:, 0]
    right = joints[0, index["right_hip"]] - joints[0, index["left_hip"]]
    forward = np.cross([0.0, 1.0, 0.0], right)  # body faces up x right
    forward /= np.linalg.norm(forward) + 1e-9
    left = np.cross([0.0, 1.0, 0.0], forward)
    shift = root[-1] - root[0]
    height = joints[..., 1] - joints[..., 1].min()
    return {
        "fwd": float(shift @ forward), "side": float(shift @ left),
        "pelvis_range": float(np.ptp(root[:, 1])),
        "l_wrist": float(height[:, index["left_wrist"]].max()),
        "r_wrist": float(height[:, index["right_wrist"]].max()),
        "l_foot": float(height[:, index["left_foot"]].max()),
        "r_foot": float(height[:, index["right_foot"]].max()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", type=Path)
    parser.add_argument("--nfe", type=int, default=4, help="consistency models only")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--render", type=Path, default=None)
    args = parser.parse_args()

    gen = mlct.load(args.model)
    options = {"nfe": args.nfe} if gen.sampler.steps_option == "nfe" else {}
    texts = [text for text, _ in PROMPTS]
    seconds = [s for _, s in PROMPTS]
    rows = {text: [] for text in texts}
    for seed in args.seeds:
        for motion in gen.generate(texts, seconds=seconds, seed=seed, **options):
            rows[motion.text].append(readouts(motion.joints, gen.skeleton.joint_names))
            if args.render is not None and seed == args.seeds[0]:
                args.render.mkdir(parents=True, exist_ok=True)
                render_motion(motion.joints, args.render / f"{texts.index(motion.text):02d}.png",
                              gen.skeleton, title=motion.text)
    keys = list(rows[texts[0]][0])
    print(f"{'prompt':58s} " + " ".join(f"{k:>12s}" for k in keys))
    for text in texts:
        values = np.array([[r[k] for k in keys] for r in rows[text]])
        cells = " ".join(f"{m:+6.2f}±{s:4.2f}" for m, s in zip(values.mean(0), values.std(0)))
        print(f"{text[:58]:58s} {cells}")
    print(f"(mean ± std over seeds {args.seeds}; metres; {gen.sampler.name}"
          f"{', nfe %d' % args.nfe if options else ''})")


if __name__ == "__main__":
    main()
