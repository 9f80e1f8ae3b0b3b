"""Typed configuration schema.

Hydra composes YAML from ``conf/``; :func:`to_typed` merges the result into
these dataclasses, so code reads attributes with known types and units, and a
malformed value fails early with a one-line :class:`~simbench.errors.SimbenchError`.
Units are in the field names or in the comments. Choice fields are ``str``
Enums whose member names are the YAML words, so OmegaConf rejects any other
value at composition, naming the key and the allowed values.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

from simbench.bounds import check_bounds
from simbench.errors import SimbenchError, require_at_least, require_elevation_mask, require_positive
from simbench.paths import require_file
from simbench.source_registry import SIMULATED, DataConfig, SourceConfig, scenario_config
from simbench.typed import Choice, check_choices

#: Coherent integration a GPS C/A receiver can use [s]: one code period up to one navigation data bit.
INTEGRATION_RANGE_S = (0.001, 0.020)

#: The most satellites the generator computes per epoch (a broadcast GPS file has up to 32 PRNs).
MAX_SATELLITES = 32
#: Peak memory of a generated scenario per satellite-epoch and per IMU sample [bytes]; measured on the
#: urban preset (peak RSS of 300 and 1200 s at 1 and 10 Hz: ~400 B per satellite-epoch over 32 PRNs,
#: ~600 B per 100 Hz IMU sample), rounded up.
BYTES_PER_SATELLITE_EPOCH = 400
BYTES_PER_IMU_SAMPLE = 600
#: Fallback budget where the physical memory cannot be read (no ``os.sysconf``) [bytes].
DEFAULT_MEMORY_BUDGET = 8 * 2**30

#: Antenna pattern nodes of :func:`simbench.sim.tracking.antenna_gain_dbi`: off-boresight angle [deg] and
#: gain [dBi]. The first five are the upright-antenna values at 90, 75, 60, 25, 0 deg elevation. Behind the
#: ground plane the gain falls linearly to -25 dBi straight back (front-to-back ratio 37 dB, typical of a
#: patch on a ground plane): a satellite there reaches only -158.5 - 25 + 201 = 17.5 dB-Hz, below any
#: tracking threshold, so a tilted or inverted antenna masks it, while rays just under the horizon stay
#: marginally trackable. Here as numbers, not arrays: the config checks need no numpy.
ANTENNA_GAIN_ANGLE_DEG = (0.0, 25.0, 60.0, 75.0, 90.0, 180.0)
ANTENNA_GAIN_DBI = (12.0, 9.0, 3.0, -1.0, -6.0, -25.0)

#: Upper bounds of the IMU sigmas (:meth:`ImuConfig.validate`), each far beyond the worst grade of
#: Groves Table 4.1 (consumer MEMS: accel bias ~0.1-1 m/s^2, gyro bias ~100-10,000 deg/h, ARW a few
#: deg/sqrt(h)): a larger value is a unit or typing error, and the mechanisation overflows on it.
IMU_SIGMA_LIMITS: dict[str, float] = {
    "accel_bias_sigma_mps2": 9.81,  # 1 g
    "accel_bias_instability_mps2": 9.81,
    "accel_noise_mps2_rthz": 1.0,
    "gyro_bias_sigma_dph": 36_000.0,  # 10 deg/s
    "gyro_bias_instability_dph": 36_000.0,
    "gyro_noise_dph_rthz": 3_600.0,  # 60 deg/sqrt(h)
}


class TrajectoryKind(Choice):
    """How the simulated vehicle moves."""

    urban_drive = "urban_drive"  #: street grid with stops (:class:`UrbanDriveConfig`)
    flight = "flight"  #: fixed-wing UAV (:class:`FlightConfig`)
    replay = "replay"  #: a recorded trajectory file (:class:`ReplayConfig`)


class ConstellationKind(Choice):
    """Where the satellite orbits and clocks come from."""

    nominal = "nominal"  #: GPS 24-slot constellation, no files
    broadcast = "broadcast"  #: a RINEX GPS navigation file (``nav_path``)


class FacadeMaterial(Choice):
    """Building facade material and its electrical properties, which set the Fresnel reflection
    coefficients (:func:`simbench.sim.canyon.fresnel_circular`).

    ITU-R P.2040-1 Table 3 at 1-10 GHz: relative permittivity ``a`` and conductivity ``c f_GHz^d`` [S/m].
    """

    permittivity: float  #: a [-]
    conductivity: tuple[float, float]  #: (c [S/m], d [-])

    def __new__(cls, word: str, a: float, c: float, d: float) -> FacadeMaterial:
        member = str.__new__(cls, word)
        member._value_ = word
        member.permittivity, member.conductivity = a, (c, d)
        return member

    concrete = "concrete", 5.24, 0.0462, 0.7822
    brick = "brick", 3.91, 0.0238, 0.16
    glass = "glass", 6.31, 0.0036, 1.3394
    metal = "metal", 1.0, 1e7, 0.0


class HeightDistribution(Choice):
    """How the heights of the street canyon's buildings are drawn (:func:`simbench.sim.trajectory.block_sides`)."""

    uniform = "uniform"  #: uniform over ``building_height_m``
    rayleigh = "rayleigh"  #: Rayleigh with scale ``building_height_scale_m`` (ITU-R P.1410-5 statistical city)


