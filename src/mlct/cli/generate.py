"""`mlct generate`: text to motion files (GIF, MP4, PNG, NPY, JSON, BVH, GLB, FBX, VRMA,
NPZ)."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import Any

from mlct.cli.parser import THREADS_HELP, Commands, thread_count
from mlct.errors import MlctError

MAX_MOTIONS = 100_000  # motions one `mlct generate` makes (files and names are listed first)


def run(args: argparse.Namespace) -> int:
    import mlct
    from mlct.generate import files as generate_files
    from mlct.generate.compose.prompts import clean_prompt, read_prompts

    if args.prompts is not None and args.text:
        raise MlctError("give prompts on the command line or with --prompts FILE, not both")
    if args.num < 1:
        raise MlctError(f"--num must be at least 1, got {args.num}")
    if args.num > MAX_MOTIONS:  # checked before a name per motion is built (10^9 ran out of memory)
        raise MlctError(f"--num {args.num} is more than the {MAX_MOTIONS:,} motions one command "
                        f"makes; split the work over several commands")
    prompts = (read_prompts(args.prompts) if args.prompts is not None
               else [clean_prompt(t) for t in args.text])
    if len(prompts) * args.num > MAX_MOTIONS:
        raise MlctError(f"{len(prompts)} prompts x --num {args.num} make more than the "
                        f"{MAX_MOTIONS:,} motions one command makes")
    if not prompts:
        raise MlctError("no prompt: mlct generate \"a person walks forward\" --out walk.gif")
    long = args.prompts is None and len(prompts) > 1
    if long and args.num > 1:
        raise MlctError("--num makes variations of one prompt; several prompts make one long "
                        "motion")
    if args.candidates is not None:
        from mlct.generate.compose.critic import check_candidates

        check_candidates(args.candidates)
    if args.critic_margin is not None:
        from mlct.generate.compose.critic import check_margin

        check_margin(args.critic_margin)
    from mlct.generate.load import check_options

    check_options(args.device, args.dtype, args.backend)  # a combination no model runs
    request = generate_files.Request(prompts, args.seconds, args.length, args.num, args.nfe,
                                     args.seed, long, split_actions=not args.whole_prompt,
                                     control=_control(args), candidates=args.candidates,
                                     critic_margin=args.critic_margin,
                                     keep_going=not args.no_keep_going,
                                     plant_feet=not args.no_plant_feet,
                                     text_anchors=not args.no_text_anchors,
                                     in_place=args.in_place)
    names = ["_".join(prompts)] if long else [p for p in prompts for _ in range(args.num)]
    paths = generate_files.output_paths(names, args.out, args.out_dir, args.format)
    def load() -> Any:
        # A status line while the model and the text encoder load (a second or more cold),
        # on a terminal only: scripts and pipes keep a clean stderr.
        status = not args.quiet and sys.stderr.isatty()
        if status:
            print("mlct: loading the model and the text encoder ...", end="\r", file=sys.stderr,
                  flush=True)
        generator = mlct.load(args.model, device=args.device, dtype=args.dtype,
                              backend=args.backend, threads=args.threads)
        generator.text_encoder  # noqa: B018 - loads it now, under the status line
        if status:
            print(" " * 50, end="\r", file=sys.stderr, flush=True)
        if args.verbose:
            handoff = getattr(generator.networks, "torch_min_batch", None)  # the onnx ones'
            print(f"mlct: backend {generator.backend_note}"
                  + (f"; batches of {handoff} or more latents on the torch networks"
                     if handoff else ""), file=sys.stderr, flush=True)
            _show_decisions()
        return generator

    try:
        written = generate_files.run(load, request, paths, features=args.features,
                                     progress=not args.quiet, rig=args.rig,
                                     notice=_notice)
    finally:
        _hide_decisions()  # main() may be called again in one process (tests, scripts)
    for path in written:
        print(path)
    return 0


def _notice(line: str) -> None:
    """A prompt the model does not know, said on stderr also without --verbose (and --quiet,
    which hides only the progress bar): a user would otherwise take its motion for the
    prompt's. Through tqdm, so that a progress bar stays whole."""
    from tqdm import tqdm

    tqdm.write(f"mlct: {line}", file=sys.stderr)


