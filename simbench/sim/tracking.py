"""Receiver tracking: thermal-noise jitter of DLL/PLL, antenna gain, link-budget C/N0.

Jitter formulas follow Kaplan & Hegarty, *Understanding GPS*, 2nd ed., ch. 5
(Betz & Kolodziejski noncoherent early-minus-late power DLL; PLL thermal
noise), as quoted in the dissertation's eqs. 5.13-5.15. Only thermal noise enters the
jitter formulas. The correlator-level functions (band-limited C/A
correlation, the early-minus-late DLL settling on a sum of rays, PLL dynamic
stress) turn multipath rays and vehicle dynamics into tracking errors. All
functions are vectorised over their array arguments; receiver parameters are
scalars that select the formula.
"""

from __future__ import annotations

import math
from fractions import Fraction
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import sici

from simbench.core.constants import CHIP_RATE_CA, DEG, LAMBDA_L1
from simbench.core.frames import dot_last_axis
from simbench.errors import SimbenchError
from simbench.sim.config import ANTENNA_GAIN_ANGLE_DEG, ANTENNA_GAIN_DBI

__all__ = [
    "dll_jitter_chips",
    "pll_jitter_rad",
    "pll_jitter_m",
    "antenna_gain_dbi",
    "cn0_mean_dbhz",
    "effective_spacing_chips",
    "code_phase_step_chips",
    "sample_grid_code_error_chips",
    "band_limited_correlation",
    "dll_tracking_point",
    "multipath_error_envelope_chips",
    "pll_dynamic_stress_deg",
    "channel_lock_states",
]

FloatArray = NDArray[np.float64]

_LN10_OVER_10 = math.log(10.0) / 10.0


def _positive_scalar(value: float, field: str, unit_scale: float = 1.0, unit: str = "") -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise SimbenchError(
            field,
            f"expected one number, got {value!r}",
            "receiver parameters are scalars; see conf/receiver/ for presets",
        ) from None
    if not (math.isfinite(x) and x > 0.0):
        raise SimbenchError(field, f"must be positive, got {x / unit_scale:g}{unit}", "see conf/receiver/ for presets")
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
        raise SimbenchError(
            "receiver.correlator_spacing_chips",
            f"must be below 2 chips, got {d:g}",
            "use an early-late spacing such as 0.1-1 chip",
        )
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
    """Thermal-noise carrier phase jitter on L1 in metres (eq. 5.13): :func:`pll_jitter_rad` (its
    parameters and errors) times ``lambda_L1 / (2 pi)``.

    Returns
    -------
    numpy.ndarray
        1-sigma carrier phase jitter [m] (``lambda_L1 / (2 pi)`` times radians).
    """
    return (LAMBDA_L1 / (2.0 * math.pi)) * pll_jitter_rad(cn0_dbhz, pll_bw_hz, integration_s)


#: Antenna pattern nodes (:data:`simbench.sim.config.ANTENNA_GAIN_DBI`) in radians and dBi.
_GAIN_ANGLE_RAD = np.array(ANTENNA_GAIN_ANGLE_DEG) * DEG
_GAIN_DBI = np.array(ANTENNA_GAIN_DBI)


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


# =========================================================================== correlator-level multipath

#: Tabulation of the band-limited correlation function: half-width [chip] and step [chip].
#: Beyond 2.5 chips from the peak the ripple of a >= 2 MHz front end is below 1e-3 of the peak.
_CORR_HALF_WIDTH_CHIPS = 2.5
_CORR_STEP_CHIPS = 5e-4


def effective_spacing_chips(spacing_chips: float, sampling_hz: float) -> float:
    """Early-late spacing a sampled correlator can realise: a whole number of samples.

    A software receiver forms early and late replicas by shifting the sampled
    code by whole samples, so the spacing is ``round(D f_s / R_c)`` samples
    (at least one). This is where the preset's sampling rate enters the noise
    and the multipath error: 16.368 MHz gives 16 samples per chip, so a nominal
    0.2-chip spacing is realised as 3 samples = 0.1875 chip.

    Parameters
    ----------
    spacing_chips : float
        Nominal early-late spacing ``D`` [chip].
    sampling_hz : float
        Sampling rate ``f_s`` [Hz].

    Returns
    -------
    float
        Realised spacing [chip].

    Raises
    ------
    SimbenchError
        If a parameter is not a positive number.
    """
    d = _positive_scalar(spacing_chips, "receiver.correlator_spacing_chips", unit=" chip")
    fs = _positive_scalar(sampling_hz, "receiver.sampling_mhz", 1e6, " MHz")
    samples_per_chip = fs / CHIP_RATE_CA
    return max(1, round(d * samples_per_chip)) / samples_per_chip