class MaskedReflection(Choice):
    """Where a masked satellite's reflecting building stands (:func:`simbench.sim.canyon.canyon_rays`)."""

    #: the far facade at any height, plus ``reflector_beyond_m`` (the canyon model's original rule)
    any_height = "any_height"
    #: where the bounced ray clears both roofs (plus ``reflector_beyond_m`` behind the far facade),
    #: no reception beyond ``reflector_max_m``: the delay grows as the elevation falls
    visible = "visible"


# --------------------------------------------------------------------------- trajectory


@dataclass
class UrbanDriveConfig:
    """A drive on a rectangular street grid with stops at intersections."""

    block_length_m: float = 120.0  #: distance between intersections
    n_blocks_east: int = 4  #: grid size (blocks) east-west
    n_blocks_north: int = 4  #: grid size (blocks) north-south
    cruise_speed_mps: float = 10.0
    turn_speed_mps: float = 4.0
    max_accel_mps2: float = 1.5
    turn_radius_m: float = 8.0
    stop_probability: float = 0.3  #: chance to stop at an intersection
    stop_duration_s: tuple[float, float] = (5.0, 30.0)  #: uniform range of a stop
    start_static_s: float = 30.0  #: standing still before driving (alignment)


@dataclass
class FlightConfig:
    """A small fixed-wing UAV: take-off climb, banked loiter turns, figure eights."""

    airspeed_mps: float = 22.0
    cruise_altitude_m: float = 120.0  #: above the origin
    climb_rate_mps: float = 3.0
    turn_radius_m: float = 150.0  #: loiter radius; bank = atan(v^2 / (g R))
    leg_length_m: float = 600.0
    start_static_s: float = 30.0


@dataclass
class ReplayConfig:
    """Replay of a recorded trajectory file (``SOW X Y Z``, ECEF metres)."""

    path: str = ""
    gps_week: int = 2032
    max_gap_s: float = 2.0  #: gaps longer than this are not interpolated (no epochs there)


@dataclass
class TrajectoryConfig:
    kind: TrajectoryKind = TrajectoryKind.urban_drive  #: urban_drive | flight | replay
    origin_lat_deg: float = 39.6295  #: Morgantown, WV
    origin_lon_deg: float = -79.9559
    origin_h_m: float = 290.0
    urban_drive: UrbanDriveConfig = field(default_factory=UrbanDriveConfig)
    flight: FlightConfig = field(default_factory=FlightConfig)
    replay: ReplayConfig = field(default_factory=ReplayConfig)


# --------------------------------------------------------------------------- sky


