"""The dissertation's Morgantown drives as scenarios: roadside buildings and the published-median table."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import simbench
from simbench.analysis.published import CH6_DRIVE_MEDIANS_M, DRIVE_MEDIANS_M
from simbench.analysis.tables import drive_comparison
from simbench.errors import SimbenchError
from simbench.sim.config import NlosConfig, ReplayConfig
from simbench.sim.trajectory import replay, roadside_street


@pytest.fixture(scope="module")
def drive_1(shared_data):
    traj, _ = replay(ReplayConfig(path=str(shared_data / "wvu_drives" / "drive_1.xyz")), 1.0, 600.0)
    return traj


def test_roadside_buildings_follow_the_route_in_segments(drive_1) -> None:
    nlos = NlosConfig(
        building_height_m=(4.0, 12.0), wall_distance_m=(10.0, 25.0), open_fraction=0.5, roadside_segment_m=40.0
    )
    street = roadside_street(drive_1, nlos, np.random.default_rng(3))
    step = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(drive_1.pos, axis=0), axis=1))]
    changes = np.flatnonzero(np.diff(street.height_left_m) != 0.0) + 1
    # a side changes only where the travelled distance crosses a multiple of the segment length
    assert len(changes) > 10
    assert np.all(np.floor(step[changes] / 40.0) > np.floor(step[changes - 1] / 40.0))
    segment = (step // 40.0).astype(int)
    first = np.r_[0, np.flatnonzero(np.diff(segment)) + 1]
    assert len(first) > 40
    for h in (street.height_left_m, street.height_right_m):
        built = h > 0.0
        assert 0.3 < built[first].mean() < 0.7  # open_fraction of the segments, not of the time
        assert h[built].min() >= 4.0 and h.max() <= 12.0
    assert street.wall_left_m.min() >= 10.0 and street.wall_right_m.max() <= 25.0
    np.testing.assert_allclose(street.road_heading_rad, drive_1.att[:, 2] % (2 * np.pi))


def test_roadside_bad_segment_is_one_line(drive_1) -> None:
    with pytest.raises(SimbenchError, match="roadside_segment_m"):
        roadside_street(drive_1, NlosConfig(roadside_segment_m=0.0), np.random.default_rng(0))


def test_morgantown_scenario_has_suburban_nlos(shared_data) -> None:
    sc = simbench.simulate("morgantown1", "low", seed=0, **{"scenario.duration_s": 600.0})
    share = sc.labels["nlos"].mean()
    # low houses set back from the road: NLOS is rare, but present (urban gives about 0.1)
    assert 0.003 < share < 0.08
    again = simbench.simulate("morgantown1", "low", seed=0, **{"scenario.duration_s": 600.0})
    pd.testing.assert_frame_equal(sc.observations, again.observations)


def _row(scenario: str, receiver: str, estimator: str, seed: int, median: float, status: str = "ok") -> dict:
    return {
        "sweep": "ch5_bce_morgantown",
        "scenario": scenario,
        "receiver": receiver,
        "estimator": estimator,
        "seed": seed,
        "status": status,
        "availability": 0.9,
        "horizontal_median_ref": median,
        "overrides": "{}",
        "variant": "",
    }


def test_drive_comparison_sets_our_medians_beside_the_published() -> None:
    summary = pd.DataFrame(
        [
            _row("morgantown2", "low", "dcs", 0, 1.0),
            _row("morgantown2", "low", "dcs", 1, 3.0),
            _row("morgantown2", "low", "dcs", 2, 9.0, status="failed"),
            _row("morgantown3", "high", "isam2_mm", 0, 0.5),
            _row("urban", "low", "dcs", 0, 7.0),
            _row("morgantown1", "low", "bce_ad", 0, 7.0),
        ]
    )
    table = drive_comparison(summary)
    assert len(table) == 2
    dcs = table[table["estimator"] == "dcs"].iloc[0]
    assert dcs["drive"] == 2 and dcs["n_seeds"] == 2 and dcs["median_ref"] == pytest.approx(2.0)
    assert dcs["published"] == DRIVE_MEDIANS_M[("low", 2)]["DCS"]
    assert dcs["ratio"] == pytest.approx(2.0 / 2.08)
    mm = table[table["estimator"] == "isam2_mm"].iloc[0]
    assert mm["published_as"] == "MM" and mm["published"] == DRIVE_MEDIANS_M[("high", 3)]["MM"]
    assert drive_comparison(summary[summary["scenario"] == "urban"]).empty
    # BCE-AD's study is set beside Ch.6's own table (low receiver only), not beside Ch.7's
    ch6 = pd.DataFrame(
        [{**_row("morgantown3", "low", name, 0, 4.0), "sweep": "ch6_bce_ad"} for name in ("bce_ad", "l2")]
        + [{**_row("morgantown3", "high", "l2", 0, 4.0), "sweep": "ch6_bce_ad"}]
    )
    table = drive_comparison(ch6).set_index("estimator")
    assert list(table.index) == ["bce_ad", "l2"] and table.loc["bce_ad", "published_as"] == "BCE-AD"
    assert table.loc["bce_ad", "published"] == CH6_DRIVE_MEDIANS_M[("low", 3)]["BCE-AD"] == 3.25
    assert table.loc["l2", "published"] == CH6_DRIVE_MEDIANS_M[("low", 3)]["L2"] != DRIVE_MEDIANS_M[("low", 3)]["L2"]
