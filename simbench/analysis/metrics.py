"""Scoring: per-epoch ENU error against truth, summary statistics, ECDF.

Errors are taken relative to the true antenna position in the local
east-north-up frame at that position, without any alignment (dissertation
scoring); horizontal error is sqrt(dE^2 + dN^2) ("RSOS").

Statistics "over reference epochs" count every epoch that has truth, solved
or not: an unsolved epoch is a missed epoch with an infinite error. So an
estimator that skips hard epochs is never rewarded for it: its ECDF ends at
its availability instead of 1, and a percentile above its availability does
not exist (``inf``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd
import pymap3d
from scipy import stats
from scipy.spatial import cKDTree

from simbench.errors import SimbenchError


def enu_errors(solution: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Per-epoch east, north, up, horizontal and 3-D error [m].

    Parameters
    ----------
    solution : pandas.DataFrame
        Columns ``epoch, x, y, z`` (ECEF metres), plus any others (kept).
    truth : pandas.DataFrame
        Columns ``epoch, x, y, z``.

    Returns
    -------
    pandas.DataFrame
        The solution rows that have a truth epoch, with ``e, n, u, horizontal, error_3d`` added.
    """
    merged = solution.merge(truth[["epoch", "x", "y", "z"]], on="epoch", suffixes=("", "_true"))
    lat, lon, _ = pymap3d.ecef2geodetic(
        merged["x_true"].to_numpy(), merged["y_true"].to_numpy(), merged["z_true"].to_numpy()
    )
    d = [merged[c].to_numpy() - merged[f"{c}_true"].to_numpy() for c in ("x", "y", "z")]
    e, n, u = pymap3d.ecef2enuv(d[0], d[1], d[2], lat, lon)
    out = merged.drop(columns=["x_true", "y_true", "z_true"])
    out["e"], out["n"], out["u"] = e, n, u
    out["horizontal"] = np.hypot(e, n)
    out["error_3d"] = np.sqrt(e * e + n * n + u * u)
    return out