@dataclass
class ConstellationConfig:
    kind: ConstellationKind = ConstellationKind.nominal  #: nominal (GPS 24-slot, no files) | broadcast (RINEX nav file)
    nav_path: str = ""  #: RINEX 2/3 GPS navigation file, for kind=broadcast
    elevation_mask_deg: float = 7.0
    #: Klobuchar coefficients handed to the receiver with the nominal constellation
    #: (those of ``wvu_drives/brdc.18n``); broadcast files bring their own.
    iono_alpha: tuple[float, float, float, float] = (8.382e-09, -1.490e-08, -5.960e-08, 1.192e-07)
    iono_beta: tuple[float, float, float, float] = (9.421e04, -1.311e05, -1.311e05, 8.520e05)


# --------------------------------------------------------------------------- errors


@dataclass
class ReceiverClockConfig:
    enabled: bool = True
    bias0_sigma_s: float = 30e-9  #: Table 4.4.1
    drift0_sigma_sps: float = 1e-7  #: initial frequency offset (100 ppb, TCXO)
    h0: float = 2e-19  #: white frequency noise (Allan h0) [s]
    h_2: float = 2e-20  #: random-walk frequency noise (Allan h-2) [1/s]


@dataclass
class TroposphereConfig:
    enabled: bool = True
    #: true zenith wet delay = Saastamoinen wet value * scale, scale ~ N(1, sigma)
    wet_scale_sigma: float = 0.3
    wet_rw_mps: float = 3e-5  #: random walk of the zenith wet delay [m/sqrt(s)]


@dataclass
class IonosphereConfig:
    enabled: bool = True
    #: true delay = Klobuchar * scale (scale ~ N(1, sigma), per scenario) + per-satellite GM
    scale_sigma: float = 0.3
    residual_sigma_m: float = 0.5  #: per-satellite L1 zenith-equivalent residual
    residual_tau_s: float = 1800.0


@dataclass
class OrbitClockErrorConfig:
    """Error of the orbit/clock product handed to the receiver (truth minus product)."""

    enabled: bool = True
    orbit_sigma_m: float = 0.05  #: per axis
    clock_sigma_m: float = 0.05
    tau_s: float = 3600.0


@dataclass
class MultipathConfig:
    enabled: bool = True
    code_sigma_m: float = 0.4  #: Gauss-Markov std (elevation-independent model)
    tau_s: float = 15.0
    elevation_dependent: bool = False  #: sigma = a + b exp(-el / c)
    el_a_m: float = 0.47
    el_b_m: float = 0.78
    el_c_deg: float = 20.9
    phase_sigma_m: float = 0.003  #: carrier multipath (mm-level)


@dataclass
class NlosConfig:
    """Street canyon: buildings along the road mask LOS; reflections arrive late."""

    enabled: bool = True
    building_height_m: tuple[float, float] = (10.0, 40.0)  #: uniform per block side
    #: uniform (over building_height_m) | rayleigh (scale building_height_scale_m)
    height_distribution: HeightDistribution = HeightDistribution.uniform
    #: Rayleigh scale of the heights [m]; ITU-R P.1410-5 gives 8 suburban, 15 urban, 20 dense urban, 50 high-rise
    building_height_scale_m: float = 50.0
    wall_distance_m: tuple[float, float] = (8.0, 20.0)  #: road centre to facade
    open_fraction: float = 0.2  #: fraction of block sides with no building
    #: chance that a facade offers a specular reflection where geometry allows one
    #: (recesses, windows, gaps and passing traffic break the rest); persistent in time
    reflection_probability: float = 0.5
    facade_material: FacadeMaterial = FacadeMaterial.concrete  #: Fresnel coefficients of the facades
    #: per-bounce loss of a rough, irregular facade on top of the Fresnel coefficient [dB]
    scattering_loss_db: float = 2.0
    #: antenna rejection of left-hand circular polarisation at zenith, falling as sin(elevation)
    #: (a single bounce turns RHCP towards LHCP) [dB]
    lhcp_rejection_db: float = 10.0
    #: facade relief (recessed windows, pillars, balconies): std of the reflecting surface's offset [m]
    facade_relief_sigma_m: float = 0.3
    #: and its correlation length along the road [m]: moving past it makes reflections fade
    facade_relief_length_m: float = 2.0
    #: a masked satellite's reflecting building stands this far beyond the far facade (taller buildings
    #: behind, across crossing streets), uniform and persistent per satellite [m]; (0, 0): the far facade
    reflector_beyond_m: tuple[float, float] = (0.0, 0.0)
    #: any_height (the far facade reflects a masked satellite at any height) | visible (the reflector
    #: stands where the bounced ray clears both roofs: simbench.sim.canyon.visible_reflector_m)
    masked_reflection: MaskedReflection = MaskedReflection.any_height
    #: with masked_reflection=visible: no reflector of a masked satellite further than this from the
    #: road axis [m] (the street's surroundings offer no specular facade beyond it)
    reflector_max_m: float = 200.0
    #: replayed routes: length of road along which one building side keeps its height and setback [m]
    roadside_segment_m: float = 60.0