class _ToStderr(logging.Handler):
    """A log record as "mlct: message" on sys.stderr as it is when the record comes (not as it
    was when the handler was made: a test's captured stream is gone by then)."""

    def emit(self, record: logging.LogRecord) -> None:
        print(f"mlct: {record.getMessage()}", file=sys.stderr, flush=True)


def _show_decisions() -> None:
    """--verbose: the pipeline's decisions (logger "mlct", e.g. a gait kept going) on stderr."""
    log = logging.getLogger("mlct")
    if not any(isinstance(h, _ToStderr) for h in log.handlers):
        log._level_before_verbose = log.level  # type: ignore[attr-defined]
        log.addHandler(_ToStderr())
    log.setLevel(logging.INFO)


def _hide_decisions() -> None:
    """Undo _show_decisions: the "mlct" logger as it was before --verbose."""
    log = logging.getLogger("mlct")
    shown = [h for h in log.handlers if isinstance(h, _ToStderr)]
    for handler in shown:
        log.removeHandler(handler)
    if shown:
        log.setLevel(getattr(log, "_level_before_verbose", logging.NOTSET))


def _control(args: argparse.Namespace) -> Any:
    """The control of --control/--path/--keyframes/--edit/--parts/--prefix, read before the
    model loads (generate/control/schema.py); None when none is given."""
    from mlct.generate.control.files import control_from_files
    from mlct.motion.skeleton import get_skeleton

    given = (args.control, args.path, args.keyframes, args.edit, args.parts, args.prefix)
    if all(value is None for value in given):
        return None
    skeleton = get_skeleton("humanml3d")  # controls need its 22 joints (checked again later)
    frames = None  # the length an end_pose needs; a bad --seconds is reported by generation
    if args.length is not None and len(args.length) == 1:
        frames = args.length[0]
    elif (args.seconds is not None and len(args.seconds) == 1
          and isinstance(args.seconds[0], float) and 0 < args.seconds[0] < 1e6):
        frames = int(round(args.seconds[0] * skeleton.fps))
    return control_from_files(skeleton, control=args.control, path=args.path,
                              keyframes=args.keyframes, edit=args.edit, parts=args.parts,
                              prefix=args.prefix, frames=frames)


def _seconds(value: str) -> float | str:
    """--seconds: a number, or 'auto' (from the text)."""
    if value.strip().lower() == "auto":
        return "auto"
    try:
        return float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number of seconds or 'auto': {value!r}"
                                         ) from None


