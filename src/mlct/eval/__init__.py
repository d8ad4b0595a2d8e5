"""Evaluation: the measuring (metrics, protocol, AITS, reports, read-outs) here, the judge
(the matching evaluator, its networks and word vectors, the action classifier) in judge/.

- metrics.py: R-precision, FID, MM-Dist, Diversity, MultiModality, confidence intervals;
- protocol.py: a test split measured by an evaluator, replications, the real side cached;
- aits.py: inference time per sentence; run.py: `mlct eval`; report.py: results.json / .md;
- readouts.py: what a motion does, read from its joints (the benchmark's label checks).

Names are resolved on first use (PEP 562), so `import mlct.eval.metrics` or `import mlct` loads
no evaluator network; `from mlct.eval import Evaluator` still works.
"""

from __future__ import annotations

import importlib
from typing import Any

# the read-outs of benchmark version 3's and 4's families register themselves with readouts.py
from mlct.eval import readouts_arms as _readouts_arms  # noqa: F401
from mlct.eval import readouts_body as _readouts_body  # noqa: F401
from mlct.eval import readouts_more as _readouts_more  # noqa: F401

# name -> the module that defines it
_EXPORTS = {
    **dict.fromkeys(("ActionClassifier", "action_targets", "load_action_classifier",
                     "semantic_accuracy", "train_action_classifier"),
                    "mlct.eval.judge.action_classifier"),
    **dict.fromkeys(("EMBEDDING_DIM", "UNIT_LENGTH", "Evaluator", "EvaluatorSizes",
                     "build_networks"), "mlct.eval.judge.evaluator"),
    **dict.fromkeys(("import_official_evaluator", "load_evaluator_dir", "write_evaluator_dir"),
                    "mlct.eval.judge.evaluator_dir"),
    "LearnedWordVectors": "mlct.eval.judge.learned_words",
    **dict.fromkeys(("activation_statistics", "confidence_interval", "diversity",
                     "euclidean_distance_matrix", "fid", "frechet_distance", "matching_score",
                     "multimodality", "r_precision", "r_precision_batched", "top_k_matches"),
                    "mlct.eval.metrics"),
    **dict.fromkeys(("MotionEncoderBiGRUCo", "MovementConvEncoder", "TextEncoderBiGRUCo"),
                    "mlct.eval.judge.networks"),
    **dict.fromkeys(("EvaluatorTrainConfig", "train_evaluator"),
                    "mlct.eval.judge.train_evaluator"),
    **dict.fromkeys(("POS_ENUMERATOR", "VIP_WORDS", "WordVectorizer"),
                    "mlct.eval.judge.word_vectors"),
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'mlct.eval' has no attribute {name!r}")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value  # resolved once
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
