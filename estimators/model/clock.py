"""The receiver clock as an oscillator: where its offset may be predicted from the last epoch.

A receiver's clock offset moves by its drift times the interval, plus the oscillator's white
frequency noise; a free (white) clock per epoch throws that away, and with it the one state that
tells a common delay of the epoch's signals (a street's late, reflected rows) from the height. Some
receivers hold their clock, or their time tags, within a millisecond by steps (u-blox: 300-3000 km
at once): there the offset starts afresh. A step is found on the single point clocks, which every
epoch has; the noise of a code-only fix in a street (the Hong Kong log: the step minus the
Doppler's prediction p50 4 m, p99 130 m) is three orders below a millisecond's jump.
"""

from __future__ import annotations

import numpy as np

__all__ = ["clock_links", "offset_step_sigma", "single_point_drift"]


def single_point_drift(t_s: np.ndarray, clock_m: np.ndarray, jump_m: float) -> float:
    """The receiver clock drift times c [m/s] from consecutive single point clocks: the median rate of
    the steps that are not jumps (0 where there are fewer than two epochs).

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Epoch times [s], increasing.
    clock_m : ndarray, shape (n,)
        Single point receiver clock times c [m].
    jump_m : float
        Steps larger than this are jumps [m].
    """
    if len(t_s) < 2:
        return 0.0
    rate = np.diff(clock_m) / np.maximum(np.diff(t_s), 1e-6)
    steady = np.abs(np.diff(clock_m)) < jump_m
    return float(np.median(rate[steady])) if steady.any() else 0.0


def clock_links(t_s: np.ndarray, clock_m: np.ndarray, drift_mps: np.ndarray, jump_m: float) -> np.ndarray:
    """Whether epoch ``k``'s clock offset is predicted from epoch ``k - 1``'s (False at 0 and at jumps).

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Epoch times [s].
    clock_m : ndarray, shape (n,)
        Single point receiver clock times c [m].
    drift_mps : ndarray, shape (n,)
        Clock drift times c at each epoch [m/s] (a Doppler fix, or a constant).
    jump_m : float
        A step further than this from ``drift x dt`` is a jump [m].

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    links = np.zeros(len(t_s), bool)
    if len(t_s) > 1:
        predicted = drift_mps[:-1] * np.diff(t_s)
        links[1:] = np.abs(np.diff(clock_m) - predicted) <= jump_m
    return links


def offset_step_sigma(dt_s: float, offset_density_m_rts: float, drift_density_mps_rts: float) -> float:
    """Sigma of the clock offset's step about ``drift x dt`` over ``dt_s`` seconds [m]: the white
    frequency noise's ``q_b dt`` plus the drift random walk's ``q_d dt^3 / 3`` (the exact discretisation's
    cross-covariance with the drift step is dropped, as for position and velocity)."""
    dt = max(dt_s, 0.0)
    return float(np.sqrt(offset_density_m_rts**2 * dt + drift_density_mps_rts**2 * dt**3 / 3.0))
