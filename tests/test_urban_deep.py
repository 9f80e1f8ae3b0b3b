"""The calibrated deep-urban preset (issue 14, item 3) against the Hong Kong TST log, and its new physics.

Calibration (``benchmarks/calibrate_urban_deep.py``) used seeds 1000-1002; these
tests evaluate seeds 0, 1, 2 pooled.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from simbench.analysis.calibration import TOLERANCES, misfit, pool_samples, seeds_statistics
from simbench.analysis.validation import ValidationSample, WorldStatistics, residual_sample, world_statistics
from simbench.data.rinex import load_rinex
from simbench.runs.compose import compose_config
from simbench.runs.scenarios import sim_config
from simbench.sim.canyon import canyon_rays
from simbench.sim.config import HeightDistribution, NlosConfig
from simbench.sim.generator import generate
from simbench.sim.trajectory import block_sides
from tests.conftest import one_line_error

EVALUATION_SEEDS = (0, 1, 2)


@pytest.fixture(scope="module")
def hk_sample(shared_data: Path) -> ValidationSample:
    d = shared_data / "hk_tst_2019"
    return residual_sample(
        load_rinex(d / "COM3_190428_124409.obs", d / "hksc1180.19n", d / "groundTruth_TST.csv", name="hk_tst_2019")
    )


@pytest.fixture(scope="module")
def hk(hk_sample: ValidationSample) -> WorldStatistics:
    return world_statistics(hk_sample)


@pytest.fixture(scope="module")
def deep() -> WorldStatistics:
    config = sim_config(compose_config(["scenario=urban_deep", "receiver=consumer"]))
    return seeds_statistics(config, EVALUATION_SEEDS, "urban_deep consumer seeds 0-2")


@pytest.mark.parametrize("tolerance", TOLERANCES, ids=[t.statistic for t in TOLERANCES])
def test_urban_deep_matches_hong_kong(tolerance, deep: WorldStatistics, hk: WorldStatistics) -> None:
    err = misfit(deep, hk, [tolerance])[tolerance.statistic]
    assert abs(err) <= 1.0, (
        f"{tolerance.statistic}: urban_deep {getattr(deep, tolerance.statistic):.3g} "
        f"against Hong Kong {getattr(hk, tolerance.statistic):.3g}"
    )


def test_urban_deep_is_harsher_than_urban(deep: WorldStatistics) -> None:
    urban = seeds_statistics(sim_config(compose_config(["scenario=urban", "receiver=low"])), (0,), "urban")
    assert deep.share_over_10m > 3.0 * urban.share_over_10m
    assert deep.cn0_p50 < urban.cn0_p50 - 5.0


def test_rayleigh_building_heights() -> None:
    """ITU-R P.1410 heights: Rayleigh, median scale sqrt(2 ln 2); open sides have height 0."""
    nlos = NlosConfig(
        height_distribution=HeightDistribution.rayleigh,
        building_height_scale_m=50.0,
        open_fraction=0.25,
        wall_distance_m=(5.0, 25.0),
    )
    dist, height = block_sides(nlos, (40_000,), np.random.default_rng(1))
    built = height > 0.0
    assert abs(1.0 - built.mean() - 0.25) < 0.01
    assert np.median(height[built]) == pytest.approx(50.0 * np.sqrt(2.0 * np.log(2.0)), rel=0.02)
    assert dist.min() >= 5.0 and dist.max() <= 25.0


def test_reflector_beyond_lengthens_only_masked_single_bounces() -> None:
    """A reflector 30 m behind the far facade adds 2 * 30 cos(el) |s| to a masked satellite's single bounce."""
    n, m = 200, 6
    rng = np.random.default_rng(5)
    el = rng.uniform(0.2, 1.3, (n, m))
    az = rng.uniform(0.0, 2.0 * np.pi, (n, m))
    road = np.zeros(n)
    walls, heights = np.full(n, 12.0), np.full(n, 40.0)
    travelled = np.linspace(0.0, 500.0, n)
    base = NlosConfig(reflection_probability=0.9)

    def rays(cfg: NlosConfig):
        return canyon_rays(el, az, road, walls, walls, heights, heights, travelled, cfg, 1.0, np.random.default_rng(7))

    near = rays(base)
    far = rays(replace(base, reflector_beyond_m=(30.0, 30.0)))
    extra = far.delay_m - near.delay_m
    expected = 2.0 * 30.0 * np.cos(el) * np.abs(np.sin(az))
    assert near.blocked.any() and (~near.blocked).any()
    np.testing.assert_allclose(extra[..., 1], np.where(near.blocked, expected, 0.0), atol=1e-9)
    np.testing.assert_array_equal(extra[..., [0, 2]], 0.0)
    np.testing.assert_array_equal(far.amplitude, near.amplitude)


def test_pool_samples_keeps_epochs_and_arcs_apart(hk_sample: ValidationSample) -> None:
    one = hk_sample
    two = pool_samples([one, one], "twice")
    assert len(two.rows) == 2 * len(one.rows)
    assert len(np.unique(two.reference_epochs)) == 2 * len(np.unique(one.reference_epochs))
    arcs = one.rows["arc"].to_numpy()
    assert two.rows["arc"].nunique() == 2 * one.rows["arc"].nunique() - (1 if (arcs < 0).any() else 0)
    a, b = world_statistics(one), world_statistics(two)
    assert (b.sats_median, b.share_over_10m, b.arc_median_s) == (a.sats_median, a.share_over_10m, a.arc_median_s)
    assert b.residual_p90_m == pytest.approx(a.residual_p90_m, rel=1e-3)  # percentile interpolation differs


@pytest.mark.parametrize(
    "override", ["scenario.errors.nlos.reflector_beyond_m=[50,10]", "scenario.errors.nlos.building_height_scale_m=0"]
)
def test_bad_canyon_values_fail_in_one_line(override: str) -> None:
    config = sim_config(compose_config(["scenario=urban_deep", "scenario.duration_s=60", override]))
    assert one_line_error(generate, config).startswith(override.split("=")[0])
