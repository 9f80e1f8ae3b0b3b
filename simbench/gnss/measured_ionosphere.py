"""The slant ionosphere measured by a receiver's second frequency, and carried to its single-frequency rows.

A receiver that tracks a second frequency on some satellites only (a u-blox F9P sees no L2 on
the GPS IIR satellites, which send no L2C; weak second signals drop in a street) cannot form the
ionosphere-free combination everywhere. Its code pair still measures the delay where it has one:

    P2 - P1 = (gamma - 1) I1 + d_sat + d_rx,

with ``I1`` the slant delay on the first carrier, ``gamma = (f1 / f2)**2``, ``d_sat`` the
satellite's broadcast group-delay difference and ``d_rx`` the receiver's, which is the same for
every satellite of a system and so moves every measured delay of that system alike, which that
system's receiver clock absorbs. The geometry (and an NLOS path's extra length) cancels, the code
noise and multipath do not. Where both carriers' phases are tracked, their difference follows the
delay to millimetres up to a constant per unbroken stretch, ``(phi1 - phi2) / (gamma - 1) = I1 +
c``: the stretch is levelled to the median of the code pair over it ("carrier-to-code levelling"),
so that the delay handed to the phase carries no code noise (a carrier phase takes a delay's
changes at its own millimetre weight). Elsewhere a running median along each satellite's code
pairs (of what the broadcast model leaves of them) keeps the slowly changing delay. Rows without
a second frequency get the broadcast (Klobuchar) delay scaled and offset to agree with the
measured rows of their system, ``a K + b`` fitted on those rows, so that a system's rows share
one offset ``b`` (the ``d_rx / (gamma - 1)`` of its measured rows) and the clock still absorbs it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.stats import median_abs_deviation

__all__ = [
    "MeasuredIonosphere",
    "geometry_free_delay",
    "levelled_phase_delay",
    "measurement_sigmas",
    "running_median_per_satellite",
    "measured_ionosphere",
]

#: Centred window of the running median along a satellite's rows [s]: long enough to average code
#: noise and street multipath (correlation times of seconds to tens of seconds), short against the
#: change of a slant delay (centimetres per minute above 15 deg; a median follows a linear trend).
MEDIAN_WINDOW_S = 120.0
#: A phase stretch is levelled only with this many code pairs on it (fewer: the running median).
MIN_LEVEL_ROWS = 20
#: A step of the phase-pair delay beyond this between consecutive rows of a satellite starts a new
#: stretch [m] (a slip of one cycle on either carrier moves it by 0.29 m or more at L1/L2) ...
STEP_BREAK_M = 0.15
#: ... plus this much per second between the rows (the delay drifts by up to a centimetre a second) [m/s].
STEP_BREAK_RATE_MPS = 0.01
#: Time over which street multipath on a code pair stays alike [s] (the simulated canyon's 15 s
#: Gauss-Markov time, doubled: reflections from one facade persist while the car passes it).
MULTIPATH_CORRELATION_S = 30.0
#: Rms error of the broadcast (Klobuchar) delay relative to the delay [-]: the model removes
#: about half of it (IS-GPS-200), so its error is about half of it.
BROADCAST_RELATIVE_ERROR = 0.5
#: A system's broadcast model is fitted to its measured delays only with this many measured rows ...
MIN_FIT_ROWS = 30
#: ... from this many satellites (one satellite's pass cannot separate the scale from the offset).
MIN_FIT_SATELLITES = 2
#: Measured delays further than this many robust sigmas from the fit are left out of the next [-].
FIT_CLIP_SIGMAS = 3.0
#: Floor of that robust sigma [m].
FIT_MIN_SIGMA_M = 0.05
#: Prior sigma of the broadcast model's scale around 1 [-] (Klobuchar removes about half of the
#: delay, rms: true-to-broadcast ratios of 0.5-2 are common, 3 rare).
FIT_SCALE_SIGMA = 0.5


@dataclass(frozen=True)
class MeasuredIonosphere:
    """What :func:`measured_ionosphere` returns.

    Attributes
    ----------
    delay_m : ndarray, shape (N,)
        Slant delay on each row's first carrier [m], to subtract from its code and add to its phase.
    measured : ndarray of bool, shape (N,)
        Rows whose delay comes from their own second frequency.
    fits : dict
        Per system letter, ``(a, b)`` of the broadcast model fitted to the measured rows [-, m];
        a system absent here kept the broadcast delay on every row.
    """

    delay_m: np.ndarray
    measured: np.ndarray
    fits: dict[str, tuple[float, float]]


def geometry_free_delay(
    code_l1: np.ndarray, code_l2: np.ndarray, gamma: np.ndarray, sat_dcb: np.ndarray | float = 0.0
) -> np.ndarray:
    """Slant delay on the first carrier from a code pair, ``(P2 - P1 - d_sat) / (gamma - 1)`` [m].

    Parameters
    ----------
    code_l1, code_l2 : ndarray, shape (N,)
        Code pseudoranges on the first and second carrier [m].
    gamma : ndarray, shape (N,)
        ``(f1 / f2)**2`` [-].
    sat_dcb : ndarray or float
        Broadcast group delay of the second signal minus the first's, times c [m] (0: unknown).

    Returns
    -------
    ndarray, shape (N,)
        Includes the receiver's group-delay difference over ``gamma - 1`` (common to a system).
    """
    return (code_l2 - code_l1 - sat_dcb) / (gamma - 1.0)


def levelled_phase_delay(
    code_delay: np.ndarray, phase_delay: np.ndarray, sat: np.ndarray, t: np.ndarray, lost_lock: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The phase pair's delay levelled to its code pair's over each unbroken stretch [m].

    Parameters
    ----------
    code_delay : ndarray, shape (N,)
        :func:`geometry_free_delay` of the code pair [m]; NaN without one.
    phase_delay : ndarray, shape (N,)
        The phase pair's ``(phi1 - phi2) / (gamma - 1)`` with both phases in metres [m] (the delay
        plus a constant per stretch: a carrier advances where the code is delayed); NaN without both.
    sat : ndarray of str, shape (N,)
    t : ndarray, shape (N,)
        Row times [s].
    lost_lock : ndarray of bool, shape (N,)
        Loss of lock on either carrier at the row (starts a stretch).

    Returns
    -------
    delay : ndarray, shape (N,)
        NaN on rows without a phase pair and on stretches with fewer than :data:`MIN_LEVEL_ROWS`
        code pairs. A stretch ends at a satellite's gap, a loss of lock or a step beyond
        :data:`STEP_BREAK_M` plus :data:`STEP_BREAK_RATE_MPS` per second.
    stretch : ndarray of int, shape (N,)
        Stretch id of each row with a levelled delay, -1 elsewhere: a carrier phase corrected by
        the delay is continuous within a stretch only (each has its own level).
    """
    both = np.isfinite(phase_delay)
    rows = np.flatnonzero(both)
    rows = rows[np.lexsort((t[rows], sat[rows]))]
    out = np.full(len(phase_delay), np.nan)
    ids = np.full(len(phase_delay), -1, np.int64)
    if rows.size == 0:
        return out, ids
    ps, ts = phase_delay[rows], t[rows]
    new = np.r_[True, sat[rows][1:] != sat[rows][:-1]]
    step = np.abs(np.diff(ps, prepend=np.nan))
    dt = np.diff(ts, prepend=np.nan)
    new |= lost_lock[rows] | ~(step <= STEP_BREAK_M + STEP_BREAK_RATE_MPS * dt)
    stretch = np.cumsum(new) - 1
    offset = pd.Series(code_delay[rows] - ps).groupby(stretch)
    level = offset.transform("median").to_numpy(float)
    count = offset.transform("count").to_numpy(float)
    enough = count >= MIN_LEVEL_ROWS
    out[rows] = np.where(enough, ps + level, np.nan)
    ids[rows] = np.where(enough, stretch, -1)
    return out, ids


