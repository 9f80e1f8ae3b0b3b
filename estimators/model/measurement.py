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

import hashlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from estimators.model.ppp_config import IonosphereMode, MeasurementMode, SigmaModel, VarianceComponents, WetDelayMode
from simbench.contract import NavInfo, ReceiverData
from simbench.core import atmosphere
from simbench.core.constants import DEG, F_L1
from simbench.core.frames import geodetic_from_ecef
from simbench.core.gpstime import day_of_year
from simbench.errors import SimbenchError, warn
from simbench.gnss.arcs import CODE_PHASE_MAX_RATE_MPS, CodePhaseCheck, arc_ids, check_code_phase
from simbench.gnss.geometry import sagnac_range_gradient
from simbench.gnss.measured_ionosphere import (
    BROADCAST_RELATIVE_ERROR,
    MeasuredIonosphere,
    geometry_free_delay,
    levelled_phase_delay,
    measured_ionosphere,
)
from simbench.gnss.signals import L1_FREQUENCY_HZ, l1_wavelength_m
from simbench.gnss.spp import SppSolution, position_gains, solve_epochs
from simbench.gnss.troposphere import troposphere_terms

__all__ = [
    "AUTO_FREE_MIN_FRACTION",
    "PppObservations",
    "SAT_DCB_COLUMN",
    "SAT_DCB_SIGMA_COLUMN",
    "VC_CLIP",
    "VC_MIN_REDUNDANCY",
    "VC_MIN_ROWS",
    "arc_ids",
    "checked_arcs",
    "content_digest",
    "if_combination",
    "klobuchar_scale",
    "pair_against_broadcast",
    "prepare_ppp",
    "predict",
    "predict_given_troposphere",
    "split_arcs",
    "sigma_factor",
    "variance_factors",
    "zenith_wet_delay_m",
    "ionosphere_choice",
    "ionosphere_free",
    "N_BASE_STATES",
]

#: Number of non-ambiguity states in :func:`predict`'s Jacobian: x, y, z, clock, zwd.
N_BASE_STATES = 5

_REQUIRED = ("epoch", "t", "sat", "code_l1", "phase_l1", "lli_l1", "sat_x", "sat_y", "sat_z", "sat_clock", "el", "az")
_REQUIRED_L2 = ("code_l2", "phase_l2", "lli_l2")
#: Columns a code row needs, finite, to be used
_CODE_COLUMNS = ("code_l1", "sat_x", "sat_y", "sat_z", "sat_clock", "el", "az", "t")
#: Interval between the rough single-point positions used for the Klobuchar pierce points [s].
_ROUGH_POSITION_INTERVAL_S = 60.0
#: ``ionosphere=auto`` forms the ionosphere-free combination when every satellite above the mask
#: has a second frequency on at least this share of its rows (a few rows without one are dropped)
AUTO_FREE_MIN_FRACTION = 0.9
#: Optional observation column [m]: the broadcast group delay of the ``*_l2`` signal minus that of
#: the ``*_l1`` signal, times c (GPS ``(gamma - 1) c TGD``, Galileo ``(gamma - 1) c BGD``, BeiDou
#: B1I/B3I ``-c TGD1``; NaN or absent: 0). ``sat_clock`` is the first frequency's clock (``c (dt -
#: TGD)``); the ionosphere-free combination needs ``sat_clock + sat_dcb / (gamma - 1)``.
SAT_DCB_COLUMN = "sat_dcb"
#: Optional observation column [m]: the stated RMS of what :data:`SAT_DCB_COLUMN` misses of the pair's
#: group-delay difference (:func:`simbench.data.rinex.second_group_delay_sigmas`; NaN or absent: nothing known)
SAT_DCB_SIGMA_COLUMN = "sat_dcb_sigma"
#: GLONASS L1 FDMA carrier of channel 0 [Hz] (the table does not carry the channel)
_F_GLONASS_L1_NOMINAL_HZ = 1_602.0e6
#: Fewest usable rows a variance group needs for its own factor.
VC_MIN_ROWS = 30
#: Fewest degrees of freedom (sum of the redundancy numbers) a variance group needs for its own factor.
VC_MIN_REDUNDANCY = 3.0
#: Normalised residuals count at most this many sigmas in the variance estimate.
VC_CLIP = 10.0
#: Solve-and-rescale rounds of the variance components (two systems with 0.5 m and 1.5 m noise
#: and a dozen rows per epoch: within 1 % after 3).
_VC_ITERATIONS = 4
#: C/N0 bin width of ``variance_components=system_cn0`` [dB-Hz].
_CN0_BIN_DBHZ = 5.0
#: Huber threshold of the robust single-point pass [standard deviations] (95 % Gaussian efficiency).
_HUBER_K = 1.345


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


