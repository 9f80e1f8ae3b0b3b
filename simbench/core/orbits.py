"""GPS satellite orbits and clocks: nominal constellation and broadcast ephemeris.

Time convention (everywhere in :mod:`simbench.sim`): ``t_gps`` is continuous GPS
time in seconds since the GPS epoch 1980-01-06 00:00:00 GPS, i.e.
``week * 604800 + seconds_of_week``, as float64.

Precision note: near 2018 a float64 ``t_gps`` (~1.2e9 s) resolves 0.24 us, which
moves a GPS satellite by ~1 mm. Every ``states`` method therefore takes an
optional ``offset_s`` that is added *after* the large reference time has been
differenced with Toe/Toc, so transmit times ``t_rx - tau`` keep sub-ns precision.

All orbit providers implement the :class:`Constellation` protocol
(``sats`` + ``states``), which is what :mod:`simbench.sim.geometry` consumes.
"""

from __future__ import annotations

import decimal
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from simbench.core.constants import (
    DEG,
    F_REL,
    GPS_MINUS_UTC_1993_07_01,
    MU_EARTH,
    OMEGA_EARTH,
)
from simbench.core.gpstime import datetime64_to_gps, format_gps_time
from simbench.errors import SimbenchError

__all__ = [
    "SatelliteStates",
    "Constellation",
    "NominalConstellation",
    "BroadcastEphemeris",
    "ClosestRecordSelector",
    "state_time_grid",
    "FIT_HALF_WINDOW_S",
]

_TWO_PI_DEC = decimal.Decimal("6.28318530717958647692528676655900576839433879875021")

#: Half of the 4-hour curve-fit interval of a standard GPS broadcast ephemeris [s].
FIT_HALF_WINDOW_S: float = 7200.0
#: Epochs per block in the vectorised evaluation (cache-sized temporaries).
_CHUNK_EPOCHS = 512


# --------------------------------------------------------------------------- time


def _angle_mod_2pi(angle0: float, rate: float, dt: float) -> float:
    """(angle0 + rate * dt) mod 2 pi [rad], exact to float64 even for huge ``dt``."""
    with decimal.localcontext() as ctx:
        ctx.prec = 50
        a = decimal.Decimal(angle0) + decimal.Decimal(rate) * decimal.Decimal(dt)
        return float(a % _TWO_PI_DEC)


# --------------------------------------------------------------------------- states


@dataclass(frozen=True)
class SatelliteStates:
    """Satellite positions, velocities and clocks at ``n`` epochs for ``m`` satellites.

    Attributes
    ----------
    sats : np.ndarray of str, shape (m,)
        Satellite ids such as ``'G01'``.
    pos : np.ndarray, shape (n, m, 3)
        Position in the Earth-fixed (ECEF) frame *of the evaluation time* [m].
    vel : np.ndarray, shape (n, m, 3)
        Velocity relative to the rotating ECEF frame [m/s].
    clock : np.ndarray, shape (n, m)
        Satellite clock offset including the relativistic eccentricity term,
        excluding TGD [s]. Positive means the satellite clock is ahead.
    clock_drift : np.ndarray, shape (n, m)
        Time derivative of ``clock`` [s/s].
    valid : np.ndarray of bool, shape (n, m)
        Ephemeris available (within its fit interval) and healthy. Invalid
        entries are NaN in the float arrays.
    """

    sats: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    clock: np.ndarray
    clock_drift: np.ndarray
    valid: np.ndarray


class Constellation(Protocol):
    """Anything that can give satellite states at GPS times (used by geometry)."""

    sats: np.ndarray

    def states(self, t_gps: np.ndarray, offset_s: np.ndarray | float | None = None) -> SatelliteStates:
        """Satellite states at ``t_gps + offset_s``; see :class:`BroadcastEphemeris`."""
        ...


