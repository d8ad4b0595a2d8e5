"""The standard text-to-motion metrics on evaluator embeddings (numpy, float64).

Definitions follow EricGuo5513/text-to-motion utils/metrics.py and final_evaluations.py
(also MLD's mld/models/metrics/tm2t.py, which batches the same way):

- R-precision: in each group of 32 (text, motion) pairs, rank the 32 motions by Euclidean
  distance to each text; top-k counts texts whose own motion is among the k nearest. Groups are
  consecutive rows; a remainder smaller than a group is dropped (the reference's DataLoader has
  drop_last=True, MLD loops over count // 32 groups).
- MM-Dist (matching score): mean distance between a text and its own motion.
- FID: Frechet distance between Gaussians fitted (mean, np.cov) to real and generated motion
  embeddings; sqrtm of the covariance product, eps * I added when it is not finite, a small
  imaginary part dropped.
- Diversity: mean distance of `times` (300) pairs, each side drawn without replacement
  independently of the other (so a pair can be one sample twice).
- MultiModality: the same on the generations of each text, one draw of `times` (10) index pairs
  shared by all texts, averaged over texts and pairs.
- Replications (20): mean and 1.96 * std / sqrt(n), std with ddof=0.

Randomness comes only from the np.random.Generator passed in.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy import linalg

from mlct.errors import MlctError

R_PRECISION_GROUP = 32
TOP_K = 3
DIVERSITY_TIMES = 300
MULTIMODALITY_TIMES = 10
FID_EPS = 1e-6
CI_Z = 1.96  # two-sided 95% normal quantile


def _matrix(x: np.ndarray, name: str) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2:
        raise MlctError(f"{name} must be (N, D), got shape {x.shape}")
    return x


def euclidean_distance_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N1, D), (N2, D) -> (N1, N2) with [i, j] = ||a_i - b_j||."""
    a, b = _matrix(a, "a"), _matrix(b, "b")
    if a.shape[1] != b.shape[1]:
        raise MlctError(f"embedding widths differ: {a.shape[1]} vs {b.shape[1]}")
    # |a|^2 - 2 a.b + |b|^2 keeps memory at N1 x N2; rounding can make it slightly negative for
    # (near-)equal rows, where the reference's sqrt gives NaN: clamp at zero instead.
    squared = (a * a).sum(1)[:, None] - 2.0 * a @ b.T + (b * b).sum(1)[None, :]
    return np.sqrt(np.maximum(squared, 0.0))


def top_k_matches(dist: np.ndarray, top_k: int = TOP_K) -> np.ndarray:
    """(N, N) distances -> (N, top_k) bool: row i's match (column i) is among its k nearest."""
    dist = np.asarray(dist)
    if dist.ndim != 2 or dist.shape[0] != dist.shape[1]:
        raise MlctError(f"need a square distance matrix, got shape {dist.shape}")
    # A stable argsort breaks ties by column index (the reference's quicksort leaves them open).
    order = np.argsort(dist, axis=1, kind="stable")[:, :top_k]  # (N, k) nearest columns
    hits = order == np.arange(len(dist))[:, None]
    return np.logical_or.accumulate(hits, axis=1)


def r_precision(text_emb: np.ndarray, motion_emb: np.ndarray, top_k: int = TOP_K) -> np.ndarray:
    """(top_k,) fractions of the group's texts whose motion is within the k nearest."""
    dist = euclidean_distance_matrix(text_emb, motion_emb)
    return top_k_matches(dist, top_k).mean(axis=0)


def r_precision_batched(text_emb: np.ndarray, motion_emb: np.ndarray,
                        group: int = R_PRECISION_GROUP, top_k: int = TOP_K,
                        rng: np.random.Generator | None = None) -> np.ndarray:
    """(top_k,) R-precision over consecutive groups of `group` pairs; the remainder is dropped.

    With `rng`, the pairs are shuffled first (the reference's loader shuffles; MLD permutes).
    """
    text_emb, motion_emb = _matrix(text_emb, "text_emb"), _matrix(motion_emb, "motion_emb")
    _check_pairs(text_emb, motion_emb)
    n_groups = len(text_emb) // group
    if n_groups == 0:
        raise MlctError(f"R-precision needs at least {group} pairs (one group), "
                        f"got {len(text_emb)}")
    if rng is not None:
        order = rng.permutation(len(text_emb))
        text_emb, motion_emb = text_emb[order], motion_emb[order]
    hits = np.zeros(top_k)
    for start in range(0, n_groups * group, group):
        dist = euclidean_distance_matrix(text_emb[start:start + group],
                                         motion_emb[start:start + group])
        hits += top_k_matches(dist, top_k).sum(axis=0)
    return hits / (n_groups * group)


def _check_pairs(text_emb: np.ndarray, motion_emb: np.ndarray) -> None:
    if text_emb.shape != motion_emb.shape:
        raise MlctError(f"text and motion embeddings must pair up: shapes {text_emb.shape} "
                        f"vs {motion_emb.shape}")


