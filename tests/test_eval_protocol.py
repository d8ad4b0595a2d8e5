"""The evaluation protocol end to end on tiny inputs: replications, Real row, report, CLI, errors.

A procedural dataset of 64 motions (evaluated on its train split: 51 items, one R-precision
group of 32 kept per replication), a random-weight evaluator with small widths, and a tiny MLCT
model and DDIM baseline trained for a few steps.
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch

import mlct
from mlct.train.export import export_run
from mlct.config import load_config
from mlct.data.dataset import Text2MotionEvalDataset
from mlct.data.synth.build import synthesize_dataset
from mlct.errors import MlctError
from mlct.eval import Evaluator, EvaluatorSizes, LearnedWordVectors, build_networks
from mlct.eval import write_evaluator_dir
from mlct.eval.judge.learned_words import build_vocabulary
from mlct.eval.metrics import CI_Z
from mlct.eval.protocol import METRICS, Protocol, ProtocolConfig, check_model, open_protocol
from mlct.eval.report import write_report
from mlct.eval.run import run_evaluation
from mlct.train.loop import train

SPLIT = "train"
SIZES = EvaluatorSizes(word=16, movement_hidden=32, movement_latent=32, text_hidden=32,
                       motion_hidden=32, embedding=32)
SMALL = ProtocolConfig(reps=3, seed=7, aits_runs=2, aits_warmup=1)


pytestmark = pytest.mark.usefixtures("one_thread")


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("synth") / "data"
    synthesize_dataset(root, num=64, seed=3, progress=False)
    return root


def make_evaluator_dir(out: Path, data: Path, width: int = 263, skeleton: str = "humanml3d",
                       seed: int = 0) -> Path:
    """Random weights of small widths; word vectors for the dataset's vocabulary."""
    dataset = Text2MotionEvalDataset(data, SPLIT, seed=0)
    words = build_vocabulary(r.tokens for item in dataset.items for r in item.captions)
    rng = np.random.default_rng(seed)
    vectors = LearnedWordVectors(words, rng.normal(size=(len(words), SIZES.word)))
    torch.manual_seed(seed)
    mean = np.resize(dataset.mean, width)
    std = np.resize(dataset.std, width) / 2  # not the dataset's: its own statistics
    evaluator = Evaluator(build_networks(width, SIZES), mean, std, vectors)
    write_evaluator_dir(out, evaluator, SIZES, meta={"skeleton": skeleton})
    return out


@pytest.fixture(scope="module")
def evaluator_dir(data: Path, tmp_path_factory) -> Path:
    return make_evaluator_dir(tmp_path_factory.mktemp("ev") / "ev", data)


@pytest.fixture(scope="module")
def models(data: Path, tmp_path_factory) -> tuple[Path, Path]:
    """(MLCT model, DDIM baseline): the tiny preset for 196 frames, a few steps each."""
    run = tmp_path_factory.mktemp("run")
    common = [f"text.cache_dir={tmp_path_factory.mktemp('cache')}", "data.max_motion_length=196"]
    for stage, steps in (("ae", 10), ("cm", 4), ("diffusion", 2)):
        train(stage, data, run, load_config("tiny"), progress=False,
              overrides=[*common, f"train.{stage}.max_steps={steps}",
                         f"train.{stage}.val_every=100"])
    out = tmp_path_factory.mktemp("models")
    return export_run(run, out / "mlct", stage="cm"), export_run(run, out / "ldm",
                                                                  stage="diffusion")


@pytest.fixture(scope="module")
def report(models, data: Path, evaluator_dir: Path, tmp_path_factory) -> dict:
    """Both models: MLCT at 1 and 2 steps, DDIM at 3 steps with CFG 0.5 and 2; with MM."""
    config = ProtocolConfig(reps=3, seed=7, mm=True, mm_texts=4, mm_generations=3, mm_times=2,
                            aits_runs=2, aits_warmup=1)
    return run_evaluation(models, data, evaluator_dir, nfe=[1, 2], ddim_steps=[3],
                          guidance=[0.5, 2.0], split=SPLIT, config=config, device="cpu",
                          command="test")


@pytest.fixture(scope="module")
def protocol(data: Path, evaluator_dir: Path) -> Protocol:
    return open_protocol(data, evaluator_dir, SPLIT, SMALL)


