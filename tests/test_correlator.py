"""Receiver physics at the correlator: band-limited correlation, the DLL on a sum of rays,
canyon rays (diffraction, Fresnel reflection), channel lock states, and the presets in the generator."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

import simbench
from simbench.core.constants import CHIP_LENGTH_CA, CHIP_RATE_CA, DEG
from simbench.errors import SimbenchError
from simbench.runs.compose import compose_config
from simbench.sim.canyon import canyon_rays, fresnel_circular, knife_edge_loss_db
from simbench.sim.config import FacadeMaterial, NlosConfig, ReceiverConfig
from simbench.sim.processes import stream
from simbench.sim.tracking import (
    band_limited_correlation,
    channel_lock_states,
    dll_tracking_point,
    effective_spacing_chips,
    multipath_error_envelope_chips,
    pll_dynamic_stress_deg,
)
from simbench.typed import to_typed

WIDE_BAND_HZ = 1e9  # ~1000 chip rates: the correlation is the ideal triangle to 1e-3
PHASES = np.linspace(0.0, 2.0 * np.pi, 72, endpoint=False)


def _preset(name: str) -> tuple[float, float]:
    """Realised spacing [chip] and front-end bandwidth [Hz] of a receiver preset in conf/."""
    rx = to_typed(compose_config([f"receiver={name}"])["receiver"], ReceiverConfig)
    return effective_spacing_chips(rx.correlator_spacing_chips, rx.sampling_mhz * 1e6), rx.front_end_bw_mhz * 1e6


def _two_rays(alpha: float, delay_chips: float, phases: np.ndarray, spacing: float, bw: float) -> np.ndarray:
    """Tracking error [chip] for a direct ray plus one reflection at each carrier phase."""
    k = len(phases)
    amp = np.tile([1.0, alpha], (k, 1))
    delay = np.tile([0.0, delay_chips], (k, 1))
    phase = np.stack([np.zeros(k), phases], axis=1)
    return dll_tracking_point(amp, delay, phase, np.zeros(k), spacing, bw)[0]


# --------------------------------------------------------------------------- correlation function


@pytest.mark.parametrize("bw_hz", [4.092e6, 9.66e6])
@pytest.mark.parametrize("tau", [0.0, 0.3, 0.9, 1.2])
def test_band_limited_correlation_is_the_filtered_spectrum(bw_hz: float, tau: float) -> None:
    # R_b(tau) = int_{-b/2}^{b/2} sinc^2(f) cos(2 pi f tau) df, the C/A spectrum through a brick wall
    b = bw_hz / CHIP_RATE_CA
    expected = 2.0 * quad(lambda f: np.sinc(f) ** 2 * np.cos(2 * np.pi * f * tau), 0.0, b / 2, limit=200)[0]
    assert band_limited_correlation(tau, bw_hz)[0] == pytest.approx(expected, abs=1e-6)


def test_band_limited_correlation_limits() -> None:
    r, slope = band_limited_correlation(np.array([-1.5, -0.5, 0.0, 0.25, 0.5, 1.5, 3.0]), WIDE_BAND_HZ)
    np.testing.assert_allclose(r, [0.0, 0.5, 1.0, 0.75, 0.5, 0.0, 0.0], atol=2e-3)
    np.testing.assert_allclose(slope[[1, 3, 4]], [1.0, -1.0, -1.0], atol=1e-3)
    # a 4 MHz front end rounds the peak: 95 % of it remains
    assert band_limited_correlation(0.0, 4.092e6)[0] == pytest.approx(0.9499, abs=1e-4)


def test_sampling_rate_quantises_the_spacing() -> None:
    assert effective_spacing_chips(0.5, 4.092e6) == 0.5  # 4 samples per chip: 2 samples
    assert effective_spacing_chips(0.2, 16.368e6) == pytest.approx(3 / 16)  # 3.2 samples -> 3
    assert effective_spacing_chips(0.05, 4.092e6) == 0.25  # at least one sample
    with pytest.raises(SimbenchError, match="receiver.sampling_mhz"):
        effective_spacing_chips(0.5, 0.0)


# --------------------------------------------------------------------------- DLL on rays


@pytest.mark.parametrize("spacing", [0.5, 0.2, 0.1])
@pytest.mark.parametrize("alpha", [0.3, 0.6, 0.9])
def test_in_phase_reflection_follows_the_closed_form_envelope(spacing: float, alpha: float) -> None:
    """Infinite bandwidth: alpha tau/(1+alpha), plateau alpha D/2, fall to 0 at 1 + D/2."""
    for tau in np.linspace(0.01, 1.6, 40):
        err = _two_rays(alpha, tau, np.array([0.0]), spacing, WIDE_BAND_HZ)[0]
        assert err == pytest.approx(multipath_error_envelope_chips(alpha, tau, spacing), abs=2e-4), tau
    assert multipath_error_envelope_chips(alpha, 0.4, spacing) <= alpha * spacing / 2 + 1e-15
    assert multipath_error_envelope_chips(alpha, 1.0 + spacing / 2, spacing) == 0.0


def test_out_of_phase_reflection_pulls_early() -> None:
    alpha, spacing = 0.5, 0.5
    # -alpha tau / (1 - alpha) below (1 - alpha) D / 2, then the plateau -alpha D / 2
    assert _two_rays(alpha, 0.05, np.array([np.pi]), spacing, WIDE_BAND_HZ)[0] == pytest.approx(-0.05, abs=1e-4)
    assert _two_rays(alpha, 0.5, np.array([np.pi]), spacing, WIDE_BAND_HZ)[0] == pytest.approx(-0.125, abs=1e-4)


def test_lone_reflection_is_tracked_at_its_full_delay() -> None:
    """NLOS-only reception: the DLL locks to the reflection, error = the whole extra path."""
    for name in ("low", "high"):
        spacing, bw = _preset(name)
        tau, prompt, _ = dll_tracking_point(
            np.array([[0.0, 0.4]]), np.array([[0.0, 0.11]]), np.array([[0.0, 2.0]]), np.array([0.11]), spacing, bw
        )
        assert tau[0] == pytest.approx(0.11, abs=1e-6)
        assert prompt[0] == pytest.approx(0.4, rel=1e-6)  # C/N0 drops by 20 log10(0.4) = 8 dB


def test_narrow_correlator_sees_less_short_delay_multipath_and_none_beyond_one_chip() -> None:
    """Presets from conf/: high and geodetic never worse than low below one chip, all unbiased beyond."""
    low, high, geodetic = _preset("low"), _preset("high"), _preset("geodetic")
    alpha = 0.5
    for tau in np.linspace(0.02, 1.0, 50):
        worst = [np.abs(_two_rays(alpha, tau, PHASES, *p)).max() for p in (low, high, geodetic)]
        assert worst[1] <= worst[0] + 2e-3 and worst[2] <= worst[1] + 2e-3, (tau, worst)
        if tau >= 0.15:  # beyond the shortest delays the narrow correlators are clearly better
            assert worst[1] < 0.6 * worst[0] and worst[2] < 0.6 * worst[1], (tau, worst)
    # Beyond 1 + D/2 chips nothing biases a tracked direct signal: the mean over the carrier phase
    # is 0 for every preset; only the ripple skirt of low's 4 MHz front end still wiggles it (< 0.5 m).
    for tau in (1.3, 1.45, 1.7, 2.2):
        errors = [_two_rays(alpha, tau, PHASES, *p) * CHIP_LENGTH_CA for p in (low, high, geodetic)]
        assert all(abs(e.mean()) < 0.02 for e in errors), tau
        assert np.abs(errors[0]).max() < 0.5 and np.abs(errors[1]).max() < 0.05 and np.abs(errors[2]).max() < 0.01


def test_carrier_multipath_is_the_phase_of_the_composite() -> None:
    # one reflection at delay well inside the correlator: psi = atan(a sin t / (1 + a cos t))
    alpha, theta = 0.5, np.array([0.5, 1.5, 2.5])
    amp = np.tile([1.0, alpha], (3, 1))
    _, prompt, phase = dll_tracking_point(
        amp, np.tile([0.0, 0.001], (3, 1)), np.stack([0 * theta, theta], 1), np.zeros(3), 0.5, WIDE_BAND_HZ
    )
    np.testing.assert_allclose(phase, np.arctan2(alpha * np.sin(theta), 1 + alpha * np.cos(theta)), atol=2e-3)
    np.testing.assert_allclose(prompt, np.abs(1 + alpha * np.exp(1j * theta)), atol=2e-3)


# --------------------------------------------------------------------------- canyon rays


def test_knife_edge_and_fresnel_reference_values() -> None:
    loss = knife_edge_loss_db(np.array([-1.0, 0.0, 1.0, 3.0]))
    np.testing.assert_allclose(loss, [0.0, 6.03, 13.93, 22.42], atol=0.05)
    co, cross = fresnel_circular(np.array([1.0, 0.0]), FacadeMaterial.concrete)
    # normal incidence: all LHCP, |Gamma| = |(sqrt(eps) - 1) / (sqrt(eps) + 1)| ~ 0.39; grazing: all RHCP, -1
    assert abs(co[0]) < 1e-12 and abs(cross[0]) == pytest.approx(0.394, abs=0.005)
    assert co[1] == pytest.approx(-1.0) and abs(cross[1]) < 1e-12
    co, cross = fresnel_circular(np.array([1.0]), FacadeMaterial.metal)
    assert abs(cross[0]) == pytest.approx(1.0, abs=1e-3)


def test_canyon_rays_geometry() -> None:
    """Across a street: a 10 m building 10 m east (near side), a 60 m one 20 m west (far side)."""
    el = np.radians(np.array([[10.0, 40.0, 60.0, 80.0]]))
    az = np.full((1, 4), 90 * DEG)  # east, across a north-south street
    one = np.ones(1)
    cfg = NlosConfig(reflection_probability=1.0 - 1e-12, facade_relief_sigma_m=1e-9)
    rays = canyon_rays(el, az, 0 * one, 20 * one, 10 * one, 60 * one, 10 * one, np.zeros(1), cfg, 1.0, stream(0, "t"))
    k = np.tan(el[0])  # |sin(az - heading)| = 1
    np.testing.assert_array_equal(rays.blocked[0], [True, True, False, False])  # masked below 45 deg
    # one bounce: masked satellites (original rule), and at 60 deg the bounce point 35 m is below the 60 m roof
    np.testing.assert_array_equal(rays.amplitude[0, :, 1] > 0, [True, True, True, False])
    # two bounces: only behind the near building, bounces below both roofs, clearing the near one
    np.testing.assert_array_equal(rays.amplitude[0, :, 2] > 0, (k * 10 < 10) & (k * 40 < 60) & (k * 70 > 10))
    np.testing.assert_allclose(rays.delay_m[0, :, 1], 2 * 20 * np.cos(el[0]), atol=1e-6)
    np.testing.assert_allclose(rays.delay_m[0, :, 2], 2 * 30 * np.cos(el[0]), atol=1e-6)
    # knife edge: 10 deg is deep behind the roof (v ~ 8), 40 deg just behind it (v ~ 1.1, J ~ 14.6 dB)
    assert rays.amplitude[0, 0, 0] < 0.05
    assert 20 * np.log10(rays.amplitude[0, 1, 0]) == pytest.approx(-14.6, abs=0.5)
    np.testing.assert_array_equal(rays.amplitude[0, 2:, 0], 1.0)  # clear line of sight
    assert (rays.amplitude[0, :, 1:] < 1.0).all()  # reflections lose power
    # the loops lock to the bounce in deep shadow, to the diffracted ray just behind the roof
    np.testing.assert_array_equal(rays.reference[0], [1, 0, 0, 0])


# --------------------------------------------------------------------------- tracking states


def test_channel_lock_states_hysteresis_and_reacquisition() -> None:
    cn0 = np.array([40, 40, 30, 30, 20, 40, 40, 40, 30, 20, 30, 40], float)[:, None]
    tracked = channel_lock_states(cn0 >= 33, cn0 >= 25, acquisition_epochs=2)[:, 0]
    # kept between the thresholds, dropped below 25, re-acquired after 2 epochs above 33
    np.testing.assert_array_equal(tracked, [1, 1, 1, 1, 0, 0, 1, 1, 1, 0, 0, 0])


def test_pll_dynamic_stress_kaplan() -> None:
    # theta_e = 0.4828 jerk / B^3 with jerk in deg/s^3: 1 g/s at 18 Hz -> 0.4828 * 9.807 * 1891.8 / 5832 = 1.536 deg
    assert pll_dynamic_stress_deg(9.80665, 18.0)[()] == pytest.approx(1.536, abs=0.002)
    assert pll_dynamic_stress_deg(-5.0, 15.0) > pll_dynamic_stress_deg(5.0, 25.0)


# --------------------------------------------------------------------------- in the generator


@pytest.fixture(scope="module")
def canyon_by_preset() -> dict[str, simbench.Scenario]:
    """One urban scenario received by each preset: diffuse multipath and thermal noise off."""
    quiet = {
        "scenario.duration_s": 300,
        "scenario.errors.multipath.enabled": False,
        "scenario.errors.tracking_noise": False,
    }
    return {rx: simbench.simulate("urban", rx, seed=1, **quiet) for rx in ("low", "high")}


def test_urban_canyon_multipath_smaller_for_the_narrow_correlator(canyon_by_preset) -> None:
    """Same environment, only the receiver differs: LOS rows tracked by both, canyon delays < 1 chip."""
    low, high = (canyon_by_preset[rx].labels.set_index(["epoch", "sat"]) for rx in ("low", "high"))
    both = low.index.intersection(high.index)
    los = ~low.loc[both, "nlos"].to_numpy() & ~high.loc[both, "nlos"].to_numpy()
    mp_low = np.abs(low.loc[both, "multipath_code_l1"].to_numpy()[los])
    mp_high = np.abs(high.loc[both, "multipath_code_l1"].to_numpy()[los])
    reflected = mp_low > 1e-6
    assert reflected.sum() > 200
    # Canyon reflections arrive 3-40 m late, mostly inside both correlators' D/2, where the error
    # alpha tau / (1 + alpha) is the same for any spacing: the narrow correlator wins on the rest.
    assert mp_high[reflected].mean() < 0.92 * mp_low[reflected].mean()
    assert np.percentile(mp_high[reflected], 95) < 0.92 * np.percentile(mp_low[reflected], 95)


def test_nlos_takes_the_extra_path_and_loses_power(canyon_by_preset) -> None:
    sc = canyon_by_preset["low"]
    lab, obs = sc.labels, sc.observations
    nlos = lab["nlos"].to_numpy()
    assert 0.01 < nlos.mean() < 0.5
    # the observed code carries the tracked ray's extra path plus the DLL's mixture error
    # (+ atmosphere and orbit/clock, which are the same with and without it)
    reflected = nlos & (lab["nlos_delay"].to_numpy() > 1.0)
    assert reflected.sum() > 20
    assert np.median(obs["cn0_l1"][~nlos]) - np.median(obs["cn0_l1"][reflected]) > 5.0
