"""`mlct data synth|rephrase|oversample|merge|stats|check|import`: make, check and describe datasets."""

from __future__ import annotations

import argparse
from pathlib import Path

from mlct.cli.parser import Commands, Parser

# mlct.data.corpora's names, spelled here so that building the parser imports no importer
CORPUS_NAMES = ("bandai-namco", "cmu", "cmu-expmap")


def run_synth(args: argparse.Namespace) -> int:
    from mlct.data.synth.build import synthesize_dataset

    summary = synthesize_dataset(args.out, num=args.num, seed=args.seed, skeleton=args.skeleton,
                                 workers=args.workers, progress=not args.quiet,
                                 overwrite=args.overwrite, version=args.benchmark_version)
    print(f"wrote {summary['motions']} motions ({summary['frames']} frames, "
          f"skating ratio {summary['skating_ratio']:.4f}) to {args.out}")
    return 0


def run_rephrase(args: argparse.Namespace) -> int:
    from mlct.data.synth.rephrase import rephrase_dataset

    summary = rephrase_dataset(args.src, args.out, per_motion=args.per_motion,
                               splits=tuple(args.splits.split(",")), seed=args.seed,
                               overwrite=args.overwrite, vocabulary=args.vocabulary,
                               skip_families=tuple(f for f in args.skip_families.split(",") if f))
    print(f"wrote {args.out}: {summary['captions']} {args.vocabulary} captions added to "
          f"{summary['motions']} motions ({args.splits})")
    return 0


def run_oversample(args: argparse.Namespace) -> int:
    from mlct.data.oversample import oversample_dataset

    summary = oversample_dataset(args.src, args.out, families=args.families.split(","),
                                 times=args.times, split=args.split,
                                 single_only=not args.with_sequences, overwrite=args.overwrite)
    print(f"wrote {args.out}: {summary['chosen']} motions of {args.split} listed {args.times} "
          f"times ({summary['items']} items)")
    return 0


def run_merge(args: argparse.Namespace) -> int:
    from mlct.data.merge import merge_datasets

    summary = merge_datasets(args.sources, args.out, overwrite=args.overwrite)
    sizes = ", ".join(f"{split} {n}" for split, n in summary["splits"].items())
    print(f"wrote {args.out}: {sum(summary['motions'])} motions from {len(args.sources)} "
          f"datasets ({sizes}; Mean/Std of {args.sources[0]})")
    return 0


def run_stats(args: argparse.Namespace) -> int:
    from mlct.data.stats import dataset_statistics, format_statistics

    stats = dataset_statistics(args.dir, skeleton=args.skeleton, write_mean_std=not args.no_write)
    print(format_statistics(stats))
    return 0


def run_check(args: argparse.Namespace) -> int:
    from mlct.data.check import check_dataset

    problems = check_dataset(args.dir, skeleton=args.skeleton)
    for problem in problems:
        print(problem)
    if problems:
        print(f"{len(problems)} problem(s) found in {args.dir}")
        return 1
    print(f"{args.dir}: no problems found")
    return 0


def run_import(args: argparse.Namespace) -> int:
    from mlct.data.importer import format_summary, import_dataset, parse_split
    from mlct.errors import MlctError

    if args.corpus is not None:
        from mlct.data.corpora import import_corpus

        given = [flag for flag, value in (("--captions", args.captions),
                                          ("--joint-map", args.joint_map),
                                          ("--scale", args.scale), ("--fps", args.fps))
                 if value is not None]
        if given:
            raise MlctError(f"--corpus makes its own captions, joint map and units; drop "
                            f"{', '.join(given)}")
        name, src = args.corpus
        contents = None if args.contents is None else set(args.contents.split(","))
        summary = import_corpus(name, src, args.out, captions_per_clip=args.captions_per_clip,
                                contents=contents, split=parse_split(args.split),
                                seed=args.seed, overwrite=args.overwrite,
                                level=not args.keep_floor_tilt, progress=not args.quiet)
        print(format_summary(summary))
        return 0
    if args.captions is None:
        raise MlctError("--captions FILE is needed with --joints or --bvh")
    if args.contents is not None:
        raise MlctError("--contents is for --corpus input")
    summary = import_dataset(args.out, args.captions, joints_dir=args.joints, bvh_dir=args.bvh,
                             skeleton=args.skeleton, joint_map=args.joint_map, scale=args.scale,
                             fps=args.fps, split=parse_split(args.split), seed=args.seed,
                             skip_uncaptioned=args.skip_uncaptioned, overwrite=args.overwrite,
                             level=not args.keep_floor_tilt, progress=not args.quiet)
    print(format_summary(summary))
    return 0


