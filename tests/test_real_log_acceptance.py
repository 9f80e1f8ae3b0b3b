"""Issue 24's acceptance on every real GNSS log in ``../shared`` and on simulated ``urban_deep`` seeds 0-4.

One test per log, each on the shipped defaults (``python -m simbench scenario=<log>``):

* batch L2 (``l2``) is no worse than per-epoch WLS (``wls_spp``) on the same rows: median and
  95th percentile of the horizontal error over the epochs both solved;
* the best robust estimator (lowest median of ``dcs`` and ``mm``) beats ``huber_spp`` in median
  and 95th percentile, on the epochs both solved;
* Hong Kong (GPS + BeiDou) also: best robust median <= 2.5 m and p95 <= 8 m, ``ekf_ppp`` median
  at most twice the best, every estimator run here at availability >= 0.95, and so ``rtklib_spp``;
* Nagoya (open sky, ionosphere-free) also: every GNSS estimator, built-in or plug-in, at a
  horizontal median <= 1.0 m.

The real GNSS logs are Hong Kong (``hk_tst_2019``) and Nagoya (``nagoya_static``); the WVU
drives are simulated worlds on real trajectories, and the ``librsf`` preset points at a test
fixture, not a log. "The best robust" is the better of the batch DCS and MM, the best on the
tuning data; ``bce`` is left out (Hong Kong: median 2.94 m, p95 15.5 m, against DCS's 2.39 / 4.70 m
and MM's 2.99 / 5.10 m), as are the incremental ones (the issue's table has all of them). A
promise the defaults do not keep is ``xfail(strict=True)`` with the measured numbers, so it
stays visible and flips when it holds.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import estimators
import simbench
from simbench.contract import Scenario
from simbench.runs.runner import run_estimators

#: The robust estimators that can be the best; ``l2``, the per-epoch baselines and the EKF beside them.
ROBUST = ("dcs", "mm")
#: Each log runs the graph estimators for tens of seconds to minutes (Hong Kong: 100 s of CPU).
pytestmark = pytest.mark.slow

#: Seeds of the simulated acceptance world (the defaults were tuned on seeds >= 1000 only).
URBAN_DEEP_SEEDS = range(5)


@dataclass(frozen=True)
class Stats:
    """Horizontal error statistics of one estimator on a set of epochs [m]."""

    median: float
    p95: float

    def __str__(self) -> str:
        return f"{self.median:.2f}/{self.p95:.2f} m"


@dataclass(frozen=True)
class LogRun:
    """Per-epoch horizontal errors and summary rows of the estimators on one log (or pooled seeds)."""

    epochs: pd.DataFrame  #: columns ``run`` (seed), ``epoch``, ``estimator``, ``horizontal`` [m]
    summary: pd.DataFrame  #: one row per run x estimator (``availability``, ``status``, ...)
    #: per run, the GNSS systems a real log's rows were used for (RINEX letters; "" when simulated)
    systems_used: tuple[str, ...]

    def on_common(self, a: str, b: str) -> tuple[Stats, Stats]:
        """Statistics of ``a`` and ``b`` over the epochs both solved (pooled over the runs)."""
        wide = self.epochs[self.epochs["estimator"].isin([a, b])].pivot_table(
            index=["run", "epoch"], columns="estimator", values="horizontal"
        )
        both = wide[[a, b]].dropna()
        assert len(both), f"{a} and {b} have no epoch in common"
        return stats(both[a]), stats(both[b])

    def median(self, name: str) -> float:
        """Median horizontal error of ``name`` over all its solved epochs (pooled over the runs) [m]."""
        return float(np.median(self.epochs.loc[self.epochs["estimator"] == name, "horizontal"]))

    def best_robust(self) -> str:
        """The robust estimator with the lowest median over its own epochs."""
        return min(ROBUST, key=self.median)


def stats(errors: Iterable[float]) -> Stats:
    """Median and 95th percentile of horizontal errors [m]."""
    e = np.asarray(list(errors), float)
    return Stats(float(np.median(e)), float(np.percentile(e, 95)))


def run_log(name: str, estimators: Iterable[str], seeds: Iterable[int] = (0,)) -> LogRun:
    """Run ``estimators`` with their shipped defaults on preset ``name`` for each seed; pool the results."""
    return run_scenarios([simbench.scenario(name, seed=seed) for seed in seeds], estimators)


def run_scenarios(scenarios: Iterable[Scenario], estimators: Iterable[str]) -> LogRun:
    """Run ``estimators`` with their shipped defaults on each scenario; pool the results (``run``: its seed)."""
    frames, summaries, systems = [], [], []
    for scenario in scenarios:
        seed = int(scenario.meta.get("seed", 0))
        result = run_estimators(scenario, dict.fromkeys(estimators), progress=False)
        frames.append(result.epochs[["epoch", "estimator", "horizontal"]].assign(run=seed))
        summaries.append(result.summary.assign(run=seed))
        systems.append(str(scenario.meta.get("systems_used", "")))
    return LogRun(pd.concat(frames, ignore_index=True), pd.concat(summaries, ignore_index=True), tuple(systems))


def check_baseline_inequalities(log: LogRun) -> list[str]:
    """The failed "L2 no worse than WLS" and "best robust beats Huber" inequalities, one line each."""
    failed = []
    l2, wls = log.on_common("l2", "wls_spp")
    if l2.median > wls.median or l2.p95 > wls.p95:
        failed.append(f"l2 {l2} worse than wls_spp {wls} on the same epochs")
    best = log.best_robust()
    robust, huber = log.on_common(best, "huber_spp")
    if not (robust.median < huber.median and robust.p95 < huber.p95):
        failed.append(f"best robust {best} {robust} does not beat huber_spp {huber} on the same epochs")
    return failed


def assert_all_ok(log: LogRun) -> None:
    bad = log.summary[log.summary["status"] != "ok"]
    assert bad.empty, bad[["run", "estimator", "status", "message"]].to_string()


# --------------------------------------------------------------------------- Hong Kong
# Each log's tests share one worker (``--dist loadgroup``): its module fixture runs once, not once per worker.


@pytest.fixture(scope="module")
def hong_kong_log(shared_data: Path) -> Scenario:
    return simbench.scenario("hk_tst_2019")


@pytest.fixture(scope="module")
def hong_kong(hong_kong_log: Scenario) -> LogRun:
    return run_scenarios([hong_kong_log], ("l2", *ROBUST, "wls_spp", "huber_spp", "ekf_ppp"))


@pytest.mark.xdist_group("hong_kong")
def test_hong_kong_runs_gps_and_beidou(hong_kong: LogRun) -> None:
    """The preset is the issue's target configuration: GPS + BeiDou, every estimator available."""
    assert hong_kong.systems_used == ("GC",)
    assert_all_ok(hong_kong)
    low = hong_kong.summary[hong_kong.summary["availability"] < 0.95]
    assert low.empty, low[["estimator", "availability"]].to_string()