def code_phase_step_chips(sampling_hz: float, integration_s: float) -> float:
    """Resolution of the code phase a sampled correlator can see within one integration.

    The replica is evaluated at the sample instants only, so the correlation
    changes with the replica's code phase only where a chip edge crosses a
    sample instant. With ``f_s / R_c = p / s`` in lowest terms, the samples fall
    on ``p`` distinct phases per chip: the correlation, hence the DLL's
    discriminator, is a staircase in steps of ``1 / p`` chip. A sampling rate
    commensurate with the chip rate keeps ``p`` small (Akos & Pini,
    NAVIGATION 53(2), 2006; Tran et al., J. Navigation 71(2), 2018): 4.092 MHz
    gives 1/4 chip (73 m), 16.368 MHz 1/16 chip. When the pattern does not
    repeat within the integration (``s > R_c T``), the phases are as fine as
    the integration's samples allow.

    Parameters
    ----------
    sampling_hz : float
        Sampling rate ``f_s`` [Hz], taken to the nearest Hz.
    integration_s : float
        Predetection integration time ``T`` [s].

    Returns
    -------
    float
        Code phase step [chip].

    Raises
    ------
    SimbenchError
        If a parameter is not a positive number.
    """
    return _sample_grid(sampling_hz, integration_s)[0]


def _sample_grid(sampling_hz: float, integration_s: float) -> tuple[float, float]:
    """Code phase step [chip] and the drift of the grid [chip/s]: ``f_s / R_c`` a little off
    its nearest short fraction ``p / s`` slides the grid like a code Doppler."""
    fs = _positive_scalar(sampling_hz, "receiver.sampling_mhz", 1e6, " MHz")
    t = _positive_scalar(integration_s, "receiver.integration_s", unit=" s")
    ratio = Fraction(round(fs), round(CHIP_RATE_CA)).limit_denominator(max(1, int(CHIP_RATE_CA * t)))
    return 1.0 / ratio.numerator, CHIP_RATE_CA * (float(ratio) * CHIP_RATE_CA / round(fs) - 1.0)


