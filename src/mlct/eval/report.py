"""Evaluation reports: REPORT_DIR/results.json, results.md (laid out as MLCT's Table 1), plots.

    results.json   every number (per-replication values too), the config, timings, command line
    results.md     Methods | R@1 | R@2 | R@3 | FID | MM-Dist | Diversity | MModality | NFE | AITS,
                   values as mean±1.96·std/√reps; then the AITS split and the protocol's choices
    nfe.png        FID and R@3 against NFE, one line per (model, guidance)
    guidance.png   FID and R@3 against the guidance scale, when several were evaluated

Every file is written atomically. Plots use matplotlib's object API on an Agg canvas.
"""

from __future__ import annotations

import json
import os
from collections import defaultdict
from pathlib import Path
from typing import Any

from mlct.generate.samplers import sampler_class
from mlct.io import atomic_path, check_writable_dir, write_text

COLUMNS = [("R@1 ↑", "r_precision_top1"), ("R@2 ↑", "r_precision_top2"),
           ("R@3 ↑", "r_precision_top3"), ("FID ↓", "fid"), ("MM-Dist ↓", "mm_dist"),
           ("Diversity →", "diversity"), ("MModality ↑", "multimodality")]
# Beyond the paper, with --classifier: shown only when some row has them.
SEMANTIC_COLUMNS = [("Sem. exact ↑", "semantic_exact"), ("Sem. recall ↑", "semantic_recall")]
DASH = "-"


def format_value(metric: dict[str, Any] | None, digits: int = 3) -> str:
    """{mean, ci} -> '0.775±0.003'; a missing metric -> '-'."""
    if not metric:
        return DASH
    # FID of identical sets comes out as -1e-12 or so: print 0.000, not -0.000.
    mean, ci = (0.0 if round(v, digits) == 0 else v for v in (metric["mean"], metric["ci"]))
    return f"{mean:.{digits}f}±{ci:.{digits}f}"


def format_nfe(row: dict[str, Any]) -> str:
    if row.get("nfe") is None:
        return DASH
    if row["network_passes"] != row["nfe"]:
        return f"{row['nfe']} (×2 CFG)"
    return str(row["nfe"])


def _aits(row: dict[str, Any]) -> str:
    timing = row.get("timing")
    return f"{timing['aits_ms']:.1f}" if timing else DASH


