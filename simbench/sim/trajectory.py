"""Vehicle trajectories: a drive through a street grid, a small-UAV flight, a recorded replay.

Every trajectory is sampled on a uniform time grid (the IMU rate) and carries
ECEF position, velocity and kinematic acceleration, the attitude of the body
(x forward, y right, z down) with respect to the local NED frame, and the
angular rate of the body with respect to the Earth, in body axes.

The synthetic trajectories are built analytically so that their derivatives
are exact rather than numerical:

* the horizontal path is a chain of straight lines, clothoids (Euler spirals,
  curvature linear in arc length, evaluated with Fresnel integrals) and
  circular arcs, so heading and curvature are continuous;
* speed follows smoothstep transitions (``3x^2 - 2x^3``) between constant
  levels, so the along-track acceleration is continuous and peaks at the
  configured limit;
* the path lives in the local-level Cartesian frame of the origin (NED0),
  which is Earth-fixed, so ECEF velocity and acceleration are the NED0 ones
  rotated by a constant matrix -- no approximation. "Flat ground" means the
  tangent plane at the origin: the ellipsoidal height rises by r^2 / (2 R)
  (3 cm at 600 m from the origin).
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline, CubicSpline, make_smoothing_spline
from scipy.special import fresnel

from simbench.core.constants import DEG, G0_STD, WGS84_A, WGS84_E2
from simbench.core.frames import (
    dcm_body_to_ecef,
    dcm_body_to_ned,
    dcm_body_to_ned_from_trig,
    dcm_ned_to_ecef,
    ecef_from_geodetic,
    geodetic_from_ecef,
    geodetic_trig,
)
from simbench.errors import SimbenchError
from simbench.sim.config import (
    FlightConfig,
    HeightDistribution,
    NlosConfig,
    ReplayConfig,
    TrajectoryConfig,
    UrbanDriveConfig,
)
from simbench.sim.trajectory_file import REPLAY_PATH_FIELD, read_xyz_trajectory

#: A smoothstep speed change of dv over T seconds peaks at 1.5 dv / T.
_SMOOTHSTEP_PEAK = 1.5
#: Urban corners: each clothoid turns pi/8, the arc the remaining pi/4 of a 90 deg turn.
_URBAN_CLOTHOID_TURN_RAD = math.pi / 8.0
#: Take-off roll: peak longitudinal acceleration of the UAV on the ground [m/s^2].
TAKEOFF_ACCEL_MPS2 = 2.0
#: Time to establish (or stop) the climb rate at lift-off and level-off [s].
CLIMB_TRANSITION_S = 3.0
#: Time to roll into a turn (length of the entry clothoid at airspeed) [s].
ROLL_IN_S = 2.0
#: Straight flight after reaching cruise altitude before the first turn [s].
LEVEL_OFF_MARGIN_S = 5.0
#: Below this horizontal speed the heading of a replayed trajectory is held [m/s].
HOLD_HEADING_SPEED_MPS = 0.5
#: Faster motion lasting less than this is treated as noise of a standing vehicle (RTK jumps) [s].
MIN_MOVING_S = 1.0
#: Scatter of a recorded reference position about the path it measures [m]: centimetres
#: while RTK is fixed, decimetres (WVU drive 2: half a metre) while it floats.
REPLAY_POSITION_SIGMA_M = 0.2
#: Power spectral density of a car's acceleration, the smoothness prior of a replayed path [m^2/s^3].
#: With 10 Hz positions of REPLAY_POSITION_SIGMA_M scatter the spline passes motion slower than
#: about 0.2 Hz (half power where (2 pi f)^4 = q dt / sigma^2): a car's turns and stops, not the jumps.
REPLAY_ACCEL_PSD = 1.0
#: A reference epoch farther than this from the smoothed path is an outlier (wrong fix) and dropped [m].
REPLAY_OUTLIER_M = 1.0
#: Rounds of smoothing and outlier rejection per segment (stops earlier when no epoch is dropped).
_REPLAY_OUTLIER_ROUNDS = 5
#: A smoothing spline needs this many epochs; shorter segments are interpolated.
_MIN_SMOOTHED_EPOCHS = 5
#: Facade distances are never closer than this to the antenna [m].
_MIN_WALL_DISTANCE_M = 0.5


# =========================================================================== data


@dataclass(frozen=True)
class StreetGeometry:
    """Buildings along the road at each sample, for the street-canyon NLOS model.

    All arrays have shape (k,). ``road_heading_rad`` is the direction of travel
    along the road axis (clockwise from north); left and right are relative to
    it. Heights are 0 where that side is open (no building, or an intersection).
    """

    road_heading_rad: np.ndarray  #: road axis direction, clockwise from north [rad]
    wall_left_m: np.ndarray  #: perpendicular distance vehicle -> left facade [m]
    wall_right_m: np.ndarray  #: perpendicular distance vehicle -> right facade [m]
    height_left_m: np.ndarray  #: left building height [m]; 0 = open
    height_right_m: np.ndarray  #: right building height [m]; 0 = open


@dataclass(frozen=True)
class Trajectory:
    """True motion sampled on a uniform time grid.

    Attributes
    ----------
    t : ndarray, shape (k,)
        Time since scenario start [s].
    pos, vel, acc : ndarray, shape (k, 3)
        ECEF position [m], velocity [m/s] and kinematic acceleration (second
        derivative of the position in the Earth-fixed frame) [m/s^2].
    att : ndarray, shape (k, 3)
        Roll, pitch, yaw of the body w.r.t. the local NED frame [rad].
    omega_eb_b : ndarray, shape (k, 3)
        Angular rate of the body w.r.t. ECEF, in body axes [rad/s].
    street : StreetGeometry or None
        Buildings along the road (urban drive only).
    valid : ndarray of bool, shape (k,)
        False inside data gaps of a replay (the samples there are a smooth
        bridge, not truth); all True for synthetic trajectories.
    c_b_e : ndarray, shape (k, 3, 3)
        Body-to-ECEF rotation C_b^e, the attitude in the frame the IMU model works in;
        from ``pos`` and ``att`` unless the constructor has it already.
    """

    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    att: np.ndarray
    omega_eb_b: np.ndarray
    street: StreetGeometry | None = None
    valid: np.ndarray = None  # type: ignore[assignment]  # all True unless given: __post_init__ fills it
    c_b_e: np.ndarray = None  # type: ignore[assignment]  # from pos and att unless given: __post_init__ fills it

    def __post_init__(self) -> None:
        if self.valid is None:
            object.__setattr__(self, "valid", np.ones(len(self.t), dtype=bool))
        if self.c_b_e is None:
            object.__setattr__(self, "c_b_e", dcm_body_to_ecef(self.pos, self.att))

    def valid_every(self, step: float) -> np.ndarray:
        """Indices of every ``step``-th sample (rounded to a whole number), the invalid ones left out:
        a sensor sampled at this trajectory's rate / ``step``."""
        idx = np.arange(0, len(self.t), int(round(step)))
        return idx[self.valid[idx]]


# =========================================================================== frames