@pytest.mark.xdist_group("hong_kong")
def test_hong_kong_batch_and_robust_beat_the_per_epoch_baselines(hong_kong: LogRun) -> None:
    assert check_baseline_inequalities(hong_kong) == []


@pytest.mark.xdist_group("hong_kong")
def test_hong_kong_best_robust_meets_the_target(hong_kong: LogRun) -> None:
    """Met since the urban preset's 1 m arc-start ionosphere prior (DCS 2.97/5.16 -> 2.39/4.7 m; MM
    2.67/8.32 -> 2.99/5.1 m): docs/estimators.md, "A static receiver in the canyon"."""
    best = hong_kong.best_robust()
    robust = stats(hong_kong.epochs.loc[hong_kong.epochs["estimator"] == best, "horizontal"])
    assert robust.median <= 2.5 and robust.p95 <= 8.0, f"best robust {best} {robust}"


@pytest.mark.xdist_group("hong_kong")
def test_hong_kong_ekf_within_twice_the_best_robust(hong_kong: LogRun) -> None:
    best = hong_kong.best_robust()
    ekf = hong_kong.median("ekf_ppp")
    assert ekf <= 2.0 * hong_kong.median(best), (
        f"ekf_ppp median {ekf:.2f} m, best robust {best} {hong_kong.median(best):.2f} m"
    )


