"""Physical and GPS constants (IS-GPS-200, WGS-84).

All values in SI units unless the name says otherwise.
"""

from __future__ import annotations

import math

C_LIGHT: float = 299_792_458.0  #: speed of light in vacuum [m/s]
MU_EARTH: float = 3.986005e14  #: WGS-84 gravitational parameter used by IS-GPS-200 [m^3/s^2]
OMEGA_EARTH: float = 7.2921151467e-5  #: WGS-84 Earth rotation rate [rad/s]
F_REL: float = -4.442807633e-10  #: relativistic clock correction constant [s/sqrt(m)]
WGS84_A: float = 6_378_137.0  #: WGS-84 semi-major axis [m]
WGS84_F: float = 1.0 / 298.257223563  #: WGS-84 flattening [-]
WGS84_E2: float = WGS84_F * (2.0 - WGS84_F)  #: first eccentricity squared [-]

F_L1: float = 1_575.42e6  #: GPS L1 carrier frequency [Hz]
F_L2: float = 1_227.60e6  #: GPS L2 carrier frequency [Hz]
F_B1I: float = 1_561.098e6  #: BeiDou B1I carrier frequency [Hz]
LAMBDA_L1: float = C_LIGHT / F_L1  #: L1 wavelength [m]
LAMBDA_L2: float = C_LIGHT / F_L2  #: L2 wavelength [m]
CHIP_RATE_CA: float = 1.023e6  #: C/A code chipping rate [chip/s]
CHIP_LENGTH_CA: float = C_LIGHT / CHIP_RATE_CA  #: C/A chip length [m]

#: Ionosphere-free combination coefficients: IF = A1 * O1 - A2 * O2 (2.546, 1.546).
IF_A1: float = F_L1**2 / (F_L1**2 - F_L2**2)
IF_A2: float = F_L2**2 / (F_L1**2 - F_L2**2)
#: Ionospheric delay on L2 relative to L1 (f1^2 / f2^2).
IONO_L2_SCALE: float = (F_L1 / F_L2) ** 2

SECONDS_PER_WEEK: float = 604_800.0
DEG: float = math.pi / 180.0
SECONDS_PER_DAY: float = 86_400.0

#: Start of GPS time (week 0, second 0), as an ISO string in the GPS time scale.
GPS_EPOCH_ISO: str = "1980-01-06T00:00:00"
#: GPS - UTC at the SPS nominal-constellation reference epoch 1993-07-01 [s].
GPS_MINUS_UTC_1993_07_01: float = 9.0

#: WGS-84 gravitational parameter (with atmosphere), used by the gravity model [m^3/s^2].
#: IS-GPS-200 keeps the older 3.986005e14 (MU_EARTH) for orbits.
MU_EARTH_WGS84: float = 3.986004418e14
J2_EARTH: float = 1.082627e-3  #: WGS-84 second zonal harmonic of the geopotential [-]
G0_STD: float = 9.80665  #: standard gravity, for bank angles and unit conversions [m/s^2]