def sample_grid_code_error_chips(
    code_phase_chips: ArrayLike,
    code_rate_chips_per_s: ArrayLike,
    cn0_dbhz: ArrayLike,
    *,
    sampling_hz: float,
    dll_bw_hz: float,
    spacing_chips: float,
    front_end_bw_hz: float,
    integration_s: float,
) -> FloatArray:
    """Code tracking error of a DLL whose discriminator sees the code phase on a grid.

    The DLL settles on the grid point (:func:`code_phase_step_chips`, step
    ``q``) nearest to the true code phase ``x``: an error ``q (round(x/q) - x/q)``,
    a sawtooth ``q sum_k (-1)^k sin(2 pi k x/q) / (pi k)``. Three things
    smooth it, each per harmonic ``k``:

    * thermal noise dithers the grid: each integration's discriminator noise,
      ``sigma_T = sigma_DLL / sqrt(2 B T)`` in code phase, multiplies harmonic
      ``k`` by the Gaussian's characteristic function
      ``exp(-2 pi^2 k^2 sigma_T^2 / q^2)``;
    * the code phase slides across the grid at the code Doppler
      ``r`` (pseudorange rate over the chip length, receiver clock drift
      included, plus the grid's own drift when ``f_s / R_c`` is only near a
      short fraction), ``r T`` within one integration: ``sinc(k r T / q)``;
    * the first-order DLL (noise bandwidth ``B``) passes the sawtooth's
      harmonic at ``f_k = k r / q`` with ``H(f) = 1 / (1 + j pi f / (2 B))``.

    A satellite whose code phase barely moves relative to the receiver's
    sample clock keeps an error of up to ``q / 2`` for as long as that lasts;
    a weak signal or a fast one averages it away.

    Parameters
    ----------
    code_phase_chips : array_like
        Received code phase relative to the sample grid [chip]: the
        pseudorange over the chip length plus the grid's offset.
    code_rate_chips_per_s : array_like
        Its rate of change, the code Doppler seen by the sample clock [chip/s].
    cn0_dbhz : array_like
        Carrier-to-noise density [dB-Hz].
    sampling_hz, dll_bw_hz, spacing_chips, front_end_bw_hz, integration_s : float
        The receiver preset: sampling rate [Hz], DLL noise bandwidth [Hz],
        realised early-late spacing [chip], double-sided front-end bandwidth
        [Hz], predetection integration [s].

    Returns
    -------
    numpy.ndarray
        Code error [chip] (pseudorange error over the chip length), the
        broadcast shape of the array arguments.
    """
    q, grid_drift = _sample_grid(sampling_hz, integration_s)
    bw = _positive_scalar(dll_bw_hz, "receiver.dll_bw_hz", unit=" Hz")
    sigma_t = dll_jitter_chips(cn0_dbhz, bw, spacing_chips, front_end_bw_hz, integration_s) / math.sqrt(
        2.0 * bw * integration_s
    )
    x, rate, dither = np.broadcast_arrays(
        np.asarray(code_phase_chips, dtype=float) / q,
        (np.asarray(code_rate_chips_per_s, dtype=float) + grid_drift) / q,
        -2.0 * math.pi**2 * (sigma_t / q) ** 2,
    )
    # Harmonic k by recurrences on elementwise arrays, without a transcendental call per k:
    # exp(k^2 d) = exp((k-1)^2 d) exp(d)^(2k-1); sinc(k u) = sinc(u) U_{k-1}(cos pi u) / k (Chebyshev
    # polynomials of the second kind, stable for |cos| <= 1); Im(e^{2 pi j k x} / (1 + j k b)) =
    # (sin - k b cos) / (1 + k^2 b^2) with b = pi r / (2 B).
    turn = np.exp(2j * math.pi * x)
    harmonic = np.ones_like(turn)
    u = rate * integration_s
    cos_u = np.cos(math.pi * u)
    cheb_prev, cheb = np.zeros(x.shape), np.ones(x.shape)  # U_{k-2}, U_{k-1}
    step = np.exp(dither)
    step_sq = step * step
    odd = step.copy()  # exp(d)^(2k-1)
    damping = np.ones(x.shape)  # exp(k^2 d)
    b = rate * (math.pi / (2.0 * bw))
    b_sq = b * b
    total = np.zeros(x.shape)
    # Harmonic k's amplitude is at most q/(pi k) exp(k^2 dither): stop once it is below a micro-chip.
    floor = float(dither.max(initial=-np.inf)) if dither.size else -np.inf
    k = 1
    while k <= 256 and q / (math.pi * k) * math.exp(k * k * floor) > 1e-6:
        harmonic *= turn
        damping *= odd
        odd *= step_sq
        if k > 1:
            cheb_prev, cheb = cheb, 2.0 * cos_u * cheb - cheb_prev
        lag = harmonic.imag - k * b * harmonic.real
        total += ((-1) ** k * q / (math.pi * k * k)) * damping * cheb * lag / (1.0 + (k * k) * b_sq)
        k += 1
    return total * np.sinc(u)


@lru_cache(maxsize=8)
def _correlation_table(front_end_bw_hz: float) -> tuple[FloatArray, FloatArray]:
    """Band-limited C/A correlation and its slope on the uniform grid, see :func:`band_limited_correlation`."""
    b = front_end_bw_hz / CHIP_RATE_CA
    x = np.arange(-_CORR_HALF_WIDTH_CHIPS, _CORR_HALF_WIDTH_CHIPS + 0.5 * _CORR_STEP_CHIPS, _CORR_STEP_CHIPS)

    def ramp_filtered(u: FloatArray) -> FloatArray:
        si, _ = sici(math.pi * b * u)
        return u * (0.5 + si / math.pi) + np.cos(math.pi * b * u) / (math.pi**2 * b)

    r = ramp_filtered(x + 1.0) - 2.0 * ramp_filtered(x) + ramp_filtered(x - 1.0)
    r[0] = r[-1] = 0.0  # the lookup returns the end values outside the grid
    return r, np.diff(r) / _CORR_STEP_CHIPS


