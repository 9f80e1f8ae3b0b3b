"""Checks of DLL/PLL thermal jitter, antenna pattern and link-budget C/N0."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simbench.core.constants import CHIP_LENGTH_CA, CHIP_RATE_CA, LAMBDA_L1
from simbench.errors import SimbenchError
from simbench.sim.tracking import (
    antenna_gain_dbi,
    cn0_mean_dbhz,
    code_phase_step_chips,
    dll_jitter_chips,
    pll_jitter_m,
    pll_jitter_rad,
    sample_grid_code_error_chips,
)

T_1MS = 1e-3
# Dissertation Table 5.3.1 presets: (DLL bandwidth Hz, spacing chip, double-sided front end Hz)
LOW = dict(dll_bw_hz=2.0, spacing_chips=0.5, front_end_bw_hz=4.092e6, integration_s=T_1MS)
HIGH = dict(dll_bw_hz=1.0, spacing_chips=0.2, front_end_bw_hz=9.66e6, integration_s=T_1MS)
CN0_GRID = np.arange(25.0, 55.01, 0.5)


# --------------------------------------------------------------------------- DLL


def test_dll_preset_reference_values():
    # Low preset at 45 dB-Hz, by hand: c = 10^4.5 = 31623 Hz; B_fe T_c = 4.092/1.023 = 4,
    # so R_c/B_fe = 0.25 < D = 0.5 < pi/4: middle regime.
    # spectral = 0.25 + 4/(pi - 1) (0.5 - 0.25)^2 = 0.25 + 0.116742 = 0.366742
    # squaring = 1 + 2/(0.001 * 31623 * 1.5) = 1.042164
    # sigma = sqrt(2/(2*31623) * 0.366742 * 1.042164) = 3.4765e-3 chip = 1.0188 m
    c = 10**4.5
    spectral = 0.25 + 4.0 / (math.pi - 1.0) * 0.25**2
    sigma_low = math.sqrt(2.0 / (2.0 * c) * spectral * (1.0 + 2.0 / (T_1MS * c * 1.5)))
    assert sigma_low * CHIP_LENGTH_CA == pytest.approx(1.0188, abs=1e-4)
    assert CHIP_LENGTH_CA * dll_jitter_chips(45.0, **LOW) == pytest.approx(1.0188, abs=1e-4)
    assert dll_jitter_chips(45.0, **LOW) == pytest.approx(sigma_low, rel=1e-12)

    # High preset: B_fe T_c = 9.4428, R_c/B_fe = 0.1059 < 0.2 < 0.3327: middle regime too.
    bt = 9.66e6 / CHIP_RATE_CA
    spectral = 1.0 / bt + bt / (math.pi - 1.0) * (0.2 - 1.0 / bt) ** 2
    sigma_high = math.sqrt(1.0 / (2.0 * c) * spectral * (1.0 + 2.0 / (T_1MS * c * 1.8)))
    assert CHIP_LENGTH_CA * dll_jitter_chips(45.0, **HIGH) == pytest.approx(0.4514, abs=1e-4)
    assert dll_jitter_chips(45.0, **HIGH) == pytest.approx(sigma_high, rel=1e-12)


def test_dll_outer_regimes_follow_eqs_5_14_and_5_15():
    c = 10**4.0
    # Wide (eq. 5.14): D = 1 with a 20 MHz front end (pi R_c/B_fe = 0.16).
    wide = math.sqrt(3.0 / (2 * c) * 1.0 * (1 + 2 / (0.02 * c * (2 - 1.0))))
    assert dll_jitter_chips(40.0, 3.0, 1.0, 20e6, 0.02) == pytest.approx(wide, rel=1e-12)
    # Narrow (eq. 5.15): D = 0.05 with a 4 MHz front end (R_c/B_fe = 0.256).
    narrow = math.sqrt(3.0 / (2 * c) * (CHIP_RATE_CA / 4e6) * (1 + 1 / (0.02 * c)))
    assert dll_jitter_chips(40.0, 3.0, 0.05, 4e6, 0.02) == pytest.approx(narrow, rel=1e-12)
    # No further gain below R_c/B_fe.
    assert dll_jitter_chips(40.0, 3.0, 0.01, 4e6, 0.02) == dll_jitter_chips(40.0, 3.0, 0.2, 4e6, 0.02)


@pytest.mark.parametrize("front_end_bw_hz", [4.092e6, 9.66e6, 24e6])
def test_dll_continuity_at_regime_boundaries(front_end_bw_hz):
    cn0 = CN0_GRID
    eps = 1e-10
    wide_edge = math.pi * CHIP_RATE_CA / front_end_bw_hz
    if wide_edge < 2.0:
        above = dll_jitter_chips(cn0, 1.0, wide_edge * (1 + eps), front_end_bw_hz, T_1MS)
        below = dll_jitter_chips(cn0, 1.0, wide_edge * (1 - eps), front_end_bw_hz, T_1MS)
        assert np.max(np.abs(above / below - 1.0)) < 1e-6

    narrow_edge = CHIP_RATE_CA / front_end_bw_hz
    # The spectral term joins continuously; isolate it with an integration time
    # long enough to remove the squaring loss (1/(T c) < 1e-8).
    above = dll_jitter_chips(cn0, 1.0, narrow_edge * (1 + eps), front_end_bw_hz, 1e6)
    below = dll_jitter_chips(cn0, 1.0, narrow_edge * (1 - eps), front_end_bw_hz, 1e6)
    assert np.max(np.abs(above / below - 1.0)) < 1e-6
    # With T = 1 ms the published squaring loss switches from 2/(2 - D) to 1 there
    # (Kaplan & Hegarty eq. as printed); the jump is exactly that ratio.
    above = dll_jitter_chips(cn0, 1.0, narrow_edge * (1 + eps), front_end_bw_hz, T_1MS)
    below = dll_jitter_chips(cn0, 1.0, narrow_edge * (1 - eps), front_end_bw_hz, T_1MS)
    c = 10 ** (cn0 / 10)
    ratio = np.sqrt((1 + 2 / (T_1MS * c * (2 - narrow_edge))) / (1 + 1 / (T_1MS * c)))
    np.testing.assert_allclose(above / below, ratio, rtol=1e-8)


def test_dll_monotone_and_presets_ordered():
    for preset in (LOW, HIGH):
        sigma = dll_jitter_chips(CN0_GRID, **preset)
        assert sigma.shape == CN0_GRID.shape
        assert np.all(np.diff(sigma) < 0.0)
    assert np.all(dll_jitter_chips(CN0_GRID, **LOW) > dll_jitter_chips(CN0_GRID, **HIGH))
    # Smaller spacing within the same front end helps; larger bandwidth hurts.
    assert dll_jitter_chips(40.0, 2.0, 0.3, 9.66e6, T_1MS) < dll_jitter_chips(40.0, 2.0, 0.6, 9.66e6, T_1MS)
    assert dll_jitter_chips(40.0, 4.0, 0.5, 9.66e6, T_1MS) == pytest.approx(
        math.sqrt(2.0) * dll_jitter_chips(40.0, 2.0, 0.5, 9.66e6, T_1MS), rel=1e-12
    )


def test_dll_broadcasts_and_chip_length():
    cn0 = np.linspace(30.0, 50.0, 12).reshape(3, 4)
    chips = dll_jitter_chips(cn0, **LOW)
    assert chips.shape == (3, 4)
    assert CHIP_LENGTH_CA == pytest.approx(293.052, abs=1e-3)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(LOW, spacing_chips=2.0), "correlator_spacing"),
        (dict(LOW, spacing_chips=0.0), "correlator_spacing"),
        (dict(LOW, spacing_chips=np.array([0.1, 0.2])), "correlator_spacing"),
        (dict(LOW, dll_bw_hz=-1.0), "dll_bw"),
        (dict(LOW, front_end_bw_hz=0.0), "front_end_bw"),
        (dict(LOW, integration_s=float("nan")), "integration"),
    ],
)
def test_dll_rejects_bad_receiver_parameters(kwargs, field):
    with pytest.raises(SimbenchError, match=field):
        dll_jitter_chips(40.0, **kwargs)


# --------------------------------------------------------------------------- PLL


def test_pll_reference_value():
    # 30 dB-Hz, 50 Hz, 1 ms: sqrt(50/1000 (1 + 1/(2 * 0.001 * 1000))) = sqrt(0.075) rad = 15.69 deg.
    rad = pll_jitter_rad(30.0, 50.0, T_1MS)
    assert rad == pytest.approx(math.sqrt(0.075), rel=1e-12)
    assert math.degrees(rad) == pytest.approx(15.69, abs=0.01)
    assert pll_jitter_m(30.0, 50.0, T_1MS) == pytest.approx(LAMBDA_L1 / (2 * math.pi) * math.sqrt(0.075), rel=1e-12)
    assert pll_jitter_m(30.0, 50.0, T_1MS) == pytest.approx(8.29e-3, abs=1e-5)


def test_pll_monotone_and_presets():
    low = pll_jitter_rad(CN0_GRID, 50.0, T_1MS)
    high = pll_jitter_rad(CN0_GRID, 25.0, T_1MS)
    assert np.all(np.diff(low) < 0.0)
    assert np.all(low > high)
    # Strong signal: the squaring term vanishes and sigma^2 -> B / c.
    assert pll_jitter_rad(60.0, 25.0, T_1MS) == pytest.approx(math.sqrt(25.0 / 1e6), rel=1e-3)
    with pytest.raises(SimbenchError, match="pll_bw"):
        pll_jitter_rad(30.0, 0.0, T_1MS)


# --------------------------------------------------------------------------- antenna, C/N0


def test_antenna_gain_table_points_and_back_lobe():
    elevation_deg = np.array([0.0, 15.0, 30.0, 65.0, 90.0])
    gain = antenna_gain_dbi(np.radians(90.0 - elevation_deg))
    np.testing.assert_allclose(gain, [-6.0, -1.0, 3.0, 9.0, 12.0], atol=1e-9)
    assert antenna_gain_dbi(math.pi) == pytest.approx(-25.0, abs=1e-9)
    assert antenna_gain_dbi(np.radians(135.0)) == pytest.approx(-15.5, abs=1e-9)
    # Piecewise linear between nodes.
    assert antenna_gain_dbi(np.radians(42.5)) == pytest.approx(6.0, abs=1e-9)


def test_antenna_gain_monotone_from_boresight():
    theta = np.linspace(0.0, math.pi, 1801)
    gain = antenna_gain_dbi(theta)
    assert np.all(np.diff(gain) < 0.0)
    assert gain.shape == theta.shape


def test_cn0_link_budget():
    theta = np.radians([[0.0, 90.0, 180.0]])
    cn0 = cn0_mean_dbhz(theta)
    np.testing.assert_allclose(cn0, [[54.5, 36.5, 17.5]], atol=1e-9)
    # Per-epoch power offsets broadcast against per-satellite angles.
    cn0_b = cn0_mean_dbhz(theta, received_power_dbw=np.array([[-158.5], [-160.5]]), constant_db=200.0)
    assert cn0_b.shape == (2, 3)
    np.testing.assert_allclose(cn0_b[1] - cn0_b[0], -2.0, atol=1e-12)
    np.testing.assert_allclose(cn0_b[0], cn0[0] - 1.0, atol=1e-12)


# --------------------------------------------------------------------------- sample grid


@pytest.mark.parametrize(
    ("sampling_hz", "integration_s", "step"),
    [
        (4.092e6, T_1MS, 1 / 4),
        (16.368e6, T_1MS, 1 / 16),
        (40.92e6, 0.01, 1 / 40),
        (6.138e6, T_1MS, 1 / 6),
        (1.5 * CHIP_RATE_CA, T_1MS, 1 / 3),  # 3 samples per 2 chips
        (5e6, T_1MS, 1 / 5000),  # 5000 / 1023: the pattern spans the whole integration
    ],
)
def test_code_phase_step_of_the_sampling_rate(sampling_hz, integration_s, step):
    assert code_phase_step_chips(sampling_hz, integration_s) == pytest.approx(step)


def _grid(x, rate, cn0, preset=LOW, fs=4.092e6):
    return sample_grid_code_error_chips(x, rate, cn0, sampling_hz=fs, **preset)


def test_sample_grid_error_without_noise_or_motion_is_the_rounding_error():
    """At a C/N0 where thermal noise cannot dither the grid, a still code phase is rounded to
    the nearest quarter chip: a sawtooth of amplitude q/2 and rms q/sqrt(12) (q = 73.3 m)."""
    x = np.linspace(0.0, 1.0, 4001)
    e = _grid(x, 0.0, 90.0)
    q = 0.25
    away_from_jumps = np.abs((x / q) % 1.0 - 0.5) > 0.05  # the truncated series rings at the jumps
    np.testing.assert_allclose(e[away_from_jumps], (q * (np.round(x / q) - x / q))[away_from_jumps], atol=5e-4)
    assert e.std() == pytest.approx(q / math.sqrt(12.0), rel=0.01)


def test_sample_grid_error_is_dithered_by_thermal_noise():
    """At 42 dB-Hz the low preset's grid is dithered to its first harmonic: amplitude
    (q / pi) exp(-2 pi^2 sigma_T^2 / q^2) with sigma_T = sigma_DLL / sqrt(2 B T)."""
    x = np.linspace(0.0, 1.0, 4000, endpoint=False)
    q, cn0 = 0.25, 42.0
    sigma_t = dll_jitter_chips(cn0, **LOW) / math.sqrt(2.0 * LOW["dll_bw_hz"] * T_1MS)
    amplitude = q / math.pi * math.exp(-2.0 * math.pi**2 * (sigma_t / q) ** 2)
    e = _grid(x, 0.0, cn0)
    assert 0.01 < amplitude < 0.05  # a few metres: the regime the test is about
    assert np.abs(e).max() == pytest.approx(amplitude, rel=0.02)
    assert _grid(x, 0.0, 30.0).std() < 1e-6  # a weak signal averages the grid away


def test_sample_grid_error_averaged_by_code_doppler_through_the_dll():
    """A code phase sliding at r chip/s is the first harmonic at f = r / q through the
    first-order DLL, |H| = 1 / |1 + j pi f / (2 B)|, and the integration's sinc(f T)."""
    x = np.linspace(0.0, 1.0, 4000, endpoint=False)
    still = np.abs(_grid(x, 0.0, 42.0)).max()
    for rate in (0.1, 1.0, 3.0):
        f = rate / 0.25
        gain = abs(np.sinc(f * T_1MS) / (1 + 1j * math.pi * f / (2 * LOW["dll_bw_hz"])))
        assert np.abs(_grid(x, rate, 42.0)).max() == pytest.approx(still * gain, rel=0.02), rate


def test_sample_grid_error_of_the_presets_at_high_cn0():
    """The dissertation's low preset (4.092 MHz, 4 samples per chip) keeps metres of grid error
    on a strong, slowly sliding signal; high (16.368 MHz) a few centimetres; an incommensurate
    rate nothing."""
    x = np.linspace(0.0, 1.0, 4000, endpoint=False)
    low = CHIP_LENGTH_CA * _grid(x, 0.05, 47.0).std()
    high = CHIP_LENGTH_CA * _grid(x, 0.05, 47.0, HIGH, 16.368e6).std()
    odd = CHIP_LENGTH_CA * _grid(x, 0.05, 47.0, LOW, 4.1e6).std()
    assert low > 5.0 and high < 0.2 and odd < 0.01, (low, high, odd)
