"""The raw-log -> scenario steps that every real-log reader shares (RINEX, libRSF).

A reader turns its file into per-row pseudoranges and satellite positions; from
there the steps are the same: the nominal epoch grid (gaps in the log stay gaps),
a rough single-point fix per epoch for elevation and azimuth (a receiver knows no
reference), the observation table in the simulator's columns, the truth table
from a reference trajectory, and a :class:`~simbench.contract.Scenario` without
labels or IMU data.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from simbench.contract import IMU_COLUMNS, OBSERVATION_COLUMNS, NavInfo, RinexFiles, Scenario
from simbench.data.reference import Reference, check_near_fixes, match_reference, truth_table
from simbench.gnss.geometry import elevation_azimuth
from simbench.gnss.spp import ROUGH_FIX_MAX_RMS_M, SppSolution, solve_epochs

__all__ = [
    "EpochGrid",
    "RoughFix",
    "empty_imu",
    "epoch_grid",
    "epoch_grid_of",
    "rough_fix",
    "observation_table",
    "log_truth",
    "log_scenario",
]


def empty_imu() -> pd.DataFrame:
    """The IMU table of a log without inertial data (zero rows, IMU columns)."""
    return pd.DataFrame({c: np.zeros(0) for c in IMU_COLUMNS})


def epoch_grid(t_rel: np.ndarray, interval_s: float) -> np.ndarray:
    """Epoch index on the nominal grid: gaps in the log leave gaps in the index.

    Parameters
    ----------
    t_rel : np.ndarray, shape (n,)
        Epoch times since the first epoch [s], increasing.
    interval_s : float
        Nominal interval [s].
    """
    idx = np.round(t_rel / interval_s).astype(np.int64)
    if np.any(np.diff(idx) <= 0):
        # irregular tags (e.g. a receiver that slews its clock): fall back to ranks
        idx = np.arange(t_rel.size, dtype=np.int64)
    return idx


@dataclass(frozen=True)
class EpochGrid:
    """The nominal epoch grid of a log.

    Attributes
    ----------
    index : np.ndarray, shape (n_log,)
        Grid index of each epoch of the log (:func:`epoch_grid`).
    t : np.ndarray, shape (n,)
        Time of each grid slot since the first epoch [s]: the log's own tag where it has an epoch.
    """

    index: np.ndarray
    t: np.ndarray

    @property
    def n(self) -> int:
        """Number of grid slots, gaps included."""
        return int(self.t.size)


def epoch_grid_of(t_rel: np.ndarray, interval_s: float) -> EpochGrid:
    """The :class:`EpochGrid` of epoch times ``t_rel`` [s since the first epoch] at nominal ``interval_s`` [s]."""
    index = epoch_grid(t_rel, interval_s)
    t = np.arange(int(index[-1]) + 1) * interval_s
    t[index] = t_rel
    return EpochGrid(index=index, t=t)


@dataclass(frozen=True)
class RoughFix:
    """A per-epoch single-point fix and the elevation and azimuth it gives each row.

    Attributes
    ----------
    fix : SppSolution
        One position per epoch of the log (untrusted epochs filled from their neighbours).
    el, az : np.ndarray, shape (n_rows,)
        Elevation and azimuth of each row's satellite from its epoch's fix [rad].
    """

    fix: SppSolution
    el: np.ndarray
    az: np.ndarray


def rough_fix(
    row_epoch: np.ndarray,
    sat_pos: np.ndarray,
    code: np.ndarray,
    *,
    n_epochs: int,
    system_index: np.ndarray,
    x0: np.ndarray | None = None,
) -> RoughFix:
    """Single-point fixes of a log's epochs and each row's elevation and azimuth from them.

    Tens of metres of position error move an elevation by far less than a millidegree.

    Parameters
    ----------
    row_epoch : np.ndarray, shape (n_rows,)
        Epoch of the log (0-based, not the grid index) of each row.
    sat_pos : np.ndarray, shape (n_rows, 3)
        Satellite ECEF position [m].
    code : np.ndarray, shape (n_rows,)
        Pseudorange with the satellite clock applied [m].
    n_epochs : int
        Number of epochs of the log.
    system_index : np.ndarray, shape (n_rows,)
        Receiver clock of each row (one per system: inter-system biases).
    x0 : np.ndarray, shape (3,), optional
        Starting position [m ECEF], e.g. the RINEX header's approximate position.
    """
    fix = solve_epochs(
        row_epoch,
        sat_pos,
        code,
        n_epochs=n_epochs,
        system_index=system_index,
        x0=x0,
        max_rms_m=ROUGH_FIX_MAX_RMS_M,
        fill_untrusted=True,
    )
    el, az = elevation_azimuth(fix.pos[row_epoch], sat_pos[:, None, :])
    return RoughFix(fix=fix, el=el[:, 0], az=az[:, 0])


def observation_table(columns: dict[str, np.ndarray]) -> pd.DataFrame:
    """The observation table (:data:`~simbench.contract.OBSERVATION_COLUMNS`, in that order) sorted by epoch
    and satellite; ``columns`` holds one array per column, row-aligned."""
    return (
        pd.DataFrame({c: columns[c] for c in OBSERVATION_COLUMNS})
        .sort_values(["epoch", "sat"], kind="stable")
        .reset_index(drop=True)
    )


def log_truth(
    grid: EpochGrid,
    t0_gps: float,
    reference: Reference | None,
    max_gap_s: float,
    epochs: np.ndarray,
    rough: RoughFix | None = None,
    field: str = "scenario.truth",
) -> pd.DataFrame:
    """The truth table of a log: the reference at each grid slot that it covers.

    Parameters
    ----------
    grid : EpochGrid
    t0_gps : float
        GPS time of grid time 0 [s since the GPS epoch].
    reference : Reference or None
        None: an empty truth table (nothing can be scored).
    max_gap_s : float
        Reference samples further apart are not interpolated [s].
    epochs : np.ndarray
        The ``epoch`` column of the observation table (gives ``n_visible``).
    rough : RoughFix, optional
        The log's own fixes: a reference far from them is refused
        (:func:`~simbench.data.reference.check_near_fixes`); None checks nothing.
    field : str
        The setting that named the reference file, for error messages.
    """
    matched = None
    if reference is not None:
        matched = match_reference(reference, t0_gps + grid.t, max_gap_s)
        if rough is not None:
            fix_pos = np.where(rough.fix.trusted[:, None], rough.fix.pos, np.nan)
            check_near_fixes(reference, matched[grid.index, :3], fix_pos, field)
    return truth_table(grid.t, matched, np.bincount(epochs, minlength=grid.n))


def log_scenario(
    observations: pd.DataFrame,
    truth: pd.DataFrame,
    nav: NavInfo,
    meta: dict[str, Any],
    *,
    odometry: pd.DataFrame | None = None,
    rinex: RinexFiles | None = None,
) -> Scenario:
    """A real log's :class:`~simbench.contract.Scenario`: no labels, an empty IMU table, odometry if it has one."""
    if odometry is None:
        return Scenario(observations, empty_imu(), truth, None, nav, meta, rinex=rinex)
    return Scenario(observations, empty_imu(), truth, None, nav, meta, rinex=rinex, odometry=odometry)
