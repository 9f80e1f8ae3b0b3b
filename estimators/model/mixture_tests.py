"""Equivalence tests and merge equations for Gaussian mixture components (dissertation Sec. 7.2.2).

ICE decides whether a newly clustered component ``g_n`` (its member residuals
``R``, ``m`` points of dimension ``d``) describes the same error source as a
component ``g_g = {w_g, mu_g, Lambda_g}`` of the current model. Two tests must
both accept:

* Covariance (eqs. 7.4-7.5): whiten the residuals with the Cholesky factor of
  the hypothesis covariance, ``y = L^{-1} r`` with ``Lambda_g = L L^T``, and
  test ``cov(Y) = I`` with the Ledoit-Wolf (2002) ``W`` statistic::

      W = (1/d) tr((S - I)^2) - (d/m) ((1/d) tr S)^2 + d/m,   m W d / 2 ~ chi2(d (d + 1) / 2)

* Mean (eqs. 7.6-7.7): Hotelling's one-sample ``T^2``::

      T^2 = m (mu_n - mu_g)^T S_r^{-1} (mu_n - mu_g),   (m - d) / (d (m - 1)) T^2 ~ F(d, m - d)

Where the text is ambiguous the standard definitions are used:

* ``S`` (the text's ``Lambda_y = cov(Y)``) is the unbiased sample covariance
  (divisor ``m - 1``) in both tests, which makes the ``F`` law of eq. 7.7 exact
  for normal data; the ``W`` test is asymptotic whichever divisor is used.
* Eq. 7.6 writes ``m ||mu_n - mu_g||_{Lambda_y}``: a Mahalanobis norm with the
  covariance of the *whitened* residuals. It is applied here to the whitened
  mean difference ``L^{-1}(mu_n - mu_g)``, squared, with ``Lambda_y^{-1}`` as
  the metric, which equals the textbook ``T^2`` on the raw residuals
  (whitening is an affine map and ``T^2`` is affine invariant).

Merge equations (7.8-7.12): the model keeps, per component, the number of
points it represents (``N w_g``), the mean and the maximum-likelihood
covariance (divisor ``m``). With those, eqs. 7.8-7.9 give exactly the mean
and the divisor-``n`` covariance of the pooled points, and eqs. 7.10-7.12
(``w = count / (N + M)``) give the weights.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

__all__ = [
    "MixtureModel",
    "TestResult",
    "components_equivalent",
    "hotelling_t2_test",
    "merge_moments",
    "w_statistic_test",
]


@dataclass(frozen=True)
class TestResult:
    """Outcome of one equivalence test.

    Attributes
    ----------
    statistic : float
        The test statistic on its reference scale (``m W d / 2`` for the
        covariance test, the ``F`` value of eq. 7.7 for the mean test).
    p_value : float
        Probability of a statistic at least this large under equivalence.
    accept : bool
        ``p_value > alpha``: equivalence not rejected.
    """

    statistic: float
    p_value: float
    accept: bool


def _as_samples(residuals: np.ndarray) -> np.ndarray:
    r = np.asarray(residuals, dtype=float)
    if r.ndim == 1:
        r = r[:, None]
    if r.ndim != 2 or r.shape[0] <= r.shape[1]:
        raise ValueError(f"need an (m, d) sample with m > d, got shape {np.shape(residuals)}")
    return r


def w_statistic_test(residuals: np.ndarray, cov_g: np.ndarray, alpha: float = 0.05) -> TestResult:
    """Covariance equivalence test of eqs. 7.4-7.5 (Ledoit-Wolf ``W``).

    Parameters
    ----------
    residuals : ndarray, shape (m, d)
        Residuals assigned to the new component [m].
    cov_g : ndarray, shape (d, d)
        Hypothesis covariance ``Lambda_g`` [m^2].
    alpha : float
        Significance level.

    Returns
    -------
    TestResult
        ``statistic = m W d / 2``, compared with ``chi2(d (d + 1) / 2)``.
    """
    r = _as_samples(residuals)
    m, d = r.shape
    L = np.linalg.cholesky(np.atleast_2d(cov_g))
    y = np.linalg.solve(L, r.T).T
    S = np.atleast_2d(np.cov(y, rowvar=False))
    tr = np.trace(S) / d
    D = S - np.eye(d)
    W = np.einsum("ij,ji->", D, D) / d - d / m * tr**2 + d / m
    stat = m * W * d / 2.0
    p = float(stats.chi2.sf(stat, d * (d + 1) // 2))
    return TestResult(float(stat), p, p > alpha)


def hotelling_t2_test(
    residuals: np.ndarray, mean_g: np.ndarray, cov_g: np.ndarray | None = None, alpha: float = 0.05
) -> TestResult:
    """Mean equivalence test of eqs. 7.6-7.7 (one-sample Hotelling ``T^2``).

    Parameters
    ----------
    residuals : ndarray, shape (m, d)
        Residuals assigned to the new component [m]; their mean is ``mu_n``.
    mean_g : ndarray, shape (d,)
        Hypothesis mean ``mu_g`` [m].
    cov_g : ndarray, shape (d, d), optional
        Hypothesis covariance used to whiten first, as the text does; the
        statistic does not depend on it (affine invariance), it only keeps
        the numbers well scaled.
    alpha : float
        Significance level.

    Returns
    -------
    TestResult
        ``statistic = (m - d) / (d (m - 1)) T^2``, compared with ``F(d, m - d)``.
    """
    r = _as_samples(residuals)
    m, d = r.shape
    diff = r.mean(axis=0) - np.atleast_1d(mean_g)
    if cov_g is not None:
        L = np.linalg.cholesky(np.atleast_2d(cov_g))
        r = np.linalg.solve(L, r.T).T
        diff = np.linalg.solve(L, diff)
    S = np.atleast_2d(np.cov(r, rowvar=False))
    t2 = m * float(diff @ np.linalg.solve(S, diff))
    f = (m - d) / (d * (m - 1)) * t2
    p = float(stats.f.sf(f, d, m - d))
    return TestResult(f, p, p > alpha)


def components_equivalent(
    residuals: np.ndarray, mean_g: np.ndarray, cov_g: np.ndarray, alpha: float = 0.05
) -> tuple[bool, float]:
    """Both tests of Sec. 7.2.2 against one model component.

    Returns
    -------
    accept : bool
        True when neither the covariance nor the mean test rejects.
    p_min : float
        The smaller of the two p-values (to rank several accepting components).
    """
    w = w_statistic_test(residuals, cov_g, alpha)
    t = hotelling_t2_test(residuals, mean_g, cov_g, alpha)
    return w.accept and t.accept, min(w.p_value, t.p_value)


def merge_moments(
    count_g: float, mean_g: np.ndarray, cov_g: np.ndarray, count_n: float, mean_n: np.ndarray, cov_n: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Pooled mean and covariance of two components, eqs. 7.8-7.9.

    Parameters
    ----------
    count_g : float
        Points represented by the model component, ``N w_g``.
    mean_g, cov_g : ndarray
        Its mean [m] and maximum-likelihood covariance [m^2].
    count_n : float
        Points of the new component, ``m``.
    mean_n, cov_n : ndarray
        Their mean and maximum-likelihood (divisor ``m``) covariance.

    Returns
    -------
    mean, cov : ndarray
        Mean and divisor-``(N w_g + m)`` covariance of the pooled points.
    """
    total = count_g + count_n
    mean_g, mean_n = np.atleast_1d(mean_g), np.atleast_1d(mean_n)
    mean = (count_g * mean_g + count_n * mean_n) / total
    second = (
        count_g * (np.atleast_2d(cov_g) + np.outer(mean_g, mean_g))
        + count_n * (np.atleast_2d(cov_n) + np.outer(mean_n, mean_n))
    ) / total
    return mean, second - np.outer(mean, mean)