@dataclass
class AttitudeMaskingConfig:
    enabled: bool = True
    #: satellites further than this from the antenna boresight are not tracked
    max_off_boresight_deg: float = 95.0


@dataclass
class CycleSlipConfig:
    enabled: bool = True
    cn0_threshold_dbhz: float = 35.0
    low_cn0_probability: float = 0.2  #: per epoch below the threshold
    rate_per_s: float = 1e-4  #: random slips on healthy channels (Poisson)
    flagged_fraction: float = 0.9  #: slips the receiver flags with LLI
    max_jump_cycles: int = 20


@dataclass
class Cn0Config:
    received_power_dbw: float = -158.5
    constant_db: float = 201.0  #: -N0 minus implementation losses [dB]
    noise_db: float = 1.0  #: white N(0, sigma) per epoch
    fade_sigma_db: float = 1.0  #: slow Gauss-Markov fading per satellite
    fade_tau_s: float = 10.0


@dataclass
class ScintillationConfig:
    """C/N0 fades per satellite (:mod:`simbench.sim.error_sources.scintillation`); off by default."""

    enabled: bool = False
    rate_per_s: float = 0.002  #: fade onsets per satellite per second (Poisson)
    depth_db: float = 10.0  #: C/N0 drop during a fade [dB]
    duration_s: float = 20.0  #: length of a fade [s]


@dataclass
class ErrorsConfig:
    receiver_clock: ReceiverClockConfig = field(default_factory=ReceiverClockConfig)
    troposphere: TroposphereConfig = field(default_factory=TroposphereConfig)
    ionosphere: IonosphereConfig = field(default_factory=IonosphereConfig)
    orbit_clock: OrbitClockErrorConfig = field(default_factory=OrbitClockErrorConfig)
    multipath: MultipathConfig = field(default_factory=MultipathConfig)
    nlos: NlosConfig = field(default_factory=NlosConfig)
    attitude_masking: AttitudeMaskingConfig = field(default_factory=AttitudeMaskingConfig)
    cycle_slips: CycleSlipConfig = field(default_factory=CycleSlipConfig)
    cn0: Cn0Config = field(default_factory=Cn0Config)
    scintillation: ScintillationConfig = field(default_factory=ScintillationConfig)
    tracking_noise: bool = True  #: DLL/PLL thermal jitter
    #: code error of a sampling rate commensurate with the chip rate (simbench.sim.tracking)
    sample_grid: bool = True