def zenith_wet_delay_m(mode: WetDelayMode, lat: float, h: float, doy: float) -> float:
    """The zenith wet delay the model starts from [m] at one receiver position.

    ``model``: the RTCA MOPS climatology (:func:`simbench.core.atmosphere.mops_zenith_wet_m`), which
    follows latitude and season, held as the model's wet delay. ``estimate``: Table 4.4.2's prior
    mean of the ZWD state, Saastamoinen's wet delay of the standard atmosphere
    (:func:`simbench.core.atmosphere.saastamoinen_zenith_m`).

    Parameters
    ----------
    mode : WetDelayMode
    lat, h : float
        Geodetic latitude [rad] and height [m].
    doy : float
        Day of year.
    """
    if WetDelayMode(mode) == WetDelayMode.model:
        return float(atmosphere.mops_zenith_wet_m(lat, h, doy))
    return float(atmosphere.saastamoinen_zenith_m(lat, h)[1])


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
    #: ionosphere-free combination (True) or the first frequency with Klobuchar (False): the
    #: ``ionosphere`` mode's decision on these data
    ionosphere_free: bool
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
    #: per solved epoch, (n_epochs, 8), the columns of :data:`EPOCH_ODOMETRY`: mean wheel speed [m/s],
    #: yaw rate [rad/s] (positive turning right), body right and down velocities [m/s] and their mean
    #: reported variances over the odometry samples since the previous epoch (t_{k-1}, t_k]; NaN rows
    #: without samples, NaN right/down where the vehicle reports none; None when there is no odometry
    odometry: np.ndarray | None = None
    #: rows dropped for want of a second frequency (ionosphere-free only)
    n_single_frequency_dropped: int = 0
    #: what the ``ionosphere`` choice resolved to on these data (free, measured or broadcast)
    ionosphere: IonosphereMode = IonosphereMode.broadcast
    #: rows whose slant delay their own second frequency measured (``measured`` only)
    n_ionosphere_measured: int = 0
    #: per system, ``(a, b)`` of the broadcast delay fitted to the measured ones [-, m] (``measured`` only)
    ionosphere_fits: dict[str, tuple[float, float]] = field(default_factory=dict)
    #: per system with code pairs, the position error expected from the pairs' unbroadcast biases and from the
    #: broadcast model's error [m] (:func:`pair_against_broadcast`; ``ionosphere=auto`` only, where it decided)
    ionosphere_expected_m: dict[str, tuple[float, float]] = field(default_factory=dict)
    #: factor on the code sigma per variance group ("G", "C 35-40 dB-Hz", ...); empty without
    #: variance components
    variance_factors: dict[str, float] = field(default_factory=dict)
    #: what :func:`checked_arcs` found and did: the drift of code minus phase the arcs share [m/s], the
    #: jumps at which arcs were broken, the arcs and rows whose phase was dropped; empty without phase
    phase_check: dict[str, Any] = field(default_factory=dict)

    def model_info(self) -> dict[str, Any]:
        """The measurement model's data-driven choices, for an estimator's diagnostics (JSON values)."""
        return {
            "ionosphere_free": bool(self.ionosphere_free),
            "ionosphere": self.ionosphere.value,
            "single_frequency_rows_dropped": int(self.n_single_frequency_dropped),
            "ionosphere_measured_rows": int(self.n_ionosphere_measured),
            "ionosphere_fits": _rounded_pairs(self.ionosphere_fits),
            "ionosphere_expected_m": {
                k: [round(a, 3), round(b, 3)] for k, (a, b) in self.ionosphere_expected_m.items()
            },
            "code_variance_factors": dict(self.variance_factors),
            "systems": list(self.systems),
            "rows_without_cn0": int(np.isnan(self.cn0).sum()),
            **self.phase_check,
        }

    @property
    def broadcast_ionosphere(self) -> bool:
        """The first frequency with the broadcast delay: the only mode whose rows keep an ionosphere
        error that slant-ionosphere states (``estimate_iono``) are there to take up."""
        return not self.ionosphere_free and self.ionosphere == IonosphereMode.broadcast

    @property
    def has_phase(self) -> np.ndarray:
        """bool, (N,): rows that carry a usable carrier phase (``phase`` finite, ``arc >= 0``)."""
        return self.arc >= 0

    def previous_rows(self) -> np.ndarray:
        """int, (N,): the previous row of each row's phase arc in epoch order; -1 at an arc's first row
        and on rows without phase (which belong to no arc)."""
        phase_rows = np.flatnonzero(self.has_phase)
        order = phase_rows[np.lexsort((self.epoch[phase_rows], self.arc[phase_rows]))]
        same = self.arc[order][1:] == self.arc[order][:-1]
        prev = np.full(self.n_obs, -1, np.int64)
        prev[order[1:][same]] = order[:-1][same]
        return prev

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

    @property
    def row_epoch(self) -> np.ndarray:
        """int, (N,): solved-epoch index 0..n_epochs-1 of each row."""
        return np.repeat(np.arange(self.n_epochs), self.epoch_stop - self.epoch_start)

    def single_point(self, **solver: Any) -> SppSolution:
        """Code-only single-point fix of every solved epoch on these rows, weights and clocks.

        :func:`~simbench.gnss.spp.solve_epochs` with this table's rows, code sigmas, one clock per
        system and the troposphere at ``el``/``doy``; ``solver`` adds or replaces its keywords
        (e.g. ``huber_k``, ``max_rms_m``, or ``system_index=None`` for one clock).
        """
        kwargs: dict[str, Any] = {
            "n_epochs": self.n_epochs,
            "sigma": self.sigma_code,
            "system_index": self.system_index,
            "el": self.el,
            "doy": self.doy,
        }
        return solve_epochs(self.row_epoch, self.sat_pos, self.code, **{**kwargs, **solver})

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
    ionosphere: IonosphereMode = IonosphereMode.auto,
    code_sigma_m: float,
    phase_sigma_m: float,
    elevation_mask_deg: float,
    min_satellites: int = 4,
    max_gap_epochs: int = 1,
    measurements: MeasurementMode = MeasurementMode.code_phase,
    sigma_model: SigmaModel = SigmaModel.elevation,
    cn0_ref_dbhz: float = 45.0,
    doppler_slip_m: float = 0.0,
    variance_components: VarianceComponents = VarianceComponents.none,
) -> PppObservations:
    """Select, correct and weight the observations for PPP.

    Rows with missing values in the columns used, or below the elevation mask,
    are dropped; then epochs with fewer than ``min_satellites`` rows. Phase
    arcs are identified on all rows with a valid phase (before the mask and
    the epoch selection: a satellite that dips under the mask while the
    receiver keeps lock keeps its arc); a row without phase ends its
    satellite's arc. Each arc's code minus phase is then held to what the
    ionosphere can do (:func:`checked_arcs`): an arc is broken at a jump, and
    the phase of an arc, or of every row when code and phase run on different
    clocks, is dropped where it drifts faster, with one warning (``phase_check``).

    Parameters
    ----------
    data : ReceiverData
    ionosphere : IonosphereMode
        How the delay leaves the code and phase (:class:`IonosphereMode`). ``free`` combines each
        row's two frequencies ``(gamma P1 - P2) / (gamma - 1)``, ``gamma = f1_f2_ratio**2``, the
        satellite clock moved to the combination's reference with the optional
        :data:`SAT_DCB_COLUMN`, and drops rows without a second frequency
        (``n_single_frequency_dropped``); under ``auto`` a system whose pairs lose to the broadcast
        model (:func:`pair_against_broadcast`) keeps the broadcast delay, in one warning line. The
        decision is the result's ``ionosphere``, the expected errors its ``ionosphere_expected_m``.
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
        ``code_phase`` (default) drops rows without carrier phase (or whose phase
        the check dropped); ``auto`` keeps them as code-only rows (real receivers
        often report code without phase); ``code`` ignores the phase everywhere.
        A code-only row has ``phase`` NaN and ``arc`` -1.
    sigma_model, cn0_ref_dbhz : SigmaModel, float
        How the sigmas follow elevation and C/N0 (:func:`sigma_factor`).
    variance_components : VarianceComponents
        Scale each row's code sigma by a factor estimated from the log
        (:func:`variance_factors`); ``none`` keeps the a-priori sigmas.

    Raises
    ------
    SimbenchError
        Missing columns, ``ionosphere=free`` on data without a second frequency,
        bad sigmas, or no epoch with enough satellites.
    """
    _check_prepare_inputs(data.observations, ionosphere, code_sigma_m, phase_sigma_m, min_satellites)
    weighting = _Weighting(code_sigma_m, sigma_model, cn0_ref_dbhz)
    picked = _picked_rows(
        data, ionosphere, measurements, weighting, elevation_mask_deg, min_satellites, max_gap_epochs, doppler_slip_m
    )
    rows = _Rows.of(data, picked, weighting)
    _say_missing_cn0(rows.cn0, sigma_model, variance_components, id(data.observations))
    corrected = _without_ionosphere(data, picked, rows, ionosphere)
    sigma_code, factors = _scaled_code_sigmas(
        variance_components,
        code_sigma_m * rows.sigma_scale,
        rows.sats.systems,
        rows.sats.system_index,
        rows.cn0,
        rows.epoch_stop - rows.epoch_start,
        rows.sat_pos,
        corrected.code,
        picked.el,
        rows.doy,
    )
    return _observations(data, picked, rows, corrected, sigma_code, phase_sigma_m * rows.sigma_scale, factors)