@dataclass
class MixtureModel:
    """The measurement uncertainty model ``GMM_g``: components with point counts.

    Weights are ``counts / counts.sum()``, which is eqs. 7.10-7.12 when a
    batch of ``M`` new points is merged or added at once.

    Attributes
    ----------
    means : ndarray, shape (K, d)
        Component means [m].
    covs : ndarray, shape (K, d, d)
        Component covariances [m^2].
    counts : ndarray, shape (K,)
        Points each component represents (``N w_k``).
    history : list of dict
        Snapshot of the model after each adaptation.
    """

    means: np.ndarray
    covs: np.ndarray
    counts: np.ndarray
    history: list[dict] = field(default_factory=list)

    @classmethod
    def single(cls, mean: np.ndarray, cov: np.ndarray, count: float = 1.0) -> MixtureModel:
        """A one-component (a priori) model."""
        return cls(np.atleast_2d(mean).astype(float), np.atleast_2d(cov)[None].astype(float), np.array([float(count)]))

    @property
    def n_components(self) -> int:
        return len(self.counts)

    @property
    def weights(self) -> np.ndarray:
        return self.counts / self.counts.sum()

    def log_likelihoods(self, r: np.ndarray) -> np.ndarray:
        """``log w_k N(r | mu_k, Lambda_k)`` for every residual and component, shape (n, K)."""
        r = np.atleast_2d(r)
        d = r.shape[1]
        # Gaussian log-density through the Cholesky factors, every component in one stacked call:
        # scipy.stats.multivariate_normal checks and eigen-decomposes the covariance at every call, and a
        # loop over components costs a LAPACK round trip each (ICE calls this at every epoch)
        chol = np.linalg.cholesky(self.covs)  # (K, d, d)
        z = np.linalg.solve(chol, (r[None, :, :] - self.means[:, None, :]).transpose(0, 2, 1))  # (K, d, n)
        log_det = 2.0 * np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(axis=1)
        log_density = -0.5 * (d * np.log(2.0 * np.pi) + log_det[:, None] + (z * z).sum(axis=1))
        return (log_density + np.log(self.weights)[:, None]).T

    def most_likely(self, r: np.ndarray) -> np.ndarray:
        """Index of the most likely component of each residual (eq. 7.1), shape (n,)."""
        return np.argmax(self.log_likelihoods(r), axis=1)

    def adapt(
        self,
        samples: np.ndarray,
        labels: np.ndarray,
        *,
        alpha: float = 0.05,
        min_points: int = 2,
        max_components: int = 20,
    ) -> dict:
        """Merge or add each cluster of ``samples`` (eqs. 7.4-7.12).

        Each cluster (``labels == c``) with at least ``min_points`` points is
        tested against every model component; it is merged into the accepting
        component with the largest smaller-p-value, else added as a new
        component. When the model already has ``max_components`` components an
        unmatched cluster is dropped (the text gives the cap but not what
        happens at it). Merging and adding are decided against the model as it
        was before this call, so clusters of one batch do not merge with each
        other.

        Parameters
        ----------
        samples : ndarray, shape (M, d)
            Buffered outlier residuals [m].
        labels : ndarray of int, shape (M,)
            Cluster of each residual.

        Returns
        -------
        dict
            ``merged``, ``added``, ``dropped`` cluster counts of this call.
        """
        samples = np.atleast_2d(samples)
        base = self.n_components
        merged = added = dropped = 0
        for c in np.unique(labels):
            pts = samples[labels == c]
            m = len(pts)
            if m < max(min_points, samples.shape[1] + 1):
                dropped += 1
                continue
            mean_n = pts.mean(axis=0)
            cov_n = np.atleast_2d(np.cov(pts, rowvar=False, bias=True))
            best, best_p = -1, -1.0
            for k in range(base):
                ok, p = components_equivalent(pts, self.means[k], self.covs[k], alpha)
                if ok and p > best_p:
                    best, best_p = k, p
            if best >= 0:
                self.means[best], self.covs[best] = merge_moments(
                    self.counts[best], self.means[best], self.covs[best], m, mean_n, cov_n
                )
                self.counts[best] += m
                merged += 1
            elif self.n_components < max_components:
                self.means = np.vstack([self.means, mean_n])
                self.covs = np.concatenate([self.covs, cov_n[None]])
                self.counts = np.append(self.counts, float(m))
                added += 1
            else:
                dropped += 1
        self.history.append(self.snapshot())
        return {"merged": merged, "added": added, "dropped": dropped}

    def snapshot(self) -> dict:
        """JSON-serialisable copy of the current model."""
        return {
            "weights": self.weights.tolist(),
            "means": self.means.tolist(),
            "covs": self.covs.tolist(),
            "counts": self.counts.tolist(),
        }
