"""Galileo broadcast ephemerides: the GPS Keplerian algorithm with Galileo constants.

Galileo OS SIS ICD (Issue 1.3, 2016; Issue 2.0, 2021), section 5.1:

* constants (5.1.1, Table 59 in Issue 2.0): mu = 3.986004418e14 m^3/s^2,
  Omega_e = 7.2921151467e-5 rad/s; the relativistic term uses
  F = -2 sqrt(mu) / c^2 = -4.442807309e-10 s/sqrt(m) (5.1.4);
* Galileo System Time (5.1.2): GST is steered to GPS time (the GPS-GST
  offset GGTO is a few ns; a per-system receiver clock absorbs it) and its
  week starts with the GPS week, so in RINEX 3 the Galileo week of Toe is the
  continuous GPS week number and Omega0 refers to the GPS week start;
* clock (5.1.4-5.1.5): the I/NAV clock (af0..af2) refers to the E1-E5b
  ionosphere-free combination; a single-frequency E1 user corrects it with
  the broadcast group delay, ``dt_sv(E1) = dt_sv(E1,E5b) - BGD(E1,E5b)``
  (ICD eq. 12 of Issue 1.3). F/NAV records carry the E1-E5a clock and
  BGD(E1,E5a) instead; the reader keeps one of the two per satellite, and
  ``tgd`` holds the matching BGD.

Everything else (closest-Toe record selection, Kepler solution, harmonic
corrections, velocities) is :class:`simbench.core.orbits.BroadcastEphemeris`.
The RINEX reader is :func:`simbench.data.broadcast.read_navigation` (``"E"``).
"""

from __future__ import annotations

import math

from simbench.core.constants import C_LIGHT
from simbench.core.orbits import BroadcastEphemeris

__all__ = ["GalileoEphemeris"]


class GalileoEphemeris(BroadcastEphemeris):
    """Galileo broadcast ephemerides (see the module docstring); ``tgd`` holds the E1 BGD.

    ``records`` as for :class:`~simbench.core.orbits.BroadcastEphemeris`, with
    ``toe``/``toc`` in continuous GPS seconds (GST taken as GPS time) and
    ``tgd`` the BGD of the record's clock model: BGD(E1,E5b) for I/NAV,
    BGD(E1,E5a) for F/NAV [s].
    """

    mu = 3.986004418e14  #: Galileo gravitational parameter (OS SIS ICD 5.1.1) [m^3/s^2]
    omega_e = 7.2921151467e-5  #: Galileo Earth rotation rate (OS SIS ICD 5.1.1) [rad/s]
    f_rel = -2.0 * math.sqrt(mu) / C_LIGHT**2  #: relativistic clock constant [s/sqrt(m)]
    system_name = "Galileo"