def band_limited_correlation(tau_chips: ArrayLike, front_end_bw_hz: float) -> tuple[FloatArray, FloatArray]:
    """C/A code autocorrelation after an ideal (rectangular) front-end filter, and its slope.

    The ideal-code correlation is the triangle ``Lambda(tau) = r(tau+1) - 2 r(tau) + r(tau-1)``
    (``r`` the unit ramp, ``tau`` in chips). Filtering with a brick-wall
    low-pass of double-sided bandwidth ``b = B_fe / R_c`` (impulse response
    ``b sinc(b t)``) turns each ramp into the closed form
    ``g(u) = u (1/2 + Si(pi b u) / pi) + cos(pi b u) / (pi^2 b)``, with ``Si``
    the sine integral, so ``R_b(tau) = g(tau+1) - 2 g(tau) + g(tau-1)`` (Betz,
    *Engineering Satellite-Based Navigation and Timing*, 2016, ch. 19: the
    band-limited triangle; ``R_b -> Lambda`` as ``b -> inf``). The function is
    tabulated once per bandwidth (step 5e-4 chip) and interpolated linearly; the
    slope is that of the interpolant, so Newton steps on it are exact within a
    table cell. Outside +-2.5 chips it is 0.

    Parameters
    ----------
    tau_chips : array_like
        Lag between replica and signal [chip], any shape.
    front_end_bw_hz : float
        Double-sided front-end bandwidth ``B_fe`` [Hz].

    Returns
    -------
    r, slope : numpy.ndarray
        ``R_b(tau)`` (unitless, 1 at the peak for an infinite bandwidth) and ``dR_b/dtau`` [1/chip].
    """
    bfe = _positive_scalar(front_end_bw_hz, "receiver.front_end_bw_mhz", 1e6, " MHz")
    table, slope = _correlation_table(bfe)
    u = (np.asarray(tau_chips, dtype=float) + _CORR_HALF_WIDTH_CHIPS) * (1.0 / _CORR_STEP_CHIPS)
    i = np.clip(u.astype(np.intp), 0, len(slope) - 1)  # astype truncates; clipped below the grid anyway
    frac = np.clip(u - i, 0.0, 1.0)
    s = slope[i]
    return table[i] + frac * (s * _CORR_STEP_CHIPS), np.where((u > 0.0) & (u < len(slope)), s, 0.0)


def _composite(
    x: FloatArray, gain_re: FloatArray, gain_im: FloatArray, delay: FloatArray, bfe: float, slope: bool = True
) -> tuple[FloatArray, ...]:
    """Sum over rays (last axis) of ``a e^{j theta} R(x - tau)`` as real and imaginary parts, then
    (with ``slope``) those of its derivative in ``x``."""
    r, dr = band_limited_correlation(x[..., None] - delay, bfe)
    if not slope:
        return dot_last_axis(gain_re, r), dot_last_axis(gain_im, r)
    return dot_last_axis(gain_re, r), dot_last_axis(gain_im, r), dot_last_axis(gain_re, dr), dot_last_axis(gain_im, dr)