def nearest_reference_distance(position: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """3-D distance from each position to the nearest reference point, whatever its time [m].

    libRSF's published numbers are the RMS of this over the estimates (``ATE`` of its
    ``test/TestUtils.cpp``: the closest ground-truth point, no alignment); an error along the
    track, or a late solution, costs less here than against the reference of its own epoch.

    Parameters
    ----------
    position : numpy.ndarray
        (n, 3) estimated ECEF positions [m]; a row with a NaN gives NaN.
    reference : numpy.ndarray
        (m, 3) reference ECEF positions of the run [m].

    Returns
    -------
    numpy.ndarray
        (n,) distances [m].
    """
    position = np.asarray(position, float).reshape(-1, 3)
    out = np.full(len(position), np.nan)
    finite = np.isfinite(position).all(axis=1)
    if finite.any() and len(reference):
        out[finite] = cKDTree(np.asarray(reference, float)).query(position[finite])[0]
    return out


def local_enu(position: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """East, north, up of ECEF points in the local frame at ``origin`` [m].

    Parameters
    ----------
    position : numpy.ndarray
        (n, 3) ECEF positions [m].
    origin : numpy.ndarray
        (3,) ECEF origin [m], e.g. the first reference point of a scenario.

    Returns
    -------
    numpy.ndarray
        (n, 3) east, north, up [m].
    """
    lat, lon, h = pymap3d.ecef2geodetic(*np.asarray(origin, float))
    p = np.asarray(position, float).reshape(-1, 3)
    return np.column_stack(pymap3d.ecef2enu(p[:, 0], p[:, 1], p[:, 2], lat, lon, h))


def nees(error: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """Normalised estimation error squared ``d^T P^-1 d`` per epoch (dimensionless).

    Parameters
    ----------
    error : numpy.ndarray
        (n, k) estimation errors, e.g. ECEF position minus truth [m].
    covariance : numpy.ndarray
        (n, k, k) covariances in the same frame and unit squared [m^2]; an epoch whose
        covariance is not finite or not positive definite gets NaN.

    Returns
    -------
    numpy.ndarray
        (n,) NEES; chi-square with k degrees of freedom for a consistent estimator.
    """
    d = np.asarray(error, float)
    P = np.asarray(covariance, float)
    out = np.full(len(d), np.nan)
    usable = np.isfinite(P).all(axis=(1, 2)) & np.isfinite(d).all(axis=1)
    if usable.any():
        # a singular or indefinite block (no covariance: all zero) is no statement about consistency
        eig = np.linalg.eigvalsh(P[usable])
        ok = np.flatnonzero(usable)[eig.min(axis=1) > 0]
        out[ok] = np.einsum("ni,ni->n", d[ok], np.linalg.solve(P[ok], d[ok][..., None])[..., 0])
    return out


def summary_stats(values: np.ndarray, prefix: str) -> dict[str, float]:
    """Median, mean, variance, standard deviation, p95 and max of an error series [m, m^2].

    NaNs are ignored; an empty series gives NaN statistics.
    """
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {f"{prefix}_{k}": np.nan for k in ("median", "mean", "var", "std", "p95", "max")}
    return {
        f"{prefix}_median": float(np.median(v)),
        f"{prefix}_mean": float(v.mean()),
        f"{prefix}_var": float(v.var()),
        f"{prefix}_std": float(v.std()),
        f"{prefix}_p95": float(np.percentile(v, 95)),
        f"{prefix}_max": float(v.max()),
    }


def ecdf(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Empirical CDF (scipy.stats.ecdf): sorted unique values and their probabilities."""
    v = np.asarray(values, float)
    res = stats.ecdf(v[np.isfinite(v)])
    return res.cdf.quantiles, res.cdf.probabilities


def reference_ecdf(values: np.ndarray, n_reference: int) -> tuple[np.ndarray, np.ndarray]:
    """ECDF over all reference epochs: sorted errors and the fraction of reference epochs at or below each.

    Parameters
    ----------
    values : numpy.ndarray
        Errors of the solved epochs [m]; non-finite values count as unsolved.
    n_reference : int
        Reference epochs (epochs with truth) the errors were taken from, solved or not.

    Returns
    -------
    x, p : numpy.ndarray
        Sorted unique errors [m] and fractions; ``p[-1]`` is the availability
        (solved / reference epochs), below 1 when epochs were missed.
    """
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    _check_reference(v.size, n_reference)
    if v.size == 0:
        return np.empty(0), np.empty(0)
    x, p = ecdf(v)
    return x, p * (v.size / n_reference)


def reference_percentile(values: np.ndarray, n_reference: int, q: float) -> float:
    """The ``q``-th percentile over all reference epochs, an unsolved epoch counting as an infinite error [m].

    The smallest error ``x`` whose ECDF over reference epochs (:func:`reference_ecdf`)
    reaches ``q`` % (NumPy's ``inverted_cdf``): ``inf`` when the availability is
    below ``q`` %, NaN when there are no reference epochs.
    """
    v = np.asarray(values, float)
    v = np.sort(v[np.isfinite(v)])
    _check_reference(v.size, n_reference)
    if n_reference == 0:
        return np.nan
    rank = max(int(np.ceil(q / 100.0 * n_reference - 1e-9)), 1)  # 1-based; tolerance for q * n in floats
    return float(v[rank - 1]) if rank <= v.size else np.inf


def reference_stats(values: np.ndarray, n_reference: int, prefix: str) -> dict[str, float]:
    """Median and p95 over all reference epochs (:func:`reference_percentile`) [m].

    Keys ``{prefix}_median_ref`` and ``{prefix}_p95_ref``.
    """
    return {
        f"{prefix}_median_ref": reference_percentile(values, n_reference, 50.0),
        f"{prefix}_p95_ref": reference_percentile(values, n_reference, 95.0),
    }


def _check_reference(n_solved: int, n_reference: int) -> None:
    if n_reference < n_solved:
        raise SimbenchError(
            "n_reference",
            f"is {n_reference}, fewer than the {n_solved} solved epochs",
            "pass the number of epochs with truth the errors were taken from",
        )


def rmse(values: np.ndarray) -> float:
    """Root mean square of the finite values (the solved epochs' errors) [m]; NaN when there are none.

    Unlike the percentiles over reference epochs it cannot count an unsolved epoch: read it with the
    availability beside it.
    """
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v * v))) if v.size else np.nan


def block_length(values: np.ndarray) -> int:
    """Block length of a moving-block bootstrap of a time series [epochs].

    The integrated autocorrelation time ``1 + 2 sum rho_k`` (summed until ``rho_k`` first drops
    below 0.05), at least ``n^(1/3)`` (Kuensch's rate) and at most ``n / 4``: blocks of
    correlated epochs are resampled together, so slowly varying errors (multipath, a filter's
    memory) do not make the interval too narrow.
    """
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    n = v.size
    if n < 8:
        return 1
    d = v - v.mean()
    spectrum = np.fft.rfft(d, 2 * n)
    acf = np.fft.irfft(spectrum * np.conj(spectrum))[:n]
    rho = acf / acf[0] if acf[0] > 0 else np.zeros(n)
    below = np.flatnonzero(rho < 0.05)
    k = int(below[0]) if below.size else n
    tau = 1.0 + 2.0 * float(rho[1:k].sum())
    return int(np.clip(np.ceil(max(tau, n ** (1 / 3))), 1, max(n // 4, 1)))


def block_bootstrap(
    errors: np.ndarray,
    statistics: dict[str, Callable[[np.ndarray], np.ndarray]],
    resamples: int = 2000,
    confidence: float = 0.95,
    seed: int = 0,
) -> dict[str, tuple[float, float]]:
    """Percentile intervals of statistics of one run's error series by a circular moving-block bootstrap.

    Parameters
    ----------
    errors : numpy.ndarray
        (n,) errors at the reference epochs in time order [m]; ``inf`` for an unsolved epoch.
    statistics : dict
        Name to a function of a (resamples, n) array, each row a resample sorted ascending (sorted
        once for every statistic), giving (resamples,) values: e.g. :func:`reference_percentiles`,
        :func:`row_rmse`.
    resamples : int
    confidence : float
    seed : int
        Of the random generator: the same series gives the same interval.

    Returns
    -------
    dict
        Name to (low, high); NaN for a series shorter than 8 epochs, or bounds that are not finite.
    """
    e = np.asarray(errors, float)
    n = e.size
    if n < 8:
        return {name: (np.nan, np.nan) for name in statistics}
    block = block_length(e)
    rng = np.random.default_rng(seed)
    starts = rng.integers(0, n, size=(resamples, -(-n // block)))
    index = ((starts[:, :, None] + np.arange(block)) % n).reshape(resamples, -1)[:, :n]
    sample = np.sort(e[index], axis=1)  # once: a percentile of a sorted row is an index
    tail = 50.0 * (1.0 - confidence)
    out = {}
    for name, statistic in statistics.items():
        # order statistics, not interpolation: a resample may hold an infinite (undefined) percentile
        values = np.sort(statistic(sample))
        low = values[int(np.floor(tail / 100.0 * (resamples - 1)))]
        high = values[int(np.ceil((100.0 - tail) / 100.0 * (resamples - 1)))]
        out[name] = (float(low), float(high)) if np.isfinite([low, high]).all() else (np.nan, np.nan)
    return out


def reference_percentiles(sample: np.ndarray, q: float) -> np.ndarray:
    """:func:`reference_percentile` of each row of ``sample``, rows sorted ascending (unsolved epochs
    ``inf``, last) [m]."""
    n = sample.shape[1]
    rank = max(int(np.ceil(q / 100.0 * n - 1e-9)), 1)
    return sample[:, rank - 1]


def row_rmse(sample: np.ndarray) -> np.ndarray:
    """:func:`rmse` of each row of ``sample`` over its finite values [m]."""
    finite = np.isfinite(sample)
    squares = np.where(finite, sample, 0.0) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sqrt(squares.sum(axis=1) / finite.sum(axis=1))