def _euler_rates_to_body(
    sr: np.ndarray,
    cr: np.ndarray,
    sp: np.ndarray,
    cp: np.ndarray,
    roll_dot: np.ndarray,
    pitch_dot: np.ndarray,
    yaw_dot: np.ndarray,
) -> np.ndarray:
    """Body angular rate [rad/s] from sin/cos of roll and pitch and the z-y-x Euler rates [rad/s]."""
    return np.stack(
        [roll_dot - yaw_dot * sp, pitch_dot * cr + yaw_dot * sr * cp, -pitch_dot * sr + yaw_dot * cr * cp], axis=-1
    )


# =========================================================================== path geometry
# Horizontal positions are complex numbers z = north + i east, so a unit step
# along heading h (clockwise from north) is exp(i h).


def _increment(sigma: np.ndarray, h0: np.ndarray, k0: np.ndarray, dk: np.ndarray) -> np.ndarray:
    """Displacement after arc length sigma along a path of heading h0 + k0 s + dk s^2 / 2.

    All arguments have the same shape; returns complex north + i east [m].
    """
    out = sigma * np.exp(1j * h0)
    arc = (k0 != 0.0) & (dk == 0.0)
    if arc.any():
        sg, h, k = sigma[arc], h0[arc], k0[arc]
        out[arc] = (np.exp(1j * (h + k * sg)) - np.exp(1j * h)) / (1j * k)
    spiral = dk != 0.0
    if spiral.any():
        # Complete the square: heading = phi + (dk/2)(s + b)^2, then u = a (s + b) turns the
        # integral of exp(i heading) into Fresnel integrals; dk < 0 is the mirror image.
        sg, h, k, d = sigma[spiral], h0[spiral], k0[spiral], dk[spiral]
        sgn = np.sign(d)
        a = np.sqrt(np.abs(d) / np.pi)
        b = k / d
        s0, c0 = fresnel(a * b)
        s1, c1 = fresnel(a * (sg + b))
        f = np.exp(1j * (sgn * h - k * k / (2.0 * np.abs(d)))) * ((c1 - c0) + 1j * (s1 - s0)) / a
        out[spiral] = f.real + 1j * sgn * f.imag
    return out


def _increment_scalar(sigma: float, h0: float, k0: float, dk: float) -> complex:
    """:func:`_increment` for one primitive, without the array overhead (path building loops)."""
    if dk == 0.0:
        if k0 == 0.0:
            return sigma * cmath.exp(1j * h0)
        return (cmath.exp(1j * (h0 + k0 * sigma)) - cmath.exp(1j * h0)) / (1j * k0)
    sgn = -1.0 if dk < 0.0 else 1.0
    a = math.sqrt(abs(dk) / math.pi)
    b = k0 / dk
    s0, c0 = fresnel(a * b)
    s1, c1 = fresnel(a * (sigma + b))
    f = cmath.exp(1j * (sgn * h0 - k0 * k0 / (2.0 * abs(dk)))) * complex(c1 - c0, s1 - s0) / a
    return complex(f.real, sgn * f.imag)


@dataclass(frozen=True)
class _Path:
    s0: np.ndarray  #: arc length at the start of each primitive [m]
    length: np.ndarray
    z0: np.ndarray  #: start point (complex, north + i east) [m]
    h0: np.ndarray  #: start heading [rad]
    k0: np.ndarray  #: start curvature [1/m], positive turning right
    dk: np.ndarray  #: curvature rate [1/m^2]
    tag: np.ndarray  #: caller's label (street edge index)

    @property
    def total(self) -> float:
        return float(self.s0[-1] + self.length[-1])


class _PathBuilder:
    """Chains lines, clothoids and arcs with continuous position, heading and curvature."""

    def __init__(self, z: complex, heading: float) -> None:
        self.z, self.h, self.k, self.s = complex(z), float(heading), 0.0, 0.0
        self._rows: list[tuple[float, float, complex, float, float, float, int]] = []

    def add(self, length: float, dk: float, tag: int, k_end: float | None = None) -> None:
        if length <= 0.0:
            return
        self._rows.append((self.s, length, self.z, self.h, self.k, dk, tag))
        self.z += _increment_scalar(length, self.h, self.k, dk)
        self.h += self.k * length + 0.5 * dk * length * length
        # pin the end curvature so that rounding cannot leave a tiny curvature on a "straight"
        self.k = self.k + dk * length if k_end is None else k_end
        self.s += length

    def turn(self, angle: float, radius: float, clothoid: float, tag_in: int, tag_out: int) -> None:
        """Clothoid in, circular arc, clothoid out; ``angle`` > 0 turns right [rad]."""
        kappa = math.copysign(1.0 / radius, angle)
        arc = radius * abs(angle) - clothoid  # each clothoid turns clothoid / (2 radius)
        self.add(clothoid, kappa / clothoid, tag_in, k_end=kappa)
        self.add(0.5 * arc, 0.0, tag_in)
        self.add(0.5 * arc, 0.0, tag_out)
        self.add(clothoid, -kappa / clothoid, tag_out, k_end=0.0)

    def build(self) -> _Path:
        s0, length, z0, h0, k0, dk, tag = zip(*self._rows)
        return _Path(
            np.array(s0), np.array(length), np.array(z0), np.array(h0), np.array(k0), np.array(dk), np.array(tag)
        )


def _eval_path(path: _Path, s: np.ndarray) -> tuple[np.ndarray, ...]:
    """Position (complex), heading, curvature, d(curvature)/ds, primitive index and offset in it at s."""
    i = np.clip(np.searchsorted(path.s0, s, side="right") - 1, 0, len(path.s0) - 1)
    sigma = np.clip(s - path.s0[i], 0.0, path.length[i])
    h0, k0, dk = path.h0[i], path.k0[i], path.dk[i]
    z = path.z0[i] + _increment(sigma, h0, k0, dk)
    return z, h0 + sigma * (k0 + 0.5 * dk * sigma), k0 + dk * sigma, dk, i, sigma


# =========================================================================== speed profiles
# A profile is a list of phases (duration T, start speed v0, change dv); inside a phase
# v = v0 + dv S(tau), S = 3 tau^2 - 2 tau^3, tau = (t - t0) / T. Holds have dv = 0.


