"""BeiDou (BDS) broadcast ephemerides: the GPS Keplerian algorithm with BDS constants and time.

Differences from GPS (BDS-SIS-ICD-B1I 3.0, section 5.2.4):

* CGCS2000 constants: mu = 3.986004418e14 m^3/s^2, Earth rate 7.2921150e-5 rad/s;
  the relativistic constant follows as F = -2 sqrt(mu) / c^2;
* BeiDou time: BDT = GPST - 14 s, BDT week 0 = GPS week 1356; Toe is in
  seconds of the BDT week and Omega0 refers to the BDT week start;
* geostationary satellites (C01-C05, C59-C63) are computed in a frame that
  does not rotate with the Earth (``Omega_k = Omega0 + OmegaDot tk - Omega_e
  Toe``) and then rotated: ``x = R_Z(Omega_e tk) R_X(-5 deg) x_GK``;
* the clock refers to B3I: a B1I user applies ``dt_sv - TGD1``.

Everything else (record selection by closest Toe, Kepler solution, harmonic
corrections) is :class:`simbench.core.orbits.BroadcastEphemeris`; times stay
continuous GPS seconds, so BeiDou and GPS states come out in one time scale.
The RINEX reader is :func:`simbench.data.broadcast.read_navigation` (``"C"``).
"""

from __future__ import annotations

import math

import numpy as np

from simbench.core.constants import C_LIGHT, DEG
from simbench.core.orbits import BroadcastEphemeris

__all__ = ["BeidouEphemeris", "GPS_MINUS_BDT_S", "BDT_WEEK_OFFSET", "GEO_PRNS"]

GPS_MINUS_BDT_S: float = 14.0  #: GPST - BDT [s]
BDT_WEEK_OFFSET: int = 1356  #: GPS week of BDT week 0
#: Geostationary PRNs (BDS-2 C01-C05, BDS-3 C59-C63).
GEO_PRNS = frozenset([1, 2, 3, 4, 5, 59, 60, 61, 62, 63])
_GEO_TILT_RAD = -5.0 * DEG


class BeidouEphemeris(BroadcastEphemeris):
    """BeiDou broadcast ephemerides (see the module docstring); ``tgd`` holds TGD1 (B1I).

    Read from a file with :func:`simbench.data.broadcast.read_navigation` (``"C"``).
    ``records`` as for :class:`~simbench.core.orbits.BroadcastEphemeris`, with
    ``toe``/``toc`` in continuous GPS seconds.
    """

    mu = 3.986004418e14  #: CGCS2000 gravitational parameter [m^3/s^2]
    omega_e = 7.2921150e-5  #: CGCS2000 Earth rotation rate [rad/s]
    f_rel = -2.0 * math.sqrt(mu) / C_LIGHT**2  #: relativistic clock constant [s/sqrt(m)]
    week_origin_s = GPS_MINUS_BDT_S
    system_name = "BeiDou"

    def _node_rate(self, omegadot: np.ndarray) -> np.ndarray:
        """GEO elements are in a frame that does not rotate with the Earth: no -Omega_e in their node rate."""
        prn = np.array([int(s[1:3]) for s in self.sats.tolist()])
        self._geo_record = np.isin(prn, list(GEO_PRNS))[self._sat_idx]
        lamdot = super()._node_rate(omegadot)
        return np.where(self._geo_record, lamdot + self.omega_e, lamdot)

    def _to_earth_fixed(self, gi: np.ndarray, tk: np.ndarray, pos: np.ndarray, vel: np.ndarray) -> None:
        """The GEO rotation from the inertial-like frame into BDCS."""
        geo = self._geo_record[gi]
        if not geo.any():
            return
        t = tk[geo]
        th = self.omega_e * t
        ct, st = np.cos(th), np.sin(th)
        cp, sp = math.cos(_GEO_TILT_RAD), math.sin(_GEO_TILT_RAD)
        x, v = pos[geo], vel[geo]

        # R_X(phi) = [[1,0,0],[0,c,s],[0,-s,c]] then R_Z(th) = [[c,s,0],[-s,c,0],[0,0,1]]
        def rx(u: np.ndarray) -> np.ndarray:
            return np.stack([u[:, 0], cp * u[:, 1] + sp * u[:, 2], -sp * u[:, 1] + cp * u[:, 2]], axis=1)

        xr, vr = rx(x), rx(v)
        pos[geo] = np.stack([ct * xr[:, 0] + st * xr[:, 1], -st * xr[:, 0] + ct * xr[:, 1], xr[:, 2]], axis=1)
        w = self.omega_e
        vel[geo] = np.stack(
            [
                ct * vr[:, 0] + st * vr[:, 1] + w * (-st * xr[:, 0] + ct * xr[:, 1]),
                -st * vr[:, 0] + ct * vr[:, 1] + w * (-ct * xr[:, 0] - st * xr[:, 1]),
                vr[:, 2],
            ],
            axis=1,
        )
