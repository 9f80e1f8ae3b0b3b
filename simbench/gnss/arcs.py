"""Continuous carrier-phase arcs of an observation table."""
from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["arc_ids"]


def arc_ids(obs: pd.DataFrame, max_gap_epochs: int = 1, *, use_l2: bool = False) -> np.ndarray:
    """Identify continuous carrier-phase arcs.

    A new arc starts at a satellite's first row, where the epoch index jumps by
    more than ``max_gap_epochs`` since the satellite's previous row (1: every
    epoch must be present), and where the loss-of-lock flag is set
    (``lli_l1``, or ``lli_l1 | lli_l2`` with ``use_l2``).

    Parameters
    ----------
    obs : pandas.DataFrame
        Observation rows with ``epoch``, ``sat``, ``lli_l1`` (and ``lli_l2``), any order.
    max_gap_epochs : int
        Largest epoch step within one arc.
    use_l2 : bool
        Also break arcs at L2 loss of lock (dual-frequency processing).

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
