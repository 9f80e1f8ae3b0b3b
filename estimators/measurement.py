"""The shared PPP measurement model (dissertation eqs. 4.1-4.4).

Every PPP estimator (the EKF, the GTSAM batch and incremental graphs) uses the
same observation preparation and the same prediction, so differences between
estimators come from the estimators, not from the model.

Model, per satellite ``j`` at one epoch (metres)::

    code_j  = r_j(x) + c dt_r + ZHD m_h(el_j) + ZWD m_w(el_j)            + e
    phase_j = r_j(x) + c dt_r + ZHD m_h(el_j) + ZWD m_w(el_j) + B_arc(j) + e

``r_j`` is the geometric range with the Earth-rotation (Sagnac) term
(:func:`simbench.gnss.geometry.sagnac_range`), ``ZHD`` the Saastamoinen zenith
hydrostatic delay at the current position estimate, ``m_h``/``m_w`` the Niell
mappings, ``ZWD`` the estimated zenith wet delay and ``B`` a float carrier-phase
bias (metres) per continuous phase arc. The observations are corrected before:
the product satellite clock is added, and either the ionosphere-free
combination is formed (dual frequency, eq. 4.1) or the broadcast Klobuchar
delay is removed (subtracted from code, added to phase).

State order used by :func:`predict`'s Jacobian: ``[x, y, z, clock_m, zwd_m]``
(ECEF metres, receiver clock times c in metres, zenith wet delay in metres).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pandas as pd

from estimators.ppp_config import MeasurementMode, SigmaModel
from simbench.contract import ReceiverData
from simbench.core import atmosphere
from simbench.core.constants import DEG, IF_A1, IF_A2
from simbench.core.frames import geodetic_from_ecef
from simbench.core.gpstime import day_of_year
from simbench.errors import SimbenchError
from simbench.gnss.arcs import arc_ids
from simbench.gnss.geometry import sagnac_range_gradient
from simbench.gnss.signals import l1_wavelength_m
from simbench.gnss.spp import solve_epochs
from simbench.gnss.troposphere import troposphere_terms

__all__ = [
    "PppObservations",
    "arc_ids",
    "prepare_ppp",
    "predict",
    "predict_given_troposphere",
    "sigma_factor",
    "N_BASE_STATES",
]

#: Number of non-ambiguity states in :func:`predict`'s Jacobian: x, y, z, clock, zwd.
N_BASE_STATES = 5

_REQUIRED = ("epoch", "t", "sat", "code_l1", "phase_l1", "lli_l1", "sat_x", "sat_y", "sat_z", "sat_clock", "el", "az")
_REQUIRED_L2 = ("code_l2", "phase_l2", "lli_l2")
#: Interval between the rough single-point positions used for the Klobuchar pierce points [s].
_ROUGH_POSITION_INTERVAL_S = 60.0


# --------------------------------------------------------------------------- prediction


def predict_given_troposphere(
    sat_pos: np.ndarray,
    rx_pos: np.ndarray,
    clock_m: float,
    zwd_m: float,
    slant_hydrostatic_m: np.ndarray,
    m_wet: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`predict` with the troposphere terms of :func:`troposphere_terms` given."""
    rng, grad = sagnac_range_gradient(sat_pos, rx_pos)
    H = np.empty((len(rng), N_BASE_STATES))
    H[:, :3] = grad
    H[:, 3] = 1.0
    H[:, 4] = m_wet
    return rng + clock_m + slant_hydrostatic_m + zwd_m * m_wet, H