def running_median_per_satellite(
    values: np.ndarray, sat: np.ndarray, t: np.ndarray, window_s: float = MEDIAN_WINDOW_S
) -> np.ndarray:
    """Centred running median of ``values`` along each satellite's rows, over ``window_s`` of time.

    Parameters
    ----------
    values : ndarray, shape (N,)
        NaN values are skipped (a row whose window holds none stays NaN).
    sat : ndarray of str, shape (N,)
        Satellite of each row.
    t : ndarray, shape (N,)
        Time of each row [s].
    window_s : float
        Window length [s], centred on each row.

    Returns
    -------
    ndarray, shape (N,)
        In the order of the input rows.
    """
    order = np.lexsort((t, sat))
    frame = pd.DataFrame({"sat": sat[order], "v": values[order]}, index=pd.to_timedelta(t[order], unit="s"), copy=False)
    smooth = frame.groupby("sat", sort=False)["v"].rolling(f"{window_s}s", center=True, min_periods=1).median()
    out = np.empty(len(values))
    # groupby-rolling returns the groups in order of appearance, which the sort made the row order
    out[order] = smooth.to_numpy(float)
    return out


def measured_ionosphere(
    broadcast_m: np.ndarray,
    measured_m: np.ndarray,
    sat: np.ndarray,
    t: np.ndarray,
    window_s: float = MEDIAN_WINDOW_S,
    levelled_m: np.ndarray | None = None,
    stretch: np.ndarray | None = None,
    exclude: tuple[str, ...] = (),
) -> MeasuredIonosphere:
    """Each row's slant delay: measured where its second frequency gives one, else the fitted broadcast model.

    Parameters
    ----------
    broadcast_m : ndarray, shape (N,)
        Broadcast (Klobuchar) delay on each row's first carrier [m].
    measured_m : ndarray, shape (N,)
        :func:`geometry_free_delay` of each row [m]; NaN where the row has no second frequency.
    sat : ndarray of str, shape (N,)
        Satellite ids ('G05', 'C11', ...); the first letter is the system.
    t : ndarray, shape (N,)
        Row times [s].
    window_s : float
        Running-median window [s] (:data:`MEDIAN_WINDOW_S`).
    levelled_m : ndarray, shape (N,), optional
        :func:`levelled_phase_delay` of each row [m]; taken where finite, the running median elsewhere.
    stretch : ndarray of int, shape (N,), optional
        Its stretch ids (-1: none); a levelled delay is as good as its stretch is long.
    exclude : tuple of str
        System letters that keep the broadcast delay on every row whatever their pairs measure (their
        pairs' biases are expected to cost more than the broadcast model's error).

    Returns
    -------
    MeasuredIonosphere
        A system keeps the broadcast delay on all its rows (a mix of measured and broadcast delays
        without a fit would differ by the receiver's group delay within one clock) when it has fewer
        than :data:`MIN_FIT_ROWS` measured rows or :data:`MIN_FIT_SATELLITES` measured satellites,
        or when its measured delays are less certain than the broadcast model
        (:func:`measurement_sigmas`; a street's multipath on a weak second signal: code pairs
        scattered by 8 m in the simulated ``urban_deep`` with a consumer receiver, by 0.3 m on the
        Nagoya log).
    """
    sat = np.asarray(sat).astype(str)
    # the median runs on what the broadcast model leaves, which the elevation changes less: a window
    # cut by the end of a pass is then less one-sided
    broadcast_m = np.asarray(broadcast_m, float)
    smooth = broadcast_m + running_median_per_satellite(
        np.asarray(measured_m, float) - broadcast_m, sat, np.asarray(t, float), window_s
    )
    if levelled_m is not None:
        smooth = np.where(np.isfinite(levelled_m), levelled_m, smooth)
    measured = np.isfinite(smooth)
    delay = broadcast_m.copy()
    system = np.array([s[:1] for s in sat.tolist()])
    sigma = measurement_sigmas(np.asarray(measured_m, float) - smooth, system, np.asarray(t, float), stretch, window_s)
    fits: dict[str, tuple[float, float]] = {}
    for letter in np.unique(system).tolist():
        rows = system == letter
        have = rows & measured
        if letter in exclude or have.sum() < MIN_FIT_ROWS or np.unique(sat[have]).size < MIN_FIT_SATELLITES:
            continue
        # written so that an unknown (NaN) scatter fails too
        if not np.median(sigma[have]) <= np.median(BROADCAST_RELATIVE_ERROR * np.abs(broadcast_m[rows])):
            continue
        a, b = _robust_line(delay[have], smooth[have])
        fits[letter] = (a, b)
        delay[rows] = a * delay[rows] + b
        delay[have] = smooth[have]
    keep = np.isin(system, list(fits))
    return MeasuredIonosphere(delay_m=delay, measured=measured & keep, fits=fits)


