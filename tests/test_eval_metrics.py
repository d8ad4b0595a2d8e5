"""The standard metrics against closed forms and independent computations."""

from __future__ import annotations

import numpy as np
import pytest

from mlct.errors import MlctError
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


def diagonal_fid(mu1, s1, mu2, s2):
    """FID of N(mu1, diag s1) and N(mu2, diag s2): the covariances commute, sqrt is elementwise."""
    return float(np.sum((mu1 - mu2) ** 2) + np.sum(s1 + s2 - 2.0 * np.sqrt(s1 * s2)))


def spd_sqrt(a):
    w, v = np.linalg.eigh(a)
    return (v * np.sqrt(np.clip(w, 0, None))) @ v.T


def random_spd(rng, d):
    a = rng.normal(size=(d, d))
    return a @ a.T + 0.1 * np.eye(d)


# ---------------------------------------------------------------- distances and R-precision

def test_distance_matrix_matches_brute_force_and_is_zero_on_equal_rows():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(5, 7)), rng.normal(size=(4, 7))
    brute = np.linalg.norm(a[:, None] - b[None], axis=-1)
    np.testing.assert_allclose(euclidean_distance_matrix(a, b), brute, rtol=1e-12, atol=1e-12)
    # Large equal rows: the |a|^2 - 2ab + |b|^2 form rounds below zero; must give 0, not NaN.
    big = rng.normal(size=(6, 512)).astype(np.float32) * 1e3
    diagonal = np.diag(euclidean_distance_matrix(big, big))
    assert np.isfinite(diagonal).all() and np.abs(diagonal).max() < 1e-2


def test_r_precision_identity_matched_is_one():
    rng = np.random.default_rng(1)
    emb = rng.normal(size=(32, 16))
    np.testing.assert_array_equal(r_precision(emb, emb), [1.0, 1.0, 1.0])


