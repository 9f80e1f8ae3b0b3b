"""Carrier-phase arcs, cycle slips and integer ambiguities.

A new arc (new random ambiguity, loss-of-lock flag set) starts whenever the PLL
(re)gains carrier lock on a satellite. Within an arc, slips happen when C/N0 is
below a threshold (with some probability per epoch) and at a small Poisson rate;
a slip adds a non-zero integer to the ambiguity and is flagged by the receiver
with a configurable probability. Where the PLL's jitter breaks its lock rule the
receiver has no phase at all (:func:`simbench.sim.generator` decides the lock).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simbench.sim.config import CycleSlipConfig
from simbench.sim.processes import Columns

#: Range of the initial ambiguity of an arc [cycles]; receivers start phase arbitrarily.
INITIAL_AMBIGUITY_CYCLES = 1_000_000


@dataclass(frozen=True)
class PhaseArcs:
    """Arrays of shape (n, m)."""

    arc_start: np.ndarray  #: satellite (re)acquired at this epoch
    slip: np.ndarray  #: true cycle slip inside an arc at this epoch
    lli: np.ndarray  #: loss-of-lock flag the receiver reports
    ambiguity: np.ndarray  #: integer ambiguity [cycles] (int64), meaningful where tracked


def phase_arcs(
    tracked: np.ndarray,
    cn0_dbhz: np.ndarray,
    cfg: CycleSlipConfig,
    dt_s: float,
    rng: np.random.Generator,
    n_frequencies: int = 1,
    columns: Columns | None = None,
) -> list[PhaseArcs]:
    """Draw arcs, slips and ambiguities for every (epoch, satellite).

    Parameters
    ----------
    tracked : ndarray of bool, shape (n, m)
        The PLL holds carrier lock on the satellite at this epoch.
    cn0_dbhz : ndarray, shape (n, m)
        Carrier-to-noise density [dB-Hz].
    cfg : CycleSlipConfig
    dt_s : float
        Epoch interval [s].
    rng : numpy.random.Generator
    n_frequencies : int
        1 (L1) or 2 (L1, L2); slips hit all frequencies at once, each with its own jump.
    columns : Columns, optional
        Which satellites of the constellation the m columns are: every draw spans all
        ``columns.width`` (by default the m columns are the constellation). The satellites
        left out must never be tracked (the number of arcs sizes a draw).

    Returns
    -------
    list of PhaseArcs, one per frequency.
    """
    n, m = tracked.shape
    draw = (Columns.every(m) if columns is None else columns).draw
    previous = np.vstack([np.zeros((1, m), bool), tracked[:-1]])
    arc_start = tracked & ~previous
    if cfg.enabled:
        weak = (cn0_dbhz < cfg.cn0_threshold_dbhz) & (draw(rng.random, n) < cfg.low_cn0_probability)
        poisson = draw(rng.random, n) < -np.expm1(-cfg.rate_per_s * dt_s)
        slip = tracked & ~arc_start & (weak | poisson)
        flagged = slip & (draw(rng.random, n) < cfg.flagged_fraction)
    else:
        slip = np.zeros((n, m), bool)
        flagged = slip
    lli = arc_start | flagged
    arc_id = np.cumsum(arc_start, axis=0)  # per satellite, 1-based within tracked spans
    # the ambiguities are worked out on the satellites ever tracked only (the draws are taken for all,
    # so that the numbers do not depend on which); elsewhere they are 0
    cols = np.flatnonzero(tracked.any(axis=0))
    arc_id_c, slip_c = arc_id[:, cols], slip[:, cols]
    # jumps accumulate only within the current arc: subtract the sum reached at its start
    start_row = np.maximum.accumulate(np.where(arc_start[:, cols], np.arange(n)[:, None], -1), axis=0)
    in_arc, start_row = start_row >= 0, np.maximum(start_row, 0)
    out = []
    for _ in range(n_frequencies):
        magnitude = draw(rng.integers, n, 1, max(cfg.max_jump_cycles, 1) + 1)
        sign = draw(rng.choice, n, [-1, 1])
        n_arcs = int(arc_id.max(initial=0))
        initial = draw(rng.integers, n_arcs + 1, -INITIAL_AMBIGUITY_CYCLES, INITIAL_AMBIGUITY_CYCLES + 1)
        cum = np.cumsum(np.where(slip_c, magnitude[:, cols] * sign[:, cols], 0), axis=0)
        base = np.where(in_arc, np.take_along_axis(cum, start_row, axis=0), 0)
        ambiguity = np.zeros((n, m), np.int64)
        ambiguity[:, cols] = initial[arc_id_c, cols[None, :]] + cum - base
        out.append(PhaseArcs(arc_start=arc_start, slip=slip, lli=lli, ambiguity=ambiguity))
    return out
