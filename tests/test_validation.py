"""Sim-vs-real statistics (simbench.analysis.validation, python -m simbench validate, the report section)."""

from __future__ import annotations

import copy
from functools import reduce
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from simbench.analysis.claims import claims_table
from simbench.analysis.validation import (
    MIN_ROWS_PER_CLOCK,
    ValidationSample,
    comparison_table,
    ks_distances,
    residual_by_elevation,
    residual_sample,
    world_statistics,
)
from simbench.cli.validate import parse_args, run
from simbench.contract import Scenario
from simbench.data.rinex import load_rinex
from simbench.report.build import build_report
from simbench.runs.compose import compose_config
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS
from simbench.runs.scenarios import sim_config
from simbench.sim.config import SimConfig
from simbench.sim.generator import generate
from tests.conftest import one_line_error

#: Thermal noise only: no multipath, NLOS, product errors, and an atmosphere exactly as modelled.
THERMAL_ONLY = {
    "duration_s": 300.0,
    "errors.multipath.enabled": False,
    "errors.nlos.enabled": False,
    "errors.orbit_clock.enabled": False,
    "errors.ionosphere.scale_sigma": 0.0,
    "errors.ionosphere.residual_sigma_m": 0.0,
    "errors.troposphere.wet_scale_sigma": 0.0,
    "errors.troposphere.wet_rw_mps": 0.0,
    "errors.sample_grid": False,
}

#: The issue 14 table's Hong Kong row (GPS): the procedure must reproduce it.
HK_TABLE = {
    "sats_median": 6,
    "residual_p50_m": 3.6,
    "residual_p90_m": 38.5,
    "residual_p99_m": 85.0,
    "share_over_10m": 0.33,
    "share_over_30m": 0.155,
    "cn0_p10": 20.0,
    "cn0_p50": 33.0,
    "cn0_p90": 42.0,
}


@pytest.fixture(scope="module")
def hk(shared_data: Path) -> Scenario:
    d = shared_data / "hk_tst_2019"
    return load_rinex(d / "COM3_190428_124409.obs", d / "hksc1180.19n", d / "groundTruth_TST.csv", name="hk_tst_2019")


@pytest.fixture(scope="module")
def urban_config() -> SimConfig:
    return sim_config(compose_config(["scenario=urban", "receiver=low", "seed=0"]))


def _urban(config: SimConfig, changes: dict[str, object]) -> Scenario:
    """The urban scenario with ``scenario.<dotted key>`` changed (composing once is what costs)."""
    config = copy.deepcopy(config)
    for key, value in changes.items():
        *parents, name = key.split(".")
        setattr(reduce(getattr, parents, config.scenario), name, value)
    return generate(config)


@pytest.fixture(scope="module")
def thermal(urban_config: SimConfig) -> Scenario:
    return _urban(urban_config, THERMAL_ONLY)


@pytest.fixture(scope="module")
def urban(urban_config: SimConfig) -> Scenario:
    return _urban(urban_config, {"duration_s": 180.0})


def _with_labels(sample: ValidationSample, scenario: Scenario) -> pd.DataFrame:
    labels = scenario.labels[["epoch", "sat", "noise_code_l1", "sample_grid_code_l1", "sigma_code_l1", "nlos"]]
    return sample.rows.merge(labels, on=["epoch", "sat"], how="left", validate="one_to_one")


def _minus_epoch_median(values: np.ndarray, epoch: np.ndarray) -> np.ndarray:
    return values - pd.Series(values).groupby(epoch).transform("median").to_numpy()


def test_residual_is_the_thermal_noise_when_every_other_error_is_modelled(thermal: Scenario) -> None:
    """Sagnac range, satellite clock, Saastamoinen/Niell and Klobuchar removed exactly: what is left is
    the code noise minus its per-epoch median, to a millimetre."""
    rows = _with_labels(residual_sample(thermal), thermal)
    ok = np.isfinite(rows["residual"])
    assert ok.mean() > 0.95
    expected = _minus_epoch_median(rows["noise_code_l1"].to_numpy(), rows["epoch"].to_numpy())
    assert np.max(np.abs(rows["residual"].to_numpy()[ok] - expected[ok])) < 1e-3