def second_ranked(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Texts whose own motion is the 2nd nearest: t_i lies nearer m_{i+1} than m_i."""
    motions = 10.0 * np.eye(n)
    texts = 0.45 * motions + 0.55 * np.roll(motions, -1, axis=0)
    return texts, motions


def test_r_precision_true_match_ranked_second():
    texts, motions = second_ranked(5)
    np.testing.assert_array_equal(r_precision(texts, motions), [0.0, 1.0, 1.0])


def test_top_k_matches_on_a_constructed_matrix():
    # Row 0: own column nearest; row 1: own column 3rd; row 2: own column last.
    dist = np.array([[0.1, 0.5, 0.9, 0.7],
                     [0.2, 0.5, 0.1, 0.9],
                     [0.1, 0.2, 0.9, 0.3],
                     [0.4, 0.3, 0.2, 0.1]])
    expected = np.array([[1, 1, 1], [0, 0, 1], [0, 0, 0], [1, 1, 1]], dtype=bool)
    np.testing.assert_array_equal(top_k_matches(dist, 3), expected)


def _three_groups_and_a_remainder(rng):
    """Two identity-matched groups of 32, one second-ranked group, 10 unmatched rows."""
    good = rng.normal(size=(64, 32))
    texts_2nd, motions_2nd = second_ranked(32)
    remainder_t, remainder_m = rng.normal(size=(10, 32)), 100 + rng.normal(size=(10, 32))
    return (np.concatenate([good, texts_2nd, remainder_t]),
            np.concatenate([good, motions_2nd, remainder_m]))


def test_r_precision_batched_groups_of_32_and_drops_the_remainder():
    rng = np.random.default_rng(2)
    texts, motions = _three_groups_and_a_remainder(rng)
    result = r_precision_batched(texts, motions, group=32)
    # Groups: perfect, perfect, second-ranked -> top1 2/3, top2 and top3 1; remainder ignored.
    np.testing.assert_allclose(result, [2 / 3, 1.0, 1.0])
    # Shuffling with a generator mixes groups, but a fully identity-matched set stays at 1.
    emb = rng.normal(size=(70, 8))
    np.testing.assert_array_equal(r_precision_batched(emb, emb, rng=np.random.default_rng(0)),
                                  [1.0, 1.0, 1.0])
    with pytest.raises(MlctError, match="at least 32"):
        r_precision_batched(emb[:31], emb[:31])


def test_matching_score_is_the_mean_paired_distance():
    texts = np.zeros((3, 2))
    motions = np.array([[3.0, 4.0], [0.0, 1.0], [6.0, 8.0]])  # distances 5, 1, 10
    assert matching_score(texts, motions) == pytest.approx(16.0 / 3.0)
    with pytest.raises(MlctError, match="pair up"):
        matching_score(texts, motions[:2])


# ---------------------------------------------------------------------------------- FID

def test_frechet_distance_of_diagonal_gaussians_closed_form():
    mu1, mu2 = np.array([0.0, 1.0, -2.0, 0.5]), np.array([1.0, 1.0, 0.0, -0.5])
    s1, s2 = np.array([1.0, 4.0, 0.25, 2.0]), np.array([9.0, 1.0, 0.25, 0.5])
    got = frechet_distance(mu1, np.diag(s1), mu2, np.diag(s2))
    assert got == pytest.approx(diagonal_fid(mu1, s1, mu2, s2), rel=1e-12)


def test_frechet_distance_of_full_covariances_via_eigh():
    # Tr sqrt(C1 C2) = Tr sqrt(C1^1/2 C2 C1^1/2): an independent, symmetric computation.
    rng = np.random.default_rng(3)
    c1, c2 = random_spd(rng, 6), random_spd(rng, 6)
    mu1, mu2 = rng.normal(size=6), rng.normal(size=6)
    r = spd_sqrt(c1)
    expected = np.sum((mu1 - mu2) ** 2) + np.trace(c1 + c2 - 2.0 * spd_sqrt(r @ c2 @ r))
    assert frechet_distance(mu1, c1, mu2, c2) == pytest.approx(expected, rel=1e-9)


def test_fid_of_large_samples_approaches_the_closed_form():
    rng = np.random.default_rng(4)
    mu1, mu2 = np.array([0.0, 1.0, 2.0]), np.array([0.5, 0.0, 2.0])
    s1, s2 = np.array([1.0, 2.0, 0.5]), np.array([2.0, 0.5, 0.5])
    real = mu1 + np.sqrt(s1) * rng.standard_normal((40_000, 3))
    gen = mu2 + np.sqrt(s2) * rng.standard_normal((40_000, 3))
    assert fid(real, gen) == pytest.approx(diagonal_fid(mu1, s1, mu2, s2), abs=0.03)


def test_fid_of_a_set_with_itself_is_zero():
    x = np.random.default_rng(5).normal(size=(300, 16))
    assert abs(fid(x, x)) < 1e-6


def test_activation_statistics_are_mean_and_unbiased_covariance():
    x = np.array([[1.0, 2.0], [3.0, 6.0], [5.0, 4.0]])
    mu, cov = activation_statistics(x)
    np.testing.assert_allclose(mu, [3.0, 4.0])
    np.testing.assert_allclose(cov, [[4.0, 2.0], [2.0, 4.0]])  # sums of products / (n - 1)


def test_frechet_distance_refuses_a_large_imaginary_part_and_bad_shapes():
    # diag(1, -1) is no covariance: sqrt of the product has an imaginary diagonal.
    with pytest.raises(MlctError, match="imaginary"):
        frechet_distance(np.zeros(2), np.diag([1.0, -1.0]), np.zeros(2), np.eye(2))
    with pytest.raises(MlctError, match="shapes"):
        frechet_distance(np.zeros(2), np.eye(2), np.zeros(3), np.eye(3))


# ---------------------------------------------------------- diversity, multimodality, CI

def simplex(n: int, edge: float) -> np.ndarray:
    """n points in R^n, every two at distance `edge`."""
    return np.eye(n) * edge / np.sqrt(2.0)


def test_diversity_of_equidistant_points():
    x, edge = simplex(400, 3.0), 3.0
    value = diversity(x, 300, rng=np.random.default_rng(6))
    # The protocol: two index sets, each drawn without replacement, independently; a pair
    # drawing one point twice has distance 0, every other pair exactly `edge`.
    draws = np.random.default_rng(6)
    first = draws.choice(400, 300, replace=False)
    second = draws.choice(400, 300, replace=False)
    assert value == pytest.approx(edge * np.mean(first != second), rel=1e-12)
    assert edge * (1 - 3 / 300) <= value <= edge
    with pytest.raises(MlctError, match="more than 300"):
        diversity(x[:300], 300, rng=np.random.default_rng(0))


def test_diversity_of_two_clusters():
    # Half the points at 0, half at (5, 0): a pair is 5 apart exactly when it crosses.
    x = np.zeros((40, 2))
    x[20:, 0] = 5.0
    value = diversity(x, 30, rng=np.random.default_rng(7))
    draws = np.random.default_rng(7)
    first, second = draws.choice(40, 30, replace=False), draws.choice(40, 30, replace=False)
    assert value == pytest.approx(5.0 * np.mean((first < 20) != (second < 20)), rel=1e-12)


def test_multimodality_of_equidistant_generations():
    edges = np.array([1.0, 2.0, 6.0])
    x = np.stack([simplex(30, e) for e in edges])  # (3 texts, 30 generations, 30)
    value = multimodality(x, 10, rng=np.random.default_rng(8))
    draws = np.random.default_rng(8)
    first, second = draws.choice(30, 10, replace=False), draws.choice(30, 10, replace=False)
    assert value == pytest.approx(edges.mean() * np.mean(first != second), rel=1e-12)
    with pytest.raises(MlctError, match="more than 10"):
        multimodality(x[:, :10], 10, rng=np.random.default_rng(0))


def test_randomness_comes_only_from_the_generator():
    x = np.random.default_rng(9).normal(size=(50, 4))
    a = diversity(x, 20, rng=np.random.default_rng(1))
    np.random.seed(123)  # global state must not matter
    assert diversity(x, 20, rng=np.random.default_rng(1)) == a


def test_confidence_interval_closed_form():
    mean, half = confidence_interval([1.0, 2.0, 3.0, 4.0])
    assert mean == pytest.approx(2.5)
    assert half == pytest.approx(1.96 * np.sqrt(1.25) / 2.0)  # std with ddof=0, sqrt(n) = 2
    means, halves = confidence_interval(np.array([[0.5, 1.0], [0.7, 1.0]]))
    np.testing.assert_allclose(means, [0.6, 1.0])
    np.testing.assert_allclose(halves, [1.96 * 0.1 / np.sqrt(2.0), 0.0], atol=1e-15)
