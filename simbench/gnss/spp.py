"""Weighted single-point solutions of many epochs at once.

One Gauss-Newton iteration updates every epoch in parallel: the rows
(satellite-epochs) contribute to per-epoch normal equations that are summed
with :func:`numpy.add.reduceat` and solved as a stack. The unknowns of an
epoch are the receiver position and one clock offset per GNSS system present
(the first system's clock is the receiver clock, the others absorb the
inter-system biases; up to five systems, e.g. GPS, GLONASS, Galileo, BeiDou and
QZSS). Optionally the code residuals are Huber-weighted by iterative
reweighting (a robust per-epoch fix). The hydrostatic troposphere (Saastamoinen + Niell) joins
as soon as an epoch's iterate lies near the Earth's surface; the wet delay is
left in the clock.

This is the project's only single-point solver: the log readers use it for
elevation and azimuth, the estimators for initial values.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simbench.core.frames import geodetic_from_ecef
from simbench.errors import SimbenchError
from simbench.gnss.geometry import sagnac_range_gradient
from simbench.gnss.normal_equations import pinv_solve, pinv_stack
from simbench.gnss.troposphere import troposphere_terms

__all__ = ["SppSolution", "position_gains", "solve_epochs", "system_clock_offsets", "ROUGH_FIX_MAX_RMS_M"]

#: Trust limit of the post-fit RMS for rough positions from raw logs (elevation, azimuth) [m]:
#: generous, since street-canyon NLOS leaves tens of metres, but a wrong ephemeris leaves kilometres.
ROUGH_FIX_MAX_RMS_M = 300.0

#: Heights outside this range are not a receiver near the Earth [m].
_MIN_HEIGHT_M, _MAX_HEIGHT_M = -1_000.0, 50_000.0
#: A position step above this in the last iteration means the epoch has not converged [m].
_CONVERGED_STEP_M = 1.0


@dataclass(frozen=True)
class SppSolution:
    """Single-point solutions, one per epoch index 0..n_epochs-1.

    Attributes
    ----------
    pos : np.ndarray, shape (n_epochs, 3)
        Receiver ECEF position [m]. With ``fill_untrusted`` the nearest trusted
        epoch's position where the epoch's own fit is not trusted; else NaN there.
    clock_m : np.ndarray, shape (n_epochs, n_systems)
        Receiver clock offset times c per system [m] (column 0: the reference
        system, ``system_index`` 0). Wet troposphere and, for the further
        systems, the inter-system bias are in it. 0 for a system absent from
        the epoch; refitted to ``pos`` where that was filled.
    trusted : np.ndarray of bool, shape (n_epochs,)
        The epoch's own fit passed the trust check: enough rows for the
        unknowns, converged, finite, a height within -1 km..50 km, and a
        post-fit RMS below ``max_rms_m``.
    rms_m : np.ndarray, shape (n_epochs,)
        Post-fit RMS of the unweighted residuals of the epoch's own fit [m]
        (NaN where there was nothing to fit).
    n_rows : np.ndarray of int, shape (n_epochs,)
        Rows (satellites) used by each epoch.
    residual_m : np.ndarray, shape (N,)
        Per input row: code minus the prediction of its epoch's own fit [m]; NaN for rows
        that were ignored or whose epoch is not trusted.
    redundancy : np.ndarray, shape (N,)
        Per input row: its redundancy number ``1 - h_ii`` (``h_ii`` the diagonal of the
        weighted hat matrix of its epoch), so ``residual / (sigma sqrt(redundancy))`` has
        unit variance when ``sigma`` is right; NaN where ``residual_m`` is.
    weight : np.ndarray, shape (N,)
        Per input row: the final Huber weight factor (1 without ``huber_k``, and for inliers).
    """

    pos: np.ndarray
    clock_m: np.ndarray
    trusted: np.ndarray
    rms_m: np.ndarray
    n_rows: np.ndarray
    residual_m: np.ndarray
    redundancy: np.ndarray
    weight: np.ndarray


def solve_epochs(
    epoch: np.ndarray,
    sat_pos: np.ndarray,
    code: np.ndarray,
    *,
    n_epochs: int | None = None,
    sigma: np.ndarray | None = None,
    system_index: np.ndarray | None = None,
    el: np.ndarray | None = None,
    doy: float | None = None,
    x0: np.ndarray | None = None,
    iterations: int = 12,
    tol_m: float = 1e-4,
    max_rms_m: float = np.inf,
    fill_untrusted: bool = False,
    huber_k: float | None = None,
    reweightings: int = 5,
) -> SppSolution:
    """Code-only iterative weighted least squares position and clocks of every epoch.

    Parameters
    ----------
    epoch : np.ndarray of int, shape (N,)
        Epoch index 0..n_epochs-1 of each row (any order).
    sat_pos : np.ndarray, shape (N, 3)
        Satellite ECEF positions at transmit time [m].
    code : np.ndarray, shape (N,)
        Corrected pseudoranges [m]: satellite clock applied, ionosphere removed
        or combined away. Rows with a non-finite code or position are ignored.
    n_epochs : int, optional
        Number of epochs (default ``epoch.max() + 1``).
    sigma : np.ndarray, shape (N,), optional
        Code standard deviations [m] (weights 1/sigma^2); unit weights when omitted.
    system_index : np.ndarray of int, shape (N,), optional
        GNSS system of each row, 0..n_systems-1; each system gets its own clock.
    el : np.ndarray, shape (N,), optional
        Elevations [rad]; with ``doy`` the hydrostatic troposphere is modelled.
    doy : float, optional
        Day of year (Niell mapping).
    x0 : np.ndarray, shape (3,) or (n_epochs, 3), optional
        Start of the iteration [m] (default the Earth's centre).
    iterations : int
        Gauss-Newton iterations at most.
    tol_m : float
        Stop once every epoch's position step is below this [m].
    max_rms_m : float
        Trust check: epochs whose post-fit RMS exceeds this are not trusted [m].
    fill_untrusted : bool
        Give every untrusted epoch the position of the nearest trusted epoch
        (the later one on a tie) and clocks refitted there, so callers get a
        usable rough position everywhere.
    huber_k : float, optional
        Huber threshold [standard deviations]: after the plain fit, ``reweightings``
        passes weight each row by ``min(1, huber_k / |residual / sigma|)``
        (iteratively reweighted least squares). None: plain weighted least squares.
    reweightings : int
        Reweighting passes with ``huber_k``.

    Returns
    -------
    SppSolution

    Raises
    ------
    SimbenchError
        On arrays of mismatched shapes, or (with ``fill_untrusted``) when no
        epoch gives a trusted solution.
    """
    epoch = np.asarray(epoch, dtype=np.int64).reshape(-1)
    sat_pos = np.asarray(sat_pos, dtype=float).reshape(-1, 3)
    code = np.asarray(code, dtype=float).reshape(-1)
    n = len(code)
    if len(epoch) != n or len(sat_pos) != n:
        raise SimbenchError(
            "observations",
            f"{len(epoch)} epoch indices, {len(sat_pos)} satellite positions and {n} codes",
            "pass one epoch index and one satellite position per code",
        )
    nk = int(n_epochs if n_epochs is not None else (epoch.max() + 1 if n else 0))
    sys_idx = np.zeros(n, np.int64) if system_index is None else np.asarray(system_index, np.int64).reshape(-1)
    w = np.ones(n) if sigma is None else 1.0 / np.asarray(sigma, dtype=float).reshape(-1) ** 2
    el_rows = np.asarray(el, dtype=float).reshape(-1) if el is not None and doy is not None else None
    ok = np.isfinite(code) & np.isfinite(sat_pos).all(axis=1) & np.isfinite(w) & (epoch >= 0) & (epoch < nk)
    rows = np.flatnonzero(ok)
    rows = rows[np.argsort(epoch[rows], kind="stable")]
    fit = _Fit.of(rows, epoch, sat_pos, code, w, sys_idx, el_rows, doy, int(sys_idx.max(initial=0)) + 1)
    n_rows = np.zeros(nk, np.int64)
    n_rows[fit.present] = fit.counts
    # systems present per epoch decide how many unknowns the epoch has
    has_sys = np.zeros((nk, fit.n_systems), bool)
    has_sys[fit.e, fit.sy] = True
    solvable = n_rows >= 3 + has_sys.sum(axis=1)

    pos = np.zeros((nk, 3))
    if x0 is not None:
        pos[:] = np.broadcast_to(np.asarray(x0, dtype=float), (nk, 3))
    clock = np.zeros((nk, fit.n_systems))
    passes = 1 + (max(int(reweightings), 0) if huber_k is not None else 0)
    robust, step = fit.iterate(pos, clock, solvable, passes, iterations, tol_m, huber_k)
    res = fit.c - fit.predicted(pos, clock)
    rms = np.full(nk, np.nan)
    rms[fit.present] = np.sqrt(np.add.reduceat(res * res, fit.starts) / n_rows[fit.present])
    height = _lat_height(pos)[1]
    trusted = (
        solvable
        & (step < _CONVERGED_STEP_M)
        & np.isfinite(pos).all(axis=1)
        & (height > _MIN_HEIGHT_M)
        & (height < _MAX_HEIGHT_M)
        & (rms < max_rms_m)
    )
    per_row = fit.per_row(n, rows, trusted, res, robust)
    if not fill_untrusted:
        pos[~trusted] = np.nan
        clock[~trusted] = np.nan
    else:
        _fill_untrusted(pos, clock, trusted, fit)
    return SppSolution(pos=pos, clock_m=clock, trusted=trusted, rms_m=rms, n_rows=n_rows, **per_row)


@dataclass(frozen=True)
class _Fit:
    """The rows of :func:`solve_epochs`, sorted by epoch, and how they are predicted and solved."""

    e: np.ndarray  #: epoch of each row
    s: np.ndarray  #: satellite position [m]
    c: np.ndarray  #: corrected code [m]
    w: np.ndarray  #: weight 1/sigma^2
    sy: np.ndarray  #: system index
    el: np.ndarray | None  #: elevation [rad] (with ``doy``: hydrostatic troposphere)
    doy: float | None
    A: np.ndarray  #: design matrix (position columns filled per iteration, clock columns fixed)
    starts: np.ndarray  #: first row of each present epoch
    present: np.ndarray  #: epochs with rows

    @classmethod
    def of(
        cls,
        rows: np.ndarray,
        epoch: np.ndarray,
        sat_pos: np.ndarray,
        code: np.ndarray,
        w: np.ndarray,
        sys_idx: np.ndarray,
        el: np.ndarray | None,
        doy: float | None,
        n_systems: int,
    ) -> _Fit:
        """The fit of input ``rows`` (sorted by epoch) of the per-row arrays; ``n_systems`` clock columns."""
        e, sy = epoch[rows], sys_idx[rows]
        present, starts = np.unique(e, return_index=True)
        design = np.zeros((len(rows), 3 + n_systems))
        design[np.arange(len(rows)), 3 + sy] = 1.0
        el_r = None if el is None else el[rows]
        return cls(e, sat_pos[rows], code[rows], w[rows], sy, el_r, doy, design, starts, present)

    @property
    def counts(self) -> np.ndarray:
        """Rows of each present epoch."""
        return np.diff(np.append(self.starts, len(self.e)))

    @property
    def n_systems(self) -> int:
        """Clock columns of the design matrix."""
        return int(self.A.shape[1]) - 3

    def per_row(
        self, n: int, rows: np.ndarray, trusted: np.ndarray, res: np.ndarray, robust: np.ndarray
    ) -> dict[str, np.ndarray]:
        """:class:`SppSolution`'s per-input-row fields (``n`` input rows, ``rows`` the fitted ones): residual
        [m] and redundancy number ``1 - w_i a_i^T N^-1 a_i`` of the final weighted fit where the row's
        epoch is trusted, and the final Huber weight factor."""
        n_inv = pinv_stack(_normal_matrices(self.A, self.w * robust, self.starts))
        index = np.repeat(np.arange(len(self.present)), self.counts)
        leverage = self.w * robust * np.einsum("ri,rij,rj->r", self.A, n_inv[index], self.A)
        own = trusted[self.e]
        residual = np.full(n, np.nan)
        redundancy = np.full(n, np.nan)
        weight = np.ones(n)
        residual[rows[own]] = res[own]
        redundancy[rows[own]] = 1.0 - leverage[own]
        weight[rows] = robust
        return {"residual_m": residual, "redundancy": redundancy, "weight": weight}

    def predicted(self, pos: np.ndarray, clock: np.ndarray) -> np.ndarray:
        """Predicted code of every row at ``pos``/``clock`` (fills the design matrix's position columns)."""
        return _predicted(self.s, pos, clock, self.e, self.sy, self.el, self.doy, self.A)

    def iterate(
        self,
        pos: np.ndarray,
        clock: np.ndarray,
        solvable: np.ndarray,
        passes: int,
        iterations: int,
        tol_m: float,
        huber_k: float | None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Gauss-Newton on every epoch at once (``pos``, ``clock`` updated in place), ``passes`` times with
        Huber reweighting between passes; returns the rows' final robust weights and each epoch's last step."""
        present = self.present
        step = np.full(len(pos), np.inf)
        robust = np.ones(len(self.c))
        for done in range(passes):
            for _ in range(iterations):
                res = self.c - self.predicted(pos, clock)
                N = _normal_matrices(self.A, self.w * robust, self.starts)
                b = np.add.reduceat(self.A * (self.w * robust * res)[:, None], self.starts, axis=0)
                # an absent system's clock column is zero and stays 0; a degenerate geometry must not
                # stop the other epochs
                dx = pinv_solve(N, b)
                dx[~solvable[present]] = 0.0
                pos[present] += dx[:, :3]
                clock[present] += dx[:, 3:]
                step[present] = np.linalg.norm(dx[:, :3], axis=1)
                if not np.any(step[present] >= tol_m):
                    break
            if huber_k is not None and done < passes - 1:
                z = np.abs(self.c - self.predicted(pos, clock)) * np.sqrt(self.w)
                robust = np.minimum(1.0, huber_k / np.maximum(z, 1e-12))
        return robust, step


def _fill_untrusted(pos: np.ndarray, clock: np.ndarray, trusted: np.ndarray, fit: _Fit) -> None:
    """Give every untrusted epoch the position of the nearest trusted one (the later one on a tie) and the
    clocks that fit it there (mean residual per epoch and system), in place."""
    good = np.flatnonzero(trusted)
    if good.size == 0:
        raise SimbenchError(
            "observations",
            "no epoch gives a trusted single-point solution",
            "check that the navigation data belong to the observations and the code is in metres",
        )
    bad = ~trusted
    if not bad.any():
        return
    nk, n_sys = clock.shape
    k = np.arange(nk)
    after = good[np.clip(np.searchsorted(good, k), 0, good.size - 1)]
    before = good[np.clip(np.searchsorted(good, k) - 1, 0, good.size - 1)]
    nearest = np.where(np.abs(before - k) < np.abs(after - k), before, after)
    pos[bad] = pos[nearest[bad]]
    e = fit.e
    hydro = _hydrostatic(pos, e, fit.el, fit.doy) if fit.el is not None and fit.doy is not None else np.zeros(len(e))
    res = fit.c - sagnac_range_gradient(fit.s, pos[e])[0] - hydro
    flat = e * n_sys + fit.sy
    total = np.bincount(flat, res, nk * n_sys).reshape(nk, n_sys)
    count = np.bincount(flat, minlength=nk * n_sys).reshape(nk, n_sys)
    refit = np.divide(total, count, out=np.zeros_like(total), where=count > 0)
    clock[bad] = refit[bad]


def position_gains(
    epoch: np.ndarray,
    sat_pos: np.ndarray,
    rx_pos: np.ndarray,
    sigma: np.ndarray,
    system_index: np.ndarray,
) -> np.ndarray:
    """How a range error of each row moves its epoch's weighted single-point position [m/m].

    Row ``r`` of epoch ``k`` gets ``g_r``, the position columns of ``N_k^+ a_r / sigma_r^2`` with
    ``a_r`` the row's partials (line of sight with the Sagnac term, a one in its system's clock
    column) and ``N_k`` the epoch's normal matrix, so range errors ``d`` move the epoch's fix by
    ``sum_r g_r d_r``; an error common to the rows of one system moves it by nothing (that
    system's clock takes it).

    Parameters
    ----------
    epoch : np.ndarray of int, shape (N,)
        Epoch index of each row.
    sat_pos, rx_pos : np.ndarray, shape (N, 3)
        Satellite position and the receiver position (linearisation point) of each row [m].
    sigma : np.ndarray, shape (N,)
        Code standard deviations [m].
    system_index : np.ndarray of int, shape (N,)
        System of each row, 0..n_systems-1 (one clock each).

    Returns
    -------
    np.ndarray, shape (N, 3)
        ECEF gains; NaN rows where an input is not finite.
    """
    epoch = np.asarray(epoch, np.int64)
    sys_idx = np.asarray(system_index, np.int64)
    w = 1.0 / np.asarray(sigma, float) ** 2
    ok = np.isfinite(sat_pos).all(axis=1) & np.isfinite(rx_pos).all(axis=1) & np.isfinite(w)
    rows = np.flatnonzero(ok)
    rows = rows[np.argsort(epoch[rows], kind="stable")]
    out = np.full((len(epoch), 3), np.nan)
    if not rows.size:
        return out
    _, starts, counts = np.unique(epoch[rows], return_index=True, return_counts=True)
    A = np.zeros((rows.size, 3 + int(sys_idx.max(initial=0)) + 1))
    A[:, :3] = sagnac_range_gradient(sat_pos[rows], rx_pos[rows])[1]
    A[np.arange(rows.size), 3 + sys_idx[rows]] = 1.0
    n_inv = pinv_stack(_normal_matrices(A, w[rows], starts))
    out[rows] = np.einsum("rij,rj->ri", n_inv[np.repeat(np.arange(starts.size), counts)][:, :3, :], A) * w[rows, None]
    return out


def system_clock_offsets(sol: SppSolution, epoch: np.ndarray, system_index: np.ndarray) -> np.ndarray:
    """Inter-system bias start values: each further system's clock minus the first system's [m].

    The median over the epochs whose rows include that system (an epoch without it
    has no clock for it); 0 for a system no epoch sees.

    Parameters
    ----------
    sol : SppSolution
        Solutions of the epochs ``epoch`` indexes.
    epoch, system_index : np.ndarray of int, shape (N,)
        Epoch and system of each row the solutions were computed from.

    Returns
    -------
    np.ndarray, shape (n_systems - 1,)
    """
    epoch = np.asarray(epoch, np.int64)
    system_index = np.asarray(system_index, np.int64)
    out = np.zeros(sol.clock_m.shape[1] - 1)
    for s in range(1, sol.clock_m.shape[1]):
        seen = np.unique(epoch[system_index == s])
        if seen.size:
            out[s - 1] = float(np.median(sol.clock_m[seen, s] - sol.clock_m[seen, 0]))
    return out


def _predicted(
    sat_pos: np.ndarray,
    pos: np.ndarray,
    clock: np.ndarray,
    e: np.ndarray,
    sy: np.ndarray,
    el: np.ndarray | None,
    doy: float | None,
    A: np.ndarray,
) -> np.ndarray:
    """Predicted code per row at the epochs' iterates [m]; writes the position partials into ``A``."""
    rho, A[:, :3] = sagnac_range_gradient(sat_pos, pos[e])
    hydro = _hydrostatic(pos, e, el, doy) if el is not None and doy is not None else 0.0
    return rho + clock[e, sy] + hydro


def _normal_matrices(A: np.ndarray, w: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Per-epoch normal matrices ``sum_i w_i a_i a_i^T`` of rows sorted by epoch, shape (epochs, p, p)."""
    return np.add.reduceat((A[:, :, None] * A[:, None, :]) * w[:, None, None], starts, axis=0)


def _hydrostatic(pos: np.ndarray, e: np.ndarray, el: np.ndarray, doy: float) -> np.ndarray:
    """Slant hydrostatic delay per row at each epoch's iterate; 0 while the iterate is far from the surface."""
    lat, h = _lat_height(pos)
    near = (h > _MIN_HEIGHT_M) & (h < _MAX_HEIGHT_M)
    out = np.zeros(len(e))
    rows = near[e]
    if rows.any():
        out[rows] = troposphere_terms(el[rows], lat[e][rows], h[e][rows], doy)[0]
    return out


def _lat_height(pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Geodetic latitude [rad] and height [m]; NaN height for positions near the Earth's centre (the start)."""
    lat = np.full(len(pos), np.nan)
    h = np.full(len(pos), np.nan)
    away = np.isfinite(pos).all(axis=1) & (np.einsum("ij,ij->i", pos, pos) > 1.0e6**2)
    if away.any():
        lat[away], _, h[away] = geodetic_from_ecef(pos[away])
    return lat, h
