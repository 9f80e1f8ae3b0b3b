"""ICE's component equivalence tests and merge equations (dissertation eqs. 7.4-7.12)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from estimators.model.mixture_tests import (
    MixtureModel,
    components_equivalent,
    hotelling_t2_test,
    merge_moments,
    w_statistic_test,
)

ALPHA = 0.05
DRAWS = 2000
MEAN = np.array([0.3, -0.02])
COV = np.array([[2.5**2, 0.1], [0.1, 0.25**2]])


def _draws(m: int, shift: np.ndarray | None = None, scale: float = 1.0, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    L = np.linalg.cholesky(COV)
    z = rng.standard_normal((DRAWS, m, 2))
    return MEAN + (0.0 if shift is None else shift) + scale * z @ L.T


def _binomial_band(p: float, n: int = DRAWS, k: float = 4.0) -> tuple[float, float]:
    s = np.sqrt(p * (1 - p) / n)
    return p - k * s, p + k * s


def _rejection_rate(test, samples: np.ndarray) -> float:
    return float(np.mean([not test(s).accept for s in samples]))


@pytest.mark.parametrize("m", [200, 1000])
def test_w_statistic_rejects_at_alpha_under_the_null(m: int) -> None:
    rate = _rejection_rate(lambda s: w_statistic_test(s, COV, ALPHA), _draws(m))
    lo, hi = _binomial_band(ALPHA)
    assert lo < rate < hi, rate


@pytest.mark.parametrize("m", [10, 200])
def test_hotelling_rejects_at_alpha_under_the_null(m: int) -> None:
    # the F law of eq. 7.7 is exact for normal data, so even m = 10 is calibrated
    rate = _rejection_rate(lambda s: hotelling_t2_test(s, MEAN, COV, ALPHA), _draws(m))
    lo, hi = _binomial_band(ALPHA)
    assert lo < rate < hi, rate


def test_w_statistic_detects_a_scaled_component() -> None:
    rate = _rejection_rate(lambda s: w_statistic_test(s, COV, ALPHA), _draws(200, scale=1.3, seed=1)[:500])
    assert rate > 0.95, rate


def test_w_statistic_ignores_the_mean() -> None:
    # a pure covariance test: a shifted sample with the right covariance is accepted at the null rate
    rate = _rejection_rate(lambda s: w_statistic_test(s, COV, ALPHA), _draws(200, shift=np.array([5.0, 1.0]), seed=2))
    lo, hi = _binomial_band(ALPHA)
    assert lo < rate < hi, rate


def test_hotelling_detects_a_shifted_component() -> None:
    # half a sigma on the code channel with 100 points
    shift = np.array([0.5 * 2.5, 0.0])
    rate = _rejection_rate(lambda s: hotelling_t2_test(s, MEAN, COV, ALPHA), _draws(100, shift=shift, seed=3)[:500])
    assert rate > 0.95, rate


def test_hotelling_statistic_equals_the_textbook_form() -> None:
    s = _draws(50, seed=4)[0]
    diff = s.mean(axis=0) - MEAN
    t2 = 50 * diff @ np.linalg.solve(np.cov(s, rowvar=False), diff)
    res = hotelling_t2_test(s, MEAN, COV)
    assert res.statistic == pytest.approx((50 - 2) / (2 * 49) * t2, rel=1e-10)
    assert res.p_value == pytest.approx(stats.f.sf(res.statistic, 2, 48), rel=1e-10)


def test_both_tests_accept_the_same_component_and_reject_a_different_one() -> None:
    same = np.mean([components_equivalent(s, MEAN, COV)[0] for s in _draws(300, seed=5)[:500]])
    other = np.mean(
        [
            components_equivalent(s, MEAN, COV)[0]
            for s in _draws(300, shift=np.array([1.0, 0.0]), scale=1.5, seed=6)[:500]
        ]
    )
    assert same > 0.85 and other < 0.01, (same, other)


def test_merge_preserves_pooled_mean_and_covariance_exactly() -> None:
    rng = np.random.default_rng(7)
    a = rng.normal([1.0, -2.0], [3.0, 0.5], size=(137, 2))
    b = rng.normal([-4.0, 0.3], [0.7, 2.0], size=(41, 2))
    mean, cov = merge_moments(
        len(a), a.mean(0), np.cov(a, rowvar=False, bias=True), len(b), b.mean(0), np.cov(b, rowvar=False, bias=True)
    )
    both = np.vstack([a, b])
    np.testing.assert_allclose(mean, both.mean(0), rtol=0, atol=1e-12)
    np.testing.assert_allclose(cov, np.cov(both, rowvar=False, bias=True), rtol=1e-12, atol=1e-12)


def test_adapt_merges_a_matching_cluster_and_adds_a_new_one_with_weights_7_10_to_7_12() -> None:
    rng = np.random.default_rng(8)
    prior = rng.multivariate_normal(MEAN, COV, size=900)
    model = MixtureModel(prior.mean(0)[None], np.cov(prior, rowvar=False, bias=True)[None], np.array([900.0]))
    same = rng.multivariate_normal(MEAN, COV, size=300)
    far = rng.multivariate_normal([20.0, 3.0], np.diag([4.0, 1.0]), size=100)
    lone = np.array([[100.0, 100.0]])  # a one-point cluster is dropped
    samples = np.vstack([same, far, lone])
    labels = np.repeat([0, 1, 2], [300, 100, 1])
    out = model.adapt(samples, labels, alpha=ALPHA)
    assert out == {"merged": 1, "added": 1, "dropped": 1}
    # M counts the points of kept clusters: N + M = 900 + 400
    np.testing.assert_allclose(model.weights, [1200 / 1300, 100 / 1300])
    pooled = np.vstack([prior, same])
    np.testing.assert_allclose(model.means[0], pooled.mean(0), atol=1e-12)
    np.testing.assert_allclose(model.covs[0], np.cov(pooled, rowvar=False, bias=True), atol=1e-12)
    np.testing.assert_allclose(model.means[1], far.mean(0), atol=1e-12)
    assert len(model.history) == 1 and len(model.history[0]["weights"]) == 2
    assert model.most_likely(np.array([[19.0, 3.0], [0.0, 0.0]])).tolist() == [1, 0]


def test_adapt_respects_the_component_cap() -> None:
    model = MixtureModel.single(np.zeros(2), np.eye(2))
    rng = np.random.default_rng(9)
    centres = 50.0 * np.arange(1, 6)[:, None] * np.ones(2)
    samples = np.vstack([rng.normal(c, 1.0, size=(20, 2)) for c in centres])
    out = model.adapt(samples, np.repeat(np.arange(5), 20), max_components=3)
    assert model.n_components == 3 and out["added"] == 2 and out["dropped"] == 3