def state_time_grid(t_gps: np.ndarray, offset_s: np.ndarray | float | None, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Validate the times of a ``states`` call (shared by every orbit provider).

    Parameters
    ----------
    t_gps : array_like, shape (), (n,) or (n, m)
        Reference times, continuous GPS seconds [s].
    offset_s : array_like or None
        Small offsets added after differencing [s]; broadcastable to (n, m).
    m : int
        Number of satellites.

    Returns
    -------
    t : np.ndarray, shape (n, 1) or (n, m)
        Reference times [s].
    offset : np.ndarray, shape (n, m)
        Offsets broadcast to one per epoch and satellite [s].
    """
    try:
        t = np.asarray(t_gps, dtype=float)
        off = np.zeros(1) if offset_s is None else np.asarray(offset_s, dtype=float)
    except (TypeError, ValueError):
        raise SimbenchError(
            "t_gps", "times are not numeric", "pass GPS seconds (week*604800 + seconds of week) as floats"
        ) from None
    if t.ndim == 0:
        t = t.reshape(1)
    if t.ndim == 1:
        t = t[:, None]
    if t.ndim != 2 or t.shape[1] not in (1, m):
        raise SimbenchError(
            "t_gps",
            f"shape {np.shape(t_gps)} is neither (n,) nor (n, {m})",
            "pass one time per epoch, or one per epoch and satellite",
        )
    if not np.all(np.isfinite(t)) or not np.all(np.isfinite(off)):
        raise SimbenchError("t_gps", "contains NaN or infinite times", "remove non-finite epochs")
    try:
        shape = np.broadcast_shapes(t.shape, off.shape, (t.shape[0], m))
    except ValueError:
        raise SimbenchError(
            "offset_s", f"shape {off.shape} does not broadcast to (n, m)", "pass (n, m) or (n, 1) offsets"
        ) from None
    # The reference time stays (n, 1) when shared by all satellites, so record
    # selection can work per epoch instead of per satellite-epoch.
    return t, np.broadcast_to(off, shape)


# --------------------------------------------------------------------------- nominal


# SPS Performance Standard 24-slot constellation, Table 3-1 (REFERENCE.md).
_NOMINAL_PLANE_RAAN_DEG = {"A": 272.847, "B": 332.847, "C": 32.847, "D": 92.847, "E": 152.847, "F": 212.847}
_NOMINAL_ARG_LAT_DEG = {
    "A": (268.126, 161.786, 11.676, 41.806),
    "B": (80.956, 173.336, 309.976, 204.376),
    "C": (111.876, 11.796, 339.666, 241.556),
    "D": (135.226, 265.446, 35.156, 167.356),
    "E": (197.046, 302.596, 66.066, 333.686),
    "F": (238.886, 345.226, 105.206, 135.346),
}


class NominalConstellation:
    """The GPS nominal 24-slot constellation, propagated as circular Kepler orbits.

    Slots A1..A4, B1..B4, ..., F4 are assigned PRNs G01..G24 in that order.
    Each orbit is circular (a = 26 559.7 km, i = 55 deg) with mean motion
    sqrt(mu / a^3); the node is fixed in inertial space. No J2 or other
    perturbation is modelled: the real constellation's nodes regress by about
    -0.04 deg/day, so geometry drifts from the real sky over weeks, which does
    not matter for a synthetic benchmark. Satellite clocks are perfect (0 s).

    Attributes
    ----------
    sats : np.ndarray of str, shape (24,)
        ``'G01'`` .. ``'G24'``.
    slots : np.ndarray of str, shape (24,)
        Slot names ``'A1'`` .. ``'F4'``.
    a_m : float
        Semi-major axis [m].
    incl_rad : float
        Inclination [rad].
    mean_motion_rad_s : float
        sqrt(mu / a^3) [rad/s].
    t_ref_gps : float
        Reference epoch 1993-07-01 00:00 UTC in GPS seconds [s].
    gha_ref_rad : float
        Greenwich hour angle of the vernal equinox at the reference epoch [rad].
    raan_rad : np.ndarray, shape (24,)
        Right ascension of the ascending node (inertial) [rad].
    arg_lat_ref_rad : np.ndarray, shape (24,)
        Argument of latitude at the reference epoch [rad].
    """

    def __init__(self) -> None:
        planes = list(_NOMINAL_PLANE_RAAN_DEG)
        self.slots = np.array([f"{p}{k}" for p in planes for k in range(1, 5)])
        self.sats = np.array([f"G{j:02d}" for j in range(1, 25)])
        self.raan_rad = np.array([_NOMINAL_PLANE_RAAN_DEG[p] for p in planes for _ in range(4)]) * DEG
        self.arg_lat_ref_rad = np.array([u for p in planes for u in _NOMINAL_ARG_LAT_DEG[p]]) * DEG
        self.a_m = 26_559_700.0
        self.incl_rad = 55.0 * DEG
        self.mean_motion_rad_s = math.sqrt(MU_EARTH / self.a_m**3)
        self.t_ref_gps = float(datetime64_to_gps(np.datetime64("1993-07-01T00:00:00"))[()]) + GPS_MINUS_UTC_1993_07_01
        # 18h36m14.4s of hour angle; 1 h = 15 deg.
        self.gha_ref_rad = (18.0 + 36.0 / 60.0 + 14.4 / 3600.0) * 15.0 * DEG

    def states(self, t_gps: np.ndarray, offset_s: np.ndarray | float | None = None) -> SatelliteStates:
        """Positions and velocities of the 24 satellites.

        Parameters
        ----------
        t_gps : np.ndarray, shape (n,) or (n, 24)
            Evaluation times, continuous GPS seconds [s]. A 2-D array gives one
            time per satellite (e.g. signal transmit times).
        offset_s : np.ndarray or float, optional
            Small offsets added to ``t_gps`` without losing precision [s];
            broadcastable to (n, 24).

        Returns
        -------
        SatelliteStates
            ECEF(t) positions [m] and velocities [m/s]; clocks are zero; all valid.
        """
        m = self.sats.size
        t, off = state_time_grid(t_gps, offset_s, m)
        # Decades after 1993, n * (t - t_ref) is ~1e5 rad and float64 would
        # lose ~0.5 mm; advance the elements exactly to a whole-second anchor
        # near the requested times and propagate only the remainder in float64.
        anchor = float(np.floor(t.min()))
        span = anchor - self.t_ref_gps
        u0 = np.array([_angle_mod_2pi(u, self.mean_motion_rad_s, span) for u in self.arg_lat_ref_rad])
        lam0 = np.array([_angle_mod_2pi(r - self.gha_ref_rad, -OMEGA_EARTH, span) for r in self.raan_rad])
        dt = (t - anchor) + off
        # Argument of latitude u = u0 + n dt and longitude of the node in the Earth-fixed frame
        # lam = lam0 - omega_e dt (inertial RAAN minus sidereal angle).
        if off.strides[1] == 0 and t.shape[1] == 1:
            # one time per epoch for every satellite: sin/cos of the per-epoch and per-satellite
            # angles, combined by the addition theorems (4 instead of n x 24 x 4 transcendentals)
            dt1 = dt[:, :1]
            cu, su = _rotated(u0, self.mean_motion_rad_s * dt1)
            cl, sl = _rotated(lam0, -OMEGA_EARTH * dt1)
        else:
            u, lam = u0 + self.mean_motion_rad_s * dt, lam0 - OMEGA_EARTH * dt
            cu, su = np.cos(u), np.sin(u)
            cl, sl = np.cos(lam), np.sin(lam)
        ci, si = math.cos(self.incl_rad), math.sin(self.incl_rad)
        a = self.a_m
        pos = np.empty(dt.shape + (3,))
        pos[..., 0] = a * (cu * cl - su * ci * sl)
        pos[..., 1] = a * (cu * sl + su * ci * cl)
        pos[..., 2] = a * su * si
        # d/dt = n d/du - omega_e d/dlam, and d/dlam rotates (x, y) -> (-y, x).
        n = self.mean_motion_rad_s
        vel = np.empty_like(pos)
        vel[..., 0] = n * a * (-su * cl - cu * ci * sl) + OMEGA_EARTH * pos[..., 1]
        vel[..., 1] = n * a * (-su * sl + cu * ci * cl) - OMEGA_EARTH * pos[..., 0]
        vel[..., 2] = n * a * cu * si
        zeros = np.zeros(dt.shape)
        return SatelliteStates(
            sats=self.sats,
            pos=pos,
            vel=vel,
            clock=zeros,
            clock_drift=zeros.copy(),
            valid=np.ones(dt.shape, dtype=bool),
        )


def _rotated(base: np.ndarray, step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos and sin of ``base + step`` [rad], shapes (m,) and (n, 1) -> (n, m), by the addition theorems."""
    cb, sb, cs, ss = np.cos(base), np.sin(base), np.cos(step), np.sin(step)
    return cb * cs - sb * ss, sb * cs + cb * ss


# --------------------------------------------------------------------------- broadcast


class ClosestRecordSelector:
    """Closest-reference-time record of every satellite, as one piecewise-constant table over time.

    Between consecutive breakpoints (midpoints of neighbouring reference times
    of any satellite) the closest record of every satellite is fixed, so
    choosing records for n epochs costs one searchsorted over n plus a row
    gather. Used for GPS-like Toe and GLONASS tb alike.

    Parameters
    ----------
    record_sat : np.ndarray of int, shape (R,)
        Satellite index of each record, records sorted by (satellite, time).
    record_t : np.ndarray, shape (R,)
        Reference time (Toe, tb) of each record, continuous GPS seconds [s].
    m : int
        Number of satellites.
    """

    def __init__(self, record_sat: np.ndarray, record_t: np.ndarray, m: int) -> None:
        self._t = np.asarray(record_t, dtype=float)
        self._m = m
        start = np.searchsorted(record_sat, np.arange(m), side="left")
        stop = np.searchsorted(record_sat, np.arange(m), side="right")
        mids = [0.5 * (self._t[lo : hi - 1] + self._t[lo + 1 : hi]) for lo, hi in zip(start, stop)]
        bp = np.unique(np.concatenate(mids)) if mids else np.zeros(0)
        # Interval k is (bp[k-1], bp[k]]; its right end (or +inf) represents it,
        # which makes a tie at a midpoint go to the earlier record.
        rep = np.append(bp, np.inf)
        table = np.full((rep.size, m), -1, dtype=np.intp)
        for j in range(m):  # one small searchsorted per satellite, at load time only
            lo, hi = start[j], stop[j]
            if hi == lo:
                continue
            k = np.searchsorted(mids[j], rep, side="left")
            table[:, j] = lo + k
        self._breakpoints = bp
        self._table = table

    def select(self, t_gps: np.ndarray, max_age_s: float) -> np.ndarray:
        """Record index per (epoch, satellite); -1 where |t - t_record| > ``max_age_s`` or no record.

        Parameters
        ----------
        t_gps : np.ndarray, shape (n,), (n, 1) or (n, m)
            Times [s]; 1-D (or one column) means the same time for all satellites.
        max_age_s : float
            Largest distance to the record's reference time [s].

        Returns
        -------
        np.ndarray of int, shape (n, m)
        """
        t = np.asarray(t_gps, dtype=float)
        if t.ndim == 1:
            t = t[:, None]
        k = np.searchsorted(self._breakpoints, t, side="left")
        if t.shape[1] == 1:
            idx = self._table[k[:, 0]]
        else:
            idx = self._table[k, np.arange(self._m)]
        ok = (idx >= 0) & (np.abs(t - self._t[idx]) <= max_age_s)
        return np.where(ok, idx, -1)


class RecordEphemeris:
    """What every broadcast ephemeris shares: each (epoch, satellite) takes the record whose reference
    time (Toe; GLONASS tb) is closest, within ``max_age_s``, and an epoch no record covers is an error.

    A subclass sets ``sats``, ``source``, ``max_age_s`` and calls :meth:`_index_records` with its
    records' satellites and reference times (sorted by satellite, then time).
    """

    #: Name used in messages.
    system_name: str = "GPS"
    #: What the coverage error tells the user to do.
    coverage_fix: str = "choose a start time inside that span or a navigation file for the simulated dates"
    #: Satellite ids with at least one healthy record (``'G05'``), shape (m,).
    sats: np.ndarray
    #: File name the ephemerides came from.
    source: str
    #: Largest distance of an epoch from a record's reference time (Toe, tb) at which it is used [s].
    max_age_s: float
    #: First and last GPS time at which some satellite is valid [s].
    t_coverage: tuple[float, float]

    def _index_records(self, record_sat: np.ndarray, record_t: np.ndarray) -> None:
        """Build the record selector and the coverage span."""
        self._selector = ClosestRecordSelector(record_sat, record_t, self.sats.size)
        self.t_coverage = (float(record_t.min() - self.max_age_s), float(record_t.max() + self.max_age_s))

    def select_records(self, t_gps: np.ndarray) -> np.ndarray:
        """Index of the record used for each (epoch, satellite), -1 if none.

        Parameters
        ----------
        t_gps : np.ndarray, shape (n,), (n, 1) or (n, m)
            Times [s]; 1-D (or one column) means the same time for all satellites.

        Returns
        -------
        idx : np.ndarray of int, shape (n, m)
            Index into the internal record arrays of the healthy record with the closest
            reference time (ties: the earlier), or -1 if it is more than ``max_age_s`` away
            or the satellite has no record.
        """
        return self._selector.select(t_gps, self.max_age_s)

    def _raise_coverage(self, n_bad: int, n: int, first: float) -> None:
        """The one-line error for ``n_bad`` of ``n`` epochs without a valid record, the first at ``first`` [s]."""
        raise SimbenchError(
            "t_gps",
            f"no valid {self.system_name} ephemeris at {n_bad} of {n} epochs "
            f"(first {format_gps_time(first)} GPS); {self.source or 'the ephemeris'} covers "
            f"{format_gps_time(self.t_coverage[0])} .. {format_gps_time(self.t_coverage[1])} GPS",
            self.coverage_fix,
        )


class BroadcastEphemeris(RecordEphemeris):
    """GPS broadcast ephemerides evaluated with the IS-GPS-200 user algorithm.

    The Keplerian algorithm is shared by every system that broadcasts GPS-like
    elements (Galileo, BeiDou): a subclass changes only the class constants
    ``mu``, ``omega_e``, ``f_rel``, ``week_origin_s`` and ``system_name``.

    Read from a file with :func:`simbench.gnss.navigation.read_gps_navigation`.
    For each requested (epoch, satellite) the healthy record whose Toe is
    closest to the epoch is used, provided
    |t - Toe| <= ``max_age_s`` (half the 4-hour fit interval); otherwise the
    entry is invalid.

    Attributes
    ----------
    sats : np.ndarray of str, shape (m,)
        GPS satellites with at least one healthy record.
    iono_alpha, iono_beta : np.ndarray, shape (4,), or None
        Klobuchar coefficients from the file header [s, s/semicircle, ...] and
        [s, s/semicircle, ...]; None when the header has none.
    tgd : np.ndarray, shape (m,)
        Group delay differential per satellite (median over its healthy records) [s].
    record_sat : np.ndarray of int, shape (R,)
        Satellite (index into ``sats``) of each stored record; the record
        order is what :meth:`select_records` indexes.
    record_toe : np.ndarray, shape (R,)
        Toe of each stored record, continuous GPS seconds [s].

    and those of :class:`RecordEphemeris` (``t_coverage``, ``source``, ``max_age_s``).
    """

    #: Gravitational parameter of the system's Keplerian algorithm [m^3/s^2].
    mu: float = MU_EARTH
    #: Earth rotation rate of the system's reference frame [rad/s].
    omega_e: float = OMEGA_EARTH
    #: Relativistic clock constant F = -2 sqrt(mu) / c^2 as the ICD rounds it [s/sqrt(m)].
    f_rel: float = F_REL
    #: Start of the system's week after the GPS week start (Omega0 refers to it) [s].
    week_origin_s: float = 0.0

    def __init__(
        self,
        sats: np.ndarray,
        records: dict[str, np.ndarray],
        iono_alpha: np.ndarray | None = None,
        iono_beta: np.ndarray | None = None,
        source: str = "",
        max_age_s: float = FIT_HALF_WINDOW_S,
    ) -> None:
        """Build from per-record arrays (a navigation file reader fills them).

        Parameters
        ----------
        sats : np.ndarray of str, shape (m,)
            Satellite ids; ``records['sat']`` indexes into it.
        records : dict of str -> np.ndarray, each shape (R,)
            Keys ``sat`` (int index), ``toe`` and ``toc`` (continuous GPS s), and
            the RINEX quantities ``af0 af1 af2 crs dn m0 cuc e cus sqrta cic
            omega0 cis i0 crc w omegadot idot tgd`` in SI units / radians.
            All records are taken as healthy.
        """
        self.sats = np.asarray(sats)
        self.iono_alpha = iono_alpha
        self.iono_beta = iono_beta
        self.source = source
        self.max_age_s = float(max_age_s)
        order = np.lexsort((records["toe"], records["sat"]))
        r = {k: np.asarray(v)[order] for k, v in records.items()}
        self._sat_idx = r["sat"].astype(np.intp)
        self._toe = r["toe"].astype(float)
        self._toc = r["toc"].astype(float)
        self.record_sat = self._sat_idx
        self.record_toe = self._toe
        m = self.sats.size
        start = np.searchsorted(self._sat_idx, np.arange(m), side="left")
        stop = np.searchsorted(self._sat_idx, np.arange(m), side="right")
        self._index_records(self._sat_idx, self._toe)
        # Time-independent per-record quantities, precomputed once. Trig of the
        # argument of perigee and of i0 lets _kepler use angle-addition formulas
        # instead of ~6 transcendental calls per satellite-epoch.
        a = r["sqrta"] ** 2
        e = r["e"]
        self._p = {
            "af0": r["af0"],
            "af1": r["af1"],
            "af2": r["af2"],
            "crs": r["crs"],
            "crc": r["crc"],
            "cus": r["cus"],
            "cuc": r["cuc"],
            "cis": r["cis"],
            "cic": r["cic"],
            "m0": r["m0"],
            "e": e,
            "a": a,
            "n": np.sqrt(self.mu / a**3) + r["dn"],
            "sq1e2": np.sqrt(1.0 - e**2),
            "cw": np.cos(r["w"]),
            "sw": np.sin(r["w"]),
            "ci0": np.cos(r["i0"]),
            "si0": np.sin(r["i0"]),
            "idot": r["idot"],
            # Node longitude at Toe in ECEF(Toe): Omega0 is referred to the system's week start.
            "lam0": r["omega0"] - self.omega_e * np.mod(self._toe - self.week_origin_s, 604_800.0),
            "lamdot": self._node_rate(r["omegadot"]),
            "frel": self.f_rel * e * r["sqrta"],
        }
        self._param_table = np.stack(list(self._p.values()), axis=0)
        self._param_names = list(self._p)
        # Newton from E = M: error <= e -> ~e^3/2 -> ... For e <= 0.03 (GPS
        # spec) one full step leaves < 1.4e-5 rad and two cheap series steps
        # reach float64 precision; larger e (bad records) get more full steps.
        self._newton_full_steps = 1 if float(e.max()) <= 0.03 else 5
        self.tgd = np.array(
            [np.nanmedian(r["tgd"][start[j] : stop[j]]) if stop[j] > start[j] else np.nan for j in range(m)]
        )

    def states(self, t_gps: np.ndarray, offset_s: np.ndarray | float | None = None) -> SatelliteStates:
        """Satellite positions, velocities and clocks by the IS-GPS-200 algorithm.

        Parameters
        ----------
        t_gps : np.ndarray, shape (n,) or (n, m)
            Evaluation times, continuous GPS seconds [s]; 2-D gives one time
            per satellite (e.g. transmit times). Also selects the record.
        offset_s : np.ndarray or float, optional
            Small offsets added to ``t_gps`` with full precision [s];
            broadcastable to (n, m). Record selection ignores it.

        Returns
        -------
        SatelliteStates
            Positions in ECEF(t) [m], ECEF velocities [m/s] (analytic
            derivatives), clock = af0 + af1 dt + af2 dt^2 + F e sqrtA sin E [s]
            (no TGD) and its rate [s/s].

        Raises
        ------
        SimbenchError
            If at some requested epoch no satellite has a valid ephemeris.
        """
        t, off = state_time_grid(t_gps, offset_s, self.sats.size)
        n, m = off.shape
        pos = np.empty((n, m, 3))
        vel = np.empty((n, m, 3))
        clk = np.empty((n, m))
        drift = np.empty((n, m))
        valid = np.empty((n, m), dtype=bool)
        # Blocks of epochs keep the ~50 temporaries in cache (2-3x faster than
        # whole-array numpy for ~1e6 satellite-epochs).
        for a in range(0, n, _CHUNK_EPOCHS):
            b = min(n, a + _CHUNK_EPOCHS)
            tb = t[a:b]
            idx = self.select_records(tb)
            ok = idx >= 0
            bad_epoch = ~ok.any(axis=1)
            if bad_epoch.any():
                n_bad = int((~(self.select_records(t[:, 0]) >= 0).any(axis=1)).sum())
                self._raise_coverage(n_bad, n, first=float(tb[np.argmax(bad_epoch), 0]))
            gi = np.where(ok, idx, 0)
            tk = (tb - self._toe[gi]) + off[a:b]
            tc = (tb - self._toc[gi]) + off[a:b]
            self._kepler(gi, tk, tc, pos[a:b], vel[a:b], clk[a:b], drift[a:b])
            self._to_earth_fixed(gi, tk, pos[a:b], vel[a:b])
            valid[a:b] = ok
        if not valid.all():
            nan = ~valid
            pos[nan] = np.nan
            vel[nan] = np.nan
            clk[nan] = np.nan
            drift[nan] = np.nan
        return SatelliteStates(sats=self.sats, pos=pos, vel=vel, clock=clk, clock_drift=drift, valid=valid)

    def _node_rate(self, omegadot: np.ndarray) -> np.ndarray:
        """Rate of the node longitude in the frame the elements are solved in, per record [rad/s]:
        ``OmegaDot - Omega_e`` in the Earth-fixed frame (a system with records in another frame overrides it)."""
        return omegadot - self.omega_e

    def _to_earth_fixed(self, gi: np.ndarray, tk: np.ndarray, pos: np.ndarray, vel: np.ndarray) -> None:
        """Rotate the states of records ``gi`` solved outside the Earth-fixed frame into it, in place (none here)."""

    def _kepler(
        self,
        gi: np.ndarray,
        tk: np.ndarray,
        tc: np.ndarray,
        pos: np.ndarray,
        vel: np.ndarray,
        clk: np.ndarray,
        drift: np.ndarray,
    ) -> None:
        """IS-GPS-200 Table 20-IV for records ``gi`` at Toe/Toc-relative times; fills the outputs."""
        g = np.take(self._param_table, gi, axis=1)
        P = dict(zip(self._param_names, g))
        e, n = P["e"], P["n"]
        M = P["m0"] + n * tk
        E = M.copy()
        sE, cE = np.sin(E), np.cos(E)
        for _ in range(self._newton_full_steps):
            E += (M - E + e * sE) / (1.0 - e * cE)
            sE, cE = np.sin(E), np.cos(E)
        # The remaining Newton corrections are < 2e-5 rad, so sin/cos are
        # updated by angle addition with 3rd-order series (truncation < 1e-20).
        for _ in range(2):
            d = (M - E + e * sE) / (1.0 - e * cE)
            E += d
            d2 = d * d
            cd, sd = 1.0 - 0.5 * d2, d * (1.0 - d2 / 6.0)
            sE, cE = sE * cd + cE * sd, cE * cd - sE * sd
        one_ecE = 1.0 - e * cE
        Edot = n / one_ecE
        # True anomaly nu and argument of latitude phi = nu + w by angle addition
        # (cheaper and as exact as arctan2 + sin/cos).
        snu = P["sq1e2"] * sE / one_ecE
        cnu = (cE - e) / one_ecE
        sphi = snu * P["cw"] + cnu * P["sw"]
        cphi = cnu * P["cw"] - snu * P["sw"]
        s2 = 2.0 * sphi * cphi
        c2 = cphi * cphi - sphi * sphi
        # Harmonic corrections are < 1e-4 rad, so sin/cos of (phi + du) and
        # (i0 + di) use 3rd-order series: truncation < 1e-17 rad.
        du = P["cus"] * s2 + P["cuc"] * c2
        di = P["idot"] * tk + P["cis"] * s2 + P["cic"] * c2
        cdu, sdu = 1.0 - 0.5 * du * du, du - du * du * du / 6.0
        cdi, sdi = 1.0 - 0.5 * di * di, di - di * di * di / 6.0
        su = sphi * cdu + cphi * sdu
        cu = cphi * cdu - sphi * sdu
        si = P["si0"] * cdi + P["ci0"] * sdi
        ci = P["ci0"] * cdi - P["si0"] * sdi
        r = P["a"] * one_ecE + P["crs"] * s2 + P["crc"] * c2
        nudot = Edot * P["sq1e2"] / one_ecE
        udot = nudot * (1.0 + 2.0 * (P["cus"] * c2 - P["cuc"] * s2))
        rdot = P["a"] * e * sE * Edot + 2.0 * nudot * (P["crs"] * c2 - P["crc"] * s2)
        idot = P["idot"] + 2.0 * nudot * (P["cis"] * c2 - P["cic"] * s2)
        lamdot = P["lamdot"]
        lam = P["lam0"] + lamdot * tk
        sl, cl = np.sin(lam), np.cos(lam)
        xp, yp = r * cu, r * su
        xpd = rdot * cu - yp * udot
        ypd = rdot * su + xp * udot
        ypci = yp * ci
        x = xp * cl - ypci * sl
        y = xp * sl + ypci * cl
        pos[..., 0] = x
        pos[..., 1] = y
        pos[..., 2] = yp * si
        # d/dt of the rotation: the node term (lamdot) and the inclination rate.
        zi = yp * si * idot
        ypdci = ypd * ci
        vel[..., 0] = xpd * cl - ypdci * sl + zi * sl - y * lamdot
        vel[..., 1] = xpd * sl + ypdci * cl - zi * cl + x * lamdot
        vel[..., 2] = ypd * si + ypci * idot
        clk[...] = P["af0"] + tc * (P["af1"] + tc * P["af2"]) + P["frel"] * sE
        drift[...] = P["af1"] + 2.0 * P["af2"] * tc + P["frel"] * cE * Edot