@dataclass
class OdometryConfig:
    """Wheel odometry of a car (:mod:`simbench.sim.odometry`): speed along body x and yaw rate.

    Noise defaults are what the smartLoc test vehicle reports in its libRSF
    ``odom3`` lines (variances 0.0025 m^2/s^2 and 4e-6 rad^2/s^2); the table's
    variance columns carry these configured values, as a vehicle would report
    them. The scale factor is the effective wheel radius error (tyre wear,
    pressure, load: a few tenths of a percent to about 1 %, Groves 2013 sec. 6.3);
    the yaw-rate bias is that of a consumer MEMS gyro after turn-on, as
    ``conf/imu/consumer.yaml`` (100 deg/h).
    """

    enabled: bool = False  #: on for the car scenarios (conf/scenario/urban, open_sky, replay)
    rate_hz: float = 10.0  #: sample rate; imu.rate_hz must be a multiple of it
    speed_sigma_mps: float = 0.05  #: white noise per sample
    scale_factor_sigma: float = 0.005  #: measured = (1 + s) true, s ~ N(0, sigma) per seed [-]
    yaw_rate_sigma_rps: float = 0.002  #: white noise per sample [rad/s]
    yaw_rate_bias_sigma_rps: float = 4.8e-4  #: constant bias ~ N(0, sigma) per seed [rad/s] (100 deg/h)


# --------------------------------------------------------------------------- scenario


@dataclass
class ScenarioConfig(SourceConfig):
    """The simulator's scenario (source ``simulated``); real logs have their own (:mod:`simbench.data.log_sources`)."""

    name: str = "urban"
    source: str = SIMULATED  #: the simulator (:mod:`simbench.sim.simulator_source`)
    duration_s: float = 600.0
    rate_hz: float = 1.0  #: GNSS epoch rate
    gps_week: int = 2032
    start_sow_s: float = 475_200.0  #: 2018-12-21 12:00 GPST
    dual_frequency: bool = False  #: also generate L2 code and phase
    trajectory: TrajectoryConfig = field(default_factory=TrajectoryConfig)
    constellation: ConstellationConfig = field(default_factory=ConstellationConfig)
    errors: ErrorsConfig = field(default_factory=ErrorsConfig)
    odometry: OdometryConfig = field(default_factory=OdometryConfig)


@dataclass
class ReceiverConfig:
    """Tracking-loop preset (dissertation Table 5.3.1); the defaults are the ``low`` preset.

    ``low`` (``conf/receiver/low.yaml``, the shipped default) is GNSS-SDR on IQ data
    down-sampled to 4.092 MHz; with complex sampling the double-sided front-end
    bandwidth equals the sample rate. Its tracking states are assumed, those of a
    GNSS-SDR-like 1 ms software receiver. The other presets in ``conf/receiver/`` set
    every field they change.
    """

    name: str = "low"
    sampling_mhz: float = 4.092  #: sample rate [MHz]
    front_end_bw_mhz: float = 4.092  #: double-sided [MHz]
    correlator_spacing_chips: float = 0.5  #: early-late spacing [chip]
    dll_bw_hz: float = 2.0  #: DLL one-sided noise bandwidth [Hz]
    pll_bw_hz: float = 50.0  #: PLL one-sided noise bandwidth [Hz]
    integration_s: float = 0.001  #: coherent integration time [s]
    doppler_sigma_hz: float = 0.5  #: [Hz] at the reference C/N0, scales as 10^((ref - C/N0)/20)
    doppler_ref_cn0_dbhz: float = 45.0  #: [dB-Hz]
    #: C/N0 a satellite needs to be (re)acquired [dB-Hz]
    acquisition_threshold_dbhz: float = 33.0
    #: below this C/N0 the lock detector drops the channel [dB-Hz] (GNSS-SDR's default cn0_min is 25)
    lock_threshold_dbhz: float = 25.0
    #: time a signal must stay above the acquisition threshold before it is tracked again [s]
    reacquisition_s: float = 1.0
    #: the PLL holds carrier lock, and the receiver reports phase, while its 1-sigma jitter plus a
    #: third of the dynamic stress error stays below this (Kaplan's 3 sigma + theta_e <= 45 deg) [deg]
    carrier_lock_threshold_deg: float = 15.0
    #: the receiver tracks L2 as well as L1 (``scenario.dual_frequency`` needs it; a consumer chip does not)
    tracks_l2: bool = True

    def validate(self, where: str = "receiver") -> None:
        """Raise a one-line :class:`SimbenchError` for the first value the tracking models cannot use.

        The generator and its error sources trust a validated receiver; the
        :mod:`simbench.sim.tracking` functions check the raw numbers they are given.

        Parameters
        ----------
        where : str
            Config node name, prefixed to the field in the message.
        """
        for name in (
            "sampling_mhz",
            "front_end_bw_mhz",
            "correlator_spacing_chips",
            "dll_bw_hz",
            "pll_bw_hz",
            "integration_s",
            "carrier_lock_threshold_deg",
        ):
            require_positive(f"{where}.{name}", getattr(self, name), "see conf/receiver/ for presets")
        if not self.correlator_spacing_chips < 2.0:
            raise SimbenchError(
                f"{where}.correlator_spacing_chips",
                f"must be below 2 chips, got {self.correlator_spacing_chips}",
                "use an early-late spacing such as 0.1-1 chip",
            )
        low, high = INTEGRATION_RANGE_S
        if not low <= self.integration_s <= high:
            raise SimbenchError(
                f"{where}.integration_s",
                f"must be within {low:g}..{high:g} s for GPS C/A (one code period to one data bit), "
                f"got {self.integration_s}",
                f"give seconds, e.g. {where}.integration_s=0.001 or 0.02",
            )
        require_at_least(f"{where}.doppler_sigma_hz", self.doppler_sigma_hz, 0, "give a Doppler sigma in Hz")
        if not self.acquisition_threshold_dbhz >= self.lock_threshold_dbhz:
            raise SimbenchError(
                f"{where}.acquisition_threshold_dbhz",
                f"{self.acquisition_threshold_dbhz} dB-Hz is below the lock threshold {self.lock_threshold_dbhz} dB-Hz",
                "acquiring needs at least the C/N0 that keeps lock",
            )
        require_at_least(
            f"{where}.reacquisition_s",
            self.reacquisition_s,
            0,
            f"give the re-acquisition time in seconds, e.g. {where}.reacquisition_s=1",
        )


