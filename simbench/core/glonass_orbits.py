"""GLONASS broadcast ephemerides: numerical integration of the ICD equations of motion.

GLONASS ICD (L1/L2 FDMA, Edition 5.1, 2008), Appendix A.3.1.2: a GLONASS
record gives the satellite state at ``tb`` in the Earth-fixed PZ-90 frame
(position, velocity, and the lunisolar acceleration, held constant over the
interval); the state at ``t`` follows from integrating, in that rotating
frame,

    dr/dt = v
    dv/dt = -mu r / r^3 - 3/2 J2 mu ae^2 / r^5 (x (1 - 5 z^2/r^2), y (1 - 5 z^2/r^2), z (3 - 5 z^2/r^2))
            + w^2 (x, y, 0) + 2 w (v_y, -v_x, 0) + a_lunisolar

with PZ-90 constants mu = 398 600.4418 km^3/s^2, ae = 6 378 136 m,
J2 = 1 082 625.75e-9, w = 7.2921151467e-5 rad/s. We integrate with a
4th-order Runge-Kutta, every (epoch, satellite) at once, with an equal step
count chosen so that no step exceeds :data:`GLO_MAX_STEP_S`; the velocity is
the integrated one. PZ-90.11 agrees with ITRF/WGS-84 to a few centimetres,
so positions are used as WGS-84 without transformation (metre-level work).

Time: the raw message counts ``tb`` in GLONASS time, UTC(SU) + 3 h; RINEX 3
already gives the record epoch in UTC, which the reader turns into GPS time
with the leap seconds (:func:`simbench.core.gpstime.utc_to_gps`). The
satellite clock is ``dt_sv(t) = -TauN + GammaN (t - tb)`` (RINEX stores
-TauN and +GammaN; relativistic effects are inside the broadcast clock). The
GLONASS-GPS system time offset is left to a per-system receiver clock.
The RINEX reader is :func:`simbench.data.broadcast.read_navigation` (``"R"``).
"""

from __future__ import annotations

import math

import numpy as np

from simbench.core.orbits import RecordEphemeris, SatelliteStates, state_time_grid

__all__ = [
    "GlonassEphemeris",
    "GLO_MU",
    "GLO_AE",
    "GLO_J2",
    "GLO_OMEGA_EARTH",
    "GLO_MAX_STEP_S",
    "GLO_MAX_AGE_S",
    "GLO_F1_BASE_HZ",
    "GLO_F1_STEP_HZ",
    "glonass_l1_frequency",
]

GLO_MU: float = 3.986004418e14  #: PZ-90 gravitational parameter [m^3/s^2]
GLO_AE: float = 6_378_136.0  #: PZ-90 equatorial radius [m]
GLO_J2: float = 1_082_625.75e-9  #: PZ-90 second zonal harmonic [-]
GLO_OMEGA_EARTH: float = 7.2921151467e-5  #: PZ-90 Earth rotation rate [rad/s]
GLO_MAX_STEP_S: float = 60.0  #: largest Runge-Kutta step [s]
#: Largest |t - tb| at which a record is used [s]: records come every 30 min and the ICD
#: integrates within 15 min of tb; 30 min (as RTKLIB) bridges one missing record.
GLO_MAX_AGE_S: float = 1800.0
GLO_F1_BASE_HZ: float = 1_602.0e6  #: GLONASS L1 FDMA centre frequency of channel 0 [Hz]
GLO_F1_STEP_HZ: float = 0.5625e6  #: GLONASS L1 FDMA channel spacing [Hz]


def glonass_l1_frequency(k: np.ndarray | int) -> np.ndarray:
    """L1 carrier frequency of FDMA channel ``k`` (ICD 3.3.1.1): 1602 MHz + k * 0.5625 MHz.

    Parameters
    ----------
    k : array_like of int
        Frequency channel number, -7..+6.

    Returns
    -------
    np.ndarray
        Carrier frequency [Hz].
    """
    return GLO_F1_BASE_HZ + np.asarray(k, dtype=float) * GLO_F1_STEP_HZ


def _acceleration(pos: np.ndarray, vel: np.ndarray, acc_ls: np.ndarray) -> np.ndarray:
    """Right-hand side of the ICD equations of motion for states (K, 3) in the rotating PZ-90 frame."""
    r2 = np.einsum("ij,ij->i", pos, pos)
    r = np.sqrt(r2)
    mu_r3 = GLO_MU / (r2 * r)
    j2 = 1.5 * GLO_J2 * GLO_MU * GLO_AE**2 / (r2 * r2 * r)
    z2 = 5.0 * pos[:, 2] ** 2 / r2
    w = GLO_OMEGA_EARTH
    out = np.empty_like(pos)
    c_xy = -mu_r3 - j2 * (1.0 - z2) + w * w
    out[:, 0] = c_xy * pos[:, 0] + 2.0 * w * vel[:, 1]
    out[:, 1] = c_xy * pos[:, 1] - 2.0 * w * vel[:, 0]
    out[:, 2] = (-mu_r3 - j2 * (3.0 - z2)) * pos[:, 2]
    return out + acc_ls