def measurement_sigmas(
    scatter: np.ndarray, system: np.ndarray, t: np.ndarray, stretch: np.ndarray | None, window_s: float
) -> np.ndarray:
    """Standard deviation of each row's measured delay [m].

    The code pairs of a system scatter about the measured delays by ``s`` (robust, over the
    system's rows); a delay averaged over ``T`` seconds of them (a levelled stretch's length, or
    the running median's window) keeps ``s sqrt(tau / T)``, with ``tau`` =
    :data:`MULTIPATH_CORRELATION_S` the time over which street multipath stays alike.

    Parameters
    ----------
    scatter : ndarray, shape (N,)
        Code-pair delay minus the measured delay [m]; NaN where either is missing.
    system : ndarray of str, shape (N,)
    t : ndarray, shape (N,)
        Row times [s].
    stretch : ndarray of int, shape (N,) or None
        Levelled stretch ids (-1: the running median's rows).
    window_s : float
        The running median's window [s].

    Returns
    -------
    ndarray, shape (N,)
        NaN for a system without scatter.
    """
    spread = np.full(len(scatter), np.nan)
    for letter in np.unique(system).tolist():
        rows = system == letter
        r = scatter[rows][np.isfinite(scatter[rows])]
        if r.size:
            spread[rows] = float(median_abs_deviation(r, scale="normal"))
    span = np.full(len(scatter), window_s)
    if stretch is not None and (stretch >= 0).any():
        ids = stretch >= 0
        times = pd.Series(t[ids]).groupby(stretch[ids])
        span[ids] = (times.transform("max") - times.transform("min")).to_numpy(float)
    return spread * np.sqrt(MULTIPATH_CORRELATION_S / np.maximum(span, MULTIPATH_CORRELATION_S))


def _robust_line(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """``y ~ a x + b`` by least squares with the prior ``a = 1 +- FIT_SCALE_SIGMA``, refitted without
    the points beyond :data:`FIT_CLIP_SIGMAS` robust sigmas of the first fit.

    The prior keeps the scale sane when the broadcast delays of the measured rows hardly vary (a
    short or static log, where the scale and the offset are nearly the same unknown).
    """
    design = np.column_stack([x, np.ones_like(x)])
    keep = np.ones(len(x), bool)
    coef = np.array([1.0, float(np.median(y - x))])
    for _ in range(2):
        resid = y - design @ coef
        scale = max(float(median_abs_deviation(resid[keep], scale="normal")), FIT_MIN_SIGMA_M)
        keep = np.abs(resid) <= FIT_CLIP_SIGMAS * scale
        # the prior as one more row, weighted like a measurement of a with sigma FIT_SCALE_SIGMA
        w = scale / FIT_SCALE_SIGMA
        a_rows = np.vstack([design[keep], [w, 0.0]])
        coef = np.linalg.lstsq(a_rows, np.r_[y[keep], w], rcond=None)[0]
    return float(coef[0]), float(coef[1])