def test_residual_statistics_match_the_configured_code_noise(thermal: Scenario) -> None:
    """|residual| percentiles as those of fresh noise draws with the configured (C/N0-dependent) DLL
    sigmas through the same per-epoch median."""
    rows = _with_labels(residual_sample(thermal), thermal)
    rows = rows[np.isfinite(rows["residual"])]
    draws = np.random.default_rng(1000).standard_normal((20, len(rows))) * rows["sigma_code_l1"].to_numpy()
    expected = np.abs(np.concatenate([_minus_epoch_median(d, rows["epoch"].to_numpy()) for d in draws]))
    got = np.abs(rows["residual"].to_numpy())
    for q in (50, 90):
        assert np.percentile(got, q) == pytest.approx(np.percentile(expected, q), rel=0.1)
    assert np.mean(got > 10.0) == 0.0


def test_nlos_rows_carry_the_large_residuals(urban: Scenario) -> None:
    rows = _with_labels(residual_sample(urban), urban)
    # the low receiver's sample grid (73 m steps) puts metres on strong line-of-sight rows too
    rows["residual"] = _minus_epoch_median(
        (rows["residual"] - rows["sample_grid_code_l1"]).to_numpy(), rows["epoch"].to_numpy()
    )
    res = rows["residual"].abs()
    assert rows["nlos"].any()
    assert res[rows["nlos"]].median() > 5 * res[~rows["nlos"]].median()


def test_hong_kong_log_reproduces_the_issue_table(hk: Scenario) -> None:
    stats = world_statistics(residual_sample(hk))
    assert stats.real and stats.n_epochs == 485
    assert stats.sats_median == HK_TABLE["sats_median"]
    for field in ("residual_p50_m", "residual_p90_m", "residual_p99_m"):
        assert getattr(stats, field) == pytest.approx(HK_TABLE[field], rel=0.05), field
    for field in ("share_over_10m", "share_over_30m"):
        assert getattr(stats, field) == pytest.approx(HK_TABLE[field], abs=0.01), field
    for field in ("cn0_p10", "cn0_p50", "cn0_p90"):
        assert getattr(stats, field) == pytest.approx(HK_TABLE[field], abs=1.0), field
    # a u-blox log: code without phase on many rows, short phase arcs
    assert 0.4 < stats.phase_availability < 0.8 and stats.arc_median_s < 10


def test_hong_kong_residual_by_elevation(hk: Scenario) -> None:
    """The log's NLOS tail thickens towards the horizon (notebook "A street that lifts heights"): p90 56.5 m and
    36 % of rows > 10 m late at 25-35 deg, 4.1 m and 4 % above 55 deg; no satellite tracked below 25 deg."""
    table = residual_by_elevation(residual_sample(hk), (0.0, 25.0, 35.0, 45.0, 55.0, 90.0)).set_index("el_low_deg")
    assert table.index.tolist() == [25.0, 35.0, 45.0, 55.0]
    np.testing.assert_allclose(table["p90_m"], [56.5, 36.0, 9.5, 4.1], rtol=0.05)
    np.testing.assert_allclose(table["share_late"], [0.36, 0.23, 0.10, 0.04], atol=0.01)
    assert np.all(np.diff(table["share_late"]) < 0.0) and np.all(np.diff(table["mean_m"].iloc[:3]) < 0.0)
    assert table["rows_per_epoch"].sum() == pytest.approx(len(residual_sample(hk).abs_residual) / 485, rel=1e-9)


def test_side_by_side_table_measures_ks_against_the_real_log(hk: Scenario, thermal: Scenario) -> None:
    real, sim = residual_sample(hk), residual_sample(thermal, name="thermal")
    table = comparison_table([sim, real]).set_index("name")
    assert (table["ks_against"] == real.name).all()
    assert table.loc[real.name, ["ks_residual", "ks_cn0"]].tolist() == [0.0, 0.0]
    # thermal noise alone is far from a city: most of the KS scale
    assert table.loc["thermal", "ks_residual"] > 0.5 and table.loc["thermal", "ks_cn0"] > 0.5
    assert ks_distances(sim, real) == ks_distances(real, sim)