@dataclass
class ImuConfig:
    """IMU grade (Groves, Table 4.1 ranges). Noise densities per sqrt(Hz).

    The defaults are the ``consumer`` preset (``conf/imu/consumer.yaml``, the shipped
    default): consumer MEMS, Groves Table 4.1: gyro bias > 100 deg/h, ARW > 1 deg/sqrt(h),
    accel bias > 0.1 m/s^2. The other presets in ``conf/imu/`` set every field they change.
    """

    grade: str = "consumer"
    rate_hz: float = 100.0  #: sample rate [Hz]
    accel_bias_sigma_mps2: float = 0.1  #: turn-on bias, per axis [m/s^2]
    gyro_bias_sigma_dph: float = 100.0  #: turn-on bias [deg/h]
    accel_noise_mps2_rthz: float = 3e-3  #: velocity random walk density [m/s^2/sqrt(Hz)]
    gyro_noise_dph_rthz: float = 60.0  #: angle random walk density [deg/h/sqrt(Hz)] (=1 deg/sqrt(h))
    accel_bias_instability_mps2: float = 1e-3  #: Gauss-Markov bias drift std [m/s^2]
    gyro_bias_instability_dph: float = 10.0  #: Gauss-Markov bias drift std [deg/h]
    bias_tau_s: float = 300.0  #: Gauss-Markov correlation time of the bias drift [s]

    def validate(self, where: str = "imu") -> None:
        """Raise a one-line :class:`SimbenchError` for the first value the IMU model cannot use.

        Parameters
        ----------
        where : str
            Config node name, prefixed to the field in the message.
        """
        if not 100.0 <= self.rate_hz <= 1000.0:
            raise SimbenchError(
                f"{where}.rate_hz", f"must be within 100..1000 Hz, got {self.rate_hz}", f"set e.g. {where}.rate_hz=100"
            )
        check_imu_sigmas(self, where)
        if not 0 < self.bias_tau_s < math.inf:
            raise SimbenchError(
                f"{where}.bias_tau_s",
                f"must be positive and finite, got {self.bias_tau_s}",
                "give the bias correlation time in seconds, e.g. 300",
            )


