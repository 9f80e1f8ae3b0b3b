"""The measured slant ionosphere (``ionosphere=measured``, and ``auto`` when only some satellites have a
second frequency): code-pair delays, phase levelling, the broadcast model fitted per system, and the
Nagoya log with the second frequency removed from a third of its GPS satellites (a u-blox F9P sees no
L2 on the GPS IIR satellites)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from test_ionosphere_free import KW, RATIOS, with_second_frequency

import estimators
import simbench
from estimators.model.measurement import prepare_ppp
from estimators.model.ppp_config import IonosphereMode
from simbench.analysis.metrics import enu_errors
from simbench.contract import ReceiverData
from simbench.core.constants import IONO_L2_SCALE
from simbench.gnss.measured_ionosphere import (
    geometry_free_delay,
    levelled_phase_delay,
    measured_ionosphere,
    running_median_per_satellite,
)


def test_the_code_pair_measures_the_delay_less_the_satellite_group_delay() -> None:
    iono = np.array([2.0, 5.5, 11.0])
    gamma = np.array([IONO_L2_SCALE, (154 / 115) ** 2, (1561.098 / 1207.14) ** 2])
    dcb = np.array([3.1, -1.2, 0.0])
    rng = 2.2e7 + np.arange(3.0)
    np.testing.assert_allclose(geometry_free_delay(rng + iono, rng + gamma * iono + dcb, gamma, dcb), iono, atol=1e-9)


def _one_pass(n: int = 600, slip_at: int = 300, noise_m: float = 1.0) -> dict[str, np.ndarray]:
    """One satellite at 1 Hz: a delay drifting by metres, code pairs with 1 m noise, a phase pair
    offset by a constant that a slip changes at ``slip_at``."""
    t = np.arange(float(n))
    truth = 3.0 + 2.0 * np.sin(t / 600.0)
    code = truth + np.random.default_rng(5).normal(0.0, noise_m, n)
    phase = truth + 5.0 + np.where(t >= slip_at, 0.38, 0.0)  # one L2 cycle at L1/L2: 0.244 / 0.647 m
    return {"t": t, "truth": truth, "code": code, "phase": phase, "sat": np.full(n, "G07")}


def test_levelling_follows_the_phase_and_starts_a_stretch_at_a_slip() -> None:
    p = _one_pass()
    levelled, stretch = levelled_phase_delay(p["code"], p["phase"], p["sat"], p["t"], np.zeros(600, bool))
    # each stretch is levelled by the median of 300 code pairs: about 1.25 / sqrt(300) = 0.07 m
    assert np.abs(levelled - p["truth"]).max() < 0.25
    # and it follows the delay's changes to the phase's precision (here exactly)
    np.testing.assert_allclose(np.diff(levelled[:300]), np.diff(p["truth"][:300]), atol=1e-9)
    assert len(set(stretch[:300])) == 1 and len(set(stretch[300:])) == 1 and stretch[0] != stretch[-1]
    # the running median without the phase is far noisier, but unbiased
    median = running_median_per_satellite(p["code"], p["sat"], p["t"])
    assert 0.05 < np.std(median - p["truth"]) < 0.3 and abs(np.mean(median - p["truth"])) < 0.1
    # a stretch shorter than MIN_LEVEL_ROWS is not levelled
    short, ids = levelled_phase_delay(p["code"], p["phase"], p["sat"], p["t"], p["t"] == 590.0)
    assert np.isnan(short[590:]).all() and (ids[590:] == -1).all() and np.isfinite(short[:590]).all()


def test_the_broadcast_model_is_fitted_to_each_systems_measured_rows() -> None:
    """GPS: three satellites measured, a fourth without a second frequency gets ``a K + b`` of the
    other three (a receiver group delay of 0.8 m in every measured GPS delay). Galileo: one measured
    satellite cannot separate the scale from the offset, so the system keeps the broadcast delay."""
    t = np.tile(np.arange(200.0), 6)
    sat = np.repeat(["G01", "G02", "G03", "G04", "E05", "E06"], 200)
    k = 1.0 + 0.0005 * t + np.repeat(np.arange(6.0), 200)  # broadcast delays of 1-6 m, 3 cm a minute
    truth = 1.4 * k
    measured = np.where(np.isin(sat, ["G01", "G02", "G03", "E05"]), truth + np.where(sat == "E05", 0.3, 0.8), np.nan)
    found = measured_ionosphere(k, measured, sat, t)
    assert set(found.fits) == {"G"}
    a, b = found.fits["G"]
    assert a == pytest.approx(1.4, abs=0.01) and b == pytest.approx(0.8, abs=0.02)
    gps = sat == "G04"
    np.testing.assert_allclose(found.delay_m[gps], truth[gps] + 0.8, atol=0.05)
    np.testing.assert_array_equal(found.delay_m[np.char.startswith(sat, "E")], k[np.char.startswith(sat, "E")])
    assert found.measured.sum() == 600


def test_auto_measures_when_only_some_satellites_have_a_second_frequency() -> None:
    data, _ = with_second_frequency(RATIOS["L1/L2"], n_epochs=120)
    o = data.observations
    lacking = o["sat"] == o["sat"].iloc[0]
    some = ReceiverData(o.assign(code_l2=o["code_l2"].where(~lacking)), data.imu, data.nav)
    obs = prepare_ppp(some, **KW)
    assert obs.ionosphere == IonosphereMode.measured and not obs.ionosphere_free and not obs.broadcast_ionosphere
    above = o["el"] > KW["elevation_mask_deg"]
    assert obs.n_ionosphere_measured == int((above & ~lacking).sum())
    assert obs.model_info()["ionosphere"] == "measured" and "G" in obs.model_info()["ionosphere_fits"]
    # the carrier phase is kept where the delay is levelled only
    assert not obs.has_phase[obs.sat == o["sat"].iloc[0]].any() and obs.has_phase[obs.sat != o["sat"].iloc[0]].all()
    # a table with the second code but no second phase: measured by the running median, code only
    bare = prepare_ppp(ReceiverData(some.observations.drop(columns=["phase_l2", "lli_l2"]), data.imu, data.nav), **KW)
    assert bare.ionosphere == IonosphereMode.measured and bare.n_ionosphere_measured == obs.n_ionosphere_measured
    assert not bare.has_phase.any()
    assert prepare_ppp(data, **KW).ionosphere == IonosphereMode.free
    assert prepare_ppp(data, ionosphere=IonosphereMode.measured, **KW).n_ionosphere_measured == int(above.sum())


@pytest.fixture(scope="module")
def nagoya_some_l2(shared_data: Path) -> simbench.Scenario:
    """The Nagoya log with the second frequency of every third GPS satellite removed (4 of 12)."""
    sc = simbench.scenario("nagoya_static")
    o = sc.observations
    gps = sorted(o.loc[o["sat"].str[0] == "G", "sat"].unique())
    lacking = o["sat"].isin(gps[::3])
    return dataclasses.replace(
        sc, observations=o.assign(code_l2=o["code_l2"].where(~lacking)).assign(phase_l2=o["phase_l2"].where(~lacking))
    )


@pytest.mark.xdist_group("nagoya")
@pytest.mark.parametrize("name", ["l2", "dcs", "ekf_ppp", "wls_spp"])
def test_nagoya_with_l2_on_some_gps_satellites_stays_within_a_metre(
    name: str, nagoya_some_l2: simbench.Scenario
) -> None:
    """Measured on this log (horizontal median, m): L2 0.23, DCS 0.13, EKF 0.12; with the broadcast
    delay, which ``auto`` fell back to before, 2.9 m (every estimator: a bias of the L1 Klobuchar)."""
    cls = estimators.get(name)
    sol = cls(cls.Config()).estimate(nagoya_some_l2.receiver_view())
    assert sol.diagnostics["ionosphere"] == "measured"
    assert float(np.median(enu_errors(sol.epochs, nagoya_some_l2.truth)["horizontal"])) < 1.0


def test_code_pairs_noisier_than_the_broadcast_model_leave_the_broadcast_delay() -> None:
    """Three satellites, 10 minutes, delays of 4-6 m: code pairs scattered by 0.5 m measure them
    (the running median over 120 s keeps 0.5 sqrt(30 / 120) = 0.25 m, under half the delay); by 12 m
    (a weak second signal in a street) they do not, and the system keeps the broadcast delay."""
    t = np.tile(np.arange(600.0), 3)
    sat = np.repeat(["G01", "G02", "G03"], 600)
    k = np.repeat([4.0, 5.0, 6.0], 600)
    noise = np.random.default_rng(2).normal(0.0, 1.0, t.size)
    clean = measured_ionosphere(k, 1.2 * k + 0.5 * noise, sat, t)
    assert set(clean.fits) == {"G"} and clean.measured.all()
    noisy = measured_ionosphere(k, 1.2 * k + 12.0 * noise, sat, t)
    assert noisy.fits == {} and not noisy.measured.any()
    np.testing.assert_array_equal(noisy.delay_m, k)


@pytest.mark.parametrize(
    ("world", "seed", "overrides", "expected"),
    [
        # code pairs scattered by 7.6 m about their running median: Klobuchar stays (L2 1.97 m; with
        # the measured delays 4.23 m)
        (
            "urban_deep",
            1002,
            # the consumer chip's loops on both frequencies (an F9P-like receiver: the preset is L1-only)
            {"receiver": "consumer", "receiver.tracks_l2": True, "scenario.trajectory.urban_drive.start_static_s": 1e5},
            IonosphereMode.broadcast,
        ),
        # 3.8 m, but levelled over long unbroken stretches (20 min: L2 0.69 m; Klobuchar 1.54 m)
        ("open_sky", 1001, {"receiver": "low"}, IonosphereMode.measured),
    ],
)
def test_auto_measures_only_where_the_second_frequency_is_clean_enough(
    world: str, seed: int, overrides: dict, expected: IonosphereMode
) -> None:
    sc = simbench.scenario(
        world, seed=seed, **{"scenario.dual_frequency": True, "scenario.duration_s": 600, **overrides}
    )
    o = sc.observations
    lacking = o["sat"].isin(sorted(o["sat"].unique())[::3])
    thinned = ReceiverData(o.assign(code_l2=o["code_l2"].where(~lacking)), sc.imu, sc.nav)
    assert prepare_ppp(thinned, min_satellites=1, **KW).ionosphere == expected


@pytest.mark.xdist_group("nagoya")
@pytest.mark.parametrize("name", ["isam2_ppp", "isam2_dcs", "isam2_mm", "ice"])
def test_incremental_estimators_run_on_nagoya_with_l2_on_some_satellites(
    name: str, nagoya_some_l2: simbench.Scenario
) -> None:
    """The measured mode cuts arcs per levelled stretch; on a held-out F9P log that made the fixed-lag
    window ask for a dropped arc bias. Measured here (horizontal median, m): iSAM2-PPP 0.12, ICE 1.64."""
    cls = estimators.get(name)
    sol = cls(cls.Config()).estimate(nagoya_some_l2.receiver_view())
    assert sol.diagnostics["ionosphere"] == "measured"
    assert float(np.median(enu_errors(sol.epochs, nagoya_some_l2.truth)["horizontal"])) < 2.0
