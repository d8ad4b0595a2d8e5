"""The divergence watch (train/divergence.py) read against real training logs: the bf16 stage 2
that diverged on a GPU trips it, the fp32 twin and the bundle's healthy runs do not."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from mlct.train.divergence import DivergenceWatch

LOGS = Path(__file__).resolve().parents[1] / "docs" / "logs"


def _first_warning(name: str) -> tuple[int, str] | None:
    watch = DivergenceWatch()
    for line in (LOGS / name).read_text().splitlines():
        record = json.loads(line)
        if "grad_norm" in record and (note := watch.check(record["step"], record["grad_norm"])):
            return record["step"], note
    return None


def test_the_bf16_run_that_diverged_is_caught_where_its_norm_left_the_range():
    step, note = _first_warning("gpu_stage2_bf16_vs_fp32_seed35_bf16.jsonl")
    assert step == 3250  # its norm: ~20 to 3,000 steps, 940 at 3,250, 6,662 at 3,500
    assert "940" in note and "diverging" in note


@pytest.mark.parametrize("name", ["gpu_stage2_bf16_vs_fp32_seed35_fp32.jsonl",
                                  "bundled_stage2_seed1.jsonl", "bundled_stage2_short.jsonl",
                                  "stage2_motion_term_not_shipped.jsonl",
                                  "ae_arm_decoder_continued_log.jsonl"])
def test_healthy_runs_do_not_trip_it(name):
    assert _first_warning(name) is None


def test_it_warns_once_and_on_a_non_finite_norm():
    watch = DivergenceWatch(factor=10.0, early_logs=2)
    assert watch.check(1, 2.0) is None and watch.check(2, 4.0) is None  # early median 3
    assert watch.check(3, 29.0) is None
    assert "step 4" in watch.check(4, math.inf)
    assert watch.check(5, 1e9) is None  # said once
    fresh = DivergenceWatch(factor=10.0, early_logs=2)
    fresh.check(1, 2.0)
    fresh.check(2, 4.0)
    assert "31" in fresh.check(3, 31.0)