def add_parser(commands: Commands) -> None:
    generate = commands.add_parser(
        "generate", help="text to motion: GIF, MP4, PNG filmstrip, NPY, JSON, BVH, GLB, FBX, "
        "VRMA or NPZ",
        description="One prompt: one motion (--num for variations). Several prompts with one "
                    "duration each: one continuous long motion doing them in order. --prompts "
                    "FILE: one motion per line.")
    generate.add_argument("text", nargs="*", help="what the person does")
    generate.add_argument("--prompts", type=Path, default=None,
                          help="a UTF-8 file, one prompt per line (batched)")
    generate.add_argument("--model", type=Path, default=None,
                          help="model directory (default: the bundled model)")
    length = generate.add_mutually_exclusive_group()
    length.add_argument("--seconds", type=_seconds, nargs="+", default=None,
                        help="duration; one per prompt for a long motion (default: what the "
                             "prompt says, '... for 20 seconds', else 5, or longer when its "
                             "actions usually take longer: a circle walk, actions in turn); "
                             "'auto' takes it from the text (the model's duration model)")
    length.add_argument("--length", type=int, nargs="+", default=None, help="frames")
    generate.add_argument("--nfe", type=int, default=None, help="sampling steps (default 5)")
    generate.add_argument("--seed", type=int, default=None,
                          help="motion i gets seed + i (default: random)")
    generate.add_argument("--num", type=int, default=1, help="variations per prompt (default 1)")
    generate.add_argument("--candidates", type=int, default=None,
                          help="sample N motions per prompt and keep one the model's critic "
                          "rates among the best (--critic-margin; default: the model's, 8 for "
                          "the bundled model; 1 = plain)")
    generate.add_argument("--critic-margin", type=float, default=None,
                          help="keep the first candidate, in seed order, within this much of "
                          "the critic's best score (default: the model's, 0.05; 0 = the best)")
    generate.add_argument("--device", default=None)
    generate.add_argument("--dtype", default="float32", choices=["float32", "bfloat16"],
                          help="precision of the networks' products (docs/performance.md)")
    generate.add_argument("--backend", default="auto",
                          help="auto (default: onnx on the CPU when onnxruntime is installed, "
                          "cuda-graphs on a GPU, else torch; --verbose says which), torch, "
                          "onnx (ONNX Runtime on the CPU), onnx-int8 (the denoiser's products "
                          "in int8: ~1.4x faster, motions a few mm off float32's) or "
                          "cuda-graphs (a GPU)")
    generate.add_argument("--threads", type=thread_count, default=None, help=THREADS_HELP)
    generate.add_argument("--no-keep-going", action="store_true",
                          help="locomotion asked for longer than the model's clips of it stops "
                               "where the model stops it, instead of walking on (made as takes "
                               "of its natural length, chained)")
    generate.add_argument("--no-plant-feet", action="store_true",
                          help="leave the feet as the model decodes them, sliding a few "
                               "centimetres per step as the training data's do, instead of "
                               "holding each standing foot where it stands")
    generate.add_argument("--no-text-anchors", action="store_true",
                          help="sample every prompt from its own text vector, also one worded "
                               "unlike all the model's training captions (by default pulled part "
                               "of the way towards the nearest ones: docs/training.md)")
    generate.add_argument("--in-place", action="store_true",
                          help="keep the pelvis over where it started (no travel over the "
                               "ground; turns, height and poses as made): an 'in place' clip "
                               "whose root motion a game engine applies")
    generate.add_argument("--whole-prompt", action="store_true",
                          help="give the model a prompt that names actions in sequence ('walks, "
                               "then waves') as one text, instead of one part per action, chained")
    control = generate.add_argument_group(
        "controls", "one prompt that also follows a path, keyframes, an edit or a prefix "
        "(docs/control.md)")
    control.add_argument("--control", type=Path, default=None,
                         help="a JSON file with any of the control fields below")
    control.add_argument("--path", type=Path, default=None,
                         help="root path: .json [[x, z] or [x, z, frame], ...] or .csv x,z[,frame]")
    control.add_argument("--keyframes", type=Path, default=None,
                         help="JSON list of {frame, pose | joint + position | joints}")
    control.add_argument("--edit", type=Path, default=None,
                         help="a motion .npy (joints or features) to keep all but --parts of")
    control.add_argument("--parts", default=None,
                         help="what --edit makes anew: upper, lower, arms, left_arm, right_arm, "
                              "left_leg, right_leg, head, or joint names (comma-separated)")
    control.add_argument("--prefix", type=Path, default=None,
                         help="a motion .npy to continue (the result starts with it)")
    generate.add_argument("--features", action="store_true",
                          help=".npy holds the features (T x 263) instead of joints (T x J x 3)")
    where = generate.add_mutually_exclusive_group()
    where.add_argument("--out", type=Path, default=None,
                       help="FILE.gif, .mp4, .png, .npy, .json, .bvh, .glb, .fbx, .vrma or .npz "
                       "(several: FILE_000.gif, ...)")
    where.add_argument("--out-dir", type=Path, default=None,
                       help="directory; files named after the prompts")
    generate.add_argument("--format", default=None,
                          help="with --out-dir: gif (default), mp4, png, npy, json, bvh, glb, fbx, "
                          "vrma or npz")
    generate.add_argument("--quiet", action="store_true", help="no progress bar")
    generate.add_argument("--rig", default=None,
                          help=".bvh/.glb/.fbx for a character's rig: mixamo, unreal, unity, vrm, "
                               "smpl or FILE.json (joint names, rest pose; docs/export.md)")
    generate.add_argument("--verbose", action="store_true",
                          help="say which inference backend runs the model, and why")
    generate.set_defaults(func=run)