@dataclass(frozen=True)
class _Weighting:
    """The a-priori code sigma [m] and how it follows elevation and C/N0 (:func:`sigma_factor`)."""

    code_sigma_m: float
    sigma_model: SigmaModel
    cn0_ref_dbhz: float

    def factor(self, el_rad: np.ndarray, cn0: np.ndarray) -> np.ndarray:
        """Each row's sigma factor."""
        return sigma_factor(el_rad, cn0, self.sigma_model, self.cn0_ref_dbhz)


@dataclass
class _Picked:
    """The rows :func:`prepare_ppp` keeps (sorted by epoch and satellite), their phase arcs and the
    ionosphere decision (:func:`_ionosphere_decision`)."""

    sub: pd.DataFrame
    sat: np.ndarray
    epoch: np.ndarray
    el: np.ndarray  #: [rad]
    arc: np.ndarray
    choice: IonosphereMode
    expected: dict[str, tuple[float, float]]
    declined: set[str]
    n_dropped: int  #: rows without the second frequency ``free`` needs
    checked: CodePhaseCheck


def _picked_rows(
    data: ReceiverData,
    ionosphere: IonosphereMode,
    measurements: MeasurementMode,
    weighting: _Weighting,
    elevation_mask_deg: float,
    min_satellites: int,
    max_gap_epochs: int,
    doppler_slip_m: float,
) -> _Picked:
    """Select: the rows with every value used, above the mask, in epochs with enough satellites, their
    phase arcs identified and checked (:func:`checked_arcs`), and the ionosphere decision."""
    obs = data.observations
    require_phase = measurements == MeasurementMode.code_phase
    if require_phase and len(obs) and not np.isfinite(obs["phase_l1"].to_numpy(float)).any():
        raise SimbenchError(
            "observations",
            "carry no carrier phase (e.g. a libRSF pseudorange log)",
            "set the estimator's measurements=auto or measurements=code",
        )
    valid = np.isfinite(obs[list(_CODE_COLUMNS)].to_numpy(float)).all(axis=1)
    second = _second_frequency(obs)
    above = obs["el"].to_numpy(float) > elevation_mask_deg
    choice, expected, declined = _ionosphere_decision(
        data,
        ionosphere,
        valid & above,
        elevation_mask_deg,
        weighting.code_sigma_m,
        weighting.sigma_model,
        weighting.cn0_ref_dbhz,
    )
    free = choice == IonosphereMode.free
    n_dropped = int((valid & above & ~second).sum()) if free else 0
    if free:
        valid &= second
    phase_cols = ["phase_l1"] + (["phase_l2"] if free else [])
    with_phase = np.isfinite(obs[phase_cols].to_numpy(float)).all(axis=1) & (measurements != MeasurementMode.code)
    if require_phase:
        valid &= with_phase
    obs = obs.loc[valid]
    with_phase = with_phase[valid]
    arc = np.full(len(obs), -1, np.int64)
    arc[with_phase] = arc_ids(obs.loc[with_phase], max_gap_epochs, use_l2=free, doppler_slip_m=doppler_slip_m)
    sigma = weighting.code_sigma_m * weighting.factor(obs["el"].to_numpy(float) * DEG, _cn0(obs))
    checked = checked_arcs(obs, arc, sigma, free=free, origin=id(data.observations))
    arc = checked.arc
    if require_phase:
        obs, arc = obs.loc[arc >= 0], arc[arc >= 0]
    sub, sat, epoch, el, arc = _selected_rows(obs, arc, elevation_mask_deg, min_satellites)
    return _Picked(sub, sat, epoch, el, arc, choice, expected, declined, n_dropped, checked)


@dataclass(frozen=True)
class _Satellites:
    """The satellites of the rows and their systems."""

    names: np.ndarray  #: str, the satellites, sorted
    index: np.ndarray  #: int, per row: index into ``names``
    systems: tuple[str, ...]  #: RINEX letters, GPS first
    system_index: np.ndarray  #: int, per row: index into ``systems``

    @classmethod
    def of(cls, sat: np.ndarray) -> _Satellites:
        """From each row's satellite id."""
        names, index = np.unique(sat, return_inverse=True)
        letters = np.array([str(s)[:1] for s in names])
        systems = tuple(sorted(set(letters.tolist()), key=lambda c: (c != "G", c)))
        return cls(names, index, systems, np.array([systems.index(c) for c in letters], np.int64)[index])


@dataclass
class _Rows:
    """What :func:`prepare_ppp` reads off the picked rows: times, geometry, weights, systems, epochs."""

    t: np.ndarray  #: [s]
    az: np.ndarray  #: [rad]
    sat_pos: np.ndarray  #: (n, 3) ECEF [m]
    range_rate: np.ndarray  #: [m/s]
    sat_vel: np.ndarray  #: (n, 3) [m/s]
    doy: float
    cn0: np.ndarray  #: [dB-Hz]
    sigma_scale: np.ndarray
    sats: _Satellites
    epoch_ids: np.ndarray
    epoch_start: np.ndarray
    epoch_stop: np.ndarray

    @classmethod
    def of(cls, data: ReceiverData, picked: _Picked, weighting: _Weighting) -> _Rows:
        """The rows of ``picked``, weighted by ``weighting``."""
        sub = picked.sub
        range_rate, sat_vel = _range_rates(sub)
        epoch_ids, epoch_start, n_per = np.unique(picked.epoch, return_index=True, return_counts=True)
        cn0 = _cn0(sub)
        return cls(
            t=sub["t"].to_numpy(float),
            az=sub["az"].to_numpy(float) * DEG,
            sat_pos=sub[["sat_x", "sat_y", "sat_z"]].to_numpy(float),
            range_rate=range_rate,
            sat_vel=sat_vel,
            doy=day_of_year(data.nav.gps_week, data.nav.start_sow_s),
            cn0=cn0,
            sigma_scale=weighting.factor(picked.el, cn0),
            sats=_Satellites.of(picked.sat),
            epoch_ids=epoch_ids,
            epoch_start=epoch_start,
            epoch_stop=epoch_start + n_per,
        )


@dataclass
class _Corrected:
    """Code and phase [m] with the ionospheric delay removed, the arcs that keep their phase, and the
    mode that did it."""

    code: np.ndarray
    phase: np.ndarray
    arc: np.ndarray
    choice: IonosphereMode
    n_measured: int = 0
    fits: dict[str, Any] = field(default_factory=dict)


def _without_ionosphere(data: ReceiverData, picked: _Picked, rows: _Rows, ionosphere: IonosphereMode) -> _Corrected:
    """Correct: the combination's code and phase (``free``), or the first frequency's less the broadcast or
    measured delay."""
    free = picked.choice == IonosphereMode.free
    code, phase = _ranges(picked.sub, free, picked.arc)
    out = _Corrected(code, phase, picked.arc.copy(), picked.choice)
    if free or data.nav.iono_corrected:
        return out
    rough = _rough_positions(
        rows.sat_pos,
        code,
        rows.sigma_scale,
        picked.el,
        rows.doy,
        rows.t,
        rows.epoch_start,
        rows.epoch_stop,
        rows.sats.system_index,
    )
    iono = _klobuchar_delay(data.nav, rows.t, rough, picked.el, rows.az, picked.sat)
    if out.choice == IonosphereMode.measured:
        found, stretch = _measured_delays(picked.sub, iono, picked.sat, rows.t, picked.declined)
        if not found.fits and ionosphere == IonosphereMode.auto:
            # no system's second frequency measures the delay better than the broadcast model
            out.choice = IonosphereMode.broadcast
        else:
            iono, out.n_measured, out.fits = found.delay_m, int(found.measured.sum()), found.fits
            # a carrier phase takes the delay's changes at its millimetre weight: it is kept where
            # the delay is levelled (a stretch is then an arc) and nowhere else, since there are no
            # slant-ionosphere states in this mode to take up a modelled delay's drift
            out.arc = split_arcs(np.where((stretch >= 0) & found.measured, out.arc, -1), stretch)
            out.phase = np.where(out.arc >= 0, out.phase, np.nan)
    out.code = out.code - iono
    out.phase = out.phase + iono
    return out