# --------------------------------------------------------------------------------- numbers


@pytest.mark.slow
def test_rows_configurations_and_nfe(report: dict) -> None:
    rows = report["rows"]
    assert [(r["kind"], r["nfe"], r["guidance"]) for r in rows] == [
        ("consistency", 1, 1.0), ("consistency", 2, 1.0), ("ddim", 3, 0.5), ("ddim", 3, 2.0)]
    assert [r["network_passes"] for r in rows] == [1, 2, 6, 6]  # DDIM: cond + uncond per step
    assert report["config"]["kept_per_replication"] == 32 and report["config"]["items"] == 51
    assert report["config"]["protocol"]["diversity_times"] == 31  # kept - 1 on a small split
    for row in rows:
        assert set(row["metrics"]) == set(METRICS) - {"semantic_exact", "semantic_recall"}
        assert all(np.isfinite(m["mean"]) and len(m["values"]) == 3
                   for m in row["metrics"].values())
        timing = row["timing"]
        assert timing["frames"] == 196 and timing["batch"] == 1 and timing["runs"] == 2
        parts = timing["text_ms"] + timing["sampling_ms"] + timing["decoding_ms"]
        assert timing["aits_ms"] == pytest.approx(parts) and min(
            timing["text_ms"], timing["sampling_ms"], timing["decoding_ms"]) > 0


@pytest.mark.slow
def test_real_row(report: dict) -> None:
    real = report["real"]["metrics"]
    assert "multimodality" not in real and report["real"]["nfe"] is None
    for rep in range(3):
        tops = [real[f"r_precision_top{k}"]["values"][rep] for k in (1, 2, 3)]
        assert 0 <= tops[0] <= tops[1] <= tops[2] <= 1
        assert abs(real["fid"]["values"][rep]) < 1e-6  # the same cached features on both sides
    assert real["mm_dist"]["mean"] > 0 and real["diversity"]["mean"] > 0


@pytest.mark.slow
def test_confidence_interval_is_applied(report: dict) -> None:
    for row in [report["real"], *report["rows"]]:
        for metric in row["metrics"].values():
            values = np.array(metric["values"])
            assert metric["mean"] == pytest.approx(values.mean())
            assert metric["ci"] == pytest.approx(CI_Z * values.std() / np.sqrt(len(values)))


@pytest.mark.slow
def test_same_seed_same_numbers(protocol: Protocol, models, data, evaluator_dir) -> None:
    gen = mlct.load(models[0])
    first = [protocol.replication(gen, r, nfe=2) for r in range(2)]
    again = open_protocol(data, evaluator_dir, SPLIT, SMALL)  # a fresh cache, the same draws
    assert [again.replication(mlct.load(models[0]), r, nfe=2) for r in range(2)] == first
    assert first[0] != first[1]  # replications differ (seed + r)
    other = open_protocol(data, evaluator_dir, SPLIT, ProtocolConfig(seed=8, aits_runs=0))
    assert other.replication(gen, 0, nfe=2) != first[0]


@pytest.mark.slow
def test_real_side_is_embedded_once_and_generation_is_batched(data, evaluator_dir, models,
                                                              monkeypatch) -> None:
    import mlct.eval.protocol as protocol_module

    calls = {"real": 0}
    real_embed = protocol_module.embed_real

    def counting(*args, **kwargs):
        calls["real"] += 1
        return real_embed(*args, **kwargs)

    monkeypatch.setattr(protocol_module, "embed_real", counting)
    config = ProtocolConfig(reps=2, seed=1, batch_size=16, aits_runs=0)  # 3 batches of 16
    protocol = open_protocol(data, evaluator_dir, SPLIT, config)
    gen = mlct.load(models[0])
    batches, decoded = [], []
    sample, decode = gen.sample_latents, gen.decode
    gen.sample_latents = lambda cond, *a, **k: batches.append(len(cond)) or sample(cond, *a, **k)
    gen.decode = lambda z, lengths: decoded.extend(lengths) or decode(z, lengths)
    protocol.evaluate_real()
    protocol.evaluate(gen, nfe=1)
    protocol.evaluate(gen, nfe=2)
    assert calls["real"] == 1
    assert batches == [16] * 3 * 2 * 2  # 48 kept items, 2 replications, 2 configurations
    idx, _ = protocol.order(0)
    assert decoded[:48] == protocol.real.lengths[idx].tolist()  # ground-truth lengths
    assert all(n % 4 == 0 and n <= 196 for n in decoded)


