"""Residual clustering for the adaptive estimators: variational DP-GMM and MCFS feature selection.

:func:`fit_dpgmm` fits a variational Dirichlet-process Gaussian mixture
(scikit-learn :class:`~sklearn.mixture.BayesianGaussianMixture`) with the priors of
the original BCE code (REFERENCE.md): stick-breaking ``Beta(1, gamma = 1)``,
Gauss-Wishart prior with ``m0 = 0``, ``beta0 = 1``, ``nu0 = D`` and ``W0^-1 = D I``.
scikit-learn parameterises the Wishart by ``covariance_prior`` = ``W0^-1`` (its
update is ``W_k^-1 = W0^-1 + N_k S_k + ...``), ``degrees_of_freedom_prior`` =
``nu0`` and ``mean_precision_prior`` = ``beta0``.

:func:`mcfs_scores` is the unsupervised multi-cluster feature selection of Cai,
Zhang and He (2010), used by BCE-AD (dissertation Sec. 6.2.4): a k-nearest-neighbour
graph, its spectral embedding, one least-angle regression per eigenvector, and
each feature's score the largest absolute coefficient it gets.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.linear_model import Lars
from sklearn.manifold import spectral_embedding
from sklearn.mixture import BayesianGaussianMixture
from sklearn.neighbors import kneighbors_graph

__all__ = ["Mixture", "code_marginal_labels", "fit_dpgmm", "mcfs_scores", "select_features"]


@dataclass
class Mixture:
    """A fitted mixture with its non-empty components only.

    Attributes
    ----------
    weights : ndarray, shape (K,)
        Component weights (renormalised over the kept components).
    means : ndarray, shape (K, D)
    covariances : ndarray, shape (K, D, D)
        Posterior expected covariances (scikit-learn ``covariances_``).
    labels : ndarray of int, shape (N,)
        Hard assignment (argmax responsibility) of every input point, 0..K-1.
    counts : ndarray of int, shape (K,)
        Points assigned to each component.
    """

    weights: np.ndarray
    means: np.ndarray
    covariances: np.ndarray
    labels: np.ndarray
    counts: np.ndarray
    #: the fitted scikit-learn model (pass it back as ``warm_start`` to continue from it)
    model: BayesianGaussianMixture | None = None

    @property
    def n_components(self) -> int:
        return len(self.weights)

    def to_json(self) -> dict[str, Any]:
        """JSON-friendly record (lists of floats) of the components, without labels."""
        return {
            "weights": self.weights.tolist(),
            "means": self.means.tolist(),
            "covariances": self.covariances.tolist(),
            "counts": self.counts.tolist(),
        }


def fit_dpgmm(
    x: np.ndarray,
    *,
    truncation: int = 10,
    max_iter: int = 1000,
    tol: float = 1e-4,
    seed: int = 0,
    fit_rows: np.ndarray | None = None,
    concentration: float = 1.0,
    warm_start: BayesianGaussianMixture | None = None,
) -> Mixture:
    """Fit a variational DP-GMM with full covariances and hard-assign every point.

    Parameters
    ----------
    x : ndarray, shape (N, D)
        Points (e.g. code and phase residuals [m]).
    truncation : int
        Largest number of components of the stick-breaking approximation.
    max_iter, tol : int, float
        Variational iterations and lower-bound tolerance (scikit-learn). Loose settings
        (scikit-learn's 100 / 1e-3) stop while superfluous components are still alive:
        a two-component mixture then comes back as five, each Gaussian split in pieces.
    seed : int
        Random state of the k-means++ initialisation (results are deterministic).
    fit_rows : int array, optional
        Fit on these rows only (sub-sampling for speed); all rows are assigned.
    concentration : float
        Stick-breaking concentration ``gamma`` (``Beta(1, gamma)``).
    warm_start : BayesianGaussianMixture, optional
        A previous fit (:attr:`Mixture.model`) to start the variational iterations from,
        instead of k-means: successive fits on slowly changing residuals then move
        smoothly (and take a few iterations) rather than jumping between local optima.

    Returns
    -------
    Mixture
        Components that received at least one point, relabelled 0..K-1 by decreasing count.
    """
    x = np.asarray(x, float)
    d = x.shape[1]
    fit_x = x if fit_rows is None else x[fit_rows]
    k = int(min(truncation, len(fit_x)))
    if warm_start is not None and warm_start.n_components == k and warm_start.means_.shape[1] == d:
        model = warm_start
        model.set_params(warm_start=True, max_iter=max_iter, tol=tol)
    else:
        model = BayesianGaussianMixture(
            n_components=k,
            covariance_type="full",
            weight_concentration_prior_type="dirichlet_process",
            weight_concentration_prior=concentration,
            mean_prior=np.zeros(d),
            mean_precision_prior=1.0,
            degrees_of_freedom_prior=float(d),
            covariance_prior=d * np.eye(d),
            max_iter=max_iter,
            tol=tol,
            random_state=seed,
            init_params="k-means++",
            n_init=1,
        )
    # non-convergence within max_iter still gives a usable (if slightly looser) mixture
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        # fit_predict's final E-step gives the labels predict would (fit discards them)
        fitted = model.fit_predict(fit_x)
    labels = fitted if fit_rows is None else model.predict(x)
    counts = np.bincount(labels, minlength=k)
    keep = np.flatnonzero(counts > 0)
    keep = keep[np.argsort(-counts[keep], kind="stable")]
    remap = np.full(k, -1, np.int64)
    remap[keep] = np.arange(len(keep))
    w = model.weights_[keep]
    return Mixture(
        weights=w / w.sum(),
        means=model.means_[keep].copy(),
        covariances=model.covariances_[keep].copy(),
        labels=remap[labels],
        counts=counts[keep],
        model=model,
    )


def code_marginal_labels(code: np.ndarray, weights: np.ndarray, means: np.ndarray, covs: np.ndarray) -> np.ndarray:
    """Most likely component of each code residual under the components' code marginals.

    For rows with no phase residual: the marginal of component ``c`` over its first
    (code) dimension is ``N(means[c, 0], covs[c, 0, 0])``.

    Parameters
    ----------
    code : ndarray, shape (m,)
        Code residuals [m].
    weights : ndarray, shape (K,)
    means : ndarray, shape (K, D)
    covs : ndarray, shape (K, D, D)
        Component weights, means [m] and covariances [m^2]; dimension 0 is the code.

    Returns
    -------
    ndarray of int, shape (m,)
    """
    var = covs[:, 0, 0]
    log_p = np.log(weights) - 0.5 * (np.log(var) + (code[:, None] - means[None, :, 0]) ** 2 / var)
    return np.argmax(log_p, axis=1)


def mcfs_scores(
    x: np.ndarray, *, n_clusters: int = 3, n_neighbors: int = 5, n_nonzero: int | None = None, seed: int = 0
) -> np.ndarray:
    """Multi-cluster feature selection scores (Cai et al. 2010) of each column of ``x``.

    Parameters
    ----------
    x : ndarray, shape (N, F)
        Points; columns are standardised (zero mean, unit variance) here.
    n_clusters : int
        Number of eigenvectors of the spectral embedding (expected clusters).
    n_neighbors : int
        Neighbours of the kNN graph (0/1 weights, symmetrised).
    n_nonzero : int, optional
        Cardinality of each least-angle regression (default: all features).
    seed : int
        Random state of the eigen-solver.

    Returns
    -------
    ndarray, shape (F,)
        ``max_k |a_kj|`` over the regressions of the ``n_clusters`` eigenvectors; higher is
        more relevant. A constant column scores 0.
    """
    x = np.asarray(x, float)
    std = x.std(axis=0)
    z = (x - x.mean(axis=0)) / np.where(std > 0, std, 1.0)
    w = kneighbors_graph(z, n_neighbors=n_neighbors, mode="connectivity", include_self=False)
    w = 0.5 * (w + w.T)
    # the K smallest generalised eigenvectors as in Cai et al.; the trivial constant one
    # gets zero coefficients (the features are centred), so it needs no special case
    with warnings.catch_warnings():
        # a kNN graph of well separated clusters is disconnected; the embedding is then the
        # cluster indicators, which is what MCFS wants
        warnings.simplefilter("ignore", UserWarning)
        y = spectral_embedding(w, n_components=n_clusters, drop_first=False, random_state=seed)
    nnz = z.shape[1] if n_nonzero is None else n_nonzero
    scores = np.zeros(z.shape[1])
    for j in range(y.shape[1]):
        coef = Lars(n_nonzero_coefs=nnz, fit_intercept=True).fit(z, y[:, j]).coef_
        scores = np.maximum(scores, np.abs(coef))
    scores[std == 0] = 0.0
    return scores


def select_features(x: np.ndarray, n_select: int, **mcfs_kwargs: Any) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the ``n_select`` highest-scoring MCFS features (descending) and all scores."""
    scores = mcfs_scores(x, **mcfs_kwargs)
    order = np.argsort(-scores, kind="stable")
    return np.sort(order[:n_select]), scores
