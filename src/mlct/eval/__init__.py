"""Evaluation: the standard text-motion matching evaluator (Guo et al. 2022) and the metrics."""

from mlct.eval.action_classifier import (
    ActionClassifier,
    action_targets,
    load_action_classifier,
    semantic_accuracy,
    train_action_classifier,
)
from mlct.eval.evaluator import (EMBEDDING_DIM, UNIT_LENGTH, Evaluator, EvaluatorSizes,
                                 build_networks)
from mlct.eval.evaluator_dir import (import_official_evaluator, load_evaluator_dir,
                                     write_evaluator_dir)
from mlct.eval.learned_words import LearnedWordVectors
from mlct.eval.metrics import (
    activation_statistics,
    confidence_interval,
    diversity,
    euclidean_distance_matrix,
    fid,
    frechet_distance,
    matching_score,
    multimodality,
    r_precision,
    r_precision_batched,
    top_k_matches,
)
from mlct.eval.networks import MotionEncoderBiGRUCo, MovementConvEncoder, TextEncoderBiGRUCo
from mlct.eval.train_evaluator import EvaluatorTrainConfig, train_evaluator
from mlct.eval.word_vectors import POS_ENUMERATOR, VIP_WORDS, WordVectorizer

__all__ = [
    "ActionClassifier",
    "EMBEDDING_DIM",
    "POS_ENUMERATOR",
    "UNIT_LENGTH",
    "VIP_WORDS",
    "Evaluator",
    "EvaluatorSizes",
    "EvaluatorTrainConfig",
    "LearnedWordVectors",
    "MotionEncoderBiGRUCo",
    "MovementConvEncoder",
    "TextEncoderBiGRUCo",
    "WordVectorizer",
    "action_targets",
    "activation_statistics",
    "build_networks",
    "confidence_interval",
    "diversity",
    "euclidean_distance_matrix",
    "fid",
    "frechet_distance",
    "import_official_evaluator",
    "load_action_classifier",
    "load_evaluator_dir",
    "matching_score",
    "multimodality",
    "r_precision",
    "r_precision_batched",
    "semantic_accuracy",
    "top_k_matches",
    "train_action_classifier",
    "train_evaluator",
    "write_evaluator_dir",
]