def predict(
    sat_pos: np.ndarray,
    rx_pos: np.ndarray,
    clock_m: float,
    zwd_m: float,
    el: np.ndarray,
    lat: float,
    h: float,
    doy: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Predicted code (= phase minus its bias) and Jacobian for one epoch.

    ``prediction = sagnac_range + clock_m + ZHD(lat, h) m_h(el) + zwd_m m_w(el)``.

    Parameters
    ----------
    sat_pos : ndarray, shape (k, 3)
        Satellite ECEF positions at transmit time [m].
    rx_pos : ndarray, shape (3,)
        Receiver ECEF position (linearisation point) [m].
    clock_m : float
        Receiver clock offset times c [m].
    zwd_m : float
        Zenith wet delay [m].
    el : ndarray, shape (k,)
        Elevations [rad] (for the mapping functions).
    lat, h : float
        Geodetic latitude [rad] and height [m] of the receiver (for the
        troposphere; held fixed in the Jacobian).
    doy : float
        Day of year (Niell seasonal term).

    Returns
    -------
    predicted : ndarray, shape (k,)
        Predicted range including clock and troposphere [m].
    H : ndarray, shape (k, 5)
        Partials w.r.t. ``[x, y, z, clock_m, zwd_m]``: ``[-los_unit (+ Sagnac), 1, m_w]``.
    """
    return predict_given_troposphere(sat_pos, rx_pos, clock_m, zwd_m, *troposphere_terms(el, lat, h, doy))


# --------------------------------------------------------------------------- preparation


def sigma_factor(el: np.ndarray, cn0: np.ndarray, model: SigmaModel, cn0_ref_dbhz: float = 45.0) -> np.ndarray:
    """Per-row factor on the zenith sigmas of code, phase and Doppler.

    Parameters
    ----------
    el : ndarray
        Elevation [rad].
    cn0 : ndarray
        C/N0 [dB-Hz]; NaN where the receiver reports none.
    model : SigmaModel
        ``elevation``: ``1 / sin(el)``; ``cn0``: ``10^((cn0_ref_dbhz - cn0) / 20)`` (``1 / sin(el)``
        where ``cn0`` is NaN); ``elevation_cn0``: the product (the C/N0 part 1 where NaN).
    cn0_ref_dbhz : float
        C/N0 at which the C/N0 part is 1 [dB-Hz].

    Returns
    -------
    ndarray
        Dimensionless factor, shape of ``el``.
    """
    by_elevation = 1.0 / np.sin(el)
    if model == SigmaModel.elevation:
        return by_elevation
    by_cn0 = 10.0 ** ((cn0_ref_dbhz - np.asarray(cn0, float)) / 20.0)
    if model == SigmaModel.cn0:
        return np.where(np.isfinite(by_cn0), by_cn0, by_elevation)
    return by_elevation * np.where(np.isfinite(by_cn0), by_cn0, 1.0)


@dataclass(frozen=True)
class PppObservations:
    """Usable, corrected observations as flat arrays sorted by (epoch, satellite).

    Row arrays have shape (N,); per-epoch arrays shape (n_epochs,). Rows of
    solved epoch ``k`` are ``slice(epoch_start[k], epoch_stop[k])``
    (:meth:`epoch_slice`, :meth:`iter_epochs`).
    """

    epoch: np.ndarray  #: int, GNSS epoch index of each row
    t: np.ndarray  #: s, time since scenario start
    sat: np.ndarray  #: str, satellite id
    sat_index: np.ndarray  #: int, index into ``sat_names``
    sat_pos: np.ndarray  #: m, (N, 3) satellite ECEF position at transmit time
    code: np.ndarray  #: m, corrected code (sat clock applied; Klobuchar removed or IF)
    phase: np.ndarray  #: m, corrected phase (same corrections; contains the arc bias)
    el: np.ndarray  #: rad, elevation
    az: np.ndarray  #: rad, azimuth
    arc: np.ndarray  #: int, phase arc id 0..n_arcs-1, numbered in order of arc start; -1 on rows without phase
    sigma_code: np.ndarray  #: m, zenith code sigma times ``sigma_scale``
    sigma_phase: np.ndarray  #: m, zenith phase sigma times ``sigma_scale``
    #: per row: the sigma model's factor on every zenith sigma (code, phase, Doppler; :func:`sigma_factor`)
    sigma_scale: np.ndarray
    cn0: np.ndarray  #: dB-Hz, L1 C/N0 (NaN where the receiver reports none)
    epoch_ids: np.ndarray  #: int, (n_epochs,) GNSS epoch index of each solved epoch
    epoch_t: np.ndarray  #: s, (n_epochs,) time of each solved epoch
    epoch_start: np.ndarray  #: int, (n_epochs,) first row of each solved epoch
    epoch_stop: np.ndarray  #: int, (n_epochs,) one past the last row
    sat_names: tuple[str, ...]  #: satellites appearing in the rows, sorted
    n_arcs: int  #: number of distinct phase arcs among the rows
    ionosphere_free: bool  #: IF combination (True) or L1 with Klobuchar (False)
    doy: float  #: day of year of the scenario start (Niell)
    #: GNSS systems among the rows (RINEX letters), GPS first when present: with more than one,
    #: estimators add one receiver clock offset per further system (inter-system bias)
    systems: tuple[str, ...] = ("G",)
    #: int, per row: index into ``systems`` (0 = the reference clock); None means all 0
    system_index: np.ndarray | None = None
    #: m/s, per row: measured range rate ``-lambda D`` plus the satellite clock drift (what the
    #: receiver clock drift and the geometric range rate explain); NaN without a usable Doppler
    range_rate: np.ndarray | None = None
    sat_vel: np.ndarray | None = None  #: m/s, (N, 3) satellite ECEF velocity
    #: per solved epoch, (n_epochs, 4): mean wheel speed [m/s], mean yaw rate [rad/s] (positive
    #: turning right) and their mean reported variances over the odometry samples since the
    #: previous epoch (t_{k-1}, t_k]; NaN rows without samples; None when there is no odometry
    odometry: np.ndarray | None = None

    @property
    def has_phase(self) -> np.ndarray:
        """bool, (N,): rows that carry a usable carrier phase (``phase`` finite, ``arc >= 0``)."""
        return self.arc >= 0

    @property
    def n_isb(self) -> int:
        """Number of inter-system bias states a multi-system estimator needs (0 for one system)."""
        return len(self.systems) - 1

    @property
    def n_epochs(self) -> int:
        return len(self.epoch_ids)

    @property
    def n_obs(self) -> int:
        return len(self.code)

    def epoch_slice(self, k: int) -> slice:
        """Rows of the ``k``-th solved epoch (not GNSS epoch index ``k``)."""
        return slice(int(self.epoch_start[k]), int(self.epoch_stop[k]))

    def iter_epochs(self) -> Iterator[tuple[int, slice]]:
        """Yield ``(k, rows)`` for every solved epoch in time order."""
        for k, (a, b) in enumerate(zip(self.epoch_start.tolist(), self.epoch_stop.tolist())):
            yield k, slice(a, b)


def prepare_ppp(
    data: ReceiverData,
    *,
    ionosphere_free: bool,
    code_sigma_m: float,
    phase_sigma_m: float,
    elevation_mask_deg: float,
    min_satellites: int = 4,
    max_gap_epochs: int = 1,
    measurements: MeasurementMode = MeasurementMode.code_phase,
    sigma_model: SigmaModel = SigmaModel.elevation,
    cn0_ref_dbhz: float = 45.0,
    doppler_slip_m: float = 0.0,
) -> PppObservations:
    """Select, correct and weight the observations for PPP.

    Rows with missing values in the columns used, or below the elevation mask,
    are dropped; then epochs with fewer than ``min_satellites`` rows. Phase
    arcs are identified on all rows with a valid phase (before the mask and
    the epoch selection: a satellite that dips under the mask while the
    receiver keeps lock keeps its arc); a row without phase ends its
    satellite's arc.

    Parameters
    ----------
    data : ReceiverData
    ionosphere_free : bool
        Form the L1/L2 ionosphere-free combination (needs dual-frequency data);
        otherwise use L1 with the broadcast Klobuchar delay removed.
    code_sigma_m, phase_sigma_m : float
        Zenith standard deviations [m] of the (combined) code and phase; scaled per row by
        :func:`sigma_factor`.
    elevation_mask_deg : float
        Elevation mask [deg].
    min_satellites : int
        Epochs with fewer usable satellites are dropped.
    max_gap_epochs, doppler_slip_m : int, float
        See :func:`arc_ids`.
    measurements : MeasurementMode
        ``code_phase`` (default) drops rows without carrier phase; ``auto`` keeps
        them as code-only rows (real receivers often report code without phase);
        ``code`` ignores the phase everywhere. A code-only row has ``phase`` NaN
        and ``arc`` -1.
    sigma_model, cn0_ref_dbhz : SigmaModel, float
        How the sigmas follow elevation and C/N0 (:func:`sigma_factor`).

    Raises
    ------
    SimbenchError
        Missing columns, ionosphere-free requested on single-frequency data,
        bad sigmas, or no epoch with enough satellites.
    """
    obs = data.observations
    need = _REQUIRED + (_REQUIRED_L2 if ionosphere_free else ())
    missing = [c for c in need if c not in obs.columns]
    if missing:
        raise SimbenchError(
            "observations",
            f"missing columns {missing}",
            "give an observation table with the columns of simbench.contract.OBSERVATION_COLUMNS",
        )
    if ionosphere_free and not (data.nav.dual_frequency and obs["code_l2"].notna().any()):
        raise SimbenchError(
            "ionosphere_free",
            "requested, but the data are single-frequency (no L2)",
            "set ionosphere_free=false, or simulate with scenario.dual_frequency=true",
        )
    for name, value in (("code_sigma_m", code_sigma_m), ("phase_sigma_m", phase_sigma_m)):
        if not value > 0:
            raise SimbenchError(name, f"must be positive, got {value}", "give a standard deviation in metres")
    if min_satellites < 1:
        raise SimbenchError(
            "min_satellites",
            f"must be at least 1, got {min_satellites}",
            "give 4 for snapshot-solvable epochs only, or 1 to keep every epoch with a satellite",
        )

    require_phase = measurements == MeasurementMode.code_phase
    if require_phase and len(obs) and not np.isfinite(obs["phase_l1"].to_numpy(float)).any():
        raise SimbenchError(
            "observations",
            "carry no carrier phase (e.g. a libRSF pseudorange log)",
            "set the estimator's measurements=auto or measurements=code",
        )
    phase_cols = ["phase_l1"] + (["phase_l2"] if ionosphere_free else [])
    code_cols = ["code_l1", "sat_x", "sat_y", "sat_z", "sat_clock", "el", "az", "t"]
    if ionosphere_free:
        code_cols += ["code_l2"]
    valid = np.isfinite(obs[code_cols].to_numpy(float)).all(axis=1)
    with_phase = np.isfinite(obs[phase_cols].to_numpy(float)).all(axis=1) & (measurements != MeasurementMode.code)
    if require_phase:
        valid &= with_phase
    obs = obs.loc[valid]
    with_phase = with_phase[valid]
    arc = np.full(len(obs), -1, np.int64)
    arc[with_phase] = arc_ids(
        obs.loc[with_phase], max_gap_epochs, use_l2=ionosphere_free, doppler_slip_m=doppler_slip_m
    )

    el = obs["el"].to_numpy(float) * DEG
    keep = el > elevation_mask_deg * DEG
    epoch = obs["epoch"].to_numpy(np.int64)
    if len(epoch):
        counts = np.bincount(epoch[keep], minlength=int(epoch.max()) + 1)
        keep &= counts[epoch] >= min_satellites
    if not keep.any():
        raise SimbenchError(
            "observations",
            f"no epoch has {min_satellites} satellites above the {elevation_mask_deg} deg mask",
            "lower elevation_mask_deg, or check the scenario (open sky, duration)",
        )

    sat = obs["sat"].to_numpy()[keep]
    epoch = epoch[keep]
    order = np.lexsort((sat, epoch))
    sel = np.flatnonzero(keep)[order]
    sub = obs.iloc[sel]
    sat, epoch, el, arc = sat[order], epoch[order], el[keep][order], arc[keep][order]
    t = sub["t"].to_numpy(float)
    az = sub["az"].to_numpy(float) * DEG
    sat_pos = sub[["sat_x", "sat_y", "sat_z"]].to_numpy(float)
    sat_clock = sub["sat_clock"].to_numpy(float)
    range_rate = np.full(len(sub), np.nan)
    sat_vel = np.full((len(sub), 3), np.nan)
    if {"doppler_l1", "sat_vx", "sat_vy", "sat_vz", "sat_clock_drift"} <= set(sub.columns):
        sat_vel = sub[["sat_vx", "sat_vy", "sat_vz"]].to_numpy(float)
        range_rate = -l1_wavelength_m(sub["sat"].to_numpy()) * sub["doppler_l1"].to_numpy(float) + sub[
            "sat_clock_drift"
        ].to_numpy(float)
        range_rate[~np.isfinite(sat_vel).all(axis=1)] = np.nan
    doy = day_of_year(data.nav.gps_week, data.nav.start_sow_s)

    if ionosphere_free:
        code = IF_A1 * sub["code_l1"].to_numpy(float) - IF_A2 * sub["code_l2"].to_numpy(float) + sat_clock
        phase = IF_A1 * sub["phase_l1"].to_numpy(float) - IF_A2 * sub["phase_l2"].to_numpy(float) + sat_clock
    else:
        code = sub["code_l1"].to_numpy(float) + sat_clock
        phase = sub["phase_l1"].to_numpy(float) + sat_clock
    phase = np.where(arc >= 0, phase, np.nan)

    epoch_ids, epoch_start, n_per = np.unique(epoch, return_index=True, return_counts=True)
    epoch_stop = epoch_start + n_per
    cn0 = sub["cn0_l1"].to_numpy(float) if "cn0_l1" in sub.columns else np.full(len(sub), np.nan)
    sigma_scale = sigma_factor(el, cn0, sigma_model, cn0_ref_dbhz)

    sat_names, sat_index = np.unique(sat, return_inverse=True)
    letters = np.array([str(s)[:1] for s in sat_names])
    systems = tuple(sorted(set(letters.tolist()), key=lambda c: (c != "G", c)))
    system_index = np.array([systems.index(c) for c in letters], np.int64)[sat_index]

    if not ionosphere_free and not data.nav.iono_corrected:
        lat, lon = _rough_lat_lon(sat_pos, code, sigma_scale, el, doy, t, epoch_start, epoch_stop, system_index)
        iono = atmosphere.klobuchar_l1_delay_m(
            data.nav.start_sow_s + t, lat, lon, el, az, np.asarray(data.nav.iono_alpha), np.asarray(data.nav.iono_beta)
        )
        code = code - iono
        phase = phase + iono
    _, renumbered = np.unique(arc[arc >= 0], return_inverse=True)  # monotone: keeps the start order
    arc[arc >= 0] = renumbered
    return PppObservations(
        epoch=epoch,
        t=t,
        sat=sat,
        sat_index=sat_index.astype(np.int64),
        sat_pos=sat_pos,
        code=code,
        phase=phase,
        el=el,
        az=az,
        arc=arc.astype(np.int64),
        sigma_code=code_sigma_m * sigma_scale,
        sigma_phase=phase_sigma_m * sigma_scale,
        sigma_scale=sigma_scale,
        cn0=cn0,
        epoch_ids=epoch_ids,
        epoch_t=t[epoch_start],
        epoch_start=epoch_start,
        epoch_stop=epoch_stop,
        sat_names=tuple(str(s) for s in sat_names),
        n_arcs=int(arc.max(initial=-1)) + 1,
        ionosphere_free=ionosphere_free,
        doy=doy,
        systems=systems,
        system_index=system_index,
        range_rate=range_rate,
        sat_vel=sat_vel,
        odometry=_odometry_per_epoch(data.odometry, t[epoch_start]) if len(data.odometry) else None,
    )


def _odometry_per_epoch(odo: pd.DataFrame, epoch_t: np.ndarray) -> np.ndarray:
    """Means of the odometry samples in (t_{k-1}, t_k] for every epoch (the first: up to t_0)."""
    odo = odo.sort_values("t")
    values = odo[["speed", "yaw_rate", "var_speed", "var_yaw_rate"]].to_numpy(float)
    k = np.searchsorted(epoch_t, odo["t"].to_numpy(float), side="left")
    inside = k < len(epoch_t)
    count = np.bincount(k[inside], minlength=len(epoch_t)).astype(float)
    out = np.full((len(epoch_t), 4), np.nan)
    for j in range(4):
        total = np.bincount(k[inside], values[inside, j], minlength=len(epoch_t))
        np.divide(total, count, out=out[:, j], where=count > 0)
    return out


def _rough_lat_lon(
    sat_pos: np.ndarray,
    code: np.ndarray,
    sigma: np.ndarray,
    el: np.ndarray,
    doy: float,
    t: np.ndarray,
    start: np.ndarray,
    stop: np.ndarray,
    system_index: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Receiver latitude/longitude per row for the Klobuchar pierce points.

    Single point solutions every ~60 s (each epoch takes the latest one before
    it, the first one before that); the Klobuchar delay changes by far less
    than a centimetre over the kilometres a receiver moves in a minute. Only
    epochs with 4 satellites or more are candidates (with ``min_satellites`` below
    4 many are not); when none of the chosen ones gives a trusted fix, every
    candidate is solved.
    """
    t_epoch = t[start]
    n = len(start)
    candidates = np.flatnonzero(stop - start >= 4)
    if candidates.size == 0:
        candidates = np.arange(n)  # solve_epochs then says in one line that nothing is trusted
    every = candidates[
        np.unique(
            np.minimum(
                np.searchsorted(
                    t_epoch[candidates], np.arange(t_epoch[0], t_epoch[-1] + 1e-9, _ROUGH_POSITION_INTERVAL_S)
                ),
                candidates.size - 1,
            )
        )
    ]
    for solve_at in (every, candidates):
        rows = np.concatenate([np.arange(start[k], stop[k]) for k in solve_at])
        which_rows = np.repeat(np.arange(len(solve_at)), stop[solve_at] - start[solve_at])
        try:
            sol = solve_epochs(
                which_rows,
                sat_pos[rows],
                code[rows],
                n_epochs=len(solve_at),
                sigma=sigma[rows],
                system_index=system_index[rows],
                el=el[rows],
                doy=doy,
                fill_untrusted=True,
            )
            break
        except SimbenchError:
            if solve_at is candidates:
                raise
    lats, lons, _ = geodetic_from_ecef(sol.pos)
    which = np.maximum(np.searchsorted(solve_at, np.arange(n), side="right") - 1, 0)
    per_row = np.repeat(which, stop - start)
    return lats[per_row], lons[per_row]
