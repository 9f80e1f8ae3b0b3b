"""The fixed-lag window of the incremental estimators: its schedule at any rate, arcs that resume
after leaving it, and a 30 s static station whose arcs resume after gaps."""

from __future__ import annotations

import numpy as np
import pytest

import estimators
import simbench
from estimators.incremental.configs import IncrementalConfig
from estimators.incremental.fixed_lag import LagSchedule, restart_stale_arcs
from estimators.incremental.isam2 import IncrementalGraphEstimator
from estimators.model.measurement import prepare_ppp
from simbench.contract import ReceiverData

INCREMENTAL = sorted(n for n, c in estimators.registered().items() if issubclass(c, IncrementalGraphEstimator))


@pytest.mark.parametrize("interval_s", [0.1, 1.0, 30.0])
def test_window_spans_the_lag_and_a_few_epochs_at_any_rate(interval_s: float) -> None:
    n, lag, min_epochs = 2000, 10.0, 5
    schedule = LagSchedule.of(np.arange(n) * interval_s, lag, min_epochs)
    k = np.arange(n)
    kept = k - schedule.first_kept + 1  # epochs in the window after update k
    need = max(min_epochs, int(round(lag / interval_s)) + 1)
    warm = k >= need
    assert np.all(np.diff(schedule.first_kept) >= 0)
    assert kept[warm].min() == need  # never fewer than the lag and the minimum ask
    assert kept.max() <= need + need // 2  # cut back once it has grown by half
    # epochs leave in batches of about half a window, so a marginalising update is rare
    leaving = np.flatnonzero(np.diff(schedule.first_kept) > 0)
    assert len(leaving) == pytest.approx((n - need) / max(1, need // 2), abs=2)


def test_no_lag_keeps_every_epoch() -> None:
    schedule = LagSchedule.of(np.arange(100.0), 0.0, 5)
    assert not schedule.first_kept.any() and not any(schedule.leaving(k) for k in range(100))


@pytest.fixture(scope="module")
def station() -> tuple[simbench.Scenario, ReceiverData]:
    """Three hours of a static dual-frequency receiver at 30 s; every satellite loses 1-3 epochs
    (60-120 s) every 20 minutes, and one loses 8 (270 s, longer than the window)."""
    sc = simbench.scenario(
        "open_sky",
        seed=1000,
        receiver="high",
        **{
            "scenario.rate_hz": 1 / 30,
            "scenario.duration_s": 3 * 3600,
            "scenario.trajectory.urban_drive.start_static_s": 1e6,
        },
    )
    o = sc.observations
    epoch = o["epoch"].to_numpy()
    drop = np.zeros(len(o), bool)
    for i, sat in enumerate(sorted(o["sat"].unique())):
        rows = (o["sat"] == sat).to_numpy()
        for start in np.sort(epoch[rows])[10::40]:
            missing = 8 if i == 0 and start == np.sort(epoch[rows])[10] else 1 + (start + i) % 3
            drop |= rows & (epoch > start) & (epoch <= start + missing)
    return sc, ReceiverData(o[~drop], sc.imu, sc.nav)


def test_arcs_restart_where_their_previous_row_left_the_window(station) -> None:
    _, data = station
    obs = prepare_ppp(data, code_sigma_m=0.3, phase_sigma_m=0.003, elevation_mask_deg=7.0, max_gap_epochs=10)
    schedule = LagSchedule.of(obs.epoch_t, 10.0, 5)
    cut, n_restarted = restart_stale_arcs(obs, schedule)
    assert n_restarted >= 1 and cut.n_arcs == obs.n_arcs + n_restarted
    # after the cut, every row's previous row of its arc is still in the window when the row arrives
    prev, row_epoch = cut.previous_rows(), cut.row_epoch
    resumed = np.flatnonzero(prev >= 0)
    assert all(schedule.alive(int(row_epoch[p]), int(row_epoch[r])) for p, r in zip(prev[resumed], resumed))
    # and nothing else was cut: the rows that keep their arc are the same rows
    np.testing.assert_array_equal(cut.arc >= 0, obs.arc >= 0)


@pytest.mark.parametrize("name", INCREMENTAL)
def test_incremental_estimators_run_on_a_30_s_station_whose_arcs_resume(station, name: str) -> None:
    # max_gap_epochs=10 keeps the arcs across every gap (the held-out station's arcs resumed after two
    # missing epochs): before the window owned its keys, this stopped with "Requested variable 'b12'"
    sc, data = station
    cls = estimators.get(name)
    cfg: IncrementalConfig = cls.Config(max_gap_epochs=10)
    sol = cls(cfg).estimate(data)
    assert sol.diagnostics["arcs_restarted_after_window"] >= 1
    truth = sc.truth.set_index("epoch").loc[sol.epochs["epoch"], ["x", "y", "z"]].to_numpy()
    err = np.linalg.norm(sol.epochs[["x", "y", "z"]].to_numpy() - truth, axis=1)
    assert len(sol.epochs) >= 350 and np.median(err) < 2.0, (len(sol.epochs), np.median(err))
