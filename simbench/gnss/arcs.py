"""Continuous carrier-phase arcs of an observation table."""

from __future__ import annotations

import numpy as np
import pandas as pd

from simbench.gnss.signals import l1_wavelength_m

__all__ = ["arc_ids", "doppler_phase_jumps"]


def doppler_phase_jumps(obs: pd.DataFrame) -> np.ndarray:
    """How far each row's L1 phase step disagrees with its Doppler, less the epoch's common part [m].

    For consecutive rows of one satellite the phase step should equal the range
    change the Doppler predicts, ``-lambda (D_prev + D) / 2 dt`` (trapezoid). What
    all satellites of an epoch share is the receiver's (a clock that keeps within a
    millisecond by jumps moves every phase by the same hundreds of kilometres) and
    is removed as the epoch's median; what is left on one satellite is a cycle slip
    the receiver did not flag, or the switch to another reflected path.

    Parameters
    ----------
    obs : pandas.DataFrame
        Rows with ``epoch, t, sat, phase_l1, doppler_l1`` (phase in metres, Doppler in Hz).

    Returns
    -------
    numpy.ndarray, shape (len(obs),)
        ``|step - predicted - epoch median|`` [m]; NaN at a satellite's first row, after a
        gap of more than one epoch, without a Doppler or wavelength (GLONASS FDMA), or at an
        epoch with fewer than three such steps (no common part to remove).
    """
    n = len(obs)
    out = np.full(n, np.nan)
    if n < 2:
        return out
    epoch = obs["epoch"].to_numpy(np.int64)
    _, sat_code = np.unique(obs["sat"].to_numpy(), return_inverse=True)
    order = np.lexsort((epoch, sat_code))
    e, s = epoch[order], sat_code[order]
    t = obs["t"].to_numpy(float)[order]
    phase = obs["phase_l1"].to_numpy(float)[order]
    doppler = obs["doppler_l1"].to_numpy(float)[order]
    lam = l1_wavelength_m(obs["sat"].to_numpy()[order])
    step = phase[1:] - phase[:-1] + lam[1:] * 0.5 * (doppler[1:] + doppler[:-1]) * (t[1:] - t[:-1])
    step[(s[1:] != s[:-1]) | (np.diff(e) != 1)] = np.nan
    diff = np.full(n, np.nan)
    diff[1:] = step
    ok = np.isfinite(diff)
    if ok.sum() == 0:
        return out
    frame = pd.DataFrame({"epoch": e[ok], "d": diff[ok]})
    grouped = frame.groupby("epoch")["d"]
    median = grouped.transform("median").to_numpy()
    count = grouped.transform("size").to_numpy()
    jump = np.where(count >= 3, np.abs(frame["d"].to_numpy() - median), np.nan)
    sorted_out = np.full(n, np.nan)
    sorted_out[np.flatnonzero(ok)] = jump
    out[order] = sorted_out
    return out


def arc_ids(
    obs: pd.DataFrame, max_gap_epochs: int = 1, *, use_l2: bool = False, doppler_slip_m: float = 0.0
) -> np.ndarray:
    """Identify continuous carrier-phase arcs.

    A new arc starts at a satellite's first row, where the epoch index jumps by
    more than ``max_gap_epochs`` since the satellite's previous row (1: every
    epoch must be present), where the loss-of-lock flag is set
    (``lli_l1``, or ``lli_l1 | lli_l2`` with ``use_l2``), and, with
    ``doppler_slip_m > 0``, where the phase step disagrees with the Doppler by
    more than that (:func:`doppler_phase_jumps`: an unflagged slip).

    Parameters
    ----------
    obs : pandas.DataFrame
        Observation rows with ``epoch``, ``sat``, ``lli_l1`` (and ``lli_l2``), any order.
    max_gap_epochs : int
        Largest epoch step within one arc.
    use_l2 : bool
        Also break arcs at L2 loss of lock (dual-frequency processing).
    doppler_slip_m : float
        Largest phase-step disagreement with the Doppler within one arc [m]; 0 turns
        the check off (the table then needs no ``phase_l1``/``doppler_l1``/``t``).

    Returns
    -------
    numpy.ndarray of int64, shape (len(obs),)
        Arc id per row, numbered 0.. in order of arc start (epoch, then satellite).
    """
    n = len(obs)
    if n == 0:
        return np.zeros(0, np.int64)
    epoch = obs["epoch"].to_numpy(np.int64)
    _, sat_code = np.unique(obs["sat"].to_numpy(), return_inverse=True)
    lli = obs["lli_l1"].fillna(False).to_numpy(bool)
    if use_l2 and "lli_l2" in obs:
        lli = lli | obs["lli_l2"].fillna(False).to_numpy(bool)
    if doppler_slip_m > 0:
        lli = lli | (doppler_phase_jumps(obs) > doppler_slip_m)  # False where NaN
    order = np.lexsort((epoch, sat_code))  # by satellite, then epoch
    e, s = epoch[order], sat_code[order]
    new = lli[order].copy()
    new[0] = True
    new[1:] |= (s[1:] != s[:-1]) | (np.diff(e) > max_gap_epochs)
    run = np.cumsum(new) - 1
    # renumber the arcs by (start epoch, satellite)
    rank = np.lexsort((s[new], e[new]))
    remap = np.empty_like(rank)
    remap[rank] = np.arange(len(rank))
    out = np.empty(n, np.int64)
    out[order] = remap[run]
    return out
