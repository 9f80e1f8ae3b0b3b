"""The generator against its own formulas: noise statistics, correlation, determinism, isolation."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import simbench
from simbench.contract import IMU_COLUMNS, LABEL_COLUMNS, OBSERVATION_COLUMNS, TRUTH_COLUMNS, ReceiverData, Scenario
from simbench.core.constants import CHIP_LENGTH_CA, LAMBDA_L1
from simbench.errors import SimbenchError
from simbench.sim import tracking
from simbench.sim.canyon import canyon_rays
from simbench.sim.config import CycleSlipConfig, NlosConfig
from simbench.sim.processes import Columns, gauss_markov, stream
from simbench.sim.slips import phase_arcs

SHORT = {"scenario.duration_s": 300}


@pytest.fixture(scope="module")
def urban() -> Scenario:
    return simbench.simulate("urban", "low", seed=3, **SHORT)


def test_tables_have_documented_columns(urban: Scenario) -> None:
    assert list(urban.observations.columns) == list(OBSERVATION_COLUMNS)
    assert list(urban.labels.columns) == list(LABEL_COLUMNS)
    assert list(urban.truth.columns) == list(TRUTH_COLUMNS)
    assert list(urban.imu.columns) == list(IMU_COLUMNS)
    assert len(urban.labels) == len(urban.observations)
    assert (urban.labels["sat"].to_numpy() == urban.observations["sat"].to_numpy()).all()
    assert len(urban.truth) == 300
    assert len(urban.imu) == 300 * 100


def test_receiver_view_carries_no_truth(urban: Scenario) -> None:
    view = urban.receiver_view()
    assert set(view.observations.columns) == set(OBSERVATION_COLUMNS)
    assert set(view.imu.columns) == set(IMU_COLUMNS)
    assert not hasattr(view, "truth") and not hasattr(view, "labels")
    leaked = urban.observations.assign(nlos=False)
    with pytest.raises(ValueError, match="nlos"):
        ReceiverData(leaked, urban.imu, urban.nav)


def test_same_seed_same_tables_other_seed_differs() -> None:
    a = simbench.simulate("urban", "low", seed=11, **{"scenario.duration_s": 60})
    b = simbench.simulate("urban", "low", seed=11, **{"scenario.duration_s": 60})
    c = simbench.simulate("urban", "low", seed=12, **{"scenario.duration_s": 60})
    for name in ("observations", "imu", "truth", "labels"):
        pd.testing.assert_frame_equal(getattr(a, name), getattr(b, name))
    assert not np.allclose(a.truth[["x", "y", "z"]].to_numpy(), c.truth[["x", "y", "z"]].to_numpy())
    assert not a.observations["code_l1"].equals(c.observations["code_l1"])


@pytest.fixture(scope="module")
def long_open_sky() -> Scenario:
    return simbench.simulate("open_sky", "low", seed=4, **{"scenario.duration_s": 1800})


def test_code_and_phase_noise_follow_dll_pll_formulas(long_open_sky: Scenario) -> None:
    """Normalised thermal-noise samples have unit std, and the sigmas are the eq. 5.13-5.15 values."""
    sc = long_open_sky
    lab, obs = sc.labels, sc.observations
    rx = sc.meta["config"]["receiver"]
    expected = CHIP_LENGTH_CA * tracking.dll_jitter_chips(
        obs["cn0_l1"].to_numpy(),
        rx["dll_bw_hz"],
        rx["correlator_spacing_chips"],
        rx["front_end_bw_mhz"] * 1e6,
        rx["integration_s"],
    )
    np.testing.assert_allclose(lab["sigma_code_l1"], expected, rtol=1e-9)
    z_code = lab["noise_code_l1"] / lab["sigma_code_l1"]
    z_phase = lab["noise_phase_l1"] / lab["sigma_phase_l1"]
    assert len(z_code) > 6000  # std of the std estimate < 1 %, so 5 % is > 5 sigma
    assert abs(z_code.std() - 1.0) < 0.05
    assert abs(z_phase.std() - 1.0) < 0.05
    # pooled std of the code noise vs the rms formula value within 5 %
    assert abs(lab["noise_code_l1"].std() / np.sqrt(np.mean(expected**2)) - 1.0) < 0.05


def test_phase_only_under_carrier_lock(urban: Scenario) -> None:
    """A row has a phase only where the PLL's thermal jitter at its C/N0 keeps Kaplan's rule (15 deg,
    1 sigma; the dynamic stress only adds), keeps its code and Doppler without one, and the first phase
    after a gap starts a new arc with the loss-of-lock flag."""
    obs = urban.observations
    rx = urban.meta["config"]["receiver"]
    jitter_deg = np.degrees(tracking.pll_jitter_rad(obs["cn0_l1"].to_numpy(), rx["pll_bw_hz"], rx["integration_s"]))
    has_phase = np.isfinite(obs["phase_l1"].to_numpy())
    assert (jitter_deg[has_phase] <= rx["carrier_lock_threshold_deg"]).all()
    assert not has_phase[jitter_deg > rx["carrier_lock_threshold_deg"]].any()
    lost = ~has_phase
    assert 0.01 < lost.mean() < 0.5, "a drive in town loses the carrier on some weak rows, not on most"
    assert np.isfinite(obs.loc[lost, ["code_l1", "doppler_l1"]].to_numpy()).all()
    previous = obs.assign(p=has_phase).groupby("sat")["p"].shift(fill_value=False).to_numpy()
    relock = has_phase & ~previous & (obs.groupby("sat").cumcount().to_numpy() > 0)
    assert relock.any()
    assert obs["lli_l1"].to_numpy()[relock].all()


def test_observables_close_to_their_model(urban: Scenario) -> None:
    """code - phase = 2 I + multipath difference - lambda N + noise: checks the sign conventions."""
    obs, lab = urban.observations, urban.labels
    has_phase = obs["phase_l1"].notna()
    obs, lab = obs[has_phase], lab[has_phase]
    cmp = (obs["code_l1"] - obs["phase_l1"]).to_numpy()
    model = (
        2 * lab["iono_l1"]
        + lab["multipath_code_l1"]
        - lab["multipath_phase_l1"]
        - LAMBDA_L1 * lab["ambiguity_l1"]
        + lab["noise_code_l1"]
        + lab["sample_grid_code_l1"]
        - lab["noise_phase_l1"]
    ).to_numpy()
    np.testing.assert_allclose(cmp, model, atol=1e-5)


def test_low_receiver_noisier_than_high() -> None:
    low = simbench.simulate("open_sky", "low", seed=5, **{"scenario.duration_s": 120})
    high = simbench.simulate("open_sky", "high", seed=5, **{"scenario.duration_s": 120})
    assert low.labels["sigma_code_l1"].median() > 1.5 * high.labels["sigma_code_l1"].median()
    assert low.labels["noise_code_l1"].std() > 1.5 * high.labels["noise_code_l1"].std()
    assert low.labels["sigma_phase_l1"].median() > high.labels["sigma_phase_l1"].median()


def test_gauss_markov_autocorrelation_at_tau_is_one_over_e() -> None:
    dt, tau = 1.0, 15.0
    x = gauss_markov(20_000, 40, 0.4, tau, dt, stream(0, "test"))
    lag = int(tau / dt)
    rho = np.mean(x[lag:] * x[:-lag]) / np.mean(x * x)
    assert abs(rho - np.exp(-1.0)) < 0.02
    assert abs(x.std() - 0.4) < 0.01


def test_gauss_markov_channels_are_those_of_the_whole_set() -> None:
    """Filtering only some channels gives those channels bit for bit and leaves the stream where
    the whole set leaves it (the draws are taken for every channel)."""
    full_rng, part_rng = stream(4, "test"), stream(4, "test")
    sigma = np.linspace(0.1, 1.0, 9)
    full = gauss_markov(500, 9, sigma, 20.0, 0.5, full_rng)
    part = gauss_markov(500, 9, sigma, 20.0, 0.5, part_rng, np.array([1, 4, 8]))
    assert part.tobytes() == full[:, [1, 4, 8]].tobytes()
    assert part_rng.standard_normal() == full_rng.standard_normal()


def test_kept_satellites_get_the_numbers_of_the_whole_constellation() -> None:
    """Canyon rays and phase arcs computed on some columns of a grid (draws spanning all of them)
    equal those columns of the whole grid's, bit for bit."""
    n, m, keep = 200, 9, np.array([0, 3, 4, 7])
    rng = np.random.default_rng(5)
    el, az = rng.uniform(0.1, 1.5, (n, m)), rng.uniform(0.0, 2.0 * np.pi, (n, m))
    street = (rng.uniform(0.0, 6.3, n), *rng.uniform(8.0, 25.0, (2, n)), *rng.uniform(0.0, 50.0, (2, n)))
    travelled, cfg = np.cumsum(rng.uniform(0.0, 10.0, n)), NlosConfig(reflector_beyond_m=(0.0, 40.0))
    every = canyon_rays(el, az, *street, travelled, cfg, 1.0, np.random.default_rng(9))
    some = canyon_rays(
        el[:, keep], az[:, keep], *street, travelled, cfg, 1.0, np.random.default_rng(9), columns=Columns(m, keep)
    )
    for field in ("blocked", "amplitude", "delay_m", "phase_rad"):
        assert getattr(some, field).tobytes() == getattr(every, field)[:, keep].tobytes(), field
    tracked = (rng.random((n, m)) < 0.9) & np.isin(np.arange(m), keep)  # the others never tracked, as in the generator
    cn0 = rng.uniform(20.0, 50.0, (n, m))
    slips = CycleSlipConfig(enabled=True, rate_per_s=0.05, cn0_threshold_dbhz=35.0)
    whole = phase_arcs(tracked, cn0, slips, 1.0, np.random.default_rng(3), 2)
    part = phase_arcs(tracked[:, keep], cn0[:, keep], slips, 1.0, np.random.default_rng(3), 2, Columns(m, keep))
    for a, b in zip(whole, part, strict=True):
        assert a.slip[:, keep].any() and (a.slip[:, keep] == b.slip).all() and (a.lli[:, keep] == b.lli).all()
        assert (a.ambiguity[:, keep] == b.ambiguity).all()


