"""docs/results.md from the reports of tools/reproduce.py (REPORTS/<name>/results.json).

Tables come from the reports as written by `mlct eval` (mlct.eval.report's formatting); the
reading of them (section 7) is prose kept in tools/results_reading.md, written after looking at
the numbers, and inserted as is.
"""

from __future__ import annotations

import json
import shutil
from collections import defaultdict
from pathlib import Path
from typing import Any

from mlct.eval.report import (aits_table, format_value, markdown_table, results_table,
                              semantic_table)

READING = Path(__file__).with_name("results_reading.md")
IMAGES = "img/results"


def _load_all(reports: Path) -> defaultdict[str, dict[str, Any] | None]:
    """Every report under REPORTS by name; a missing one reads as None."""
    found: defaultdict[str, dict[str, Any] | None] = defaultdict(lambda: None)
    for path in sorted(reports.glob("*/results.json")):
        found[path.parent.name] = json.loads(path.read_text(encoding="utf-8"))
    return found


def _command(report: dict[str, Any]) -> str:
    return f"`{report['command']}`"


def _missing(name: str) -> str:
    return f"*Not measured yet: `{name}` has no report (run `python tools/reproduce.py`).*\n"


def _eval_time(report: dict[str, Any]) -> str:
    rows = report["rows"]
    per_row = [row["seconds"] for row in rows]
    reps = report["config"]["protocol"]["reps"]
    return (f"{len(rows)} configurations, {reps} replications each: "
            f"{report['seconds'] / 60:.1f} min in all; per configuration "
            f"{min(per_row):.0f}–{max(per_row):.0f} s.")


def _merged(table1: dict[str, Any], mms: list[dict[str, Any]],
            aits: dict[str, Any] | None) -> dict[str, Any]:
    """Table 1's rows with MultiModality from the MM reports and AITS from the AITS report."""
    merged = json.loads(json.dumps(table1))
    def key(row: dict[str, Any]) -> tuple[str, int | None]:  # one model has a row per NFE
        return row["method"], row["nfe"]

    mm_rows = {key(row): row for mm in mms for row in mm["rows"]}
    aits_rows = {key(row): row for row in (aits or {}).get("rows", [])}
    for row in merged["rows"]:
        source = mm_rows.get(key(row))
        if source and "multimodality" in source["metrics"]:
            row["metrics"]["multimodality"] = source["metrics"]["multimodality"]
        if aits_rows.get(key(row), {}).get("timing"):
            row["timing"] = aits_rows[key(row)]["timing"]
    return merged


def _pivot(report: dict[str, Any], key: str, names: list[str], ws: list[float]) -> str:
    """Rows = latent type, columns = trained w; cells = metric `key`."""
    cells = {}
    for row in report["rows"]:
        model = Path(row["model"]).name  # cm-<type>-w<w>
        cells[(model.split("-")[1], row["guidance"])] = format_value(row["metrics"].get(key))
    return markdown_table(["latent", *(f"w = {w:g}" for w in ws)],
                  [[n, *(cells.get((n, w), "-") for w in ws)] for n in names])


def _copy_plot(reports: Path, name: str, plot: str, docs: Path) -> str | None:
    source = reports / name / plot
    if not source.exists():
        return None
    target = docs / IMAGES / f"{name}-{plot}"
    target.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(source, target)
    return f"![{name} {plot}]({IMAGES}/{name}-{plot})"


def _section(title: str, report: dict[str, Any] | None, name: str, body: list[str]) -> list[str]:
    if report is None:
        return [f"## {title}", "", _missing(name)]
    return [f"## {title}", "", *body, "", f"Command: {_command(report)}", "",
            f"Evaluation time: {_eval_time(report)}", ""]