def test_ks_distance_of_disjoint_and_equal_samples() -> None:
    def sample(residuals: list[float], cn0: list[float]) -> ValidationSample:
        rows = pd.DataFrame({"epoch": 0, "residual": residuals, "cn0": cn0})
        return ValidationSample("x", rows, np.array([0]), 1.0, real=False)

    a, b = sample([1, -2, 3], [30, 40, 50]), sample([-4, 5, 6], [30, 40, 50])
    assert ks_distances(a, b) == (1.0, 0.0)


def test_lone_satellites_get_no_residual(thermal: Scenario) -> None:
    sample = residual_sample(thermal, min_rows_per_clock=MIN_ROWS_PER_CLOCK)
    count = sample.rows.groupby(["epoch", "system"])["raw"].transform("size")
    assert sample.rows.loc[count < MIN_ROWS_PER_CLOCK, "residual"].isna().all()
    assert np.isfinite(sample.rows.loc[count >= MIN_ROWS_PER_CLOCK, "residual"]).all()
    assert "min_rows_per_clock" in one_line_error(residual_sample, thermal, min_rows_per_clock=0)


def test_cli_parses_worlds_and_rejects_bad_flags() -> None:
    worlds, options = parse_args(
        [
            "scenario=urban",
            "seed=1",
            "--against",
            "scenario=hk_tst_2019",
            "--out=/tmp/x",
            "--against",
            "scenario=open_sky",
            "--mask",
            "10",
        ]
    )
    assert worlds == [["scenario=urban", "seed=1"], ["scenario=hk_tst_2019"], ["scenario=open_sky"]]
    assert options == {"out": "/tmp/x", "mask": "10"}
    assert "--nope" in one_line_error(parse_args, ["--nope"])
    assert "--against" in one_line_error(parse_args, ["scenario=urban", "--against"])
    assert "--out" in one_line_error(parse_args, ["--out"])


def test_cli_writes_the_table_and_figure(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    table = run(
        [
            "scenario=urban",
            "scenario.duration_s=60",
            "--against",
            "scenario=urban",
            "receiver=high",
            "scenario.duration_s=60",
            "--out",
            str(tmp_path),
        ]
    )
    assert table["name"].tolist() == ["urban low seed 0", "urban high seed 0"]
    assert table["ks_against"].iloc[0] == "urban low seed 0" and table["ks_residual"].iloc[0] == 0.0
    assert {p.name for p in tmp_path.iterdir()} == {"validation.csv", "cn0_by_elevation.csv", "validation.png"}
    assert "urban high seed 0" in capsys.readouterr().out
    assert "two worlds are the same" in one_line_error(
        run, ["scenario=urban", "scenario.duration_s=60", "--against", "scenario=urban", "scenario.duration_s=60"]
    )


def test_report_shows_the_comparison_only_with_a_real_log_and_a_simulation(
    tmp_path: Path, hk: Scenario, urban: Scenario
) -> None:
    summary = pd.DataFrame(
        [
            {
                "scenario": "urban",
                "source": "simulated",
                "receiver": "low",
                "seed": 0,
                "estimator": "l2",
                "overrides": "{}",
                "variant": "",
                "uses_labels": False,
                "status": "ok",
                "horizontal_median": 1.0,
            }
        ],
        columns=list(SUMMARY_COLUMNS),
    )
    epochs = pd.DataFrame(columns=list(EPOCH_COLUMNS))
    claims = claims_table(summary, epochs)
    urban.save(tmp_path / "cache" / "sim")
    html = (build_report(tmp_path, summary, epochs, claims, {}) / "index.html").read_text()
    assert "Simulated worlds against real logs" not in html and not (tmp_path / "report" / "validation.png").exists()
    hk.save(tmp_path / "cache" / "real")
    html = (build_report(tmp_path, summary, epochs, claims, {}) / "index.html").read_text()
    assert "Simulated worlds against real logs" in html and "validation.png" in html
    assert "hk_tst_2019 (real, G)" in html and "urban low seed 0" in html
    assert (tmp_path / "report" / "validation.png").is_file()