def test_no_satellite_above_the_mask_gives_an_empty_scenario() -> None:
    """A mask no satellite clears leaves the grids without a satellite: no rows, no error."""
    sc = simbench.simulate(
        "urban", "low", seed=1, **{"scenario.duration_s": 20, "scenario.constellation.elevation_mask_deg": 89.9}
    )
    assert sc.observations.empty and sc.labels.empty and (sc.truth["n_visible"] == 0).all() and len(sc.imu) > 0


def test_generated_multipath_autocorrelation(long_open_sky: Scenario) -> None:
    lab = long_open_sky.labels.pivot(index="epoch", columns="sat", values="multipath_code_l1")
    mp = lab.to_numpy()
    lag = 15  # tau 15 s at 1 Hz
    a, b = mp[lag:], mp[:-lag]
    ok = np.isfinite(a) & np.isfinite(b)
    rho = np.sum(a[ok] * b[ok]) / np.sqrt(np.sum(a[ok] ** 2) * np.sum(b[ok] ** 2))
    assert abs(rho - np.exp(-1.0)) < 0.08  # ~8 satellites x 120 correlation times


def test_urban_canyon_creates_nlos_and_masking(urban: Scenario) -> None:
    lab, truth = urban.labels, urban.truth
    assert 0.01 < lab["nlos"].mean() < 0.5
    assert (lab.loc[lab["nlos"], "nlos_delay"] > 0).all()
    tracked = urban.observations.groupby("epoch").size().reindex(truth["epoch"], fill_value=0).to_numpy()
    assert (tracked < truth["n_visible"].to_numpy()).mean() > 0.3  # buildings mask satellites