def build_markdown(reports: Path, docs: Path, header: str) -> str:
    r = _load_all(reports)
    text = [header]
    t1 = r["table1"]
    if t1 is not None:
        mms = [r[name] for name in ("table1-mm", "table1-mm-ldm") if r[name]]
        merged = _merged(t1, mms, r["table1-aits"])
        body = [results_table(merged), ""]
        for mm in mms:
            body += [f"MModality of {', '.join(Path(m).name for m in mm['config']['models'])} "
                     f"over {mm['config']['protocol']['reps']} replications: {_command(mm)}.",
                     ""]
        if mms:
            body += [f"Every other metric over {t1['config']['protocol']['reps']}.", ""]
        if r["table1-aits"]:
            a = next(row["timing"] for row in r["table1-aits"]["rows"] if row.get("timing"))
            body += [f"AITS measured alone on the machine ({_command(r['table1-aits'])}): batch "
                     f"{a['batch']}, {a['frames']} frames, mean of {a['runs']} runs after "
                     f"{a['warmup']} warm-up runs, loading excluded, {a['device']}:", "",
                     aits_table(r["table1-aits"])]
        plot = _copy_plot(reports, "table1", "nfe.png", docs)
        body += ["", plot] if plot else []
    text += _section("1. Table 1 analogue: Real, latent diffusion (50 DDIM steps, CFG 7.5), "
                     "MLCT at 1, 3, 5, 10 NFE", t1, "table1", body if t1 else [])

    g = r["guidance"]
    body = [results_table(g)] if g else []
    plot = _copy_plot(reports, "guidance", "guidance.png", docs) if g else None
    body += ["", plot] if plot else []
    text += _section("2. Tables 3/7 analogue: the guidance weight w trained in", g, "guidance",
                     body)

    lat = r["latent"]
    body = []
    if lat:
        names, ws = ["quantized", "vae", "plain"], [0.0, 1.0, 2.0]
        body = ["FID:", "", _pivot(lat, "fid", names, ws), "", "R-precision top 3:", "",
                _pivot(lat, "r_precision_top3", names, ws), "", "Every metric:", "",
                results_table(lat)]
    text += _section("3. Figure 3 analogue: quantized vs VAE vs plain latents at w in {0, 1, 2}",
                     lat, "latent", body)

    tl = r["tokens-levels"]
    text += _section("4. Tables 4/5 analogue: tokens n in {2, 3, 4}; levels l in {100, 1000}",
                     tl, "tokens-levels", [results_table(tl)] if tl else [])
    sc = r["schedule"]
    text += _section("5. The schedule: the authors' code (b0 = 0.1, b1 = 20) against the paper's "
                     "printed b0 = 0.002, b1 = 1", sc, "schedule",
                     [results_table(sc)] if sc else [])
    sem = semantic_table(t1) if t1 else None
    text += _section("6. Semantic accuracy per action family (default model)", t1, "table1",
                     ["Recall of each class by the benchmark's action classifier, mean over the "
                      "replications; Real is the classifier's ceiling.", "", sem or ""])
    bf = r["bfloat16"]
    body = []
    if bf and t1:
        fp32 = [row for row in t1["rows"] if row["model"] == bf["rows"][0]["model"]
                and row["nfe"] == bf["rows"][0]["nfe"]]
        pair = {"real": t1["real"], "rows": [*fp32, *(dict(row, method=row["method"] + ", bf16")
                                                   for row in bf["rows"])]}
        body = ["The default model at 5 NFE with float32 matrix products (from section 1) and "
                "with bfloat16 ones (`--dtype bfloat16`), same seeds:", "",
                results_table(pair)]
    text += _section("Reduced precision: bfloat16 against float32", bf, "bfloat16", body)
    text += ["## 7. Reading", ""]
    text += [READING.read_text(encoding="utf-8") if READING.exists() else
             "*Not written yet.*", ""]
    return "\n".join(text)


def _training_times(work: Path) -> str:
    """One line per training: its name and wall time (the done/ markers of tools/reproduce.py)."""
    lines = []
    for marker in sorted((work / "done").glob("*")):
        lines.append([marker.name, marker.read_text(encoding="utf-8").strip()])
    return markdown_table(["training", "wall time (one thread, two side by side)"], lines)


def header(work: Path, scales: str) -> str:
    t1 = _load_all(work / "reports")["table1"]
    real = classifier = ""
    if t1 is not None:
        m = t1["real"]["metrics"]
        real = (f" On the real test motions it gives R@1 {format_value(m['r_precision_top1'])}, "
                f"R@3 {format_value(m['r_precision_top3'])}, MM-Dist "
                f"{format_value(m['mm_dist'])}, Diversity {format_value(m['diversity'])}.")
        versions = ", ".join(f"{k} {v}" for k, v in t1["config"]["versions"].items())
        real += f" Software: {versions}; device {t1['config']['device']}."
        if "semantic_exact" in m:
            classifier = (f" Exact-set accuracy {format_value(m['semantic_exact'])} on the real "
                          f"test motions.")
    return "\n".join([
        "# Results: the paper's comparisons on the procedural benchmark",
        "",
        "Everything below, every number and plot, comes from one command:",
        "",
        "```",
        "python tools/reproduce.py --work repro",
        "```",
        "",
        "It makes the data, trains the evaluator, the action classifier and every model, runs "
        "one `mlct eval` per section and writes this file. Each step is an `mlct` command, "
        "printed as it runs and repeated under each table; a finished step is skipped, so the "
        "command resumes after an interruption. The figures here were measured on a 2-core "
        "x86-64 CPU without a GPU.",
        "",
        "**Data.** The procedural benchmark (`mlct data synth --num 2000 --seed 0`, "
        "HumanML3D skeleton, 263-d features, splits 1600/100/300; docs/data.md).",
        "",
        "**Evaluator.** Guo et al.'s text-motion matching networks, trained on the benchmark by "
        "`mlct train evaluator --sizes compact --steps-decomp 1000 --steps-match 3000` (learned "
        "word vectors; the official widths would take about ten times longer on this CPU). Its "
        "numbers are comparable between the rows of this page, not with the papers' HumanML3D "
        "tables." + real,
        "",
        "**Action classifier** (section 6 and the Sem. columns): `mlct train classifier`."
        + classifier,
        "",
        "**Protocol.** `mlct eval`: 20 replications, R-precision in groups of 32, values "
        "mean ± 1.96 std / √20 (docs/evaluation.md). AITS: batch 1, 196 frames, this CPU.",
        "",
        scales,
        "",
        _training_times(work),
        "",
    ])


def write_results(work: Path, docs: Path, scales: str) -> Path:
    """Write docs/results.md from WORK/reports; returns its path."""
    out = docs / "results.md"
    text = build_markdown(work / "reports", docs, header(work, scales))
    text = text.replace(f"{work}/", "repro/")  # commands as `tools/reproduce.py --work repro`
    out.write_text(text, encoding="utf-8")
    return out