def dll_tracking_point(
    amplitude: ArrayLike,
    delay_chips: ArrayLike,
    phase_rad: ArrayLike,
    start_chips: ArrayLike,
    spacing_chips: float,
    front_end_bw_hz: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Where a noncoherent early-minus-late power DLL settles on a sum of rays.

    The received correlation is ``C(x) = sum_k a_k e^{j theta_k} R_b(x - tau_k)``
    (:func:`band_limited_correlation`). The DLL drives its replica delay ``x`` to
    a zero of ``f(x) = |C(x - D/2)|^2 - |C(x + D/2)|^2`` (Kaplan & Hegarty, 2nd ed.,
    Table 5.5, noncoherent early-minus-late power; the same zero as the
    normalised envelope ``(|E| - |L|)/(|E| + |L|)`` of GNSS-SDR) where ``f``
    rises through 0 (a stable lock). The loop was locked to one ray
    (``start_chips``) and follows its discriminator from there: the search
    steps by ``D/4`` in the direction the discriminator pulls until ``f``
    changes sign (at most 3 chips), then bisects the bracket and finishes with a
    Newton step inside it. With an infinite bandwidth and one in-phase
    reflection of relative amplitude ``alpha < 1`` and delay ``tau``, the error
    is :func:`multipath_error_envelope_chips` (the classic envelope).

    Parameters
    ----------
    amplitude, delay_chips, phase_rad : array_like, shape (..., k)
        Per ray: amplitude relative to an unobstructed direct signal [-], delay
        relative to the direct path [chip] and carrier phase [rad]; a ray with
        amplitude 0 is absent.
    start_chips : array_like, shape (...)
        Delay of the ray the loop is locked to [chip].
    spacing_chips : float
        Early-late spacing ``D`` [chip] (see :func:`effective_spacing_chips`).
    front_end_bw_hz : float
        Double-sided front-end bandwidth [Hz].

    Returns
    -------
    tau_hat : numpy.ndarray, shape (...)
        Tracked code delay [chip], relative to the direct path.
    prompt_amplitude : numpy.ndarray, shape (...)
        ``|C(tau_hat)| / R_b(0)``: the prompt correlator amplitude relative to an
        unobstructed direct signal (its square scales C/N0).
    prompt_phase : numpy.ndarray, shape (...)
        ``arg C(tau_hat)`` [rad]: the phase the PLL tracks.
    """
    bfe = _positive_scalar(front_end_bw_hz, "receiver.front_end_bw_mhz", 1e6, " MHz")
    half = 0.5 * _positive_scalar(spacing_chips, "receiver.correlator_spacing_chips", unit=" chip")
    a = np.asarray(amplitude, dtype=float)
    theta = np.asarray(phase_rad, dtype=float)
    delay = np.asarray(delay_chips, dtype=float)
    g_re, g_im = a * np.cos(theta), a * np.sin(theta)

    def discriminator(x: FloatArray) -> FloatArray:
        e_re, e_im = _composite(x - half, g_re, g_im, delay, bfe, slope=False)
        l_re, l_im = _composite(x + half, g_re, g_im, delay, bfe, slope=False)
        return e_re**2 + e_im**2 - l_re**2 - l_im**2

    def discriminator_and_slope(x: FloatArray) -> tuple[FloatArray, FloatArray]:
        e_re, e_im, de_re, de_im = _composite(x - half, g_re, g_im, delay, bfe)
        l_re, l_im, dl_re, dl_im = _composite(x + half, g_re, g_im, delay, bfe)
        return (
            e_re**2 + e_im**2 - l_re**2 - l_im**2,
            2.0 * (e_re * de_re + e_im * de_im - l_re * dl_re - l_im * dl_im),
        )

    x0 = np.array(start_chips, dtype=float, copy=True)
    f0 = discriminator(x0)
    direction = np.where(f0 > 0.0, -1.0, 1.0)  # f < 0: the late arm is stronger, the signal is later
    step = 0.5 * half
    lo, hi = x0.copy(), x0.copy()  # the bracket, in the search direction
    open_ = f0 != 0.0
    for _ in range(int(np.ceil(3.0 / step))):
        if not open_.any():
            break
        probe = hi + direction * step
        f = discriminator(probe)
        lo = np.where(open_, hi, lo)
        hi = np.where(open_, probe, hi)
        open_ &= np.sign(f) == np.sign(f0)
    for _ in range(6):
        mid = 0.5 * (lo + hi)
        f = discriminator(mid)
        same = np.sign(f) == np.sign(f0)
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    x = 0.5 * (lo + hi)
    f, df = discriminator_and_slope(x)
    newton = x - f / np.where(np.abs(df) > 1e-12, df, 1e-12)
    x = np.clip(newton, np.minimum(lo, hi), np.maximum(lo, hi))
    p_re, p_im = _composite(x, g_re, g_im, delay, bfe, slope=False)
    peak = band_limited_correlation(0.0, bfe)[0]
    return x, np.hypot(p_re, p_im) / peak, np.arctan2(p_im, p_re)


def multipath_error_envelope_chips(alpha: ArrayLike, delay_chips: ArrayLike, spacing_chips: float) -> FloatArray:
    """Upper multipath error envelope of an early-minus-late DLL, one reflection, infinite bandwidth.

    The error when the reflection (relative amplitude ``alpha < 1``, delay ``tau``)
    is in phase with the direct signal, from the triangle correlation and
    spacing ``D < 1`` (Braasch, in Parkinson & Spilker, *GPS: Theory and
    Applications* vol. I, 1996, ch. 14)::

        alpha tau / (1 + alpha)                 tau <= (1 + alpha) D / 2
        alpha D / 2                             ... <= 1 - (1 - alpha) D / 2
        alpha (1 + D / 2 - tau) / (2 - alpha)   ... <  1 + D / 2
        0                                       beyond

    The error over the reflection's carrier phase swings between this and the
    (smaller) out-of-phase envelope, so ``envelope / sqrt(2)`` approximates its RMS.

    Parameters
    ----------
    alpha : array_like
        Reflection amplitude relative to the tracked ray [-], clipped to 0..1.
    delay_chips : array_like
        Reflection delay relative to the tracked ray [chip] (sign ignored).
    spacing_chips : float
        Early-late spacing ``D`` [chip], below 1.

    Returns
    -------
    numpy.ndarray
        Envelope [chip], >= 0.
    """
    a = np.clip(np.asarray(alpha, dtype=float), 0.0, 1.0)
    tau = np.abs(np.asarray(delay_chips, dtype=float))
    half = 0.5 * spacing_chips
    rise = a * tau / (1.0 + a)
    fall = a * np.maximum(1.0 + half - tau, 0.0) / (2.0 - a)
    return np.minimum(np.minimum(rise, a * half), fall)


def pll_dynamic_stress_deg(los_jerk_mps3: ArrayLike, pll_bw_hz: float) -> FloatArray:
    """Steady-state dynamic stress error of a third-order PLL.

    ``theta_e = 0.4828 (d^3 R / dt^3) / B_n^3`` with the line-of-sight jerk in
    degrees of L1 carrier per s^3 (Kaplan & Hegarty, 2nd ed., eq. 5.11 and
    Table 5.6: ``omega_0 = B_n / 0.7845``). Enters Kaplan's rule of thumb for
    phase lock, ``3 sigma_PLL = 3 sigma_j + theta_e <= 45 deg``.

    Parameters
    ----------
    los_jerk_mps3 : array_like
        Line-of-sight jerk [m/s^3] (sign ignored).
    pll_bw_hz : float
        PLL noise bandwidth ``B_n`` [Hz].

    Returns
    -------
    numpy.ndarray
        Dynamic stress error [deg].
    """
    bw = _positive_scalar(pll_bw_hz, "receiver.pll_bw_hz", unit=" Hz")
    return 0.4828 * np.abs(np.asarray(los_jerk_mps3, dtype=float)) * (360.0 / LAMBDA_L1) / bw**3


def channel_lock_states(
    acquirable: NDArray[np.bool_], in_lock: NDArray[np.bool_], acquisition_epochs: int
) -> NDArray[np.bool_]:
    """Which channels are tracked: hysteresis between acquisition and loss of lock, vectorised.

    Along axis 0 (epochs), a channel enters tracking once ``acquirable`` has
    held for ``acquisition_epochs`` consecutive epochs (or since the first
    epoch: the receiver was running before the scenario starts) and leaves it
    at the first epoch that is not ``in_lock``. Between the two it keeps its
    state, so a signal that fades below the acquisition threshold but stays
    above the lock threshold is kept.

    Parameters
    ----------
    acquirable : ndarray of bool, shape (n, ...)
        Signal strong enough to be acquired (implies ``in_lock``).
    in_lock : ndarray of bool, shape (n, ...)
        Signal strong enough to be kept.
    acquisition_epochs : int
        Consecutive acquirable epochs needed to (re)acquire, >= 1.

    Returns
    -------
    ndarray of bool, shape (n, ...)
        Tracked.
    """
    acq = np.asarray(acquirable, dtype=bool) & np.asarray(in_lock, dtype=bool)
    n = acq.shape[0]
    rows = np.arange(n).reshape((n,) + (1,) * (acq.ndim - 1))
    count = np.cumsum(acq, axis=0)
    run = count - np.maximum.accumulate(np.where(acq, 0, count), axis=0)
    enter = acq & ((run >= max(int(acquisition_epochs), 1)) | (run == rows + 1))
    last = np.maximum.accumulate(np.where(enter | ~np.asarray(in_lock, dtype=bool), rows, -1), axis=0)
    return (last >= 0) & np.take_along_axis(enter, np.maximum(last, 0), axis=0)