def test_slips_change_ambiguity_and_flags(urban: Scenario) -> None:
    lab, obs = urban.labels, urban.observations
    merged = lab.assign(lli=obs["lli_l1"].to_numpy()).sort_values(["sat", "epoch"])
    amb_change = merged.groupby("sat")["ambiguity_l1"].diff().fillna(0).to_numpy() != 0
    slips = merged["slip"].to_numpy()
    assert slips.sum() > 0
    assert (amb_change[slips]).all()
    assert not amb_change[~slips & ~merged["lli"].to_numpy()].any()  # no unflagged change without a slip


@pytest.mark.parametrize(
    "override, field",
    [
        ({"scenario.duration_s": -5}, "scenario.duration_s"),
        ({"scenario.rate_hz": 0}, "scenario.rate_hz"),
        ({"scenario.trajectory.kind": "boat"}, "scenario.trajectory.kind"),
    ],
)
def test_bad_config_values_give_one_line_errors(override: dict, field: str) -> None:
    with pytest.raises(SimbenchError) as info:
        simbench.simulate("urban", "low", seed=0, **override)
    assert field in str(info.value)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("kwargs, field", [({"scenario": "mars"}, "scenario"), ({"receiver": "cheap"}, "receiver")])
def test_unknown_preset_names(kwargs: dict, field: str) -> None:
    with pytest.raises(SimbenchError, match=f"unknown {field}"):
        simbench.simulate(**kwargs)


