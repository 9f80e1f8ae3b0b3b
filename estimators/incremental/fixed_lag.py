"""A deterministic fixed-lag window over :class:`gtsam.ISAM2`.

Why not ``gtsam.IncrementalFixedLagSmoother``: before each marginalisation it picks
the keys to re-eliminate with ``BayesTreeMarginalizationHelper``, which walks
``std::unordered_set<const Clique*>`` (hashed by memory address) and skips cliques
it has already visited, so which keys it re-eliminates depends on where the cliques
happen to be allocated. The elimination, and every float after it, then differs from
process to process: 4e-7 m for iSAM2-PPP on the Hong Kong log, 9.9 m for iSAM2-DCS,
whose kernel amplifies any last-bit change (docs/notebook.md).

This window decides everything from the epoch times:

* :class:`LagSchedule` says, before the run, which epochs are kept after each update
  (at least ``lag_s`` seconds and ``min_epochs`` epochs, so the window spans a few
  epochs at 30 s as at 10 Hz). It is the one owner of "is this key alive":
  :meth:`LagSchedule.alive`. Keys leave in batches (half a window at a time) so that
  the marginalising update, which re-eliminates the whole window, is rare.
* :func:`restart_stale_arcs` cuts a phase arc where its previous row has left the
  window: the resumed arc gets a new bias key, and nothing asks for a dropped one.
* :class:`FixedLagSmoother` stamps each key with the last epoch that used it; on a
  marginalising update it re-eliminates every key with the leaving ones ordered
  first (``ISAM2UpdateParams.constrainedKeys``/``extraReelimKeys``, sorted), so the
  leaving keys are leaves, then ``ISAM2.marginalizeLeaves`` (ordered containers)
  replaces them by a linear prior on what remains. Marginalisation is exact for the
  linear part of the model.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import gtsam
import numpy as np

from estimators.model.measurement import PppObservations, split_arcs

__all__ = ["FixedLagSmoother", "LagSchedule", "restart_stale_arcs"]

#: Epochs this close to the lag's edge are inside it [s]: epoch times that are sums of a 0.1 s step
#: land a few ulps either side of it.
_EDGE_S = 1e-6


@dataclass(frozen=True)
class LagSchedule:
    """Which epochs a fixed-lag window keeps after each update.

    Attributes
    ----------
    first_kept : ndarray of int, shape (n_epochs,)
        Oldest epoch whose keys are still in the smoother after the update of epoch
        ``k``; keys last used before it have been marginalised. All zero: nothing is
        ever marginalised (plain iSAM2).
    """

    first_kept: np.ndarray

    @classmethod
    def of(cls, epoch_t: np.ndarray, lag_s: float, min_epochs: int) -> LagSchedule:
        """The schedule of epochs at times ``epoch_t`` [s].

        After the update of epoch ``k`` the window holds at least the epochs of the last
        ``lag_s`` seconds and at least the last ``min_epochs`` epochs; it is cut down to
        that once it has grown by half of it (a batch of epochs leaves at once).
        ``lag_s = 0`` keeps every epoch.

        Parameters
        ----------
        epoch_t : ndarray, shape (n_epochs,)
            Epoch times [s], increasing.
        lag_s : float
            Window length [s]; 0 for no window.
        min_epochs : int
            Epochs the window holds at least, whatever the data interval.
        """
        n = len(epoch_t)
        first_kept = np.zeros(n, np.int64)
        if lag_s <= 0 or n == 0:
            return cls(first_kept)
        k = np.arange(n)
        within_lag = np.searchsorted(epoch_t, epoch_t - lag_s - _EDGE_S, side="left")
        target = np.maximum(np.minimum(within_lag, k - min_epochs + 1), 0)
        cut = 0
        for j, (want, kept) in enumerate(zip(target.tolist(), (k - target + 1).tolist())):
            if want - cut >= max(1, kept // 2):
                cut = want
            first_kept[j] = cut
        return cls(first_kept)

    def alive(self, last_used: np.ndarray | int, k: np.ndarray | int) -> np.ndarray | bool:
        """Whether a key last used at epoch ``last_used`` is in the smoother when epoch ``k`` is added."""
        if isinstance(last_used, int) and isinstance(k, int):  # every read of the smoother asks: no arrays
            return last_used >= (int(self.first_kept[k - 1]) if k > 0 else 0)
        k = np.asarray(k)
        return np.asarray(last_used) >= np.where(k > 0, self.first_kept[np.maximum(k - 1, 0)], 0)

    def leaving(self, k: int) -> bool:
        """Whether the update of epoch ``k`` marginalises epochs."""
        return bool(self.first_kept[k] > (self.first_kept[k - 1] if k > 0 else 0))


def restart_stale_arcs(obs: PppObservations, schedule: LagSchedule) -> tuple[PppObservations, int]:
    """Cut each phase arc where its previous row has left the window.

    A satellite whose arc resumes after a gap longer than the window would ask for a
    bias (and an ionosphere key) that was marginalised; it starts a new arc instead
    (a new bias from its phase and predicted range), like a cycle slip.

    Returns
    -------
    obs : PppObservations
        ``obs`` with the cut arcs renumbered (unchanged when nothing is cut).
    n_restarted : int
        Arcs restarted.
    """
    prev = obs.previous_rows()
    resumed = np.flatnonzero(prev >= 0)
    row_epoch = obs.row_epoch
    stale = np.zeros(obs.n_obs, bool)
    stale[resumed] = ~schedule.alive(row_epoch[prev[resumed]], row_epoch[resumed])
    n_restarted = int(stale.sum())
    if not n_restarted:
        return obs, 0
    # a label that changes exactly at the cut rows of each arc: the cuts counted along each arc's rows
    stretch = np.zeros(obs.n_obs, np.int64)
    phase_rows = np.flatnonzero(obs.has_phase)
    order = phase_rows[np.lexsort((row_epoch[phase_rows], obs.arc[phase_rows]))]
    stretch[order] = np.cumsum(stale[order])
    arc = split_arcs(obs.arc, stretch)
    return dataclasses.replace(obs, arc=arc, n_arcs=int(arc.max()) + 1), n_restarted


class FixedLagSmoother:
    """:class:`gtsam.ISAM2` with the keys of epochs that :class:`LagSchedule` drops marginalised.

    Parameters
    ----------
    params : gtsam.ISAM2Params
    schedule : LagSchedule
    """

    def __init__(self, params: gtsam.ISAM2Params, schedule: LagSchedule) -> None:
        self._isam = gtsam.ISAM2(params)
        self._schedule = schedule
        self._last_used: dict[int, int] = {}
        self._next = 0  # the epoch the next update adds

    def update(self, k: int, graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, used: list[int]) -> None:
        """Add epoch ``k``'s factors and new ``values``; ``used``: older keys its factors use again."""
        last_used = self._last_used
        last_used.update(dict.fromkeys(values.keys(), k))
        last_used.update(dict.fromkeys(used, k))
        self._next = k + 1
        if not self._schedule.leaving(k):
            self._isam.update(graph, values)
            return
        keys = sorted(last_used)
        stays = {key: self.alive(key) for key in keys}
        params = gtsam.ISAM2UpdateParams()
        groups = gtsam.KeyGroupMap()
        reeliminate = gtsam.KeyList()
        for key in keys:
            groups.insert2(key, int(stays[key]))  # group 0, the leaving keys, is eliminated first
            reeliminate.push_back(key)
        params.constrainedKeys = groups
        params.extraReelimKeys = reeliminate
        self._isam.update(graph, values, params)
        leaves = gtsam.KeyList()
        for key in (key for key in keys if not stays[key]):
            leaves.push_back(key)
            del last_used[key]
        self._isam.marginalizeLeaves(leaves)

    def alive(self, key: int) -> bool:
        """Whether ``key`` is in the smoother for the next epoch: the schedule's word on its last use.

        The one test of a key's life: :func:`restart_stale_arcs` asks the same schedule ahead of
        the run, this method the smoother on every read, so a read of a dropped key is a bug
        reported by name, not a GTSAM ``IndexError``.
        """
        last_used = self._last_used.get(key)
        return last_used is not None and bool(self._schedule.alive(last_used, self._next))

    def point3(self, key: int) -> np.ndarray:
        """Current estimate of a Point3 key."""
        return self._isam.calculateEstimatePoint3(self._checked(key))

    def double(self, key: int) -> float:
        """Current estimate of a scalar key."""
        return self._isam.calculateEstimateDouble(self._checked(key))

    def joint_marginal_covariance(self, keys: list[int]) -> np.ndarray:
        """Joint marginal covariance of ``keys``, blocks in their order.

        One joint query: two ``marginalCovariance`` calls each marginalise the clique anew and
        cost 5-7x as much (2.3-3.7 ms an epoch on an hour of open sky, a third of an update).
        """
        for key in keys:
            self._checked(key)
        return np.asarray(self._isam.jointMarginalCovariance(gtsam.KeyVector(keys)).fullMatrix(), float)

    def _checked(self, key: int) -> int:
        if not self.alive(key):
            raise KeyError(f"key {gtsam.DefaultKeyFormatter(key)} has left the fixed-lag window")
        return key