def check_imu_sigmas(config: object, where: str) -> None:
    """Raise a one-line :class:`SimbenchError` for an IMU sigma of ``config`` outside 0..:data:`IMU_SIGMA_LIMITS`.

    For the simulated IMU (:class:`ImuConfig`) and the GNSS/INS estimators' model of it, which
    use the same field names and units.

    Parameters
    ----------
    config : dataclass instance
        Has the fields of :data:`IMU_SIGMA_LIMITS`.
    where : str
        Config node name, prefixed to the field in the message.
    """
    for name, limit in IMU_SIGMA_LIMITS.items():
        value = getattr(config, name)
        if not 0 <= value <= limit:  # NaN fails too
            raise SimbenchError(
                f"{where}.{name}",
                f"must be within 0..{limit:g} (more is beyond any IMU grade), got {value}",
                "check the unit in the field name; see conf/imu/ for presets",
            )


@dataclass
class SimConfig:
    """What :func:`simbench.simulate` needs: a scenario, a receiver, an IMU and a seed."""

    scenario: ScenarioConfig = field(default_factory=ScenarioConfig)
    receiver: ReceiverConfig = field(default_factory=ReceiverConfig)
    imu: ImuConfig = field(default_factory=ImuConfig)
    seed: int = 0


def sim_config_of(cfg: DataConfig) -> SimConfig:
    """``cfg`` as the :class:`SimConfig` the generator takes.

    Raises
    ------
    SimbenchError
        When ``cfg.scenario`` is not a :class:`ScenarioConfig` (:func:`simbench.source_registry.scenario_config`).
    """
    if isinstance(cfg, SimConfig):
        return cfg
    return SimConfig(scenario=scenario_config(cfg, ScenarioConfig), receiver=cfg.receiver, imu=cfg.imu, seed=cfg.seed)


def check_simulation(cfg: DataConfig) -> None:
    """The simulator's check of a data config (``Simulator.check``): :func:`validate_sim` of its :class:`SimConfig`.

    Here, beside the schema, not with the generator: the command line refuses a bad value without
    importing the simulation (:mod:`simbench.runs.schema_record`).
    """
    validate_sim(sim_config_of(cfg))


#: The fewest GNSS epochs a simulated scenario can have (one epoch failed deep in the atmosphere model).
MIN_EPOCHS = 2


def validate_sim(cfg: SimConfig) -> SimConfig:
    """Check what the types cannot: value ranges, and the files a trajectory or constellation kind needs."""
    check_choices(cfg)
    s = cfg.scenario
    if not s.duration_s > 0:  # NaN fails too
        raise SimbenchError(
            "scenario.duration_s",
            f"must be positive, got {s.duration_s}",
            "give the scenario length in seconds, e.g. scenario.duration_s=600",
        )
    if not s.rate_hz > 0:
        raise SimbenchError(
            "scenario.rate_hz",
            f"must be positive, got {s.rate_hz}",
            "give the GNSS epoch rate in Hz, e.g. scenario.rate_hz=1",
        )
    require_elevation_mask(
        "scenario.constellation.elevation_mask_deg",
        s.constellation.elevation_mask_deg,
        "give an elevation mask in degrees, e.g. 7",
    )
    cfg.imu.validate("imu")
    check_memory(cfg)
    epochs = round(s.duration_s * s.rate_hz)  # the trajectory's samples (finite: check_memory bounds it)
    if epochs < MIN_EPOCHS:
        raise SimbenchError(
            "scenario.duration_s",
            f"{s.duration_s:g} s at {s.rate_hz:g} Hz gives {epochs} epoch(s), fewer than {MIN_EPOCHS}",
            "lengthen scenario.duration_s or raise scenario.rate_hz, e.g. scenario.duration_s=60",
        )
    if s.trajectory.kind == TrajectoryKind.replay:
        if not s.trajectory.replay.path:
            raise SimbenchError(
                "scenario.trajectory.replay.path",
                "no trajectory file given",
                "set it to a 'SOW X Y Z' file, e.g. '${simbench_data:wvu_drives/drive_1.xyz}'",
            )
        require_file("scenario.trajectory.replay.path", s.trajectory.replay.path)
    if s.constellation.kind == ConstellationKind.broadcast:
        if not s.constellation.nav_path:
            raise SimbenchError(
                "scenario.constellation.nav_path",
                "no navigation file given",
                "set it to a RINEX GPS navigation file, e.g. '${simbench_data:wvu_drives/brdc.18n}'",
            )
        require_file("scenario.constellation.nav_path", s.constellation.nav_path)
    cfg.receiver.validate("receiver")
    for node in ("scenario", "receiver", "imu"):
        check_bounds(getattr(cfg, node), node)
    if s.dual_frequency and not cfg.receiver.tracks_l2:
        raise SimbenchError(
            "scenario.dual_frequency",
            f"is true, but the '{cfg.receiver.name}' receiver tracks L1 only (receiver.tracks_l2=false)",
            "set scenario.dual_frequency=false, or pick a receiver that tracks L2, e.g. receiver=low or geodetic",
        )
    check_reachable_cn0(cfg)
    return cfg