@pytest.mark.xdist_group("hong_kong")
@pytest.mark.xfail(
    strict=True, reason="rtklib_spp solves 29 % of the Hong Kong epochs (median 3.87 m, p95 16.0 m where it does)"
)
def test_hong_kong_rtklib_baseline_is_available(hong_kong_log: Scenario) -> None:
    """RTKLIB's single point fix, the external baseline of the issue's table, at availability >= 0.95."""
    log = run_scenarios([hong_kong_log], ("rtklib_spp",))
    row = log.summary.iloc[0]
    if row["status"] == "skipped":
        pytest.skip(str(row["message"]))
    assert row["availability"] >= 0.95, f"rtklib_spp availability {row['availability']:.3f}"


# --------------------------------------------------------------------------- Nagoya


@pytest.fixture(scope="module")
def nagoya(shared_data: Path) -> LogRun:
    """Every registered estimator on the Nagoya log (the GNSS/INS ones and the oracle skip: no IMU, no labels)."""
    return run_log("nagoya_static", sorted(estimators.registered()))


@pytest.mark.xdist_group("nagoya")
def test_nagoya_batch_and_robust_beat_the_per_epoch_baselines(nagoya: LogRun) -> None:
    assert check_baseline_inequalities(nagoya) == []


@pytest.mark.xdist_group("nagoya")
def test_nagoya_every_gnss_estimator_within_a_metre(nagoya: LogRun) -> None:
    """Open sky, ionosphere-free: every GNSS estimator's horizontal median <= 1.0 m (issue 24)."""
    summary = nagoya.summary.set_index("estimator")
    skipped = summary[summary["status"] == "skipped"]
    assert set(skipped.index) == {"crt_lss", "ekf_ins", "iekf_ins", "oracle"}, skipped["message"].to_string()
    ran = summary[summary["status"] != "skipped"]
    assert (ran["status"] == "ok").all(), ran[["status", "message"]].to_string()
    medians = {name: nagoya.median(name) for name in ran.index}
    assert {"l2", "dcs", "mm", "bce", "ekf_ppp", "ice", "wls_spp", "rtklib_spp"} <= set(medians)
    too_far = {name: round(m, 3) for name, m in medians.items() if not m <= 1.0}
    assert not too_far, f"horizontal median above 1.0 m: {too_far}"


# --------------------------------------------------------------------------- urban_deep


def test_urban_deep_batch_and_robust_beat_the_per_epoch_baselines() -> None:
    """Seeds 0-4 of ``scenario=urban_deep`` (receiver ``low``, 600 s each), epochs pooled over the seeds.

    The EKF runs too: parked with one or two satellites it climbed 13 km on seed 4 (``diverged``) and
    2-5 km on seeds 1 and 2 (``ok``, below the divergence line) before the standstill's vertical row;
    no estimator may stray a kilometre (now at most 391 m, ``wls_spp`` on seed 4)."""
    log = run_log("urban_deep", ("l2", *ROBUST, "ekf_ppp", "wls_spp", "huber_spp"), URBAN_DEEP_SEEDS)
    assert_all_ok(log)
    assert check_baseline_inequalities(log) == []
    strays = log.summary[log.summary["error_3d_max"] > 1000.0]
    assert strays.empty, strays[["run", "estimator", "error_3d_max"]].to_string()