def _observations(
    data: ReceiverData,
    picked: _Picked,
    rows: _Rows,
    corrected: _Corrected,
    sigma_code: np.ndarray,
    sigma_phase: np.ndarray,
    factors: dict[str, float],
) -> PppObservations:
    """Output: the :class:`PppObservations`, arcs renumbered in order of their start."""
    arc = corrected.arc
    _, renumbered = np.unique(arc[arc >= 0], return_inverse=True)  # monotone: keeps the start order
    arc[arc >= 0] = renumbered
    epoch_t = rows.t[rows.epoch_start]
    return PppObservations(
        epoch=picked.epoch,
        t=rows.t,
        sat=picked.sat,
        sat_index=rows.sats.index.astype(np.int64),
        sat_pos=rows.sat_pos,
        code=corrected.code,
        phase=corrected.phase,
        el=picked.el,
        az=rows.az,
        arc=arc.astype(np.int64),
        sigma_code=sigma_code,
        sigma_phase=sigma_phase,
        sigma_scale=rows.sigma_scale,
        cn0=rows.cn0,
        epoch_ids=rows.epoch_ids,
        epoch_t=epoch_t,
        epoch_start=rows.epoch_start,
        epoch_stop=rows.epoch_stop,
        sat_names=tuple(str(s) for s in rows.sats.names),
        n_arcs=int(arc.max(initial=-1)) + 1,
        ionosphere_free=picked.choice == IonosphereMode.free,
        ionosphere=corrected.choice,
        n_ionosphere_measured=corrected.n_measured,
        ionosphere_fits=corrected.fits,
        ionosphere_expected_m=picked.expected,
        doy=rows.doy,
        systems=rows.sats.systems,
        system_index=rows.sats.system_index,
        range_rate=rows.range_rate,
        sat_vel=rows.sat_vel,
        odometry=_odometry_per_epoch(data.odometry, epoch_t) if len(data.odometry) else None,
        n_single_frequency_dropped=picked.n_dropped,
        variance_factors=factors,
        phase_check=_phase_check_info(picked.checked),
    )


