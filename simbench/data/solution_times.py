"""Pairing the time tags of a solution file (RTKLIB, another program) with a receiver's epochs."""

from __future__ import annotations

import numpy as np

from simbench.contract import ReceiverData
from simbench.core.constants import SECONDS_PER_WEEK

__all__ = ["match_to_epochs", "match_receiver_epochs", "receiver_epoch_times", "best_time_offset", "OFFSETS_S"]

#: Whole-second shifts of a solution's times tried against the reference [s]: the GPS-UTC leap
#: seconds of any year since 1980 (up to 18 s) and a little beyond, both ways.
OFFSETS_S = np.arange(-30.0, 31.0)
#: Fewest paired epochs with truth that give a median error worth comparing.
MIN_PAIRS = 10


def match_to_epochs(t_solution: np.ndarray, t_epoch: np.ndarray, max_offset_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Pair solutions with the epochs nearest in time, at most one solution per epoch.

    Parameters
    ----------
    t_solution : np.ndarray, shape (m,)
        Solution times [s] (any origin shared with ``t_epoch``).
    t_epoch : np.ndarray, shape (n,)
        Time of epoch index 0..n-1 [s]; NaN for epochs without observations.
    max_offset_s : float
        Solutions further than this from every epoch are left unpaired [s].

    Returns
    -------
    solution_index, epoch_index : np.ndarray of int, shape (k,)
        Matched pairs, increasing in epoch; where several solutions are nearest
        to one epoch, the closest is kept.
    """
    valid = np.flatnonzero(np.isfinite(t_epoch))
    if valid.size == 0 or t_solution.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    order = valid[np.argsort(t_epoch[valid], kind="stable")]
    ts = t_epoch[order]
    right = np.clip(np.searchsorted(ts, t_solution), 1, ts.size - 1) if ts.size > 1 else np.zeros(t_solution.size, int)
    left = np.maximum(right - 1, 0)
    pick = np.where(np.abs(t_solution - ts[left]) <= np.abs(ts[right] - t_solution), left, right)
    offset = np.abs(t_solution - ts[pick])
    sol = np.flatnonzero(offset <= max_offset_s)
    epoch = order[pick[sol]]
    # closest first, then the first occurrence of each epoch
    by_offset = np.lexsort((offset[sol], epoch))
    sol, epoch = sol[by_offset], epoch[by_offset]
    first = np.ones(epoch.size, dtype=bool)
    first[1:] = np.diff(epoch) != 0
    return sol[first].astype(np.int64), epoch[first].astype(np.int64)


def match_receiver_epochs(data: ReceiverData, t_gps: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Pair solutions tagged in continuous GPS time with the receiver's epochs, within half an epoch interval.

    Parameters
    ----------
    data : ReceiverData
        The receiver view whose epochs are matched.
    t_gps : np.ndarray, shape (m,)
        Solution times, GPS seconds since 1980-01-06 [s].

    Returns
    -------
    solution_index, epoch_index : np.ndarray of int, shape (k,)
        Matched pairs (see :func:`match_to_epochs`).
    max_offset_s : float
        Half the median epoch interval, the largest offset accepted [s].
    """
    t_epoch = receiver_epoch_times(data)
    steps = np.diff(np.sort(t_epoch[np.isfinite(t_epoch)]))
    max_offset = 0.5 * (float(np.median(steps)) if steps.size else 1.0)
    si, ei = match_to_epochs(np.asarray(t_gps, float), t_epoch, max_offset)
    return si, ei, max_offset


def receiver_epoch_times(data: ReceiverData) -> np.ndarray:
    """GPS time of the receiver's epoch index 0..n-1, seconds since 1980-01-06 [s] (NaN without observations)."""
    return data.nav.gps_week * SECONDS_PER_WEEK + data.nav.start_sow_s + data.epoch_times


def best_time_offset(
    t_solution: np.ndarray,
    xyz_solution: np.ndarray,
    t_epoch: np.ndarray,
    truth_xyz: np.ndarray,
    max_offset_s: float,
    offsets_s: np.ndarray = OFFSETS_S,
) -> tuple[float, np.ndarray]:
    """The shift of a solution's times that fits the reference best: a wrong time system shows as a shift.

    A moving receiver's solution tagged in UTC under a GPST header lies 18 s of travel from the truth
    of its epoch; shifted by the right amount it lies on the truth. The mean error, not the median,
    is compared: a vehicle standing still half the time gives every shift the same median. A static
    receiver's solution fits every shift alike (the smallest shift wins the tie).

    Parameters
    ----------
    t_solution : np.ndarray, shape (m,)
        Solution times [s], the origin of ``t_epoch``.
    xyz_solution : np.ndarray, shape (m, 3)
        Solution ECEF positions [m].
    t_epoch : np.ndarray, shape (n,)
        Time of epoch index 0..n-1 [s]; NaN for epochs without observations.
    truth_xyz : np.ndarray, shape (n, 3)
        Reference ECEF position of each epoch [m]; NaN where there is none.
    max_offset_s : float
        Largest distance in time of a solution from its epoch [s] (:func:`match_to_epochs`).
    offsets_s : np.ndarray, shape (k,)
        The shifts tried [s]; 0 among them.

    Returns
    -------
    best : float
        The shift with the smallest mean 3-D error [s] (the solution's times plus it).
    mean_m : np.ndarray, shape (k,)
        Mean 3-D error at each shift [m]; inf where fewer than :data:`MIN_PAIRS` epochs pair with truth.
    """
    t = np.asarray(t_solution, float)
    xyz = np.asarray(xyz_solution, float)
    mean = np.full(len(offsets_s), np.inf)
    for k, shift in enumerate(offsets_s):
        si, ei = match_to_epochs(t + shift, t_epoch, max_offset_s)
        err = np.linalg.norm(xyz[si] - truth_xyz[ei], axis=1)
        err = err[np.isfinite(err)]
        if err.size >= MIN_PAIRS:
            mean[k] = err.mean()
    # ties (a static receiver) go to the smallest shift, 0 first
    order = np.lexsort((np.abs(offsets_s), mean))
    return float(offsets_s[order[0]]), mean
