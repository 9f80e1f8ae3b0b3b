"""Receiver tracking: thermal-noise jitter of DLL/PLL, antenna gain, link-budget C/N0.

Jitter formulas follow Kaplan & Hegarty, *Understanding GPS*, 2nd ed., ch. 5
(Betz & Kolodziejski noncoherent early-minus-late power DLL; PLL thermal
noise), as quoted in the dissertation's eqs. 5.13-5.15. Only thermal noise is
modelled: no dynamic stress, oscillator phase noise or multipath. All
functions are vectorised over C/N0 (any shape); receiver parameters are
scalars that select the formula.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simbench.errors import SimbenchError
from simbench.sim.constants import CHIP_LENGTH_CA, CHIP_RATE_CA, DEG, LAMBDA_L1

__all__ = [
    "dll_jitter_chips",
    "dll_jitter_m",
    "pll_jitter_rad",
    "pll_jitter_m",
    "antenna_gain_dbi",
    "cn0_mean_dbhz",
]

FloatArray = NDArray[np.float64]

_LN10_OVER_10 = math.log(10.0) / 10.0


def _positive_scalar(value: float, field: str, unit_scale: float = 1.0, unit: str = "") -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise SimbenchError(field, f"expected one number, got {value!r}",
                            "receiver parameters are scalars; see conf/receiver/ for presets") from None
    if not (math.isfinite(x) and x > 0.0):
        raise SimbenchError(field, f"must be positive, got {x / unit_scale:g}{unit}",
                            "see conf/receiver/ for presets")
    return x


def _cn0_ratio_hz(cn0_dbhz: ArrayLike) -> FloatArray:
    # exp is markedly faster than np.power(10, .) on large arrays.
    return np.exp(np.asarray(cn0_dbhz, dtype=float) * _LN10_OVER_10)


def dll_jitter_chips(
    cn0_dbhz: ArrayLike,
    dll_bw_hz: float,
    spacing_chips: float,
    front_end_bw_hz: float,
    integration_s: float,
) -> FloatArray:
    """Thermal-noise code tracking jitter of a noncoherent early-minus-late power DLL.

    With ``c = C/N0`` (ratio-Hz), ``B`` the DLL noise bandwidth, ``D`` the
    early-late spacing, ``T`` the predetection integration time,
    ``B_fe`` the double-sided front-end bandwidth and ``T_c = 1 / R_c`` the
    chip duration (so ``1 / (B_fe T_c) = R_c / B_fe``):

    * ``D >= pi R_c / B_fe`` (eq. 5.14, wide):
      ``s^2 = B / (2c) * D * (1 + 2 / (T c (2 - D)))``
    * ``R_c / B_fe < D < pi R_c / B_fe`` (middle):
      ``s^2 = B / (2c) * [1/(B_fe T_c) + B_fe T_c / (pi - 1) * (D - 1/(B_fe T_c))^2]
      * (1 + 2 / (T c (2 - D)))``
      (the dissertation prints ``1/B_fe`` for the first term: a typo)
    * ``D <= R_c / B_fe`` (eq. 5.15, narrow):
      ``s^2 = B / (2c) * 1/(B_fe T_c) * (1 + 1 / (T c))``

    The spectral term is continuous at both boundaries. The squaring-loss
    factor is continuous at the wide boundary but, as published, switches
    from ``2/(2 - D)`` to 1 at the narrow one: sigma jumps down by a relative
    ``sqrt((1 + 2/(T c (2 - D))) / (1 + 1/(T c))) - 1 ~ D / (4 (1 + T c))``
    when D crosses ``R_c / B_fe`` (T = 1 ms, B_fe = 4.092 MHz: 5 % at
    25 dB-Hz, 0.2 % at 45 dB-Hz). It matters only when sweeping D.

    Parameters
    ----------
    cn0_dbhz : array_like
        Carrier-to-noise density [dB-Hz], any shape.
    dll_bw_hz : float
        DLL one-sided noise bandwidth ``B_rho`` [Hz].
    spacing_chips : float
        Early-late correlator spacing ``D`` [chip], 0 < D < 2.
    front_end_bw_hz : float
        Double-sided front-end (precorrelation) bandwidth ``B_fe`` [Hz].
    integration_s : float
        Predetection integration time ``T`` [s].

    Returns
    -------
    numpy.ndarray
        1-sigma code tracking jitter [chip], shape of ``cn0_dbhz``.

    Raises
    ------
    SimbenchError
        If a receiver parameter is not a positive number or ``D >= 2``.
    """
    bw = _positive_scalar(dll_bw_hz, "receiver.dll_bw_hz", unit=" Hz")
    d = _positive_scalar(spacing_chips, "receiver.correlator_spacing_chips", unit=" chip")
    if d >= 2.0:
        raise SimbenchError("receiver.correlator_spacing_chips", f"must be below 2 chips, got {d:g}",
                            "use an early-late spacing such as 0.1-1 chip")
    bfe = _positive_scalar(front_end_bw_hz, "receiver.front_end_bw_mhz", 1e6, " MHz")
    t = _positive_scalar(integration_s, "receiver.integration_s", unit=" s")

    bfe_tc = bfe / CHIP_RATE_CA  # B_fe T_c: front-end bandwidth in units of the chip rate
    narrow_limit = 1.0 / bfe_tc
    if d >= math.pi * narrow_limit:
        spectral = d
        squaring = 2.0 / (2.0 - d)
    elif d > narrow_limit:
        spectral = narrow_limit + bfe_tc / (math.pi - 1.0) * (d - narrow_limit) ** 2
        squaring = 2.0 / (2.0 - d)
    else:
        # The band-limited correlation peak is rounded below ~1/B_fe: narrower
        # spacing buys nothing more.
        spectral = narrow_limit
        squaring = 1.0

    c = _cn0_ratio_hz(cn0_dbhz)
    inv_c = 1.0 / c
    return np.sqrt((0.5 * bw * spectral) * inv_c * (1.0 + (squaring / t) * inv_c))


def dll_jitter_m(
    cn0_dbhz: ArrayLike,
    dll_bw_hz: float,
    spacing_chips: float,
    front_end_bw_hz: float,
    integration_s: float,
) -> FloatArray:
    """Thermal-noise code tracking jitter in metres on GPS L1 C/A.

    :func:`dll_jitter_chips` times the C/A chip length (293.05 m).

    Parameters
    ----------
    cn0_dbhz : array_like
        Carrier-to-noise density [dB-Hz].
    dll_bw_hz : float
        DLL noise bandwidth [Hz].
    spacing_chips : float
        Early-late spacing [chip].
    front_end_bw_hz : float
        Double-sided front-end bandwidth [Hz].
    integration_s : float
        Predetection integration time [s].

    Returns
    -------
    numpy.ndarray
        1-sigma pseudorange jitter [m].
    """
    return CHIP_LENGTH_CA * dll_jitter_chips(
        cn0_dbhz, dll_bw_hz, spacing_chips, front_end_bw_hz, integration_s
    )


def pll_jitter_rad(cn0_dbhz: ArrayLike, pll_bw_hz: float, integration_s: float) -> FloatArray:
    """Thermal-noise phase jitter of a Costas PLL (eq. 5.13 without lambda / 2 pi).

    ``s^2 = B / c * (1 + 1 / (2 T c))`` with ``c = C/N0`` in ratio-Hz.

    Parameters
    ----------
    cn0_dbhz : array_like
        Carrier-to-noise density [dB-Hz].
    pll_bw_hz : float
        PLL one-sided noise bandwidth ``B_phi`` [Hz].
    integration_s : float
        Predetection integration time ``T`` [s].

    Returns
    -------
    numpy.ndarray
        1-sigma carrier phase jitter [rad].

    Raises
    ------
    SimbenchError
        If a receiver parameter is not a positive number.
    """
    bw = _positive_scalar(pll_bw_hz, "receiver.pll_bw_hz", unit=" Hz")
    t = _positive_scalar(integration_s, "receiver.integration_s", unit=" s")
    inv_c = 1.0 / _cn0_ratio_hz(cn0_dbhz)
    return np.sqrt(bw * inv_c * (1.0 + (0.5 / t) * inv_c))


def pll_jitter_m(cn0_dbhz: ArrayLike, pll_bw_hz: float, integration_s: float) -> FloatArray:
    """Thermal-noise carrier phase jitter on L1 in metres (eq. 5.13).

    Parameters
    ----------
    cn0_dbhz : array_like
        Carrier-to-noise density [dB-Hz].
    pll_bw_hz : float
        PLL noise bandwidth [Hz].
    integration_s : float
        Predetection integration time [s].

    Returns
    -------
    numpy.ndarray
        1-sigma carrier phase jitter [m] (``lambda_L1 / (2 pi)`` times radians).
    """
    return (LAMBDA_L1 / (2.0 * math.pi)) * pll_jitter_rad(cn0_dbhz, pll_bw_hz, integration_s)


#: Antenna pattern nodes: off-boresight angle [rad] and gain [dBi]. The first
#: five are the upright-antenna values at 90, 75, 60, 25, 0 deg elevation.
#: Behind the ground plane the gain falls linearly to -25 dBi straight back
#: (front-to-back ratio 37 dB, typical of a patch on a ground plane): a
#: satellite there reaches only -158.5 - 25 + 201 = 17.5 dB-Hz, below any
#: tracking threshold, so a tilted or inverted antenna masks it, while rays
#: just under the horizon stay marginally trackable.
_GAIN_ANGLE_RAD = np.array([0.0, 25.0, 60.0, 75.0, 90.0, 180.0]) * DEG
_GAIN_DBI = np.array([12.0, 9.0, 3.0, -1.0, -6.0, -25.0])


def antenna_gain_dbi(off_boresight_rad: ArrayLike) -> FloatArray:
    """Gain of a right-hand circularly polarised patch antenna.

    Piecewise-linear in the off-boresight angle through 12, 9, 3, -1, -6 dBi
    at 0, 25, 60, 75, 90 deg (i.e. 90, 65, 30, 15, 0 deg elevation for an
    upright antenna) and down to -25 dBi at 180 deg (back lobe). Using the
    angle from boresight rather than elevation lets vehicle attitude tilt the
    pattern, which produces attitude masking.

    Parameters
    ----------
    off_boresight_rad : array_like
        Angle between the antenna boresight and the line of sight [rad],
        0..pi (values outside are held at the end gains).

    Returns
    -------
    numpy.ndarray
        Antenna gain [dBi].
    """
    return np.interp(np.asarray(off_boresight_rad, dtype=float), _GAIN_ANGLE_RAD, _GAIN_DBI)


def cn0_mean_dbhz(
    off_boresight_rad: ArrayLike,
    received_power_dbw: ArrayLike = -158.5,
    constant_db: float = 201.0,
) -> FloatArray:
    """Noise-free link-budget carrier-to-noise density.

    ``C/N0 = P_rx + G(off-boresight) + K``. The default ``P_rx`` is the
    IS-GPS-200 minimum L1 C/A power at the Earth's surface into a 3 dBi
    antenna; ``K = 201 dB`` is ``-N0`` for a system noise temperature of about
    530 K (``10 log10(k T) = -228.6 + 27.3 dBW/Hz``) with implementation losses
    folded in. Zenith gives 54.5 dB-Hz, the horizon 36.5 dB-Hz.

    Parameters
    ----------
    off_boresight_rad : array_like
        Angle between the antenna boresight and the line of sight [rad].
    received_power_dbw : array_like, optional
        Received signal power at an isotropic antenna [dBW].
    constant_db : float, optional
        Minus the noise density and losses [dB(1/(W/Hz))].

    Returns
    -------
    numpy.ndarray
        Mean C/N0 [dB-Hz], before any random fading or noise.
    """
    return antenna_gain_dbi(off_boresight_rad) + (np.asarray(received_power_dbw, dtype=float) + constant_db)