def _check_prepare_inputs(
    obs: pd.DataFrame, ionosphere: IonosphereMode, code_sigma_m: float, phase_sigma_m: float, min_satellites: int
) -> None:
    """:func:`prepare_ppp`'s one-line refusals of its inputs: missing columns, sigmas, ``min_satellites``."""
    missing = [c for c in _REQUIRED if c not in obs.columns]
    if ionosphere == IonosphereMode.free:
        missing += [c for c in _REQUIRED_L2 if c not in obs.columns]
    if missing:
        raise SimbenchError(
            "observations",
            f"missing columns {missing}",
            "give an observation table with the columns of simbench.contract.OBSERVATION_COLUMNS",
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


def _ionosphere_decision(
    data: ReceiverData,
    ionosphere: IonosphereMode,
    usable: np.ndarray,
    elevation_mask_deg: float,
    code_sigma_m: float,
    sigma_model: SigmaModel,
    cn0_ref_dbhz: float,
) -> tuple[IonosphereMode, dict[str, tuple[float, float]], set[str]]:
    """The ionosphere mode for these data (:func:`ionosphere_choice`); under ``auto``, the expected errors of
    each system's code pairs against the broadcast model (:func:`pair_against_broadcast`) and the systems
    that keep the broadcast delay. ``usable``: rows with every code column, above the mask."""
    choice = ionosphere_choice(data.observations, ionosphere, elevation_mask_deg)
    expected: dict[str, tuple[float, float]] = {}
    declined: set[str] = set()
    if ionosphere == IonosphereMode.auto and choice != IonosphereMode.broadcast:
        expected = pair_against_broadcast(data, usable, code_sigma_m, sigma_model, cn0_ref_dbhz)
        declined = {s for s, (pairs, broadcast) in expected.items() if not pairs < broadcast}
        choice = _without_declined(choice, expected, declined, id(data.observations))
    return choice, expected, declined


def _selected_rows(
    obs: pd.DataFrame, arc: np.ndarray, elevation_mask_deg: float, min_satellites: int
) -> tuple[pd.DataFrame, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The rows above the mask in epochs of at least ``min_satellites`` of them, sorted by epoch and
    satellite: the table, and its satellites, epochs, elevations [rad] and arcs."""
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
    sub = obs.iloc[np.flatnonzero(keep)[order]]
    return sub, sat[order], epoch[order], el[keep][order], arc[keep][order]


def _range_rates(sub: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Each row's measured range rate ``-lambda D`` plus the satellite clock drift [m/s] and the satellite
    velocity [m/s] (NaN without a Doppler or a satellite velocity)."""
    range_rate = np.full(len(sub), np.nan)
    sat_vel = np.full((len(sub), 3), np.nan)
    if {"doppler_l1", "sat_vx", "sat_vy", "sat_vz", "sat_clock_drift"} <= set(sub.columns):
        sat_vel = sub[["sat_vx", "sat_vy", "sat_vz"]].to_numpy(float)
        range_rate = -l1_wavelength_m(sub["sat"].to_numpy()) * sub["doppler_l1"].to_numpy(float) + sub[
            "sat_clock_drift"
        ].to_numpy(float)
        range_rate[~np.isfinite(sat_vel).all(axis=1)] = np.nan
    return range_rate, sat_vel


def _ranges(sub: pd.DataFrame, free: bool, arc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Code and phase [m] with the satellite clock added: the first frequency, or the ionosphere-free
    combination (``free``); phase NaN outside an arc."""
    sat_clock = sub["sat_clock"].to_numpy(float)
    if free:
        gamma = sub["f1_f2_ratio"].to_numpy(float) ** 2
        # sat_clock is the first frequency's single-frequency clock (group delay removed); the
        # combination needs the clock of the broadcast reference: + dcb / (gamma - 1)
        sat_clock = sat_clock + _sat_dcb(sub) / (gamma - 1.0)
        code = if_combination(sub["code_l1"].to_numpy(float), sub["code_l2"].to_numpy(float), gamma) + sat_clock
        phase = if_combination(sub["phase_l1"].to_numpy(float), sub["phase_l2"].to_numpy(float), gamma) + sat_clock
    else:
        code = sub["code_l1"].to_numpy(float) + sat_clock
        phase = sub["phase_l1"].to_numpy(float) + sat_clock
    return code, np.where(arc >= 0, phase, np.nan)


def _measured_delays(
    sub: pd.DataFrame, broadcast_m: np.ndarray, sat: np.ndarray, t: np.ndarray, declined: set[str]
) -> tuple[MeasuredIonosphere, np.ndarray]:
    """Each row's delay measured by its code pair, levelled by its phase pair, and the broadcast delay
    ``broadcast_m`` fitted to those elsewhere (:func:`simbench.gnss.measured_ionosphere.measured_ionosphere`,
    ``declined`` systems left out); and each row's levelled stretch."""
    pair = _second_frequency(sub)
    gamma = sub["f1_f2_ratio"].to_numpy(float) ** 2
    gf = geometry_free_delay(sub["code_l1"].to_numpy(float), sub["code_l2"].to_numpy(float), gamma, _sat_dcb(sub))
    # a table may carry a second code without its phase (the contract's L2 phase columns are optional here)
    phase_l2 = sub["phase_l2"].to_numpy(float) if "phase_l2" in sub.columns else np.nan
    phase_pair = (sub["phase_l1"].to_numpy(float) - phase_l2) / (gamma - 1.0)
    lost = sub["lli_l1"].fillna(False).to_numpy(bool)
    if "lli_l2" in sub.columns:
        lost = lost | sub["lli_l2"].fillna(False).to_numpy(bool)
    code_pair = np.where(pair, gf, np.nan)
    levelled, stretch = levelled_phase_delay(code_pair, np.where(pair, phase_pair, np.nan), sat, t, lost)
    found = measured_ionosphere(
        broadcast_m, code_pair, sat, t, levelled_m=levelled, stretch=stretch, exclude=tuple(sorted(declined))
    )
    return found, stretch


def _scaled_code_sigmas(
    variance_components: VarianceComponents,
    sigma_code: np.ndarray,
    systems: tuple[str, ...],
    system_index: np.ndarray,
    cn0: np.ndarray,
    n_per: np.ndarray,
    sat_pos: np.ndarray,
    code: np.ndarray,
    el: np.ndarray,
    doy: float,
) -> tuple[np.ndarray, dict[str, float]]:
    """Each row's code sigma scaled by its group's factor estimated from the log (:func:`variance_factors`),
    and the factors by group name; ``none`` keeps the a-priori sigmas."""
    if variance_components == VarianceComponents.none:
        return sigma_code, {}
    group, names = _variance_groups(variance_components, systems, system_index, cn0)
    k = np.repeat(np.arange(len(n_per)), n_per)
    per_group = variance_factors(k, sat_pos, code, sigma_code, group, system_index=system_index, el=el, doy=doy)
    factors = {name: round(float(f), 3) for name, f in zip(names, per_group) if name}
    return sigma_code * per_group[group], factors


def _rounded_pairs(pairs: dict[str, tuple[float, float]]) -> dict[str, list[float]]:
    """``{key: (a, b)}`` as JSON lists to the millimetre."""
    return {k: [round(a, 3), round(b, 3)] for k, (a, b) in pairs.items()}


def if_combination(first: np.ndarray, second: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """Ionosphere-free combination ``(gamma first - second) / (gamma - 1)`` of two frequencies.

    Parameters
    ----------
    first, second : ndarray
        The same observable (code or phase) on the first and second carrier [m].
    gamma : ndarray
        ``(f1 / f2)**2`` per row (the contract's ``f1_f2_ratio`` squared).

    Returns
    -------
    ndarray
        The combination [m]: a delay proportional to ``1 / f**2`` cancels.
    """
    return (gamma * first - second) / (gamma - 1.0)


def klobuchar_scale(sat: np.ndarray) -> np.ndarray:
    """Factor ``(f_L1 / f)**2`` that carries the GPS-L1 Klobuchar delay to each row's first carrier.

    Parameters
    ----------
    sat : array of str
        Satellite ids ('G05', 'C11', 'R07', ...).

    Returns
    -------
    ndarray
        1 for GPS, Galileo and QZSS (1575.42 MHz), 1.018 for BeiDou B1I; GLONASS at its
        nominal 1602 MHz (the channel offsets change the factor by under 0.6 %).
    """
    carrier = {**L1_FREQUENCY_HZ, "R": _F_GLONASS_L1_NOMINAL_HZ}
    freq = np.array([carrier.get(str(s)[:1], F_L1) for s in np.asarray(sat).tolist()], float)
    return (F_L1 / freq) ** 2


def variance_factors(
    epoch: np.ndarray,
    sat_pos: np.ndarray,
    code: np.ndarray,
    sigma: np.ndarray,
    group: np.ndarray,
    *,
    system_index: np.ndarray,
    el: np.ndarray,
    doy: float,
    iterations: int = _VC_ITERATIONS,
) -> np.ndarray:
    """Robust variance components of the code: one factor on the sigma per group of rows.

    Each iteration solves every epoch by Huber-weighted single-point positioning
    (:func:`~simbench.gnss.spp.solve_epochs`) with the current sigmas and multiplies the
    group's factor by ``sqrt(sum(v^2 / sigma^2) / sum(r))`` over its rows (Helmert's
    estimate with the redundancy numbers ``r``; each squared normalised residual capped
    at ``VC_CLIP**2 r``, so a blunder of kilometres counts as 10 sigma, not more). A
    mean square rather than a robust spread (MAD): the a-priori sigmas of a street log
    describe its reflected rows too (the C/N0 model on the Hong Kong log: about 1.0,
    while ``1.4826 median |z|`` is 0.3-0.4), so the factor stays near 1 where the model
    fits and follows the receiver where it does not (a geodetic receiver: 0.3-0.8;
    GLONASS with its inter-frequency biases: 2; the ionosphere-free combination under a
    sigma calibrated for one frequency: 2.5-3). A group with fewer than :data:`VC_MIN_ROWS`
    usable rows, or less redundancy than :data:`VC_MIN_REDUNDANCY` (epochs of four satellites
    and one clock have none), keeps its factor of 1 before the normalisation.

    The factors are relative: divided by their geometric mean over the rows, so they move
    weight between groups and leave the overall scale to the a-priori model. The absolute
    scale, tried on the tuning data, hurt where a log's reflected rows dominate it: in
    simulated ``urban`` (one system, factor 1.95) batch L2's median went from 1.8 to 3.2 m
    and DCS's from 1.8 to 2.7 m (seed 1000), because the robust estimators' inlier model
    widens with it; a robust spread instead (MAD, 0.3-0.4 on the Hong Kong log) narrowed
    it and doubled DCS's p95 there.

    Parameters
    ----------
    epoch : ndarray of int, shape (N,)
        Epoch index 0..n-1 of each row.
    sat_pos, code : ndarray
        Satellite positions (N, 3) and corrected code (N,) [m].
    sigma : ndarray, shape (N,)
        A-priori code sigmas [m].
    group : ndarray of int, shape (N,)
        Group 0..G-1 of each row.
    system_index, el, doy : ndarray, ndarray, float
        Per-row system (one clock each) and elevation [rad], day of year (troposphere).
    iterations : int
        Solve-and-rescale rounds.

    Returns
    -------
    ndarray, shape (G,)
        Factor per group on the code sigma (dimensionless), geometric mean over the rows 1.
    """
    key = content_digest(epoch, sat_pos, code, sigma, group, system_index, el, np.array([doy, iterations], float))
    if key in _VC_CACHE:
        return _VC_CACHE[key].copy()
    n_groups = int(group.max(initial=-1)) + 1
    factor = np.ones(n_groups)
    start = None
    for _ in range(iterations):
        sol = solve_epochs(
            epoch,
            sat_pos,
            code,
            sigma=sigma * factor[group],
            system_index=system_index,
            el=el,
            doy=doy,
            x0=start,
            huber_k=_HUBER_K,
        )
        start = np.nan_to_num(sol.pos)  # the next round starts where this one ended
        usable = np.isfinite(sol.residual_m)
        # Helmert: sum of squared normalised residuals over the sum of redundancy numbers
        square = (sol.residual_m[usable] / (sigma * factor[group])[usable]) ** 2
        # an epoch without redundancy gives r = 1 - leverage of +-1e-16 by rounding; a group made
        # of such epochs once divided one rounding error by another (a negative ratio, every sigma
        # NaN: urban seed 3's first 40 s, four satellites or fewer per epoch)
        r = np.clip(sol.redundancy[usable], 0.0, 1.0)
        for g in range(n_groups):
            mine = group[usable] == g
            if mine.sum() >= VC_MIN_ROWS and r[mine].sum() >= VC_MIN_REDUNDANCY:
                ratio = np.sum(np.minimum(square[mine], VC_CLIP**2 * r[mine])) / np.sum(r[mine])
                factor[g] *= float(np.sqrt(ratio))
    # relative: the overall scale stays the a-priori model's (its row-weighted geometric mean 1)
    factor /= np.exp(np.mean(np.log(factor[group])))
    if len(_VC_CACHE) >= _VC_CACHE_SIZE:
        del _VC_CACHE[next(iter(_VC_CACHE))]
    _VC_CACHE[key] = factor.copy()
    return factor


#: :func:`variance_factors` of the last few inputs: every GNSS estimator of a job prepares the same
#: rows, and one estimate costs ~10 s on the Hong Kong log
_VC_CACHE: dict[str, np.ndarray] = {}
_VC_CACHE_SIZE = 8
#: warnings :func:`_warn_once` issued (table, field, problem, consequence), the last few
_WARNED: set[str] = set()
_WARNED_SIZE = 64


def content_digest(*arrays: np.ndarray) -> str:
    """Content hash of arrays (dtype, shape and bytes): the key of a cache of results computed from them."""
    h = hashlib.blake2b(digest_size=20)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _variance_groups(
    mode: VarianceComponents, systems: tuple[str, ...], system_index: np.ndarray, cn0: np.ndarray
) -> tuple[np.ndarray, list[str]]:
    """Group of each row for :func:`variance_factors` and the groups' names ('G', 'G 40-45 dB-Hz')."""
    if mode == VarianceComponents.system:
        return system_index, list(systems)
    cn0_bin = np.where(np.isfinite(cn0), np.floor(np.nan_to_num(cn0) / _CN0_BIN_DBHZ), -1).astype(np.int64)
    keys, group = np.unique(np.stack([system_index, cn0_bin]), axis=1, return_inverse=True)
    names = [
        f"{systems[s]} {b * _CN0_BIN_DBHZ:.0f}-{(b + 1) * _CN0_BIN_DBHZ:.0f} dB-Hz" if b >= 0 else f"{systems[s]}"
        for s, b in keys.T.tolist()
    ]
    return group.reshape(-1), names


def ionosphere_choice(obs: pd.DataFrame, mode: IonosphereMode, elevation_mask_deg: float) -> IonosphereMode:
    """What the ``ionosphere`` choice resolves to on these rows: ``free``, ``measured`` or ``broadcast``.

    Parameters
    ----------
    obs : pandas.DataFrame
        Observation table (:mod:`simbench.contract`).
    mode : IonosphereMode
        ``broadcast``: always; ``free`` and ``measured``: always (an error without any second
        frequency); ``auto``: ``free`` when every satellite above the mask has a second frequency on
        at least :data:`AUTO_FREE_MIN_FRACTION` of its rows, ``measured`` when some rows have one,
        else ``broadcast`` (:func:`prepare_ppp` may still turn ``free`` into ``measured`` and either
        into ``broadcast`` where a system's pairs are expected to do worse than the broadcast model,
        :func:`pair_against_broadcast`, or measure the delay less well).
    elevation_mask_deg : float
        Rows at or below this elevation [deg], and rows without a usable code, do not count.

    Returns
    -------
    IonosphereMode
    """
    used = np.isfinite(obs[list(_CODE_COLUMNS)].to_numpy(float)).all(axis=1)
    used &= obs["el"].to_numpy(float) > elevation_mask_deg
    return _decide_ionosphere(mode, obs["sat"].to_numpy()[used], _second_frequency(obs)[used])


def ionosphere_free(obs: pd.DataFrame, mode: IonosphereMode, elevation_mask_deg: float) -> bool:
    """Whether the ``ionosphere`` choice forms the ionosphere-free combination on these rows
    (:func:`ionosphere_choice` is ``free``).

    The decision :func:`prepare_ppp` takes, for estimators that hand the rows to another
    program (RTKLIB) and must choose the same way.
    """
    return ionosphere_choice(obs, mode, elevation_mask_deg) == IonosphereMode.free


def pair_against_broadcast(
    data: ReceiverData, rows: np.ndarray, code_sigma_m: float, sigma_model: SigmaModel, cn0_ref_dbhz: float
) -> dict[str, tuple[float, float]]:
    """Per system: the position error expected from its code pairs against that from the broadcast model [m].

    A code pair removes the ionosphere but leaves on each satellite's ionosphere-free code, and on the
    delay it measures, the part of its group-delay difference that no broadcast message gives,
    ``sat_dcb_sigma / (gamma - 1)`` (:data:`SAT_DCB_SIGMA_COLUMN`; a C/A code against the P(Y) code
    that GPS's TGD refers to: 0.34 m / 0.647 = 0.53 m per satellite), independent from satellite to
    satellite. The broadcast (Klobuchar) model leaves about half of the delay
    (:data:`~simbench.gnss.measured_ionosphere.BROADCAST_RELATIVE_ERROR`), an error with the model's own
    shape, so that much of it goes into the receiver clock. Both are carried to the position of a
    weighted single-point fix of every epoch at a rough position
    (:func:`simbench.gnss.spp.position_gains`): ``sqrt(mean_k sum_r |g_r|^2 s_r^2)`` for the pairs,
    ``sqrt(mean_k |sum_r g_r K_r / 2|^2)`` for the broadcast model, over the system's rows with a pair.

    Parameters
    ----------
    data : ReceiverData
    rows : ndarray of bool, shape (len(data.observations),)
        Rows used (a finite code above the mask).
    code_sigma_m, sigma_model, cn0_ref_dbhz
        The sigma model (:func:`sigma_factor`), for the weights.

    Returns
    -------
    dict
        ``{system: (pairs, broadcast)}`` for every system with a row with a code pair; empty without
        :data:`SAT_DCB_SIGMA_COLUMN`, or when the observations have no ionosphere left to remove.
    """
    obs = data.observations.loc[rows]
    if SAT_DCB_SIGMA_COLUMN not in obs.columns or data.nav.iono_corrected or not len(obs):
        return {}
    obs = obs.iloc[np.lexsort((obs["sat"].to_numpy(), obs["epoch"].to_numpy()))]
    epoch_ids, start, n_per = np.unique(obs["epoch"].to_numpy(np.int64), return_index=True, return_counts=True)
    k = np.repeat(np.arange(len(epoch_ids)), n_per)
    sat = obs["sat"].to_numpy().astype(str)
    letters = np.array([s[:1] for s in sat.tolist()])
    systems, system_index = np.unique(letters, return_inverse=True)
    el, az = obs["el"].to_numpy(float) * DEG, obs["az"].to_numpy(float) * DEG
    sat_pos, t = obs[["sat_x", "sat_y", "sat_z"]].to_numpy(float), obs["t"].to_numpy(float)
    sigma = code_sigma_m * sigma_factor(el, _cn0(obs), sigma_model, cn0_ref_dbhz)
    code = obs["code_l1"].to_numpy(float) + obs["sat_clock"].to_numpy(float)
    doy = day_of_year(data.nav.gps_week, data.nav.start_sow_s)
    rough = _rough_positions(sat_pos, code, sigma, el, doy, t, start, start + n_per, system_index)
    broadcast = BROADCAST_RELATIVE_ERROR * _klobuchar_delay(data.nav, t, rough, el, az, sat)
    gains = position_gains(k, sat_pos, rough, sigma, system_index)
    pair = _second_frequency(obs) & np.isfinite(obs[SAT_DCB_SIGMA_COLUMN].to_numpy(float))
    bias = obs[SAT_DCB_SIGMA_COLUMN].to_numpy(float) / (obs["f1_f2_ratio"].to_numpy(float) ** 2 - 1.0)
    out = {}
    for s, letter in enumerate(systems.tolist()):
        mine = pair & (system_index == s) & np.isfinite(gains).all(axis=1)
        if not mine.any():
            continue
        spread = np.bincount(k[mine], (gains[mine] ** 2).sum(axis=1) * bias[mine] ** 2, len(epoch_ids))
        shift = np.stack([np.bincount(k[mine], gains[mine, i] * broadcast[mine], len(epoch_ids)) for i in range(3)])
        epochs = np.bincount(k[mine], minlength=len(epoch_ids)) > 0
        out[letter] = (
            float(np.sqrt(np.mean(spread[epochs]))),
            float(np.sqrt(np.mean((shift[:, epochs] ** 2).sum(axis=0)))),
        )
    return out


def _without_declined(
    choice: IonosphereMode, expected: dict[str, tuple[float, float]], declined: set[str], origin: int
) -> IonosphereMode:
    """``auto``'s choice once the systems whose pairs are expected to do worse than the broadcast model keep it:
    ``broadcast`` when that is every system with pairs, ``measured`` (which keeps the broadcast delay per
    system) when it is some, the choice as it was when none; said in one warning line."""
    if not declined:
        return choice
    numbers = ", ".join(f"{s} {expected[s][0]:.2f} m against {expected[s][1]:.2f} m" for s in sorted(declined))
    if declined >= set(expected):
        choice = IonosphereMode.broadcast
        consequence = "every system uses its first frequency with the broadcast delay"
    else:
        choice = IonosphereMode.measured
        consequence = f"{', '.join(sorted(declined))} keep the broadcast delay; the other systems measure it"
    _warn_once(
        f"{origin}:ionosphere:{numbers}",
        "gnss_model.ionosphere",
        "auto: the code pairs' unbroadcast group delays are expected to move the position more than the "
        f"broadcast model's error does ({numbers})",
        consequence,
    )
    return choice


def _klobuchar_delay(
    nav: NavInfo, t: np.ndarray, rx_pos: np.ndarray, el: np.ndarray, az: np.ndarray, sat: np.ndarray
) -> np.ndarray:
    """Broadcast (Klobuchar) slant delay on each row's first carrier [m] at receiver positions ``rx_pos``."""
    lat, lon, _ = geodetic_from_ecef(rx_pos)
    return atmosphere.klobuchar_l1_delay_m(
        nav.start_sow_s + t, lat, lon, el, az, np.asarray(nav.iono_alpha), np.asarray(nav.iono_beta)
    ) * klobuchar_scale(sat)


def _second_frequency(obs: pd.DataFrame) -> np.ndarray:
    """Rows with a usable second-frequency code and a known carrier ratio."""
    if not {"code_l2", "f1_f2_ratio"} <= set(obs.columns):
        return np.zeros(len(obs), bool)
    ratio = obs["f1_f2_ratio"].to_numpy(float)
    return np.isfinite(obs["code_l2"].to_numpy(float)) & np.isfinite(ratio) & (ratio > 1.0)


def _decide_ionosphere(mode: IonosphereMode, sat: np.ndarray, second: np.ndarray) -> IonosphereMode:
    """The ``ionosphere`` choice applied to the rows above the mask (satellite ids, second frequency or not)."""
    mode = IonosphereMode(mode)
    if mode == IonosphereMode.broadcast:
        return mode
    if mode in (IonosphereMode.free, IonosphereMode.measured):
        if not second.any():
            raise SimbenchError(
                "ionosphere",
                f"{mode.value} requested, but no row has a second frequency (code_l2 and f1_f2_ratio)",
                "set gnss_model.ionosphere=auto or broadcast, or simulate with scenario.dual_frequency=true",
            )
        return mode
    if not second.any():
        return IonosphereMode.broadcast
    _, index = np.unique(sat, return_inverse=True)
    share = np.bincount(index, second.astype(float)) / np.bincount(index)
    return IonosphereMode.free if share.min() >= AUTO_FREE_MIN_FRACTION else IonosphereMode.measured


def checked_arcs(
    obs: pd.DataFrame, arc: np.ndarray, sigma: np.ndarray, *, free: bool, origin: int = 0
) -> CodePhaseCheck:
    """``arc`` after :func:`~simbench.gnss.arcs.check_code_phase`, with a one-line warning when it changed any.

    Parameters
    ----------
    obs : pandas.DataFrame
        Observation rows with ``epoch, t, sat, code_l1, phase_l1`` (and ``code_l2, phase_l2,
        f1_f2_ratio`` when ``free``).
    arc : numpy.ndarray of int, shape (len(obs),)
        Phase arc of each row, -1 without phase.
    sigma : numpy.ndarray, shape (len(obs),)
        Code standard deviation of each row [m] (of the combination when ``free``).
    free : bool
        Code minus phase of the ionosphere-free combinations, else of the first frequency.
    origin : int
        Identity of the table the rows come from (``id`` of the receiver's observation table): the
        warning is said once per table, though every estimator of a run prepares it.
    """
    code, phase = obs["code_l1"].to_numpy(float), obs["phase_l1"].to_numpy(float)
    if free:
        gamma = obs["f1_f2_ratio"].to_numpy(float) ** 2
        code = if_combination(code, obs["code_l2"].to_numpy(float), gamma)
        phase = if_combination(phase, obs["phase_l2"].to_numpy(float), gamma)
    epoch, sat, t = obs["epoch"].to_numpy(), obs["sat"].to_numpy(), obs["t"].to_numpy(float)
    found = check_code_phase(arc, epoch, sat, t, code - phase, sigma)
    said = _phase_check_warning(found)
    if said:
        _warn_once(f"{origin}:{content_digest(arc, t, code - phase)}", "observations", *said)
    return found


def _phase_check_warning(found: CodePhaseCheck) -> tuple[str, str] | None:
    """The problem and the consequence :func:`checked_arcs` warns of; None when it changed no arc."""
    bound = f"physics allows {CODE_PHASE_MAX_RATE_MPS} m/s"
    if found.receiver_mismatch:
        return (
            f"code minus phase drifts {found.receiver_rate_mps:+.3g} m/s on all {found.n_arcs_dropped} phase arcs "
            f"({bound}): code and phase on different clocks (a phone's steered code beside its raw phase)",
            f"dropped the phase of all {found.n_rows_dropped} rows; the estimators use the code alone",
        )
    problems, done = [], []
    if found.n_receiver_jumps:
        problems.append(f"jumps on every arc at {found.n_receiver_jumps} epoch{'s' * (found.n_receiver_jumps != 1)}")
        done.append("broke every arc there (a receiver clock jump in the code or the phase alone)")
    if found.n_jumps:
        problems.append(f"jumps {found.n_jumps} time{'s' * (found.n_jumps != 1)} within phase arcs")
        done.append("broke the arcs at the jumps (a new ambiguity after each)")
    if found.n_arcs_dropped:
        problems.append(f"drifts beyond {bound} on {found.n_arcs_dropped} arc{'s' * (found.n_arcs_dropped != 1)}")
        done.append(f"dropped the phase of the drifting arcs ({found.n_rows_dropped} rows)")
    return ("code minus phase " + " and ".join(problems), "; ".join(done)) if problems else None


def _warn_once(table: str, field: str, problem: str, consequence: str) -> None:
    """:func:`simbench.errors.warn` unless this warning was issued for ``table`` (the observation table's
    identity and the rows' content hash): every estimator of a run prepares the same rows, and the run
    should say it once, not once per estimator."""
    key = "\n".join((table, field, problem, consequence))
    if key in _WARNED:
        return
    if len(_WARNED) >= _WARNED_SIZE:
        _WARNED.clear()
    _WARNED.add(key)
    warn(field, problem, consequence)


def split_arcs(arc: np.ndarray, stretch: np.ndarray) -> np.ndarray:
    """``arc`` (rows in epoch order, -1: no phase) cut where ``stretch`` changes, renumbered by start.

    Parameters
    ----------
    arc : ndarray of int, shape (N,)
        Phase arc of each row, -1 without phase.
    stretch : ndarray of int, shape (N,)
        Any label that is constant along an unbroken part of an arc.
    """
    keyed = arc >= 0
    key = np.full(len(arc), -1, np.int64)
    if not keyed.any():
        return key
    _, first, inverse = np.unique(
        np.column_stack([arc, stretch])[keyed], axis=0, return_index=True, return_inverse=True
    )
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    key[keyed] = rank[inverse.ravel()]
    return key


def _say_missing_cn0(cn0: np.ndarray, sigma_model: SigmaModel, variance: VarianceComponents, origin: int) -> None:
    """Warn (once per table ``origin``, :func:`checked_arcs`) when rows without C/N0 fall back in a model
    that weights by C/N0."""
    missing = int(np.isnan(cn0).sum())
    if not missing:
        return
    fallback = {
        SigmaModel.cn0: "their sigmas follow 1/sin(elevation)",
        SigmaModel.elevation_cn0: "their sigmas follow the elevation alone",
    }.get(SigmaModel(sigma_model), "")
    if VarianceComponents(variance) == VarianceComponents.system_cn0:
        fallback += ("; " if fallback else "") + "their code variance group is their system's"
    if fallback:
        key = f"{origin}:{content_digest(np.isnan(cn0))}"
        _warn_once(key, "observations.cn0_l1", f"missing on {missing} of {len(cn0)} rows", fallback)


def _phase_check_info(found: CodePhaseCheck) -> dict[str, Any]:
    """:func:`checked_arcs`' result for :attr:`PppObservations.phase_check` (JSON values)."""
    rate = found.receiver_rate_mps
    return {
        "code_phase_drift_mps": round(rate, 4) if np.isfinite(rate) else None,
        "phase_receiver_mismatch": found.receiver_mismatch,
        "phase_receiver_jumps": found.n_receiver_jumps,
        "phase_jumps": found.n_jumps,
        "phase_arcs_dropped": found.n_arcs_dropped,
        "phase_rows_dropped": found.n_rows_dropped,
    }


def _cn0(obs: pd.DataFrame) -> np.ndarray:
    """Each row's L1 C/N0 [dB-Hz] (NaN where the receiver reports none)."""
    return obs["cn0_l1"].to_numpy(float) if "cn0_l1" in obs.columns else np.full(len(obs), np.nan)


def _sat_dcb(obs: pd.DataFrame) -> np.ndarray | float:
    """Each row's :data:`SAT_DCB_COLUMN` [m] (0 where NaN or absent)."""
    return np.nan_to_num(obs[SAT_DCB_COLUMN].to_numpy(float)) if SAT_DCB_COLUMN in obs.columns else 0.0


#: The odometry columns the GNSS estimators use, in the order of :attr:`PppObservations.odometry`.
EPOCH_ODOMETRY = (
    *("speed", "yaw_rate", "var_speed", "var_yaw_rate"),
    *("vel_right", "vel_down", "var_vel_right", "var_vel_down"),
)


def _odometry_per_epoch(odo: pd.DataFrame, epoch_t: np.ndarray) -> np.ndarray:
    """Means of the odometry samples in (t_{k-1}, t_k] for every epoch (the first: up to t_0)."""
    odo = odo.sort_values("t")
    values = odo[list(EPOCH_ODOMETRY)].to_numpy(float)
    k = np.searchsorted(epoch_t, odo["t"].to_numpy(float), side="left")
    inside = k < len(epoch_t)
    count = np.bincount(k[inside], minlength=len(epoch_t)).astype(float)
    out = np.full((len(epoch_t), len(EPOCH_ODOMETRY)), np.nan)
    for j in range(len(EPOCH_ODOMETRY)):
        total = np.bincount(k[inside], values[inside, j], minlength=len(epoch_t))
        np.divide(total, count, out=out[:, j], where=count > 0)
    return out


def _rough_positions(
    sat_pos: np.ndarray,
    code: np.ndarray,
    sigma: np.ndarray,
    el: np.ndarray,
    doy: float,
    t: np.ndarray,
    start: np.ndarray,
    stop: np.ndarray,
    system_index: np.ndarray,
) -> np.ndarray:
    """Receiver ECEF position per row [m], shape (N, 3), for the Klobuchar pierce points and the geometry.

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
    which = np.maximum(np.searchsorted(solve_at, np.arange(n), side="right") - 1, 0)
    return sol.pos[np.repeat(which, stop - start)]