def matching_score(text_emb: np.ndarray, motion_emb: np.ndarray) -> float:
    """MM-Dist: mean ||t_i - m_i|| over the pairs (the reference's trace(dist) / count)."""
    text_emb, motion_emb = _matrix(text_emb, "text_emb"), _matrix(motion_emb, "motion_emb")
    _check_pairs(text_emb, motion_emb)
    return float(np.linalg.norm(text_emb - motion_emb, axis=1).mean())


def activation_statistics(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, D) features -> mean (D,), unbiased covariance (D, D) (np.cov, ddof=1)."""
    x = _matrix(x, "features")
    if len(x) < 2:
        raise MlctError(f"a covariance needs at least 2 samples, got {len(x)}")
    return x.mean(axis=0), np.cov(x, rowvar=False)


def _sqrtm(m: np.ndarray) -> np.ndarray:
    # The reference passes disp=False (deprecated in SciPy 1.16) to keep sqrtm quiet on
    # singular input; the result is checked for finiteness below instead.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return np.asarray(linalg.sqrtm(m))


def frechet_distance(mu1: np.ndarray, cov1: np.ndarray, mu2: np.ndarray, cov2: np.ndarray,
                     eps: float = FID_EPS) -> float:
    """||mu1 - mu2||^2 + Tr(C1 + C2 - 2 sqrt(C1 C2)) between two Gaussians."""
    mu1, mu2 = (np.atleast_1d(np.asarray(m, np.float64)) for m in (mu1, mu2))
    cov1, cov2 = (np.atleast_2d(np.asarray(c, np.float64)) for c in (cov1, cov2))
    if mu1.shape != mu2.shape or cov1.shape != cov2.shape or cov1.shape != mu1.shape * 2:
        raise MlctError(f"Gaussian shapes do not match: mu {mu1.shape}, {mu2.shape}; "
                        f"cov {cov1.shape}, {cov2.shape}")
    diff = mu1 - mu2
    covmean = _sqrtm(cov1 @ cov2)
    if not np.isfinite(covmean).all():
        # Nearly singular product: shift both covariances by eps * I, as the reference does.
        offset = np.eye(len(mu1)) * eps
        covmean = _sqrtm((cov1 + offset) @ (cov2 + offset))
    if np.iscomplexobj(covmean):
        # Rounding leaves a small imaginary part; a large one means the input is not PSD.
        if not np.allclose(np.diagonal(covmean).imag, 0, atol=1e-3):
            raise MlctError(f"FID: sqrt of the covariance product has an imaginary part "
                            f"{np.abs(covmean.imag).max():.3g}")
        covmean = covmean.real
    return float(diff @ diff + np.trace(cov1) + np.trace(cov2) - 2.0 * np.trace(covmean))


def fid(real_feats: np.ndarray, gen_feats: np.ndarray) -> float:
    """FID between evaluator embeddings of real (N1, D) and generated (N2, D) motions."""
    mu_real, cov_real = activation_statistics(real_feats)
    mu_gen, cov_gen = activation_statistics(gen_feats)
    return frechet_distance(mu_real, cov_real, mu_gen, cov_gen)


def diversity(x: np.ndarray, times: int = DIVERSITY_TIMES, *, rng: np.random.Generator) -> float:
    """Mean distance of `times` random pairs of rows of (N, D) features (needs N > times)."""
    x = _matrix(x, "features")
    if len(x) <= times:
        raise MlctError(f"diversity over {times} pairs needs more than {times} samples, "
                        f"got {len(x)}")
    first = rng.choice(len(x), times, replace=False)
    second = rng.choice(len(x), times, replace=False)
    return float(np.linalg.norm(x[first] - x[second], axis=1).mean())


def multimodality(x: np.ndarray, times: int = MULTIMODALITY_TIMES, *,
                  rng: np.random.Generator) -> float:
    """Mean distance of `times` random pairs among each text's generations, (N_texts, N_gen, D)."""
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 3:
        raise MlctError(f"multimodality needs (N_texts, N_gen, D) features, got shape {x.shape}")
    if x.shape[1] <= times:
        raise MlctError(f"multimodality over {times} pairs needs more than {times} generations "
                        f"per text, got {x.shape[1]}")
    first = rng.choice(x.shape[1], times, replace=False)
    second = rng.choice(x.shape[1], times, replace=False)
    return float(np.linalg.norm(x[:, first] - x[:, second], axis=2).mean())


def confidence_interval(values: np.ndarray | list[float]
                        ) -> tuple[float | np.ndarray, float | np.ndarray]:
    """Replications (n, ...) -> mean and 1.96 * std / sqrt(n) over axis 0 (std with ddof=0).

    Scalars per replication give floats; vectors (e.g. R-precision top-1/2/3) give arrays.
    """
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 0 or len(values) == 0:
        raise MlctError("confidence_interval needs at least one replication")
    mean = values.mean(axis=0)
    # The reference divides by sqrt(replication_times), i.e. the number of values.
    half_width = CI_Z * values.std(axis=0) / np.sqrt(len(values))
    if values.ndim == 1:
        return float(mean), float(half_width)
    return mean, half_width