def check_reachable_cn0(cfg: SimConfig) -> None:
    """Raise a one-line :class:`SimbenchError` when no satellite could ever be acquired.

    The strongest mean C/N0 the scenario gives (a satellite at boresight:
    :func:`~simbench.sim.tracking.cn0_mean_dbhz`, :data:`ANTENNA_GAIN_DBI`) plus three sigmas of its noise
    and fading must reach the receiver's acquisition threshold (which is at least
    its lock threshold, :meth:`ReceiverConfig.validate`); otherwise every epoch is
    empty and the estimators would blame their elevation mask.
    """
    cn0 = cfg.scenario.errors.cn0
    peak = ANTENNA_GAIN_DBI[0] + cn0.received_power_dbw + cn0.constant_db  # the gain at boresight
    reach = peak + 3.0 * math.hypot(cn0.noise_db, cn0.fade_sigma_db)
    threshold = cfg.receiver.acquisition_threshold_dbhz
    if not threshold <= reach:
        raise SimbenchError(
            "receiver.acquisition_threshold_dbhz",
            f"{threshold} dB-Hz is above the strongest C/N0 the scenario gives ({peak:.1f} dB-Hz at boresight, "
            f"{reach:.1f} with 3-sigma noise), so no satellite is ever acquired",
            "lower it (the presets in conf/receiver/ use 15-33 dB-Hz) or raise scenario.errors.cn0.received_power_dbw",
        )


def memory_budget() -> int:
    """Bytes a scenario may take: half the physical memory (:data:`DEFAULT_MEMORY_BUDGET` where unknown)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 2
    except (AttributeError, ValueError, OSError):  # no sysconf (Windows) or no such name
        return DEFAULT_MEMORY_BUDGET


def check_memory(cfg: SimConfig) -> None:
    """Raise a one-line :class:`SimbenchError` when the scenario would not fit in :func:`memory_budget`.

    Estimated up front from the satellite-epochs (duration x rate x :data:`MAX_SATELLITES`) and the
    IMU samples (duration x IMU rate), so a mistyped duration stops before any job instead of ending
    in a MemoryError hours into a sweep.
    """
    s = cfg.scenario
    epochs = s.duration_s * s.rate_hz
    need = epochs * MAX_SATELLITES * BYTES_PER_SATELLITE_EPOCH + s.duration_s * cfg.imu.rate_hz * BYTES_PER_IMU_SAMPLE
    budget = memory_budget()
    if not need <= budget:
        raise SimbenchError(
            "scenario.duration_s",
            f"{s.duration_s:g} s at {s.rate_hz:g} Hz (IMU {cfg.imu.rate_hz:g} Hz) needs about {need / 2**30:.3g} GB, "
            f"over the budget of {budget / 2**30:.3g} GB (half this machine's memory)",
            f"shorten scenario.duration_s (at most about {s.duration_s * budget / need:.0f} s) or lower the rates",
        )