def add_parser(commands: Commands) -> None:
    data = commands.add_parser("data", help="make, check and describe datasets")
    data_commands = data.add_subparsers(dest="data_command", required=True, parser_class=Parser)

    synth = data_commands.add_parser("synth", help="write a procedural text-motion benchmark")
    synth.add_argument("--out", required=True, type=Path, help="dataset directory to create")
    synth.add_argument("--num", type=int, default=1000, help="number of motions (default 1000)")
    synth.add_argument("--seed", type=int, default=0)
    synth.add_argument("--skeleton", default="humanml3d", choices=["humanml3d", "kit"])
    synth.add_argument("--workers", type=int, default=1, help="processes (default 1)")
    synth.add_argument("--overwrite", action="store_true", help="replace an existing dataset")
    synth.add_argument("--quiet", action="store_true", help="no progress bar")
    synth.add_argument("--benchmark-version", type=int, default=3, metavar="N",  # build's newest
                       help="3 (default): 36 action families; 4: those and the families "
                            "version 4 adds; 2: the 21 families the bundled model was trained "
                            "on, remade exactly as before")
    synth.set_defaults(func=run_synth)

    rephrase = data_commands.add_parser(
        "rephrase", help="copy a procedural benchmark, adding everyday (or short) captions to a "
                         "split")
    rephrase.add_argument("src", type=Path, help="a dataset written by `mlct data synth`")
    rephrase.add_argument("--out", required=True, type=Path, help="dataset directory to create")
    rephrase.add_argument("--per-motion", type=int, default=3, help="captions added (default 3)")
    rephrase.add_argument("--splits", default="train", help="comma-separated (default train)")
    rephrase.add_argument("--vocabulary", default="everyday",
                          choices=("everyday", "short", "colloquial", "context"),
                          help="everyday phrasings (default), short ones: each action by its "
                               "bare verb ('a woman waves'), or colloquial ones: rarer verbs, "
                               "turn sizes in words, a side after its noun, negation; "
                               "context: the colloquial ones, a third of them with a place "
                               "or an addressee ('waves to a friend across the street')")
    rephrase.add_argument("--skip-families", default="",
                          help="comma-separated action families whose motions keep their "
                               "captions as they are, e.g. turn,spin")
    rephrase.add_argument("--seed", type=int, default=0)
    rephrase.add_argument("--overwrite", action="store_true", help="replace an existing dataset")
    rephrase.set_defaults(func=run_rephrase)

    oversample = data_commands.add_parser(
        "oversample", help="copy a labelled dataset, listing some families' motions several "
        "times in a split (rebalanced batches)")
    oversample.add_argument("src", type=Path, help="a dataset with labels.jsonl (`mlct data synth`)")
    oversample.add_argument("--out", required=True, type=Path, help="dataset directory to create")
    oversample.add_argument("--families", required=True,
                            help="comma-separated action families, e.g. clap,wave,turn")
    oversample.add_argument("--times", type=int, default=3,
                            help="how many times each chosen motion is listed (default 3)")
    oversample.add_argument("--split", default="train", help="the split to rebalance (train)")
    oversample.add_argument("--with-sequences", action="store_true",
                            help="also motions where the family is one action of several "
                            "(default: the family alone)")
    oversample.add_argument("--overwrite", action="store_true", help="replace an existing dataset")
    oversample.set_defaults(func=run_oversample)

    merge = data_commands.add_parser(
        "merge", help="one dataset from several: the first's names and Mean/Std, the others' "
        "names prefixed d2_, d3_ ..., each split the sources' lists joined")
    merge.add_argument("sources", type=Path, nargs="+", help="two or more datasets")
    merge.add_argument("--out", required=True, type=Path, help="dataset directory to create")
    merge.add_argument("--overwrite", action="store_true", help="replace an existing dataset")
    merge.set_defaults(func=run_merge)

    stats = data_commands.add_parser("stats", help="write Mean/Std and print dataset statistics")
    stats.add_argument("dir", type=Path)
    stats.add_argument("--skeleton", default=None, help="humanml3d or kit (default: from width)")
    stats.add_argument("--no-write", action="store_true", help="print only; keep Mean/Std")
    stats.set_defaults(func=run_stats)

    check = data_commands.add_parser("check", help="validate a dataset; exit 1 if problems")
    check.add_argument("dir", type=Path)
    check.add_argument("--skeleton", default=None, help="humanml3d or kit (default: from width)")
    check.set_defaults(func=run_check)

    imported = data_commands.add_parser(
        "import", help="turn your own motion capture (joints .npy or BVH) and captions into a "
                       "dataset in the standard layout (docs/custom_data.md)")
    source = imported.add_mutually_exclusive_group(required=True)
    source.add_argument("--joints", type=Path, help="directory of (T, J, 3) .npy joints, y up")
    source.add_argument("--bvh", type=Path, help="directory of .bvh files")
    source.add_argument("--corpus", nargs=2, metavar=("NAME", "DIR"),
                        help=f"a real corpus's release folder, captioned from its labels: "
                             f"{', '.join(CORPUS_NAMES)} (docs/data.md)")
    imported.add_argument("--captions", type=Path, default=None,
                          help="CSV (name,caption) or JSONL ({name, caption|captions}); "
                               "needed with --joints or --bvh")
    imported.add_argument("--contents", default=None,
                          help="with --corpus: only these content labels, comma-separated")
    imported.add_argument("--captions-per-clip", type=int, default=4,
                          help="with --corpus: captions made per clip (default 4)")
    imported.add_argument("--skeleton", default="humanml3d", choices=["humanml3d", "kit"])
    imported.add_argument("--out", required=True, type=Path, help="dataset directory to create")
    imported.add_argument("--joint-map", type=Path, default=None,
                          help="JSON {BVH joint: skeleton joint} (default: same names)")
    imported.add_argument("--scale", type=float, default=None,
                          help="factor to the skeleton's units, m or mm (default: guessed)")
    imported.add_argument("--fps", type=float, default=None,
                          help="input frame rate (default: BVH Frame Time; skeleton fps for .npy)")
    imported.add_argument("--split", default="0.8,0.1,0.1", help="train,val,test fractions")
    imported.add_argument("--seed", type=int, default=0, help="seed of the split shuffle")
    imported.add_argument("--skip-uncaptioned", action="store_true",
                          help="skip motion files without a caption instead of stopping")
    imported.add_argument("--keep-floor-tilt", action="store_true",
                          help="keep a floor tilted by a few degrees as captured instead of "
                               "levelling it")
    imported.add_argument("--overwrite", action="store_true", help="replace an existing dataset")
    imported.add_argument("--quiet", action="store_true", help="no progress bar")
    imported.set_defaults(func=run_import)
