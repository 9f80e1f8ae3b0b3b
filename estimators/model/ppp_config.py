"""The PPP stochastic model every PPP estimator shares (dissertation Table 4.4.2).

EKF-PPP (:class:`~estimators.filters.ekf_ppp.EkfPppConfig`) and the GTSAM graph
estimators (:class:`~estimators.model.ppp_graph.PppGraphConfig` and its children)
carry the same model fields with the same defaults; they live here once,
with their one validation entry point. The motion and clock-drift model
(:class:`MotionModelConfig`: random walk or constant velocity with Doppler and
wheel odometry) is shared the same way.

The fields that :class:`GnssModelConfig` also has take their defaults from it (the
shipped ``urban`` preset); a composed run takes them from its ``gnss_model`` preset,
and ``conf/gnss_model/dissertation.yaml`` restores Table 4.4.2's.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, NamedTuple

import numpy as np

from simbench.contract import Need
from simbench.errors import SimbenchError, require_at_least, require_elevation_mask, require_positive
from simbench.typed import Choice, check_choices

__all__ = [
    "DIRECTION_MIN_SPEED_MPS",
    "STANDSTILL_MPS",
    "ClockModel",
    "GnssModelConfig",
    "IonosphereMode",
    "MeasurementMode",
    "MotionModel",
    "MotionModelConfig",
    "NlosModel",
    "PppGraphConfig",
    "SigmaModel",
    "StochasticModelConfig",
    "WetDelayMode",
    "VarianceComponents",
]


class ClockModel(Choice):
    """Process model of the receiver clock between epochs (member names are the YAML words)."""

    white = "white"  #: re-initialised each epoch (correlation time 0, Table 4.4.2)
    random_walk = "random_walk"  #: random walk with ``clock_noise_m_rts``
    #: an oscillator: the offset advanced by the drift state (``motion_model = constant_velocity``)
    #: with white frequency noise ``oscillator_noise_m_rts``; re-initialised where the single point
    #: clock jumps (:func:`estimators.model.clock.clock_links`)
    two_state = "two_state"


class MeasurementMode(Choice):
    """Which observables enter the estimator (member names are the YAML words)."""

    #: code on every row, carrier phase on the rows that have it (real logs with sparse phase)
    auto = "auto"
    code = "code"  #: code only; phase is ignored even where present
    code_phase = "code_phase"  #: rows without carrier phase are dropped (needs phase)


class SigmaModel(Choice):
    """How a row's a-priori sigma follows its signal (member names are the YAML words).

    The zenith sigmas (``code_sigma_m``, ``phase_sigma_m``, ``doppler_sigma_mps``) are
    multiplied by a per-row factor (:func:`estimators.model.measurement.sigma_factor`).
    """

    elevation = "elevation"  #: ``1 / sin(el)`` (Table 4.4.2)
    #: ``10^((cn0_ref_dbhz - C/N0) / 20)``: the variance grows as 1/(C/N0), as the thermal DLL and
    #: PLL jitter do (dissertation eqs. 5.13-5.15); a weak, reflected or diffracted signal is
    #: trusted less whatever its elevation. Rows without a C/N0 fall back to ``1 / sin(el)``.
    cn0 = "cn0"
    elevation_cn0 = "elevation_cn0"  #: the product of the two


class IonosphereMode(Choice):
    """How the ionospheric delay leaves the code and phase (member names are the YAML words)."""

    #: ``free`` when every tracked satellite has a second frequency (decided on the data by
    #: :func:`~estimators.model.measurement.prepare_ppp`), ``measured`` when some have and their code pairs
    #: measure the delay better than the broadcast model does, else ``broadcast``; a system whose code
    #: pairs' unbroadcast group delays are expected to cost the position more than the broadcast
    #: model's error keeps the broadcast delay (:func:`~estimators.model.measurement.pair_against_broadcast`)
    auto = "auto"
    #: first frequency only, the broadcast Klobuchar delay removed (scaled to the row's carrier)
    broadcast = "broadcast"
    #: the ionosphere-free combination of each row's two frequencies (any system); rows without a
    #: second frequency are dropped
    free = "free"
    #: first frequency only, each row's slant delay measured by its code pair (levelled to its phase
    #: pair, else a running median along the satellite) and the broadcast delay fitted to those
    #: measurements on the rows without a second frequency (:mod:`simbench.gnss.measured_ionosphere`)
    measured = "measured"


class WetDelayMode(Choice):
    """How the zenith wet delay enters the model (member names are the YAML words).

    The hydrostatic delay is always modelled (Saastamoinen with the standard atmosphere, Niell
    mapping, :func:`simbench.gnss.troposphere.troposphere_terms`).
    """

    #: ``estimate`` where the log's own estimate is a wet delay, else ``model``: a batch L2 solve with the
    #: ZWD state decides, and an estimate further than :data:`WET_DELAY_GATE_SIGMAS` times
    #: :data:`WET_DELAY_CLIMATOLOGY_SIGMA_M` from the MOPS climatology is an elevation-dependent error
    #: the state took up, not the atmosphere (:func:`estimators.model.ppp_graph.wet_delay_choice`)
    auto = "auto"

    #: the wet delay modelled too, no state: the zenith wet delay of the RTCA MOPS climatology (by
    #: latitude and season) at the first fix, Niell's wet mapping
    #: (:func:`~estimators.model.measurement.zenith_wet_delay_m`)
    model = "model"
    #: a zenith wet delay state per epoch (Table 4.4.2): prior ``zwd_sigma_m`` around Saastamoinen's
    #: wet delay of the standard atmosphere, random walk ``zwd_rw_m_rts``
    estimate = "estimate"


#: Standard deviation of the MOPS climatology's vertical tropospheric delay [m] (RTCA DO-229
#: A.4.2.4, sigma_TVE): how far a true zenith wet delay may be from it.
WET_DELAY_CLIMATOLOGY_SIGMA_M = 0.12
#: ``wet_delay=auto`` keeps the ZWD state when its estimate is within this many of those sigmas.
WET_DELAY_GATE_SIGMAS = 3.0


class VarianceComponents(Choice):
    """Code variance factors estimated from the log itself (member names are the YAML words).

    A robust (Huber) single-point pass per epoch gives code residuals; per group the factor
    on the code sigma is Helmert's estimate from the residuals and their redundancy numbers,
    relative to the other groups (geometric mean over the rows 1; the overall scale stays
    the a-priori model's): :func:`estimators.model.measurement.variance_factors`.
    """

    none = "none"  #: the a-priori sigmas as they are
    system = "system"  #: one factor per GNSS system
    #: one factor per GNSS system and C/N0 bin (5 dB-Hz; the system's where a bin has few rows)
    system_cn0 = "system_cn0"


class NlosModel(Choice):
    """ICE's model of late (NLOS) code rows (member names are the YAML words)."""

    none = "none"  #: the dissertation's: ICE's zero-mean scale mixture alone
    #: a LOS/NLOS mixture whose NLOS weight and late-only mean depend on C/N0 and elevation, learned
    #: on ICE's window (:mod:`estimators.incremental.nlos_window`)
    conditioned = "conditioned"


class MotionModel(Choice):
    """Process model of the receiver position between epochs (member names are the YAML words)."""

    random_walk = "random_walk"  #: position random walk ``pos_rw_m_rts`` (Table 4.4.2)
    #: velocity states, white acceleration ``accel_sigma_mps2_rts``, Doppler range-rate factors
    constant_velocity = "constant_velocity"


@dataclass
class GnssModelConfig:
    """The model choices every GNSS estimator takes from the ``gnss_model`` config group.

    The defaults are the ``urban`` preset, the shipped default (``conf/config.yaml``):
    sigmas that follow C/N0 (a weak, reflected or diffracted signal trusted less
    whatever its elevation), a constant-velocity vehicle with Doppler range rates,
    arcs also broken where the phase disagrees with the Doppler, every epoch with a
    satellite, ICE's mixture in units of the C/N0 sigma factor and one max-mixture
    outlier scale of 10 for batch and incremental MM; chosen on tuning seeds
    1000-1002 of the simulated urban_deep and urban worlds (docs/notebook.md, "The GNSS model").
    ``conf/gnss_model/dissertation.yaml`` is Table 4.4.2's model (random walk,
    ``1/sin(el)`` weights, arcs broken at flags and gaps, epochs with 4 satellites
    or more, each max-mixture's published outlier scale), which the thesis sweeps pin.
    The estimators' ``Config`` dataclasses take these fields' defaults from here.

    :func:`simbench.runs.compose.estimator_schema` makes each model field of every
    estimator config that has it default to its ``per_estimator`` entry, else to
    ``${gnss_model.<field>}``, so one setting reaches every estimator that has the field
    and ``estimator.<name>.<field>`` still overrides it for one. A result row records
    ``name`` (its ``gnss_model`` column), and its ``overrides`` are relative to the
    estimator's dataclass defaults under this preset (:func:`simbench.runs.compose.preset_estimator_config`).
    """

    name: str = "urban"  #: the preset's name (its file in ``conf/gnss_model/``)
    motion_model: MotionModel = MotionModel.constant_velocity
    sigma_model: SigmaModel = SigmaModel.cn0
    doppler_slip_m: float = 1.0
    min_satellites: int = 1
    #: ICE's adaptive mixture over residuals in units of each row's sigma factor (False: metres)
    scaled_mixture: bool = True
    #: ICE's late code rows: a windowed LOS/NLOS mixture conditioned on C/N0 and elevation (``none``:
    #: Table 4.4.2's ICE). Tuning seeds 1000-1002 (libRSF stand-ins of ``street_canyon`` and ``urban``
    #: at 5 Hz, ``urban`` and ``urban_deep`` at 1 Hz): horizontal median lower on 11 of 12 runs
    #: (geometric mean -13 %), 3-D RMSE -3 % (docs/notebook.md, "ICE learns the street's late signals")
    nlos_model: NlosModel = NlosModel.conditioned
    #: max-mixture outlier covariance over the inlier's (MM, iSAM2-MM). C/N0 sigmas already widen a
    #: weak (often reflected) row to 10-25 m, so an NLOS excess of tens of metres sits 1.5-3 sigma out:
    #: the batch code's 1e6 (outlier beyond 3.7 sigma) keeps every row and MM equals L2; 10 (beyond
    #: 1.6 sigma, the incremental code's value) for both
    outlier_scale: float = 10.0
    #: ionosphere-free combination where every tracked satellite has a second frequency; L1 with
    #: the delay its second frequency measures where only some have (a u-blox F9P sees no L2 on
    #: the GPS IIR satellites); else L1 with the broadcast Klobuchar delay; and per system the
    #: broadcast delay where its pairs' unbroadcast group delays (a C/A code against the P(Y) code that
    #: TGD refers to, L2C, L5) are expected to cost more; ``free``, ``measured`` or ``broadcast`` force one
    ionosphere: IonosphereMode = IonosphereMode.auto
    #: code variance factors estimated from the log, relative between the GNSS systems, so that
    #: sigmas calibrated on one receiver carry over to another's systems (a no-op on one system).
    #: Nagoya (GREC, Septentrio): DCS 1.60 -> 1.15 m, L2 2.77 -> 0.70 m; Hong Kong (GC) and the
    #: single-system simulated worlds: unchanged (docs/estimators.md)
    variance_components: VarianceComponents = VarianceComponents.system
    #: a priori sigma of each arc's first slant-ionosphere residual after Klobuchar [m] (L1 only).
    #: The arc's ionosphere and bias states can absorb a shift of the position along the lines of
    #: sight, which only this prior pins (docs/estimators.md, "A static receiver in the canyon"); 1 m
    #: (Table 4.4.2's model: 2 m) lowered the median of L2, DCS and MM on urban_deep tuning seeds
    #: 1000-1004 (e.g. DCS 3.89/3.30/5.44/4.31/3.44 -> 2.61/3.24/4.07/3.57/2.93 m), of L2 and MM on
    #: urban 1000-1002 and on one hour of single-frequency open sky, and Hong Kong DCS 2.97 -> 2.39 m
    iono_sigma_m: float = 1.0
    #: the zenith wet delay: a state (``estimate``, Table 4.4.2), modelled (``model``: the MOPS
    #: climatology, no state) or ``auto``: the state where the log's estimate of it is plausible.
    #: Only the mapping function's elevation dependence separates the state from the height and the
    #: clock, and elevation-dependent code errors (GLONASS inter-frequency biases, NLOS delays, an
    #: ionosphere model's residual) have it too: counted as hundreds of independent epochs they
    #: outweighed the state's 0.3 m prior, which took them up and moved the height by 3-12 times as
    #: much. Estimates: Nagoya GLONASS only -1.08 m (code only +6.4 m), Nagoya cut to a u-blox F9P's
    #: signals -0.19 m, Hong Kong 1.15 m, simulated urban/urban_deep seeds 1000-1004 -0.33 .. +0.58 m
    #: where the truth is 0.07-0.13 m (docs/estimators.md, "The height of a static receiver")
    wet_delay: WetDelayMode = WetDelayMode.auto
    #: values of the fields above for one estimator, where its published code differs from the
    #: others (estimator name -> field -> value), e.g. ``{mm: {outlier_scale: 1.0e6}}``
    per_estimator: dict[str, dict[str, Any]] = field(default_factory=dict)

    @staticmethod
    def model_fields() -> list[str]:
        """The fields an estimator config may share: all but ``name`` and ``per_estimator``."""
        return [f.name for f in fields(GnssModelConfig) if f.name not in ("name", "per_estimator")]


@dataclass
class StochasticModelConfig:
    """Stochastic model and observation selection of PPP; defaults are Table 4.4.2 and Sec. 4.4 but for
    the :class:`GnssModelConfig` fields, whose defaults are its (the shipped ``urban`` preset's)."""

    pos_sigma_m: float = 1.0  #: a priori position sigma per axis at the first epoch [m]
    pos_rw_m_rts: float = 5.0  #: position random walk [m/sqrt(s)]
    #: auto | model (the MOPS wet delay, no state) | estimate (a ZWD state, Table 4.4.2)
    wet_delay: WetDelayMode = GnssModelConfig.wet_delay
    zwd_sigma_m: float = 0.3  #: a priori zenith wet delay sigma [m] (about the Saastamoinen value; ``estimate`` only)
    zwd_rw_m_rts: float = 3e-5  #: zenith wet delay random walk [m/sqrt(s)] (``estimate`` only)
    clock_sigma_m: float = 3e6  #: a priori receiver clock sigma [m]
    clock_noise_m_rts: float = 2000.0  #: receiver clock process noise [m/sqrt(s)] (random_walk only)
    clock_model: ClockModel = ClockModel.white  #: white (each epoch free, Table 4.4.2) | random_walk
    ambiguity_sigma_m: float = 100.0  #: a priori phase bias sigma [m]; biases are constant within an arc
    code_sigma_m: float = 2.5  #: zenith code sigma [m], scaled per row by ``sigma_model``
    phase_sigma_m: float = 0.025  #: zenith phase sigma [m], scaled per row by ``sigma_model``
    #: per-row scaling of the sigmas: elevation (1/sin(el), Table 4.4.2) | cn0 | elevation_cn0
    sigma_model: SigmaModel = GnssModelConfig.sigma_model
    #: C/N0 at which the ``cn0`` factor is 1 [dB-Hz]
    cn0_ref_dbhz: float = 45.0
    elevation_mask_deg: float = 7.0
    #: epochs with fewer usable satellites are skipped (Table 4.4.2: 4, a snapshot fix); below 4 an
    #: epoch is held by the motion model and its 1-3 rows (what a car in a canyon often has)
    min_satellites: int = GnssModelConfig.min_satellites
    max_gap_epochs: int = 1  #: a larger epoch step within a satellite's rows starts a new phase arc
    #: a phase step that disagrees with the Doppler by more than this starts a new arc [m] (an
    #: unflagged cycle slip or a switch of reflected path; :func:`simbench.gnss.arcs.doppler_phase_jumps`);
    #: 0: loss-of-lock flags and gaps only (Table 4.4.2's data came with flagged slips)
    doppler_slip_m: float = GnssModelConfig.doppler_slip_m
    #: auto (free where every satellite has a second frequency, measured where some have) |
    #: broadcast (L1, Klobuchar) | free | measured
    ionosphere: IonosphereMode = GnssModelConfig.ionosphere
    #: none | system | system_cn0: code variance factors estimated from the log (:class:`VarianceComponents`)
    variance_components: VarianceComponents = GnssModelConfig.variance_components
    #: L1 with the broadcast delay only (not in Table 4.4.2): a slant ionosphere residual per satellite
    #: arc (code +I, phase -I) so that code-phase divergence after Klobuchar does not drag the position.
    #: A measured delay (``ionosphere`` measured) needs none, and its weak direction would cost: on the
    #: Nagoya log with 4 of 12 GPS satellites' L2 removed, DCS 1.12 m with the states, 0.07 m without
    estimate_iono: bool = True
    iono_sigma_m: float = GnssModelConfig.iono_sigma_m  #: a priori sigma of the slant residual after Klobuchar [m]
    iono_rw_m_rts: float = 0.03  #: random walk of the slant residual [m/sqrt(s)]
    #: observables used: auto (phase where present, code everywhere) | code | code_phase
    measurements: MeasurementMode = MeasurementMode.auto
    #: a priori sigma of each further system's inter-system bias (receiver clock offset relative
    #: to the first system's clock) [m]; its start value comes from the single-point solution
    isb_sigma_m: float = 100.0
    #: random walk of the inter-system biases [m/sqrt(s)] (hardware delays drift slowly)
    isb_rw_m_rts: float = 0.001

    def validate(self, where: str) -> None:
        """Raise a one-line :class:`SimbenchError` for the first out-of-range field.

        Parameters
        ----------
        where : str
            Config node name, e.g. ``estimator.l2``; prefixed to the field in the message.
        """
        check_choices(self, where)
        for name in (
            "pos_sigma_m",
            "zwd_sigma_m",
            "clock_sigma_m",
            "ambiguity_sigma_m",
            "code_sigma_m",
            "phase_sigma_m",
            "iono_sigma_m",
            "isb_sigma_m",
        ):
            require_positive(f"{where}.{name}", getattr(self, name), "give a standard deviation in metres")
        for name in ("pos_rw_m_rts", "zwd_rw_m_rts", "clock_noise_m_rts", "iono_rw_m_rts", "isb_rw_m_rts"):
            require_at_least(f"{where}.{name}", getattr(self, name), 0, "give a noise density in m/sqrt(s)")
        require_elevation_mask(
            f"{where}.elevation_mask_deg", self.elevation_mask_deg, "give an elevation mask in degrees, e.g. 7"
        )
        require_at_least(
            f"{where}.doppler_slip_m",
            self.doppler_slip_m,
            0,
            "give a threshold in metres, e.g. 1, or 0 to break arcs at flags and gaps only",
        )
        require_positive(f"{where}.cn0_ref_dbhz", self.cn0_ref_dbhz, "give a reference C/N0 in dB-Hz, e.g. 45")
        require_at_least(
            f"{where}.min_satellites",
            self.min_satellites,
            1,
            "give 4 for snapshot-solvable epochs only, or 1 to keep every epoch with a satellite",
        )
        require_at_least(
            f"{where}.max_gap_epochs", self.max_gap_epochs, 1, "1 means every epoch must be present within one arc"
        )

    def needs(self) -> frozenset[Need]:
        """What the data must offer for this model: a second frequency for ``ionosphere=free``, carrier
        phase for ``code_phase``."""
        needs = {Need.dual_frequency} if self.ionosphere == IonosphereMode.free else set()
        if self.measurements == MeasurementMode.code_phase:
            needs.add(Need.phase)
        return frozenset(needs)

    def prepare_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :func:`~estimators.model.measurement.prepare_ppp` for this config."""
        return {
            "ionosphere": self.ionosphere,
            "variance_components": self.variance_components,
            "code_sigma_m": self.code_sigma_m,
            "phase_sigma_m": self.phase_sigma_m,
            "elevation_mask_deg": self.elevation_mask_deg,
            "min_satellites": self.min_satellites,
            "max_gap_epochs": self.max_gap_epochs,
            "measurements": self.measurements,
            "sigma_model": self.sigma_model,
            "cn0_ref_dbhz": self.cn0_ref_dbhz,
            "doppler_slip_m": self.doppler_slip_m,
        }


#: Below this wheel speed the vehicle stands still (zero horizontal velocity) [m/s].
STANDSTILL_MPS = 0.2
#: The smallest variance of a reported odometry component [m^2/s^2] (a reported 0 would make the row rigid).
MIN_ODOMETRY_VARIANCE = 1e-6


class Reported(NamedTuple):
    """A velocity component a vehicle reports, or the estimator's default for it."""

    value: float  #: [m/s]
    sigma: float  #: [m/s]


def reported(value: float, variance: float, default_sigma: float) -> Reported:
    """``value`` at the sigma of ``variance`` when both are finite (the vehicle reported it), else 0 at
    ``default_sigma`` (the estimator's own prior for the component)."""
    if np.isfinite(value) and np.isfinite(variance):
        return Reported(float(value), float(np.sqrt(max(variance, MIN_ODOMETRY_VARIANCE))))
    return Reported(0.0, float(default_sigma))


#: A velocity slower than this gives no usable direction of travel for the odometry [m/s].
DIRECTION_MIN_SPEED_MPS = 2.0


@dataclass
class MotionModelConfig(StochasticModelConfig):
    """The shared stochastic model plus the motion and clock-drift model between epochs.

    ``random_walk`` is Table 4.4.2's position random walk. With
    ``constant_velocity`` (default, :class:`GnssModelConfig`'s) each epoch also has a velocity, driven by white
    acceleration, and a receiver clock drift (random walk); the rows with a Doppler
    give range-rate measurements of both, and wheel odometry (when the data have
    it and ``use_odometry``) constrains the velocity.
    """

    motion_model: MotionModel = GnssModelConfig.motion_model
    #: white-acceleration density of the constant-velocity model per axis [m/s^2/sqrt(s)] (a car in town)
    accel_sigma_mps2_rts: float = 2.0
    vel_sigma_mps: float = 30.0  #: a priori velocity sigma per axis at the first epoch [m/s]
    #: zenith range-rate sigma of a Doppler measurement [m/s], scaled per row by ``sigma_model``
    doppler_sigma_mps: float = 0.3
    drift_sigma_mps: float = 1000.0  #: a priori receiver clock drift sigma [m/s] around the first epoch's fit
    drift_rw_mps_rts: float = 0.5  #: receiver clock drift random walk [m/s/sqrt(s)]
    #: ``clock_model = two_state``: the offset's random walk about ``drift x dt``, the oscillator's white
    #: frequency noise times c [m/sqrt(s)]: a TCXO's (Brown and Hwang, Allan h0 = 2e-19, the simulator's)
    oscillator_noise_m_rts: float = 0.1
    #: ``clock_model = two_state``: a single point clock step this far from the drift's prediction is a
    #: jump (a receiver holding its clock or time tags by steps: u-blox 300-3000 km) and starts the
    #: clock afresh [m]
    clock_jump_m: float = 1000.0
    #: ``clock_model = two_state``: an epoch with fewer code rows keeps a free clock. Its rows cannot
    #: check each other, and a predicted clock gives a canyon's few, mostly reflected rows a leverage
    #: on the position that a free clock takes away (urban_deep tuning seeds, 3-D RMSE: linked at every
    #: epoch +15 %, from 5 rows 0 %)
    clock_link_min_satellites: int = 5
    #: constant velocity only: add the vehicle's wheel odometry (speed, yaw rate) when the data have it
    use_odometry: bool = True
    #: sigma of the non-holonomic constraint (no sideways velocity of a car) [m/s]
    nhc_sigma_mps: float = 0.3
    #: sigma of zero vertical velocity while the wheels stand still [m/s]. A bound, not the wheel-speed
    #: sigma: with one or two satellites nothing else observes the vertical velocity (the EKF on
    #: urban_deep seed 4 climbed 13 km while parked), while the wheel-speed sigma made the EKF's height
    #: stiff over long stops (urban seeds 1000-1002 median 3-10 % worse; 3 m/s: unchanged)
    standstill_vertical_sigma_mps: float = 3.0
    #: sigma of the road grade while the wheels turn: the vertical velocity of a moving car is
    #: ``grade x speed`` [-]. 0.1 (a 6 deg slope at one sigma) bounds what streets have, yet it is
    #: what holds the height of a code-only log without Doppler, where the wheel speed has no
    #: direction to act along and nothing else damps the vertical velocity
    road_grade_sigma: float = 0.1

    def road_grade_vertical_sigma(self, speed_mps: float, speed_sigma_mps: float) -> float:
        """Sigma of the zero-vertical-velocity row of a car moving at ``speed_mps`` [m/s]: the road
        grade times the speed, with the wheel-speed sigma ``speed_sigma_mps`` as a floor in quadrature."""
        return float(np.hypot(self.road_grade_sigma * speed_mps, speed_sigma_mps))

    def vertical_velocity(self, speed_mps: float, speed_sigma_mps: float, down: float, var_down: float) -> Reported:
        """The up velocity [m/s] and its sigma: the vehicle's reported body-down velocity, negated (a car's
        pitch is small), at its reported variance where it gives one; else 0 at the road grade
        (moving) or at ``standstill_vertical_sigma_mps`` (wheels at rest)."""
        default = (
            self.standstill_vertical_sigma_mps
            if abs(speed_mps) < STANDSTILL_MPS
            else self.road_grade_vertical_sigma(speed_mps, speed_sigma_mps)
        )
        return reported(-down, var_down, default)

    def left_velocity(self, right: float, var_right: float) -> Reported:
        """The velocity to the vehicle's left [m/s] and its sigma: the reported body-right velocity,
        negated, at its reported variance; else 0 at ``nhc_sigma_mps`` (no sideways motion)."""
        return reported(-right, var_right, self.nhc_sigma_mps)

    def validate(self, where: str) -> None:
        """The shared checks, then the motion-model densities and sigmas."""
        super().validate(where)
        for name in (
            "accel_sigma_mps2_rts",
            "vel_sigma_mps",
            "doppler_sigma_mps",
            "drift_sigma_mps",
            "drift_rw_mps_rts",
            "oscillator_noise_m_rts",
            "clock_jump_m",
            "nhc_sigma_mps",
            "standstill_vertical_sigma_mps",
            "road_grade_sigma",
        ):
            require_positive(f"{where}.{name}", getattr(self, name), "give a positive sigma or density")
        require_at_least(
            f"{where}.clock_link_min_satellites", self.clock_link_min_satellites, 1, "give a number of rows, e.g. 5"
        )
        if self.clock_model == ClockModel.two_state and self.motion_model != MotionModel.constant_velocity:
            raise SimbenchError(
                f"{where}.clock_model",
                "two_state needs a clock drift state, which only motion_model=constant_velocity has",
                f"set {where}.motion_model=constant_velocity or {where}.clock_model=white",
            )


class PppGraphConfig(MotionModelConfig):
    """Stochastic model of the PPP graph: the shared model of :class:`~estimators.model.ppp_config.MotionModelConfig`.

    In the graph the clock prior holds at every epoch and the slant ionosphere
    residual is one key per row, a random walk along its arc. With
    ``motion_model = constant_velocity`` each epoch also has a velocity, driven by
    white acceleration, and a receiver clock drift (random walk), and the rows with
    a Doppler give range-rate factors on them. The drift is a state of its own, not
    the difference of consecutive clocks (GTSAM's ``DopplerFactor``): receivers that
    keep their clock within a millisecond by jumps (u-blox) make that difference
    jump by thousands of km/s.
    """