def _rk4(
    pos: np.ndarray, vel: np.ndarray, acc_ls: np.ndarray, dt: np.ndarray, max_step_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate states (K, 3) over ``dt`` (K,) with one step count for all, each step <= ``max_step_s``."""
    n_steps = max(1, math.ceil(float(np.max(np.abs(dt), initial=0.0)) / max_step_s))
    h = (dt / n_steps)[:, None]
    for _ in range(n_steps):
        k1v, k1a = vel, _acceleration(pos, vel, acc_ls)
        p2, v2 = pos + 0.5 * h * k1v, vel + 0.5 * h * k1a
        k2v, k2a = v2, _acceleration(p2, v2, acc_ls)
        p3, v3 = pos + 0.5 * h * k2v, vel + 0.5 * h * k2a
        k3v, k3a = v3, _acceleration(p3, v3, acc_ls)
        p4, v4 = pos + h * k3v, vel + h * k3a
        k4v, k4a = v4, _acceleration(p4, v4, acc_ls)
        pos = pos + h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        vel = vel + h / 6.0 * (k1a + 2.0 * k2a + 2.0 * k3a + k4a)
    return pos, vel


class GlonassEphemeris(RecordEphemeris):
    """GLONASS broadcast ephemerides (see the module docstring); same interface as the GPS one.

    Attributes
    ----------
    sats : np.ndarray of str, shape (m,)
        Satellites with at least one healthy record (``'R05'``).
    freq_number : np.ndarray of int, shape (m,)
        FDMA frequency channel k of each satellite (from its latest record).
    tgd : np.ndarray, shape (m,)
        Zeros: the broadcast GLONASS clock already refers to L1 C/A for an L1 user.
    iono_alpha, iono_beta : None
        GLONASS broadcasts no ionosphere model.

    and those of :class:`~simbench.core.orbits.RecordEphemeris` (``t_coverage``, ``source``, ``max_age_s``).
    """

    system_name = "GLONASS"
    coverage_fix = "pass the GLONASS navigation data of the observation day"

    def __init__(
        self,
        sats: np.ndarray,
        records: dict[str, np.ndarray],
        source: str = "",
        max_age_s: float = GLO_MAX_AGE_S,
        max_step_s: float = GLO_MAX_STEP_S,
    ) -> None:
        """Build from per-record arrays (the RINEX reader fills them).

        Parameters
        ----------
        sats : np.ndarray of str, shape (m,)
            GLONASS satellite ids (``'R05'``), in the order ``records['sat']`` indexes.
        records : dict of str -> np.ndarray
            ``sat`` (int index, (R,)), ``tb`` (continuous GPS s, (R,)), ``pos`` [m],
            ``vel`` [m/s] and ``acc`` (lunisolar) [m/s^2] (each (R, 3), PZ-90 at tb),
            ``clock`` (-TauN) [s], ``gamma`` (+GammaN) [-] and ``freq`` (channel k), each (R,).
        max_step_s : float
            Largest Runge-Kutta step [s].
        """
        self.sats = np.asarray(sats)
        self.source = source
        self.max_age_s = float(max_age_s)
        self.max_step_s = float(max_step_s)
        self.iono_alpha = None
        self.iono_beta = None
        order = np.lexsort((records["tb"], records["sat"]))
        r = {k: np.asarray(v)[order] for k, v in records.items()}
        self._sat_idx = r["sat"].astype(np.intp)
        self._tb = r["tb"].astype(float)
        self._pos, self._vel, self._acc = (r[k].astype(float) for k in ("pos", "vel", "acc"))
        self._clock, self._gamma = r["clock"].astype(float), r["gamma"].astype(float)
        m = self.sats.size
        last = np.searchsorted(self._sat_idx, np.arange(m), side="right") - 1
        self.freq_number = r["freq"].astype(int)[last]
        self.tgd = np.zeros(m)
        self._index_records(self._sat_idx, self._tb)

    def states(self, t_gps: np.ndarray, offset_s: np.ndarray | float | None = None) -> SatelliteStates:
        """Satellite positions, velocities and clocks from the record with the nearest tb, integrated to
        ``t_gps + offset_s`` (parameters and errors as :meth:`simbench.core.orbits.BroadcastEphemeris.states`).

        Returns
        -------
        SatelliteStates
            PZ-90 (taken as WGS-84) positions of time t [m], velocities [m/s],
            clock -TauN + GammaN (t - tb) [s] and its rate GammaN [s/s]; NaN where
            no record lies within ``max_age_s``.
        """
        t, off = state_time_grid(t_gps, offset_s, self.sats.size)
        n, m = off.shape
        idx = self.select_records(t)
        ok = idx >= 0
        bad = ~ok.any(axis=1)
        if bad.any():
            self._raise_coverage(int(bad.sum()), n, first=float(t[np.argmax(bad), 0]))
        gi = idx[ok]
        dt = (np.broadcast_to(t, (n, m))[ok] - self._tb[gi]) + off[ok]
        p, v = _rk4(self._pos[gi], self._vel[gi], self._acc[gi], dt, self.max_step_s)
        pos = np.full((n, m, 3), np.nan)
        vel = np.full((n, m, 3), np.nan)
        clk = np.full((n, m), np.nan)
        drift = np.full((n, m), np.nan)
        pos[ok], vel[ok] = p, v
        clk[ok] = self._clock[gi] + self._gamma[gi] * dt
        drift[ok] = self._gamma[gi]
        return SatelliteStates(sats=self.sats, pos=pos, vel=vel, clock=clk, clock_drift=drift, valid=ok)