def markdown_table(header: list[str], lines: list[list[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join(["---"] * len(header)) + "|"]
    out += ["| " + " | ".join(line) + " |" for line in lines]
    return "\n".join(out)


def results_table(report: dict[str, Any]) -> str:
    """The Table 1 layout: Real first, then every configuration."""
    rows = [report["real"], *report["rows"]]
    columns = COLUMNS + [c for c in SEMANTIC_COLUMNS
                         if any(c[1] in row["metrics"] for row in rows)]
    header = ["Methods", *(name for name, _ in columns), "NFE", "AITS (ms)"]
    lines = [[row["method"], *(format_value(row["metrics"].get(key)) for _, key in columns),
              format_nfe(row), _aits(row)] for row in rows]
    return markdown_table(header, lines)


def semantic_table(report: dict[str, Any]) -> str | None:
    """Recall per action class (mean over replications), one column per row; None without."""
    rows = [r for r in [report["real"], *report["rows"]] if r.get("semantic_recall")]
    if not rows:
        return None
    classes = sorted({k for r in rows for k in r["semantic_recall"]})
    lines = [[k, *(f"{r['semantic_recall'][k]:.2f}" if k in r["semantic_recall"] else DASH
                   for r in rows)] for k in classes]
    # a model evaluated at several NFE has one method name: the NFE tells its columns apart
    return markdown_table(["class", *(r["method"] + (f", NFE {r['nfe']}" if r.get("nfe") else "")
                              for r in rows)], lines)


def aits_table(report: dict[str, Any]) -> str:
    """The AITS split (text encoding, sampling, decoding) of every timed row."""
    return markdown_table(
        ["Methods", "NFE", "network passes", "text (ms)", "sampling (ms)", "decoding (ms)",
         "AITS (ms)"],
        [[row["method"], str(row["nfe"]), str(row["network_passes"]),
          *(f"{row['timing'][k]:.1f}" for k in ("text_ms", "sampling_ms", "decoding_ms",
                                                 "aits_ms"))]
         for row in report["rows"] if row.get("timing")])


def format_markdown(report: dict[str, Any]) -> str:
    """results.md: a header naming data, split and evaluator, the table, timings, choices."""
    cfg = report["config"]
    protocol = cfg["protocol"]
    reps = protocol["reps"]
    text = [
        "# Evaluation",
        "",
        f"Data `{cfg['data']}` ({cfg['skeleton']}), split `{cfg['split']}`: {cfg['items']} "
        f"items, {cfg['kept_per_replication']} kept per replication (groups of "
        f"{protocol['batch_size']}). Evaluator `{cfg['evaluator']}`. Device {cfg['device']}"
        f"{', ' + cfg['dtype'] if cfg.get('dtype', 'float32') != 'float32' else ''}.",
        f"{reps} replications (seeds {protocol['seed']}..{protocol['seed'] + reps - 1}); "
        f"values are mean±1.96·std/√{reps}. Diversity over {protocol['diversity_times']} pairs"
        + (f"; MultiModality over {protocol['mm_texts']} texts × {protocol['mm_generations']} "
           f"generations, {protocol['mm_times']} pairs." if protocol["mm"] else "."),
        "",
        results_table(report),
        "",
    ]
    timed = [row for row in report["rows"] if row.get("timing")]
    if timed:
        first = timed[0]["timing"]
        text += [
            "## Inference time (AITS)",
            "",
            f"Batch {first['batch']}, {first['frames']} frames, mean of {first['runs']} runs "
            f"after {first['warmup']} warm-up runs, loading excluded, device {first['device']}.",
            "",
            aits_table(report),
            "",
        ]
    semantic = semantic_table(report)
    if semantic:
        text += [
            "## Semantic accuracy per class",
            "",
            f"Recall of each action class (labels.jsonl) by the action classifier "
            f"`{cfg.get('classifier')}`, mean over the replications: of the prompts that ask "
            f"for a class, the share of motions in which it is detected. Real is the "
            f"classifier's own ceiling.",
            "",
            semantic,
            "",
        ]
    text += ["## Protocol choices", "", *(f"- {choice}" for choice in cfg["choices"]), "",
             f"Command: `{report['command']}`", ""]
    return "\n".join(text)


def _series(rows: list[dict[str, Any]], key: str, x: str) -> dict[str, list[dict[str, Any]]]:
    groups: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for row in rows:
        groups[row[key]].append(row)
    return {name: sorted(members, key=lambda r: r[x]) for name, members in groups.items()}


def _plot(path: Path, rows: list[dict[str, Any]], real: dict[str, Any], x: str, key: str,
          xlabel: str, log_x: bool) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import NullLocator

    fig = Figure(figsize=(10, 4), layout="constrained")
    FigureCanvasAgg(fig)
    for ax, metric, title in zip(fig.subplots(1, 2), ("fid", "r_precision_top3"),
                                 ("FID ↓", "R-precision top-3 ↑")):
        for name, members in _series(rows, key, x).items():
            ax.errorbar([r[x] for r in members], [r["metrics"][metric]["mean"] for r in members],
                        yerr=[r["metrics"][metric]["ci"] for r in members], marker="o",
                        capsize=3, label=name)
        if metric in real["metrics"]:
            ax.axhline(real["metrics"][metric]["mean"], color="gray", linestyle="--",
                       label="Real")
        values = sorted({r[x] for r in rows})
        if log_x and len(values) > 1 and values[0] > 0:
            ax.set_xscale("log")
        ax.set_xticks(values, [f"{v:g}" for v in values])
        ax.xaxis.set_minor_locator(NullLocator())  # only the evaluated values are labelled
        ax.set_xlabel(xlabel)
        ax.set_title(title)
        ax.grid(alpha=0.3)
    fig.axes[0].legend(fontsize="small")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)


def _series_names(report: dict[str, Any]) -> list[dict[str, Any]]:
    """Rows with the names of their lines: by model and guidance, and by sampler and NFE."""
    out = []
    for row in report["rows"]:
        label = row["method"]
        sampler = sampler_class(row["kind"])  # a row's kind is its sampler's name
        out.append(row | {"by_model": label,
                          "by_nfe": f"{sampler.method} {row['nfe']} {sampler.steps_unit}"})
    return out


def write_plots(out: Path, report: dict[str, Any]) -> list[Path]:
    """nfe.png always (when a model was evaluated); guidance.png for several guidance values."""
    rows = _series_names(report)
    written = []
    if rows:
        _plot(out / "nfe.png", rows, report["real"], "nfe", "by_model", "NFE (sampling steps)",
              log_x=True)
        written.append(out / "nfe.png")
    if len({row["guidance"] for row in rows}) > 1:
        _plot(out / "guidance.png", rows, report["real"], "guidance", "by_nfe",
              "guidance scale (MLCT: trained w; DDIM: CFG scale)", log_x=False)
        written.append(out / "guidance.png")
    return written


def write_report(out: str | os.PathLike, report: dict[str, Any]) -> list[Path]:
    """Write results.json, results.md and the plots into REPORT_DIR; return their paths."""
    out = check_writable_dir(out)
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / "results.json", json.dumps(report, indent=2) + "\n")
    write_text(out / "results.md", format_markdown(report))
    return [out / "results.json", out / "results.md", *write_plots(out, report)]
