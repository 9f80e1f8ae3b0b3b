"""Continuous carrier-phase arcs of an observation table, and the check that code and phase agree along each."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from simbench.gnss.signals import l1_wavelength_m

__all__ = [
    "CODE_PHASE_MAX_RATE_MPS",
    "CODE_PHASE_SIGMAS",
    "CodePhaseCheck",
    "arc_ids",
    "check_code_phase",
    "doppler_phase_jumps",
]

#: Fastest physical drift of code minus phase along one arc [m/s]. On one frequency code minus phase
#: is ``2 I + ambiguity + noise``: it drifts at twice the slant ionospheric delay rate (of the
#: ionosphere-free pair, not at all). The walls of equatorial plasma bubbles move the L1 delay by
#: ~0.3 m/min (0.005 m/s; Pune, Radio Science, doi:10.1029/2005RS003359); the steepest storm gradient
#: on record, > 60 TECU per degree of latitude (the October 2003 superstorm over North America,
#: 0.09 m/km of vertical L1 delay), crossed at 300 m/s at three times the vertical delay gives
#: 0.08 m/s of delay, 0.16 m/s of code minus phase. Three times that; ten times the fastest arc of
#: 10 rows or more on one frequency in four station days (0.054 m/s: EUREF AJAC, Galileo E1; a
#: street's short arcs scatter more, within their code noise). A receiver whose code and phase run on
#: different clocks (a phone's steered code beside its raw accumulated delta range) drifts by its
#: clock drift, ~100 m/s.
CODE_PHASE_MAX_RATE_MPS = 0.5
#: A drift or a step counts when it exceeds the bound by this many of its standard deviations (from
#: each row's code sigma): one false alarm in ~3 million tests of Gaussian noise.
CODE_PHASE_SIGMAS = 5.0
#: Fewest arcs that resolve a drift before a drift they share counts as the receiver's.
_RECEIVER_MIN_ARCS = 3
#: Fewest rows of an arc tested on its own: the one step of a two-row arc cannot tell a phase fault from
#: an error of the code (a simulated street's sampling-grid error moved one code by 16 m in a second)
_ARC_MIN_ROWS = 5


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


@dataclass(frozen=True)
class CodePhaseCheck:
    """What :func:`check_code_phase` found and did.

    Attributes
    ----------
    arc : numpy.ndarray of int64, shape (N,)
        Arc id of each row after the check (-1: no phase, or its phase dropped), numbered 0.. in order of
        arc start (epoch, then satellite).
    receiver_rate_mps : float
        Drift of code minus phase that the arcs share: the median of the arcs' drifts weighted by their
        inverse variances [m/s]; NaN with fewer than three arcs that measure one.
    receiver_mismatch : bool
        The shared drift is beyond physics: code and phase on different clocks; every row's phase dropped.
    n_receiver_jumps : int
        Epochs at which code minus phase jumped on every arc (a receiver clock jump applied to the code
        or the phase alone), where every arc was broken.
    n_jumps : int
        Steps of code minus phase beyond noise at which one arc was broken (a new ambiguity after each).
    n_arcs_dropped : int
        Arcs (or pieces between jumps) whose phase was dropped for drifting beyond physics.
    n_rows_dropped : int
        Rows whose phase was dropped.
    """

    arc: np.ndarray
    receiver_rate_mps: float
    receiver_mismatch: bool
    n_receiver_jumps: int
    n_jumps: int
    n_arcs_dropped: int
    n_rows_dropped: int


def check_code_phase(
    arc: np.ndarray,
    epoch: np.ndarray,
    sat: np.ndarray,
    t: np.ndarray,
    code_minus_phase: np.ndarray,
    sigma: np.ndarray,
    *,
    max_rate_mps: float = CODE_PHASE_MAX_RATE_MPS,
    n_sigmas: float = CODE_PHASE_SIGMAS,
) -> CodePhaseCheck:
    """Hold every phase arc to the code: code minus phase may drift only as fast as the ionosphere.

    Along an arc code minus phase is constant but for the ionosphere and noise. An arc's drift is the
    weighted least-squares slope ``b`` of code minus phase over time (weights ``1 / sigma**2``), with
    standard deviation ``s_b``; it is beyond physics when ``|b| > max_rate_mps + n_sigmas s_b``.

    First the receiver. An epoch at which the median step of all arcs departs from the receiver's
    typical step by more than noise and physics allow is a clock jump in the code or the phase alone:
    every arc is broken there. When the drift the arcs share (the median of their drifts weighted by
    ``1 / s_b**2``) is beyond physics, code and phase run on different clocks and every row's phase
    is dropped. Then each arc of at least five rows beyond physics: when its median step drifts beyond
    physics too, the drift is persistent and the arc's phase is dropped; else the arc is broken after
    each step further from that median than ``n_sigmas`` of the step's noise (a jump: a new ambiguity),
    and a piece still beyond physics is dropped. A jump ``J`` shows as a drift of about ``1.5 J / T``
    on an arc of ``T`` seconds, so on long arcs only large jumps are found here (smaller ones are the
    Doppler check's, :func:`doppler_phase_jumps`).

    Parameters
    ----------
    arc : numpy.ndarray of int, shape (N,)
        Phase arc of each row, -1 without phase (:func:`arc_ids`).
    epoch, sat : numpy.ndarray, shape (N,)
        Epoch index and satellite id of each row (to number the arcs by start).
    t : numpy.ndarray, shape (N,)
        Time of each row [s].
    code_minus_phase : numpy.ndarray, shape (N,)
        Code minus phase of each row [m] (one frequency's, or of the ionosphere-free combinations).
    sigma : numpy.ndarray, shape (N,)
        Code standard deviation of each row [m] (the phase's is negligible beside it).
    max_rate_mps : float
        Fastest physical drift [m/s] (:data:`CODE_PHASE_MAX_RATE_MPS`).
    n_sigmas : float
        Margin of each test over the noise [standard deviations] (:data:`CODE_PHASE_SIGMAS`).

    Returns
    -------
    CodePhaseCheck
    """
    epoch = np.asarray(epoch, np.int64)
    t, y, sigma = (np.asarray(a, float) for a in (t, code_minus_phase, sigma))
    has = np.asarray(arc) >= 0
    steps = _Steps.of(np.asarray(arc, np.int64), t, y, sigma)
    jump_epochs = _receiver_jumps(steps, epoch, max_rate_mps, n_sigmas)
    arc = steps.split(np.isin(epoch[steps.rows], jump_epochs) & steps.step)
    rate, sd, beyond = _drifts_beyond(arc, t, y, sigma, max_rate_mps, n_sigmas)
    measured = np.isfinite(rate)
    receiver = np.nan
    if measured.sum() >= _RECEIVER_MIN_ARCS:
        weight = sd[measured] ** -2.0
        receiver = _weighted_median(rate[measured], weight)
        # the weighted median of Gaussian drifts scatters sqrt(pi / 2) times more than their weighted mean
        if abs(receiver) > max_rate_mps + n_sigmas * np.sqrt(np.pi / 2.0 / weight.sum()):
            n_arcs = int(np.unique(arc[has]).size)
            return CodePhaseCheck(np.full_like(arc, -1), receiver, True, 0, 0, n_arcs, int(has.sum()))
    n_jumps = n_persistent = n_still = 0
    if beyond.any():
        arc, n_jumps, n_persistent = _pieces(arc, t, y, sigma, beyond, max_rate_mps, n_sigmas)
        _, _, still = _drifts_beyond(arc, t, y, sigma, max_rate_mps, n_sigmas)
        arc[(arc >= 0) & still[np.maximum(arc, 0)]] = -1
        n_still = int(still.sum())
    n_rows = int((has & (arc < 0)).sum())
    arc = _by_start(arc, epoch, sat)
    return CodePhaseCheck(arc, receiver, False, len(jump_epochs), n_jumps, n_persistent + n_still, n_rows)


@dataclass(frozen=True)
class _Steps:
    """The rows with phase in (arc, time) order and the step of code minus phase onto each."""

    arc: np.ndarray  #: int, (N,): the arc of every row, -1 without phase
    rows: np.ndarray  #: int, (M,): the rows with phase, by arc, then time
    step: np.ndarray  #: bool, (M,): the row continues its arc (a step onto it)
    dt: np.ndarray  #: s, (M,): time since the arc's previous row (NaN at an arc's first)
    dy: np.ndarray  #: m, (M,): change of code minus phase since then
    noise: np.ndarray  #: m, (M,): the step's standard deviation, from the two rows' sigmas

    @classmethod
    def of(cls, arc: np.ndarray, t: np.ndarray, y: np.ndarray, sigma: np.ndarray) -> _Steps:
        rows = np.flatnonzero(arc >= 0)
        rows = rows[np.lexsort((t[rows], arc[rows]))]
        owner = arc[rows]
        step = np.zeros(len(rows), bool)
        step[1:] = owner[1:] == owner[:-1]
        dt, dy, noise = (np.full(len(rows), np.nan) for _ in range(3))
        dt[step] = np.diff(t[rows])[step[1:]]
        dy[step] = np.diff(y[rows])[step[1:]]
        noise[step] = np.hypot(sigma[rows][1:], sigma[rows][:-1])[step[1:]]
        return cls(arc, rows, step, dt, dy, noise)

    def split(self, before: np.ndarray) -> np.ndarray:
        """Arc ids (unordered) with a new arc at every row where ``before`` (bool, (M,)) is set."""
        piece = np.full(len(self.arc), -1, np.int64)
        piece[self.rows] = np.cumsum(~self.step | before) - 1
        return piece


def _receiver_jumps(steps: _Steps, epoch: np.ndarray, max_rate_mps: float, n_sigmas: float) -> np.ndarray:
    """Epochs at which code minus phase jumped on every arc (at least three) the same way, each beyond
    ``n_sigmas`` of its step's noise and beyond physics, off the receiver's typical step rate [epoch indices].

    Every arc, not their median: a street's code errors move the median of a few arcs by metres (a
    simulated sampling-grid error: 9 m on three of five satellites in one second), a clock moves them all.
    """
    ok = steps.step
    frame = pd.DataFrame({"epoch": epoch[steps.rows][ok], "rate": (steps.dy / steps.dt)[ok]})
    count = frame.groupby("epoch")["rate"].transform("size").to_numpy()
    if not (count >= _RECEIVER_MIN_ARCS).any():
        return np.zeros(0, np.int64)
    typical = float(np.median(frame.groupby("epoch")["rate"].median()))
    off = steps.dy[ok] - typical * steps.dt[ok]
    frame["sign"] = np.sign(off)
    frame["margin"] = np.abs(off) - n_sigmas * steps.noise[ok] - max_rate_mps * steps.dt[ok]
    per_epoch = frame.groupby("epoch").agg(n=("sign", "size"), signs=("sign", "sum"), margin=("margin", "min"))
    same_way = per_epoch["signs"].abs() == per_epoch["n"]
    jumped = (per_epoch["n"] >= _RECEIVER_MIN_ARCS) & same_way & (per_epoch["margin"] > 0)
    return per_epoch.index.to_numpy()[jumped.to_numpy()]


def _drifts_beyond(
    arc: np.ndarray, t: np.ndarray, y: np.ndarray, sigma: np.ndarray, max_rate_mps: float, n_sigmas: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per arc id 0..max: :func:`_arc_drifts` and whether the drift is beyond physics (an arc of at least
    :data:`_ARC_MIN_ROWS` rows whose ``|drift| > max_rate_mps + n_sigmas sd``)."""
    rate, sd = _arc_drifts(arc, t, y, sigma)
    long_enough = np.bincount(arc[arc >= 0], minlength=len(rate)) >= _ARC_MIN_ROWS
    with np.errstate(invalid="ignore"):
        beyond = long_enough & (np.abs(rate) > max_rate_mps + n_sigmas * sd)
    return rate, sd, beyond


def _arc_drifts(arc: np.ndarray, t: np.ndarray, y: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per arc id 0..max: the weighted least-squares slope of ``y`` over ``t`` (weights ``sigma**-2``) and
    its standard deviation; NaN for an arc of fewer than two distinct times.

    The standard deviation is the model's (``sigma``) or, where the arc's residuals about its line
    scatter more (reflected code in a street: the elevation model's sigmas are metres too small),
    theirs: the arc's variance factor ``chi2 / (n - 2)``, at least 1, scales it.
    """
    has = arc >= 0
    n = int(arc.max(initial=-1)) + 1
    a, t, y, w = arc[has], t[has], y[has], sigma[has] ** -2.0
    total = np.bincount(a, w, n)
    rows = np.bincount(a, minlength=n)
    with np.errstate(invalid="ignore", divide="ignore"):
        dt = t - (np.bincount(a, w * t, n) / total)[a]
        dy = y - (np.bincount(a, w * y, n) / total)[a]
        stt = np.bincount(a, w * dt * dt, n)
        slope = np.where(stt > 0, np.bincount(a, w * dt * dy, n) / stt, np.nan)
        chi2 = np.bincount(a, w * (dy - slope[a] * dt) ** 2, n)
        factor = np.where(rows > 2, np.maximum(1.0, chi2 / (rows - 2)), 1.0)
        sd = np.where(stt > 0, np.sqrt(factor / stt), np.nan)
    return slope, sd


def _weighted_median(x: np.ndarray, w: np.ndarray) -> float:
    """The value of ``x`` at which the weights below and above balance."""
    order = np.argsort(x, kind="stable")
    cumulative = np.cumsum(w[order])
    return float(x[order][np.searchsorted(cumulative, 0.5 * cumulative[-1])])


def _pieces(
    arc: np.ndarray,
    t: np.ndarray,
    y: np.ndarray,
    sigma: np.ndarray,
    beyond: np.ndarray,
    max_rate_mps: float,
    n_sigmas: float,
) -> tuple[np.ndarray, int, int]:
    """The arcs ``beyond`` physics (bool per arc id) dropped where their drift is persistent, else broken
    at their jumps.

    A step's noise is the model's (``sigma`` of its two rows) or, where the arc's steps scatter more
    about their median, theirs (1.4826 times their median absolute deviation, which a few jumps do
    not inflate).

    Returns
    -------
    piece : numpy.ndarray of int64, shape (N,)
        Piece of each row (ids unordered; -1: no phase, or a persistent arc's row).
    n_jumps, n_persistent : int
        Jumps found, arcs dropped as persistent.
    """
    steps = _Steps.of(arc, t, y, sigma)
    owner = arc[steps.rows]
    tested = steps.step & beyond[owner]
    frame = pd.DataFrame(
        {"arc": owner[tested], "rate": (steps.dy / steps.dt)[tested], "sd": (steps.noise / steps.dt)[tested]}
    )
    frame["z"] = np.abs(frame["rate"] - frame.groupby("arc")["rate"].transform("median")) / frame["sd"]
    per_arc = frame.groupby("arc").agg(rate=("rate", "median"), sd=("sd", "median"), z=("z", "median"))
    per_arc["n"] = frame.groupby("arc").size()
    factor = np.maximum(1.0, 1.4826 * per_arc["z"].to_numpy())
    # the median of n steps scatters sqrt(pi / 2) times more than their mean
    limit = max_rate_mps + n_sigmas * np.sqrt(np.pi / 2.0) * factor * per_arc["sd"].to_numpy() / np.sqrt(per_arc["n"])
    ids = per_arc.index.to_numpy()
    persistent = ids[np.abs(per_arc["rate"].to_numpy()) > limit]
    median_rate, arc_factor = np.zeros(len(beyond)), np.ones(len(beyond))
    median_rate[ids], arc_factor[ids] = per_arc["rate"].to_numpy(), factor
    jump = tested & ~np.isin(owner, persistent)
    off = np.abs(steps.dy[jump] - median_rate[owner[jump]] * steps.dt[jump])
    jump[jump] = off > n_sigmas * arc_factor[owner[jump]] * steps.noise[jump] + max_rate_mps * steps.dt[jump]
    piece = steps.split(jump)
    piece[np.isin(arc, persistent)] = -1
    return piece, int(jump.sum()), len(persistent)


def _by_start(arc: np.ndarray, epoch: np.ndarray, sat: np.ndarray) -> np.ndarray:
    """``arc`` renumbered 0.. in order of arc start (first epoch, then satellite); -1 stays."""
    has = arc >= 0
    out = np.full(len(arc), -1, np.int64)
    if not has.any():
        return out
    ids, inverse = np.unique(arc[has], return_inverse=True)
    _, sat_code = np.unique(np.asarray(sat)[has], return_inverse=True)
    first_epoch = np.full(len(ids), np.iinfo(np.int64).max)
    np.minimum.at(first_epoch, inverse, np.asarray(epoch, np.int64)[has])
    arc_sat = np.zeros(len(ids), np.int64)
    arc_sat[inverse] = sat_code
    rank = np.empty(len(ids), np.int64)
    rank[np.lexsort((arc_sat, first_epoch))] = np.arange(len(ids))
    out[has] = rank[inverse]
    return out