def _plan_speed(
    kp_s: np.ndarray, kp_u: np.ndarray, kp_stop_s: np.ndarray, cap: np.ndarray, a_max: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fastest smoothstep profile through keypoints with speed caps and stops.

    Parameters
    ----------
    kp_s : ndarray, shape (n,)
        Arc length of the keypoints [m], increasing.
    kp_u : ndarray, shape (n,)
        Speed cap at each keypoint [m/s]; 0 where the vehicle stops.
    kp_stop_s : ndarray, shape (n,)
        Standstill duration at each keypoint [s] (used where kp_u is 0).
    cap : ndarray, shape (n - 1,)
        Speed cap on the section after each keypoint [m/s].
    a_max : float
        Peak along-track acceleration [m/s^2].

    Returns
    -------
    T, v0, dv : ndarray
        Phase durations [s], start speeds and speed changes [m/s].
    """
    lens = np.diff(kp_s)
    u = np.minimum(kp_u, np.minimum(np.r_[cap, np.inf], np.r_[np.inf, cap]))
    # A complete smoothstep change covers the same distance as a constant acceleration of
    # a_max / 1.5, so the classic forward/backward v^2 passes apply with that value.
    two_a = 2.0 * a_max / _SMOOTHSTEP_PEAK
    for i in range(len(u) - 2, -1, -1):
        u[i] = min(u[i], math.sqrt(u[i + 1] ** 2 + two_a * lens[i]))
    for i in range(len(u) - 1):
        u[i + 1] = min(u[i + 1], math.sqrt(u[i] ** 2 + two_a * lens[i]))
    ua, ub = u[:-1], u[1:]
    peak = np.minimum(cap, np.sqrt(0.5 * (two_a * lens + ua**2 + ub**2)))
    peak = np.maximum(peak, np.maximum(ua, ub))
    t_up = _SMOOTHSTEP_PEAK * (peak - ua) / a_max
    t_dn = _SMOOTHSTEP_PEAK * (peak - ub) / a_max
    hold = np.maximum(lens - 0.5 * (ua + peak) * t_up - 0.5 * (ub + peak) * t_dn, 0.0)
    t_hold = np.where(peak > 0.0, hold / np.where(peak > 0.0, peak, 1.0), 0.0)
    stop = np.where(ua == 0.0, kp_stop_s[:-1], 0.0)
    zero = np.zeros_like(ua)
    T = np.stack([stop, t_up, t_hold, t_dn], axis=1).ravel()
    v0 = np.stack([zero, ua, peak, peak], axis=1).ravel()
    dv = np.stack([zero, peak - ua, zero, ub - peak], axis=1).ravel()
    keep = T > 0.0
    return T[keep], v0[keep], dv[keep]


def _drop_empty(T: np.ndarray, v0: np.ndarray, dv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Remove zero-length phases (they would divide by zero in :func:`_eval_speed`)."""
    keep = T > 0.0
    return T[keep], v0[keep], dv[keep]


def _eval_speed(
    T: np.ndarray, v0: np.ndarray, dv: np.ndarray, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distance [m], speed [m/s] and acceleration [m/s^2] of a phase list at times t [s].

    Beyond the last phase the final speed is held.
    """
    t_start = np.r_[0.0, np.cumsum(T)[:-1]]
    s_start = np.r_[0.0, np.cumsum(T * (v0 + 0.5 * dv))[:-1]]
    i = np.clip(np.searchsorted(t_start, t, side="right") - 1, 0, len(T) - 1)
    Ti = T[i]
    tau = np.clip((t - t_start[i]) / Ti, 0.0, 1.0)
    beyond = np.maximum(t - t_start[i] - Ti, 0.0)
    v = v0[i] + dv[i] * tau * tau * (3.0 - 2.0 * tau)
    s = s_start[i] + Ti * (v0[i] * tau + dv[i] * (tau * tau * tau) * (1.0 - 0.5 * tau)) + (v0[i] + dv[i]) * beyond
    a = dv[i] / Ti * 6.0 * tau * (1.0 - tau)
    return s, v, a


# =========================================================================== assembly


def _time_grid(duration_s: float, rate_hz: float) -> np.ndarray:
    if not duration_s > 0.0:
        raise SimbenchError(
            "scenario.duration_s",
            f"must be positive, got {duration_s}",
            "give the scenario length in seconds, e.g. scenario.duration_s=600",
        )
    if not rate_hz > 0.0:
        raise SimbenchError("imu.rate_hz", f"must be positive, got {rate_hz}", "set e.g. imu.rate_hz=100")
    k = int(round(duration_s * rate_hz))
    if k < 2:
        raise SimbenchError(
            "scenario.duration_s", f"{duration_s} s gives fewer than 2 samples at {rate_hz} Hz", "use a longer duration"
        )
    return np.arange(k) / rate_hz


def _assemble_local(
    cfg: TrajectoryConfig,
    t: np.ndarray,
    z: np.ndarray,
    up: np.ndarray,
    yaw: np.ndarray,
    v_h: np.ndarray,
    a_h: np.ndarray,
    kappa: np.ndarray,
    v_u: np.ndarray,
    a_u: np.ndarray,
    roll: np.ndarray,
    roll_dot: np.ndarray,
    pitch: np.ndarray,
    pitch_dot: np.ndarray,
    street: StreetGeometry | None,
) -> Trajectory:
    """Trajectory from a path in the origin's NED frame (NED0, Earth-fixed).

    Attitude angles and rates are given w.r.t. NED0, where the Euler-rate relation
    yields omega_eb_b exactly; the reported attitude is re-expressed in the local
    NED frame of each sample (they differ by meridian convergence, ~1e-4 rad/km).
    """
    lat0, lon0 = cfg.origin_lat_deg * DEG, cfg.origin_lon_deg * DEG
    c0 = dcm_ned_to_ecef(lat0, lon0)
    r0 = ecef_from_geodetic(lat0, lon0, cfg.origin_h_m)
    cy, sy = np.cos(yaw), np.sin(yaw)
    lateral = v_h * v_h * kappa
    p_n = np.stack([z.real, z.imag, -up], axis=-1)
    v_n = np.stack([v_h * cy, v_h * sy, -v_u], axis=-1)
    a_n = np.stack([a_h * cy - lateral * sy, a_h * sy + lateral * cy, -a_u], axis=-1)
    pos = r0 + p_n @ c0.T
    vel = v_n @ c0.T
    acc = a_n @ c0.T
    sr, cr, sp, cp = np.sin(roll), np.cos(roll), np.sin(pitch), np.cos(pitch)
    omega = _euler_rates_to_body(sr, cr, sp, cp, roll_dot, pitch_dot, v_h * kappa)
    # C_b^e = C_n0^e C_b^n0 with a constant C_n0^e: one (3 x 3) x (3 x 3k) product on the
    # (3, 3, k) layout, instead of k small matrix products
    c_b_n0 = np.moveaxis(dcm_body_to_ned_from_trig(sr, cr, sp, cp, sy, cy), 0, -1)
    c_b_e = np.moveaxis(np.tensordot(c0, c_b_n0, axes=(1, 0)), -1, 0)
    # the local attitude needs five entries of C_b^n = C_e^n C_b^e: rows of C_e^n (north, east,
    # down in ECEF) times columns of C_b^e
    sl, cl, so, co, _ = geodetic_trig(pos)
    north = (-sl * co, -sl * so, cl)
    east = (-so, co)
    down = (-cl * co, -cl * so, -sl)

    def entry(row: tuple[np.ndarray, ...], col: int) -> np.ndarray:
        out = row[0] * c_b_e[:, 0, col]
        for i in range(1, len(row)):
            out += row[i] * c_b_e[:, i, col]
        return out

    att = np.stack(
        [
            np.arctan2(entry(down, 1), entry(down, 2)),
            -np.arcsin(np.clip(entry(down, 0), -1.0, 1.0)),
            np.arctan2(entry(east, 0), entry(north, 0)),
        ],
        axis=-1,
    )
    return Trajectory(t=t, pos=pos, vel=vel, acc=acc, att=att, omega_eb_b=omega, street=street, c_b_e=c_b_e)


def _positive(value: float, name: str, fix: str) -> None:
    if not value > 0.0:
        raise SimbenchError(name, f"must be positive, got {value}", fix)


# =========================================================================== urban drive

_DIRS = np.array([1.0, 1j, -1.0, -1j])  #: unit steps north, east, south, west
_DI = (0, 1, 0, -1)  #: grid column change per direction (east index)
_DJ = (1, 0, -1, 0)  #: grid row change per direction (north index)


def urban_drive(
    cfg: TrajectoryConfig, nlos: NlosConfig, duration_s: float, rate_hz: float, rng: np.random.Generator
) -> Trajectory:
    """Drive through a rectangular street grid centred on the origin.

    At every intersection the car goes straight or turns left or right
    (uniformly among the choices that stay inside the grid), with corners made
    of clothoid - arc (``turn_radius_m``) - clothoid. Speed: cruise on the
    blocks, ``turn_speed_mps`` through corners, a stop before an intersection
    with ``stop_probability`` for a uniform ``stop_duration_s``, smoothstep speed
    changes peaking at ``max_accel_mps2``; standing still for ``start_static_s``
    at the start. The car drives on the road axis on flat ground (pitch = roll = 0).

    Parameters
    ----------
    cfg : TrajectoryConfig
        Origin (grid centre) and ``cfg.urban_drive``.
    nlos : NlosConfig
        Building heights, facade distances and the open fraction, drawn per block side.
    duration_s : float
        Length of the trajectory [s]; ``round(duration_s * rate_hz)`` samples.
    rate_hz : float
        Sample rate [Hz] (the IMU rate).
    rng : numpy.random.Generator
        Source of the route, stops and buildings.

    Returns
    -------
    Trajectory
        With ``street`` set.

    Raises
    ------
    SimbenchError
        For non-positive sizes, speeds or rates, or a turn radius too large for the blocks.
    """
    u: UrbanDriveConfig = cfg.urban_drive
    t = _time_grid(duration_s, rate_hz)
    _check_urban_drive(u, nlos)
    corner = _Corner.of(u)
    grid = _StreetGrid(u.n_blocks_east, u.n_blocks_north, u.block_length_m, nlos, rng)
    geo, kps = _route(u, corner, grid, duration_s, rng)
    kp = np.array(kps)
    phases = _plan_speed(kp[:, 0], kp[:, 1], kp[:, 2], kp[:-1, 3], u.max_accel_mps2)
    s, v, a = _eval_speed(*phases, t)
    z, heading, kappa, _, prim, _ = _eval_path(geo, np.minimum(s, geo.total))
    street = grid.street(z, geo.tag[prim])
    zero = np.zeros_like(t)
    return _assemble_local(cfg, t, z, zero, heading, v, a, kappa, zero, zero, zero, zero, zero, zero, street)


_URBAN_DRIVE = "scenario.trajectory.urban_drive"


def _check_urban_drive(u: UrbanDriveConfig, nlos: NlosConfig) -> None:
    """One-line :class:`SimbenchError` for sizes, speeds or durations a street grid cannot have."""
    for name in ("block_length_m", "cruise_speed_mps", "turn_speed_mps", "max_accel_mps2", "turn_radius_m"):
        _positive(getattr(u, name), f"{_URBAN_DRIVE}.{name}", "see conf/scenario/ for typical values")
    if u.n_blocks_east < 1 or u.n_blocks_north < 1:
        raise SimbenchError(
            f"{_URBAN_DRIVE}.n_blocks_east",
            "the grid needs at least one block each way",
            "set n_blocks_east and n_blocks_north >= 1",
        )
    if min(u.stop_duration_s) < 0.0 or u.start_static_s < 0.0:
        raise SimbenchError(
            f"{_URBAN_DRIVE}.stop_duration_s",
            "durations must be non-negative",
            "give e.g. stop_duration_s=[5, 30] and start_static_s=30",
        )
    _check_buildings(nlos)


@dataclass(frozen=True)
class _Corner:
    """A 90 degree corner of clothoid - arc - clothoid: its clothoid length, the distance from the
    intersection to where it starts, and its length along the path [m]."""

    clothoid: float
    tangent: float
    length: float

    @classmethod
    def of(cls, u: UrbanDriveConfig) -> _Corner:
        R = u.turn_radius_m
        clothoid = 2.0 * R * _URBAN_CLOTHOID_TURN_RAD
        path = _PathBuilder(0j, 0.0)
        path.turn(math.pi / 2, R, clothoid, 0, 0)
        tangent = path.z.real  # vertex to turn start; equals path.z.imag by symmetry
        if 2.0 * tangent >= u.block_length_m:
            raise SimbenchError(
                f"{_URBAN_DRIVE}.turn_radius_m",
                f"corners of radius {R} m need blocks longer than {2 * tangent:.1f} m",
                "reduce turn_radius_m or increase block_length_m",
            )
        return cls(clothoid, tangent, path.s)


class _StreetGrid:
    """The street grid: intersections (i north, j east), its blocks' sides (buildings drawn per side) and
    the edges a route has driven along (each with its axis, direction and sides)."""

    def __init__(self, ne: int, nn: int, block_m: float, nlos: NlosConfig, rng: np.random.Generator) -> None:
        self.ne, self.nn, self.L = ne, nn, block_m
        # Side 0 is on the left when driving towards +east (E-W streets) or +north (N-S streets).
        self.sides = {
            kind: block_sides(nlos, shape, rng) for kind, shape in (("ew", (ne, nn + 1, 2)), ("ns", (ne + 1, nn, 2)))
        }
        self.edges: list[tuple[complex, complex, float, float, float, float]] = []  # axis start, direction, sides

    def node(self, i: int, j: int) -> complex:
        return complex((j - self.nn / 2) * self.L, (i - self.ne / 2) * self.L)

    def inside(self, i: int, j: int) -> bool:
        return 0 <= i <= self.ne and 0 <= j <= self.nn

    def sides_of(self, i: int, j: int, d: int) -> tuple[float, float, float, float]:
        """(left distance, right distance, left height, right height) leaving node (i, j) along d."""
        kind, ii, jj = {0: ("ns", i, j), 1: ("ew", i, j), 2: ("ns", i, j - 1), 3: ("ew", i - 1, j)}[d]
        dist, height = self.sides[kind]
        if kind == "ns":  # side 0 is west: left when driving north
            left, right = (0, 1) if d == 0 else (1, 0)
        else:  # side 0 is north: left when driving east
            left, right = (0, 1) if d == 1 else (1, 0)
        return dist[ii, jj, left], dist[ii, jj, right], height[ii, jj, left], height[ii, jj, right]

    def new_edge(self, i: int, j: int, d: int) -> int:
        """Record the edge leaving node (i, j) along d; its tag."""
        self.edges.append((self.node(i, j), complex(_DIRS[d]), *self.sides_of(i, j, d)))
        return len(self.edges) - 1

    def street(self, z: np.ndarray, tag: np.ndarray) -> StreetGeometry:
        """Street geometry at positions ``z`` from the block side of edge ``tag`` (corners switch half-way);
        the crossing street's facades are taken at the same setback as this block side's."""
        e = np.array([(a0.real, a0.imag, dr.real, dr.imag, *rest) for a0, dr, *rest in self.edges])[tag]
        rel = (z - (e[:, 0] + 1j * e[:, 1])) * (e[:, 2] - 1j * e[:, 3])  # along + i right-of-axis
        to_crossing = np.minimum(np.abs(rel.real), np.abs(self.L - rel.real))
        dl, dr, hl, hr = e[:, 4], e[:, 5], e[:, 6], e[:, 7]
        return StreetGeometry(
            road_heading_rad=np.arctan2(e[:, 3], e[:, 2]) % (2 * np.pi),
            wall_left_m=np.maximum(dl + rel.imag, _MIN_WALL_DISTANCE_M),
            wall_right_m=np.maximum(dr - rel.imag, _MIN_WALL_DISTANCE_M),
            height_left_m=np.where(to_crossing < dl, 0.0, hl),
            height_right_m=np.where(to_crossing < dr, 0.0, hr),
        )


def _route(
    u: UrbanDriveConfig, corner: _Corner, grid: _StreetGrid, duration_s: float, rng: np.random.Generator
) -> tuple[_Path, list[tuple[float, float, float, float]]]:
    """A random route through ``grid``: the built path and its speed keypoints (arc length, speed cap,
    standstill, cap on the following section). At every intersection the car goes straight or turns
    (uniformly among the choices that stay inside), stopping with ``stop_probability``."""
    L, tangent = u.block_length_m, corner.tangent
    v_cruise = u.cruise_speed_mps
    v_turn = min(u.turn_speed_mps, v_cruise)
    # Start in the middle of a random block, facing a random way along it.
    while True:
        i, j, d = int(rng.integers(grid.ne + 1)), int(rng.integers(grid.nn + 1)), int(rng.integers(4))
        if grid.inside(i + _DI[d], j + _DJ[d]):
            break
    tag = grid.new_edge(i, j, d)
    path = _PathBuilder(grid.node(i, j) + 0.5 * L * _DIRS[d], d * math.pi / 2)
    i, j = i + _DI[d], j + _DJ[d]
    kps: list[tuple[float, float, float, float]] = [(0.0, 0.0, u.start_static_s, v_cruise)]
    # the car cannot cover more than cruise * duration, and blocks are at least L - 2 tangent long
    n_nodes = int(math.ceil(v_cruise * duration_s / (L - 2.0 * tangent))) + 2
    for _ in range(n_nodes):
        options = [dd for dd in (d, (d + 1) % 4, (d - 1) % 4) if grid.inside(i + _DI[dd], j + _DJ[dd])]
        d_new = options[int(rng.integers(len(options)))]
        stop = bool(rng.random() < u.stop_probability)
        stop_s = float(rng.uniform(*u.stop_duration_s))
        vertex = grid.node(i, j)
        to_vertex = abs(vertex - path.z)
        s_stop = path.s + to_vertex - tangent
        if d_new == d:
            path.add(to_vertex, 0.0, tag)
            if stop:
                kps.append((s_stop, 0.0, stop_s, v_cruise))
            tag = grid.new_edge(i, j, d_new)
        else:
            path.add(to_vertex - tangent, 0.0, tag)
            kps.append((s_stop, 0.0 if stop else v_turn, stop_s if stop else 0.0, v_turn))
            tag_out = grid.new_edge(i, j, d_new)
            turn = math.pi / 2 if d_new == (d + 1) % 4 else -math.pi / 2
            path.turn(turn, u.turn_radius_m, corner.clothoid, tag, tag_out)
            kps.append((s_stop + corner.length, v_turn, 0.0, v_cruise))
            tag = tag_out
        d, i, j = d_new, i + _DI[d_new], j + _DJ[d_new]
    path.add(abs(grid.node(i, j) - path.z) - tangent, 0.0, tag)
    kps.append((path.s, 0.0, 0.0, v_cruise))
    return path.build(), kps


def block_sides(nlos: NlosConfig, shape: tuple[int, ...], rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Facade distance and building height of block sides drawn from the canyon's distributions.

    Heights are uniform over ``building_height_m`` or, with
    ``height_distribution: rayleigh``, Rayleigh with scale
    ``building_height_scale_m`` (the statistical built-up area of
    ITU-R P.1410-5; median 1.18 times the scale); distances are uniform over
    ``wall_distance_m``; a side is open (height 0) with ``open_fraction``.

    Parameters
    ----------
    nlos : NlosConfig
    shape : tuple of int
        Shape of the arrays (block sides).
    rng : numpy.random.Generator

    Returns
    -------
    distance_m, height_m : ndarray
        Road axis to facade [m] and building height above the antenna [m].
    """
    if nlos.height_distribution == HeightDistribution.rayleigh:
        height = rng.rayleigh(nlos.building_height_scale_m, size=shape)
    else:
        height = rng.uniform(*nlos.building_height_m, size=shape)
    dist = rng.uniform(*nlos.wall_distance_m, size=shape)
    height[rng.random(shape) < nlos.open_fraction] = 0.0
    return dist, height


def _check_buildings(nlos: NlosConfig) -> None:
    if min(nlos.wall_distance_m) <= 0.0 or min(nlos.building_height_m) < 0.0:
        raise SimbenchError(
            "scenario.errors.nlos.wall_distance_m",
            "facade distances must be positive and heights non-negative",
            "give e.g. wall_distance_m=[8, 20]",
        )
    if nlos.height_distribution == HeightDistribution.rayleigh:
        _positive(
            nlos.building_height_scale_m,
            "scenario.errors.nlos.building_height_scale_m",
            "set e.g. building_height_scale_m=50 (ITU-R P.1410 high-rise)",
        )
    low, high = nlos.reflector_beyond_m
    if not 0.0 <= low <= high:
        raise SimbenchError(
            "scenario.errors.nlos.reflector_beyond_m",
            f"needs 0 <= low <= high, got [{low}, {high}]",
            "give e.g. reflector_beyond_m=[0, 100], or [0, 0] for the far facade",
        )


def roadside_street(traj: Trajectory, nlos: NlosConfig, rng: np.random.Generator) -> StreetGeometry:
    """Buildings along a replayed route: a new pair of block sides every ``roadside_segment_m`` of road.

    A recorded route carries no map, so the street is drawn from the same
    distributions as the synthetic grid (``building_height_m``,
    ``wall_distance_m``, ``open_fraction``), one draw per side and segment of
    travelled distance, with the road axis along the vehicle's heading (held
    while it stands). The antenna is on the road axis.

    Parameters
    ----------
    traj : Trajectory
        Replayed motion; ``att[:, 2]`` is the course [rad].
    nlos : NlosConfig
        Building distributions and ``roadside_segment_m`` [m].
    rng : numpy.random.Generator

    Returns
    -------
    StreetGeometry
        One entry per trajectory sample.
    """
    _check_buildings(nlos)
    _positive(nlos.roadside_segment_m, "scenario.errors.nlos.roadside_segment_m", "set e.g. roadside_segment_m=60")
    step = np.linalg.norm(np.diff(traj.pos, axis=0), axis=1)
    travelled = np.r_[0.0, np.cumsum(np.where(traj.valid[1:] & traj.valid[:-1], step, 0.0))]
    segment = (travelled // nlos.roadside_segment_m).astype(np.int64)
    n_seg = int(segment[-1]) + 1
    dist, height = block_sides(nlos, (n_seg, 2), rng)
    return StreetGeometry(
        road_heading_rad=traj.att[:, 2] % (2 * np.pi),
        wall_left_m=dist[segment, 0],
        wall_right_m=dist[segment, 1],
        height_left_m=height[segment, 0],
        height_right_m=height[segment, 1],
    )


# =========================================================================== flight


def flight(cfg: TrajectoryConfig, duration_s: float, rate_hz: float, rng: np.random.Generator) -> Trajectory:
    """Small fixed-wing UAV: take-off, climb, racetrack legs, loiters and figure eights.

    Static on the ground for ``start_static_s`` at the origin facing a random
    heading, a take-off roll (smoothstep to airspeed, peak
    ``TAKEOFF_ACCEL_MPS2``), then a straight climb at ``climb_rate_mps`` to
    ``cruise_altitude_m`` and a repeating closed pattern: right 180 deg turn,
    leg back, right 180 deg turn, right 360 deg loiter, left 360 deg loiter,
    leg out. Turns are coordinated: roll = atan(v^2 kappa / g) = atan(v^2 / (g R))
    on the arcs, reached over a ``ROLL_IN_S`` clothoid with a smooth (C1) roll
    profile; pitch is the flight-path angle (no angle of attack); no wind.

    Parameters
    ----------
    cfg : TrajectoryConfig
        Origin (take-off point) and ``cfg.flight``.
    duration_s : float
        Length [s]; ``round(duration_s * rate_hz)`` samples.
    rate_hz : float
        Sample rate [Hz].
    rng : numpy.random.Generator
        Draws the runway heading.

    Returns
    -------
    Trajectory
        ``street`` is None.
    """
    f: FlightConfig = cfg.flight
    where = "scenario.trajectory.flight"
    t = _time_grid(duration_s, rate_hz)
    for name in ("airspeed_mps", "cruise_altitude_m", "climb_rate_mps", "turn_radius_m", "leg_length_m"):
        _positive(getattr(f, name), f"{where}.{name}", "see conf/scenario/flight.yaml")
    v, R, H, climb = f.airspeed_mps, f.turn_radius_m, f.cruise_altitude_m, f.climb_rate_mps
    if f.start_static_s < 0.0:
        raise SimbenchError(
            f"{where}.start_static_s",
            f"must be non-negative, got {f.start_static_s}",
            "give the time on the ground before take-off, e.g. 30",
        )
    if H < climb * CLIMB_TRANSITION_S:
        raise SimbenchError(
            f"{where}.cruise_altitude_m",
            f"{H} m is too low for a {climb} m/s climb",
            f"use at least {climb * CLIMB_TRANSITION_S:.0f} m",
        )

    # speeds: ground roll then constant airspeed; vertical speed: ramp up, hold, ramp down
    t_roll = _SMOOTHSTEP_PEAK * v / TAKEOFF_ACCEL_MPS2
    speed = (np.array([f.start_static_s, t_roll]), np.array([0.0, 0.0]), np.array([0.0, v]))
    t_liftoff = f.start_static_s + t_roll
    t_hold = H / climb - CLIMB_TRANSITION_S
    vert = (
        np.array([t_liftoff, CLIMB_TRANSITION_S, t_hold, CLIMB_TRANSITION_S]),
        np.array([0.0, 0.0, climb, climb]),
        np.array([0.0, climb, 0.0, -climb]),
    )
    speed, vert = _drop_empty(*speed), _drop_empty(*vert)

    clothoid = min(v * ROLL_IN_S, 0.5 * math.pi * R)
    fig8 = _PathBuilder(0j, 0.0)
    fig8.turn(2 * math.pi, R, clothoid, 0, 0)
    fig8.turn(-2 * math.pi, R, clothoid, 0, 0)
    drift = fig8.z.real  # the figure eight moves the aircraft along its heading; the next leg makes up for it
    if f.leg_length_m <= drift:
        raise SimbenchError(
            f"{where}.leg_length_m",
            f"must exceed {drift:.0f} m for this turn radius",
            "increase leg_length_m or reduce turn_radius_m",
        )
    first_leg = max(f.leg_length_m, 0.5 * v * t_roll + v * (H / climb + CLIMB_TRANSITION_S + LEVEL_OFF_MARGIN_S))
    path = _PathBuilder(0j, float(rng.uniform(0.0, 2.0 * math.pi)))
    path.add(first_leg, 0.0, 0)
    while path.s < v * duration_s + first_leg:
        path.turn(math.pi, R, clothoid, 0, 0)
        path.add(f.leg_length_m, 0.0, 0)
        path.turn(math.pi, R, clothoid, 0, 0)
        path.turn(2 * math.pi, R, clothoid, 0, 0)
        path.turn(-2 * math.pi, R, clothoid, 0, 0)
        path.add(f.leg_length_m - drift, 0.0, 0)
    geo = path.build()

    s, v_h, a_h = _eval_speed(*speed, t)
    up, v_u, a_u = _eval_speed(*vert, t)
    z, heading, kappa, dk, prim, sigma = _eval_path(geo, s)
    # Coordinated turn: the lift tilts to supply the centripetal force, roll = atan(v^2 kappa / g).
    # On the clothoids kappa is linear in s, which would make the roll rate jump at their ends
    # (a step in the gyro output); bank with a smoothstep of the same curvature change instead,
    # so the aircraft slips slightly while rolling in and out and is coordinated elsewhere.
    length = geo.length[prim]
    tau = sigma / length
    change = dk * length
    bank_kappa = np.where(dk != 0.0, geo.k0[prim] + change * tau * tau * (3.0 - 2.0 * tau), kappa)
    bank_dkappa = change * 6.0 * tau * (1.0 - tau) / length
    q = v_h * v_h * bank_kappa / G0_STD
    roll = np.arctan(q)
    roll_dot = (2.0 * v_h * a_h * bank_kappa + v_h**3 * bank_dkappa) / G0_STD / (1.0 + q * q)
    speed2 = v_h * v_h + v_u * v_u
    pitch = np.arctan2(v_u, v_h)
    pitch_dot = np.where(speed2 > 0.0, (v_h * a_u - v_u * a_h) / np.where(speed2 > 0.0, speed2, 1.0), 0.0)
    return _assemble_local(cfg, t, z, up, heading, v_h, a_h, kappa, v_u, a_u, roll, roll_dot, pitch, pitch_dot, None)


# =========================================================================== replay


def replay(cfg: ReplayConfig, rate_hz: float, duration_s: float | None = None) -> tuple[Trajectory, float]:
    """Recorded trajectory, smoothed and resampled to ``rate_hz`` per continuous segment.

    Epoch gaps longer than ``cfg.max_gap_s`` split the record into segments.
    Each segment is a robust cubic smoothing spline (:func:`_smooth_segment`),
    not an interpolation: a reference receiver's positions scatter by
    centimetres and jump by decimetres to metres between fixes, and the second
    derivative of a path through them reaches hundreds of m/s^2 and its course
    thousands of deg/s -- an IMU synthesised from that is no car's, and no
    strapdown mechanisation sampled at the IMU rate can follow it. The smoothed
    path is the truth the scenario is simulated on. Samples inside gaps (and
    beyond the first and last epoch a segment keeps) are a cubic Hermite bridge
    (continuous position and velocity) and flagged ``valid = False``. Samples
    fall on whole multiples of 1 / rate_hz in GPS time, so they coincide with a
    receiver's regular epochs. Attitude follows the velocity
    (:func:`_attitude_from_velocity`): roll 0, yaw and pitch along the direction
    of travel (opposite to it while reversing), turning smoothly while the car
    is slower than ``HOLD_HEADING_SPEED_MPS``; ``omega_eb_b`` is its exact rate.

    Parameters
    ----------
    cfg : ReplayConfig
        File path and gap threshold.
    rate_hz : float
        Output sample rate [Hz].
    duration_s : float, optional
        Keep only the first ``round(duration_s * rate_hz)`` samples.

    Returns
    -------
    traj : Trajectory
        ``t`` starts at 0; ``street`` is None.
    t0_sow : float
        GPS seconds of week (week ``cfg.gps_week``) of ``t = 0``.

    Raises
    ------
    SimbenchError
        Missing or malformed file, fewer than 2 epochs, bad rate or duration.
    """
    if not rate_hz > 0.0:
        raise SimbenchError("imu.rate_hz", f"must be positive, got {rate_hz}", "set e.g. imu.rate_hz=100")
    if not cfg.max_gap_s > 0.0:
        raise SimbenchError(
            "scenario.trajectory.replay.max_gap_s", f"must be positive, got {cfg.max_gap_s}", "set e.g. max_gap_s=2"
        )
    data = read_xyz_trajectory(cfg.path)
    sow, xyz = data[:, 0], data[:, 1:]
    t0_sow = math.ceil(sow[0] * rate_hz - 1e-6) / rate_hz
    t_ep = sow - t0_sow
    k = int(math.floor(t_ep[-1] * rate_hz + 1e-6)) + 1
    if duration_s is not None:
        k = min(k, int(round(duration_s * rate_hz)))
    if k < 2:
        raise SimbenchError(
            REPLAY_PATH_FIELD,
            f"'{cfg.path}' spans less than two samples at {rate_hz} Hz",
            "use a longer record or a higher rate",
        )
    t = np.arange(k) / rate_hz
    tol = 1e-6 / rate_hz

    pos, vel, acc = np.zeros((k, 3)), np.zeros((k, 3)), np.zeros((k, 3))
    valid = np.zeros(k, dtype=bool)
    cuts = np.r_[0, np.nonzero(np.diff(t_ep) > cfg.max_gap_s)[0] + 1, len(t_ep)]
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        if hi - lo < 2:
            continue  # a lone epoch between gaps: nothing to interpolate
        spline, first, last = _smooth_segment(t_ep[lo:hi], xyz[lo:hi])
        sel = (t >= first - tol) & (t <= last + tol)
        if not sel.any():
            continue
        ts = np.clip(t[sel], first, last)
        pos[sel], vel[sel], acc[sel] = spline(ts), spline(ts, 1), spline(ts, 2)
        valid[sel] = True
    if not valid.any():
        raise SimbenchError(
            REPLAY_PATH_FIELD,
            f"'{cfg.path}' has no two epochs closer than max_gap_s",
            "raise scenario.trajectory.replay.max_gap_s",
        )
    _bridge_gaps(t, pos, vel, acc, valid)
    att, omega = _attitude_from_velocity(t, pos, vel, acc, int(math.ceil(MIN_MOVING_S * rate_hz)))
    return Trajectory(t=t, pos=pos, vel=vel, acc=acc, att=att, omega_eb_b=omega, valid=valid), t0_sow


def _smooth_segment(t: np.ndarray, xyz: np.ndarray) -> tuple[BSpline | CubicSpline, float, float]:
    """Robust cubic smoothing spline through one continuous segment of reference epochs.

    The spline minimises ``sum |y_i - f(t_i)|^2 / sigma^2 + integral |f''|^2 / q``
    (``sigma = REPLAY_POSITION_SIGMA_M``, ``q = REPLAY_ACCEL_PSD``): the MAP path
    of a vehicle whose acceleration is white noise of density ``q``, seen through
    positions of scatter ``sigma``. Epochs farther than ``REPLAY_OUTLIER_M`` from
    it are dropped and the fit repeated, so an isolated wrong fix does not drag
    the path (a level shift between fixes stays, as a smooth move).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Epoch times [s], strictly increasing, n >= 2.
    xyz : ndarray, shape (n, 3)
        ECEF positions [m].

    Returns
    -------
    spline : BSpline or CubicSpline
        Position [m] as a function of time [s]; ``spline(t, 1)``, ``spline(t, 2)``
        are velocity and acceleration. Fewer than ``_MIN_SMOOTHED_EPOCHS`` epochs
        cannot separate noise from motion and are interpolated.
    first, last : float
        Time span [s] of the epochs kept.
    """
    if len(t) < _MIN_SMOOTHED_EPOCHS:
        return CubicSpline(t, xyz, axis=0), float(t[0]), float(t[-1])
    keep = np.ones(len(t), dtype=bool)
    w = np.full(len(t), REPLAY_POSITION_SIGMA_M**-2)
    for _ in range(_REPLAY_OUTLIER_ROUNDS):
        spline = make_smoothing_spline(t[keep], xyz[keep], w=w[keep], lam=1.0 / REPLAY_ACCEL_PSD)
        inlier = np.linalg.norm(spline(t) - xyz, axis=1) <= REPLAY_OUTLIER_M
        if np.count_nonzero(inlier) < _MIN_SMOOTHED_EPOCHS or np.array_equal(inlier, keep):
            break
        keep, fitted = inlier, keep
    else:
        keep = fitted  # out of rounds: the span of the epochs the last spline was fitted to
    kept = t[keep]
    return spline, float(kept[0]), float(kept[-1])


def _bridge_gaps(t: np.ndarray, pos: np.ndarray, vel: np.ndarray, acc: np.ndarray, valid: np.ndarray) -> None:
    """Fill invalid samples in place: cubic Hermite between the valid neighbours, hold at the ends."""
    idx = np.arange(len(t))
    prev = np.maximum.accumulate(np.where(valid, idx, -1))
    nxt = np.minimum.accumulate(np.where(valid, idx, len(t))[::-1])[::-1]
    gap = ~valid
    both = gap & (prev >= 0) & (nxt < len(t))
    if both.any():
        i0, i1 = prev[both], nxt[both]
        h = (t[i1] - t[i0])[:, None]
        x = (t[both] - t[i0])[:, None] / h
        p0, p1, m0, m1 = pos[i0], pos[i1], vel[i0] * h, vel[i1] * h
        pos[both] = (
            (2 * x**3 - 3 * x**2 + 1) * p0
            + (x**3 - 2 * x**2 + x) * m0
            + (-2 * x**3 + 3 * x**2) * p1
            + (x**3 - x**2) * m1
        )
        vel[both] = (
            (6 * x**2 - 6 * x) * p0 + (3 * x**2 - 4 * x + 1) * m0 + (-6 * x**2 + 6 * x) * p1 + (3 * x**2 - 2 * x) * m1
        ) / h
        acc[both] = ((12 * x - 6) * p0 + (6 * x - 4) * m0 + (-12 * x + 6) * p1 + (6 * x - 2) * m1) / h**2
    lead = gap & (prev < 0)
    tail = gap & (nxt >= len(t))
    pos[lead], vel[lead], acc[lead] = pos[nxt[lead]], 0.0, 0.0
    pos[tail], vel[tail], acc[tail] = pos[prev[tail]], 0.0, 0.0


def _attitude_from_velocity(
    t: np.ndarray, pos: np.ndarray, vel: np.ndarray, acc: np.ndarray, min_moving: int
) -> tuple[np.ndarray, np.ndarray]:
    """Roll 0, yaw and pitch along the direction of travel in local NED, and the exact omega_eb_b.

    The course is followed only within runs of at least ``min_moving`` samples
    faster than ``HOLD_HEADING_SPEED_MPS``. Between two runs the car is nearly
    standing and its course is noise, so yaw and pitch turn smoothly from the
    end of one run to the start of the next; before the first and after the
    last run they are held. A car's heading is continuous, so a run whose
    course starts more than 90 deg from where the previous one ended is driven
    the other way (backing out of a parking space, a three-point turn): the
    body points against the velocity there. Which way is forward is decided by
    distance: a car drives forward over most of its route.
    """
    lat, lon, h = geodetic_from_ecef(pos)
    c_n_e = dcm_ned_to_ecef(lat, lon)
    v_n = np.einsum("kji,kj->ki", c_n_e, vel)
    sl = np.sin(lat)
    w = np.sqrt(1.0 - WGS84_E2 * sl * sl)
    r_e = WGS84_A / w + h  # transverse radius of curvature + height
    r_n = WGS84_A * (1.0 - WGS84_E2) / w**3 + h  # meridian radius + height
    # rotation of the local NED frame as the vehicle moves over the ellipsoid (transport rate)
    w_en = np.stack([v_n[:, 1] / r_e, -v_n[:, 0] / r_n, -v_n[:, 1] * np.tan(lat) / r_e], axis=-1)
    a_n = np.einsum("kji,kj->ki", c_n_e, acc) - np.cross(w_en, v_n)

    vn, ve, vd = v_n.T
    an, ae, ad = a_n.T
    vh = np.hypot(vn, ve)
    starts, ends = _moving_runs(vh > HOLD_HEADING_SPEED_MPS, min_moving)
    yaw, pitch, yaw_dot, pitch_dot = np.zeros((4, len(vh)))
    if len(starts):
        run = np.cumsum(np.bincount(starts, minlength=len(vh))) - 1  # the latest run started, -1 before the first
        moving = (run >= 0) & (np.arange(len(vh)) < ends[np.maximum(run, 0)])
        sign = np.where(moving, _run_directions(np.arctan2(ve, vn), vh, starts, ends)[np.maximum(run, 0)], 1.0)
        vh_safe = np.where(moving, vh, 1.0)
        ah = (vn * an + ve * ae) / vh_safe
        yaw, yaw_dot = _turn_between_runs(
            t,
            moving,
            np.arctan2(sign * ve, sign * vn),
            np.where(moving, (vn * ae - ve * an) / vh_safe**2, 0.0),
            wrap=True,
        )
        pitch, pitch_dot = _turn_between_runs(
            t,
            moving,
            np.arctan2(-sign * vd, vh),
            np.where(moving, sign * (-vh * ad + vd * ah) / (vh_safe**2 + vd * vd), 0.0),
            wrap=False,
        )
    att = np.stack([np.zeros_like(yaw), pitch, yaw], axis=-1)
    c_b_n = dcm_body_to_ned(att)
    zero, one = np.zeros_like(yaw), np.ones_like(yaw)
    omega = np.einsum("kji,kj->ki", c_b_n, w_en) + _euler_rates_to_body(
        zero, one, np.sin(pitch), np.cos(pitch), zero, pitch_dot, yaw_dot
    )
    return att, omega


def _moving_runs(fast: np.ndarray, min_moving: int) -> tuple[np.ndarray, np.ndarray]:
    """Start and stop indices of the runs of ``fast`` samples at least ``min_moving`` long.

    Shorter bursts are position jumps and noise of a standing vehicle; they would set a random heading.
    """
    edges = np.diff(np.r_[0, fast.astype(np.int8), 0])
    starts, ends = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]
    long = ends - starts >= min_moving
    return starts[long], ends[long]


def _run_directions(course: np.ndarray, speed: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """+1 for each run driven forward, -1 for one driven in reverse.

    Consecutive runs change direction when the course jumps by more than 90 deg
    across the stop between them; the direction covering the longer distance
    (sum of speeds over the run's samples) is forward.
    """
    jump = np.angle(np.exp(1j * (course[starts[1:]] - course[ends[:-1] - 1])))
    flipped = np.r_[0, np.cumsum(np.abs(jump) > 0.5 * math.pi)] % 2 == 1
    travelled = np.r_[0.0, np.cumsum(speed)]
    dist = travelled[ends] - travelled[starts]
    reverse = flipped if dist[flipped].sum() < dist[~flipped].sum() else ~flipped
    return np.where(reverse, -1.0, 1.0)


def _turn_between_runs(
    t: np.ndarray, moving: np.ndarray, angle: np.ndarray, rate: np.ndarray, wrap: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Fill the samples outside the runs: a smoothstep turn between runs, held before the first and after the last.

    Parameters
    ----------
    t : ndarray, shape (k,)
        Sample times [s].
    moving : ndarray of bool, shape (k,)
        Samples inside a run (at least one); only there are ``angle`` and ``rate`` used.
    angle, rate : ndarray, shape (k,)
        Angle [rad] and its time derivative [rad/s].
    wrap : bool
        Turn the short way round and return angles in (-pi, pi] (a heading).

    Returns
    -------
    angle, rate : ndarray, shape (k,)
    """
    idx = np.arange(len(t))
    last = np.maximum.accumulate(np.where(moving, idx, -1))
    nxt = np.minimum.accumulate(np.where(moving, idx, len(t))[::-1])[::-1]
    angle, rate = angle.copy(), rate.copy()
    both = ~moving & (last >= 0) & (nxt < len(t))
    i0, i1 = last[both], nxt[both]
    span = t[i1] - t[i0]
    x = (t[both] - t[i0]) / span
    turn = angle[i1] - angle[i0]
    if wrap:
        turn = np.angle(np.exp(1j * turn))
    angle[both] = angle[i0] + turn * (3.0 - 2.0 * x) * x * x
    rate[both] = turn * 6.0 * x * (1.0 - x) / span
    lead, tail = ~moving & (last < 0), ~moving & (nxt >= len(t))
    angle[lead], rate[lead] = angle[nxt[lead]], 0.0
    angle[tail], rate[tail] = angle[last[tail]], 0.0
    return (np.angle(np.exp(1j * angle)) if wrap else angle), rate