def test_missing_files_give_one_line_errors(tmp_path) -> None:
    with pytest.raises(SimbenchError, match="replay.path"):
        simbench.simulate("replay", **{"scenario.trajectory.replay.path": str(tmp_path / "none.xyz")})
    bad = tmp_path / "bad.18n"
    bad.write_text("this is not a navigation file\n")
    with pytest.raises(SimbenchError) as info:
        simbench.simulate("replay", **{"scenario.constellation.nav_path": str(bad), "scenario.duration_s": 30})
    assert "\n" not in str(info.value)


def test_scenario_parquet_round_trip(urban: Scenario, tmp_path) -> None:
    urban.save(tmp_path / "s")
    back = Scenario.load(tmp_path / "s")
    for name in ("observations", "imu", "truth", "labels"):
        pd.testing.assert_frame_equal(getattr(back, name), getattr(urban, name))
    assert back.nav == urban.nav
    assert back.meta["seed"] == 3 and back.meta["config"]["scenario"]["duration_s"] == 300


def test_canyon_rays_where_wanted_are_those_of_the_whole_grid() -> None:
    """Rays computed for a subset of (epoch, satellite) pairs are bit for bit those of the whole grid."""
    n, m = 300, 8
    rng = np.random.default_rng(2)
    el, az = rng.uniform(-0.2, 1.5, (n, m)), rng.uniform(0.0, 2.0 * np.pi, (n, m))
    heading = rng.uniform(0.0, 2.0 * np.pi, n)
    left, right = rng.uniform(8.0, 25.0, (2, n))
    h_left, h_right = rng.uniform(0.0, 50.0, (2, n))
    travelled = np.cumsum(rng.uniform(0.0, 10.0, n))
    cfg = NlosConfig(reflector_beyond_m=(0.0, 40.0))
    wanted = el > 0.3
    args = (el, az, heading, left, right, h_left, h_right, travelled, cfg, 1.0)
    every = canyon_rays(*args, np.random.default_rng(9))
    some = canyon_rays(*args, np.random.default_rng(9), where=wanted)
    for field in ("blocked", "amplitude", "delay_m", "phase_rad"):
        full, part = getattr(every, field), getattr(some, field)
        assert part.shape[0] == wanted.sum(), field
        assert full[wanted].tobytes() == part.tobytes(), field