# ---------------------------------------------------------------------------------- report


@pytest.mark.slow
def test_report_files(report: dict, tmp_path: Path) -> None:
    written = write_report(tmp_path / "out", report)
    names = sorted(path.name for path in written)
    assert names == ["guidance.png", "nfe.png", "results.json", "results.md"]
    parsed = json.loads((tmp_path / "out" / "results.json").read_text())
    assert parsed["rows"] == json.loads(json.dumps(report["rows"]))
    assert parsed["format"] == "mlct-eval-report" and parsed["command"] == "test"
    for png in ("nfe.png", "guidance.png"):
        assert (tmp_path / "out" / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (tmp_path / "out" / "results.md").read_text()
    table = [line for line in md.splitlines() if line.startswith("| ")]
    assert table[0].startswith("| Methods | R@1 ↑ | R@2 ↑ | R@3 ↑ | FID ↓ | MM-Dist ↓ | "
                               "Diversity → | MModality ↑ | NFE | AITS (ms) |")
    real = table[1].split(" | ")
    assert real[0] == "| Real" and re.fullmatch(r"\d+\.\d{3}±\d+\.\d{3}", real[1])
    assert real[4] == "0.000±0.000"  # Real's FID (never -0.000)
    assert "| 3 (×2 CFG) |" in md and "(MLCT, w=1)" in md and "(DDIM, CFG 0.5)" in md


# ------------------------------------------------------------------------------ bad input


def _one_line(match: str, call) -> None:
    with pytest.raises(MlctError, match=match) as info:
        call()
    assert "\n" not in str(info.value)


@pytest.fixture
def no_work(monkeypatch):
    """Any embedding of the real side means the checks came too late."""
    import mlct.eval.protocol as protocol_module

    def fail(*args, **kwargs):
        raise AssertionError("work started before the inputs were checked")

    monkeypatch.setattr(protocol_module, "embed_real", fail)


@pytest.mark.slow
def test_bad_inputs_fail_before_any_work(data, evaluator_dir, models, tmp_path, no_work) -> None:
    model = models[0]

    def run(model_dirs=(model,), data_dir=data, ev=evaluator_dir, **kwargs):
        return lambda: run_evaluation(model_dirs, data_dir, ev, split=kwargs.pop("split", SPLIT),
                                      config=SMALL, device="cpu", **kwargs)

    kit_ev = make_evaluator_dir(tmp_path / "kit_ev", data, width=251, skeleton="kit")
    _one_line(r"reads 251-d motion features, the dataset .* has 263-d \(humanml3d\)",
              run(ev=kit_ev))
    mislabeled = make_evaluator_dir(tmp_path / "mislabeled", data, skeleton="kit")
    _one_line("was trained on the kit skeleton, the dataset .* is humanml3d", run(ev=mislabeled))

    foreign = tmp_path / "foreign_model"
    shutil.copytree(model, foreign)
    meta = json.loads((foreign / "config.json").read_text())
    (foreign / "config.json").write_text(json.dumps(meta | {"skeleton": "kit",
                                                            "feature_dim": 251}))
    _one_line(r"foreign_model was trained on kit \(251-d features\), the dataset .* is "
              r"humanml3d \(263-d\)", run(model_dirs=(model, foreign)))

    no_stats = tmp_path / "no_stats"
    shutil.copytree(data, no_stats)
    (no_stats / "Mean.npy").unlink()
    _one_line(r"Mean\.npy: missing \(the dataset's normalization statistics",
              run(data_dir=no_stats))
    ev_no_std = tmp_path / "ev_no_std"
    shutil.copytree(evaluator_dir, ev_no_std)
    (ev_no_std / "Std.npy").unlink()
    _one_line(r"Std\.npy: missing \(the evaluator's own normalization statistics",
              run(ev=ev_no_std))

    _one_line("fewer than one R-precision group of 32", run(split="test"))
    _one_line("--guidance applies to DDIM", run(guidance=[1.0]))
    _one_line("nfe must be within", run(nfe=[0]))
    _one_line("no such model directory", run(model_dirs=(tmp_path / "nowhere",)))
    _one_line("diversity over 40 pairs needs more than 40 items",
              lambda: open_protocol(data, evaluator_dir, SPLIT,
                                    ProtocolConfig(diversity_times=40)))


@pytest.mark.slow
def test_a_model_too_short_for_the_split(protocol: Protocol) -> None:
    short = SimpleNamespace(max_frames=64, sampler=SimpleNamespace(name="consistency"),
                            check_nfe=lambda n: n)
    _one_line("makes at most 64 frames, the split has items of up to",
              lambda: check_model(protocol, short, [5], "short"))


# --------------------------------------------------------------------------------- the CLI


def _exit_code(argv: list[str]) -> int:
    """main's return value, or the code of argparse's SystemExit (usage errors)."""
    from mlct.cli import main

    try:
        return main(argv)
    except SystemExit as exit_info:
        return int(exit_info.code or 0)


@pytest.mark.slow
def test_cli_eval_end_to_end_and_exit_2(models, data, evaluator_dir, tmp_path, capsys) -> None:
    from mlct.cli import main

    out = tmp_path / "report"
    argv = ["eval", "--model", str(models[0]), "--data", str(data), "--evaluator",
            str(evaluator_dir), "--split", SPLIT, "--reps", "2", "--nfe", "1",
            "--aits-runs", "1", "--device", "cpu", "--out", str(out)]
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert captured.out.startswith("| Methods | R@1")
    assert "replication 2/2" in captured.err  # progress on stderr
    report = json.loads((out / "results.json").read_text())
    assert report["command"].startswith("mlct eval --model")
    assert len(report["rows"]) == 1 and report["real"]["method"] == "Real"
    assert (out / "results.md").is_file() and (out / "nfe.png").is_file()

    kit_ev = make_evaluator_dir(tmp_path / "kit_ev", data, width=251, skeleton="kit")
    bad = [(["--evaluator", str(kit_ev)], "251-d"),
           (["--nfe", "1,x"], "expected integers"),
           (["--guidance", "2"], "--guidance applies to DDIM")]
    for extra, message in bad:
        assert _exit_code([*argv, *extra, "--out", str(tmp_path / "bad")]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "bad").exists()  # nothing written on bad input


def test_cli_train_parses_every_stage(monkeypatch, tmp_path, capsys) -> None:
    from mlct.cli import build_parser, main

    args, extra = build_parser().parse_known_args(
        ["train", "cm", "--data", "d", "--out", "r", "--config", "tiny", "a.b=1"])
    assert args.stage == "cm" and args.overrides == ["a.b=1"] and not extra
    seen = {}

    def fake(data_dir, out_dir, **kwargs):
        seen.update(kwargs, data=data_dir, out=out_dir)
        return {"vocabulary": "learned", "vocabulary_size": 9, "train_items": 3,
                "best_step": 2, "path": str(out_dir)}

    import importlib

    # the module (the package's attribute of that name is the function)
    module = importlib.import_module("mlct.eval.judge.train_evaluator")
    monkeypatch.setattr(module, "train_evaluator", fake)
    assert main(["train", "evaluator", "--data", "d", "--out", str(tmp_path / "ev"),
                 "--steps-decomp", "3", "--steps-match", "4", "--device", "cpu",
                 "--quiet"]) == 0
    assert seen["steps_decomp"] == 3 and seen["steps_match"] == 4 and seen["glove_dir"] is None
    assert seen["device"] == "cpu" and seen["data"] == Path("d")
    assert seen["config"].sizes == module.EvaluatorSizes()  # the official widths by default
    assert "best step 2" in capsys.readouterr().out
    assert main(["train", "evaluator", "--data", "d", "--out", str(tmp_path / "ev"),
                 "--sizes", "compact", "--quiet"]) == 0
    assert seen["config"].sizes.motion_hidden == 256 and seen["steps_match"] == 15000
    assert _exit_code(["train", "evaluator", "--data", "d", "--out", "e", "a.b=1"]) == 2
    assert "unrecognized arguments: a.b=1" in capsys.readouterr().err


@pytest.mark.slow
def test_semantic_accuracy_with_an_action_classifier(models, data, evaluator_dir,
                                                     tmp_path) -> None:
    from mlct.eval.judge.action_classifier import (ClassifierSizes, action_targets,
                                                   load_action_classifier, read_labels,
                                                   semantic_accuracy, train_action_classifier)
    from mlct.eval.report import format_markdown

    sizes = ClassifierSizes(hidden=32, blocks=2)
    classifier_dir = tmp_path / "cls"
    train_action_classifier(data, classifier_dir, steps=20, batch_size=16, progress=False,
                            sizes=sizes)
    config = ProtocolConfig(reps=2, seed=7, aits_runs=0)
    report = run_evaluation([models[0]], data, evaluator_dir, nfe=[1], split=SPLIT,
                            config=config, device="cpu", command="test",
                            classifier_dir=classifier_dir)
    real, row = report["real"], report["rows"][0]
    for r in (real, row):
        for key in ("semantic_exact", "semantic_recall"):
            values = r["metrics"][key]["values"]
            assert len(values) == 2 and all(0.0 <= v <= 1.0 for v in values)
        assert r["semantic_recall"] and all(0 <= v <= 1 for v in r["semantic_recall"].values())
    # the Real row's replication 0 is the classifier on those real motions, computed directly
    protocol = open_protocol(data, evaluator_dir, SPLIT, config)
    idx, _ = protocol.order(0)
    labels = read_labels(data)
    dataset = protocol.dataset
    raw = [dataset.denormalize(dataset[i].motion[None])[0, :dataset[i].length].numpy()
           for i in idx]
    direct = semantic_accuracy(load_action_classifier(classifier_dir), raw,
                               [action_targets(labels[dataset.name(i)]) for i in idx])
    assert real["metrics"]["semantic_exact"]["values"][0] == pytest.approx(
        direct["exact_set_accuracy"])
    markdown = format_markdown(report)
    assert "Sem. recall ↑" in markdown and "## Semantic accuracy per class" in markdown
    # a benchmark without labels cannot be judged: one line, before any work
    unlabeled = tmp_path / "unlabeled"
    shutil.copytree(data, unlabeled)
    (unlabeled / "labels.jsonl").unlink()
    with pytest.raises(MlctError, match="labels.jsonl: missing"):
        run_evaluation([models[0]], unlabeled, evaluator_dir, split=SPLIT, config=config,
                       classifier_dir=classifier_dir)


@pytest.mark.slow
def test_results_report_assembles_the_reproduction_tables(report, tmp_path) -> None:
    """tools/results_report.py: tables from mlct eval's JSON; MM merged; gaps say so."""
    import copy
    import json
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
    from results_report import build_markdown

    reports = tmp_path / "reports"
    no_mm = copy.deepcopy(report)
    for row in no_mm["rows"]:
        row["metrics"].pop("multimodality", None)
    latent = copy.deepcopy(report)
    latent["rows"] = latent["rows"][:1]
    latent["rows"][0].update(model=str(tmp_path / "cm-vae-w2"), guidance=2.0)
    for name, content in (("table1", no_mm), ("table1-mm", report), ("latent", latent)):
        (reports / name).mkdir(parents=True)
        (reports / name / "results.json").write_text(json.dumps(content))
    text = build_markdown(reports, tmp_path / "docs", "# head")
    section1 = text.split("## 2.")[0]
    table = section1.split("\n\n")[1].splitlines()[3:]  # the rows after Real
    for line, row in zip(table, report["rows"], strict=True):  # merged row by row (model, NFE)
        mm = row["metrics"]["multimodality"]
        assert line.startswith(f"| {row['method']} |")
        assert f"| {mm['mean']:.3f}±{mm['ci']:.3f} |" in line  # from table1-mm
    fid = latent["rows"][0]["metrics"]["fid"]
    pivot = text.split("## 3.")[1].split("R-precision")[0]
    assert f"| vae | - | - | {fid['mean']:.3f}±{fid['ci']:.3f} |" in pivot
    for missing in ("guidance", "tokens-levels", "schedule"):
        assert f"`{missing}` has no report" in text
