"""Every claim rule on hand-made result rows: the measured number and the holds/does-not-hold verdict.

Each rule gets rows built so that the verdict is known by construction (one
case that holds, one that does not) and its measured number is checked; a run
without the claim's sweep leaves every claim ``not measured``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
import pytest

from estimators.incremental.configs import IceConfig
from estimators.incremental.ice import AdaptiveNoiseModel
from simbench.analysis.claims import CLAIMS, CONVERGENCE_S, adaptation_outcome, claims_by_world, claims_table
from simbench.analysis.variants import overrides_json, variant_label
from simbench.runs.runner import SUMMARY_COLUMNS

NO_EPOCHS = pd.DataFrame(columns=["sweep", "t", "estimator", "seed", "error_3d"])
#: Per-seed multipliers around 1 (seed to seed spread, so bootstrap intervals are not degenerate).
BASE = 5.0 + np.random.default_rng(0).normal(0, 0.3, 12)


def _rows(
    sweep: str,
    values: dict[str, Any],
    column: str = "horizontal_median",
    receiver: str = "low",
    overrides: dict[str, Any] | None = None,
) -> pd.DataFrame:
    """Summary rows with status ok: one per (estimator, seed), ``values[estimator][seed]`` in ``column``.

    Every other column of :data:`SUMMARY_COLUMNS` exists and is empty, as in a real summary.
    """
    overrides = overrides or {}
    return pd.DataFrame(
        [
            {
                "sweep": sweep,
                "scenario": "urban",
                "receiver": receiver,
                "seed": seed,
                "estimator": name,
                "overrides": overrides_json(overrides),
                "variant": variant_label(overrides),
                "status": "ok",
                column: float(value),
            }
            for name, per_seed in values.items()
            for seed, value in enumerate(per_seed)
        ],
        columns=list(SUMMARY_COLUMNS),
    )


def _verdict(
    summary: pd.DataFrame, claim_id: str, epochs: pd.DataFrame = NO_EPOCHS, diagnostics: dict | None = None
) -> pd.Series:
    return claims_table(summary, epochs, diagnostics).set_index("claim_id").loc[claim_id]


def _scaled(**factors: float) -> dict[str, np.ndarray]:
    """Every estimator's per-seed values: BASE times its factor (paired over seeds)."""
    return {name: BASE * f for name, f in factors.items()}


def test_every_claim_has_a_test_here() -> None:
    tested = {
        "ch4_convergence",
        "ch4_overall_median",
        "ch5_bce_low",
        "ch5_high_comparable",
        "ch5_sensitivity",
        "ch5_runtime",
        "ch6_bce_ad",
        "ch7_ice_low",
        "ch7_high_comparable",
        "ch7_adaptations",
        "crt_accuracy_order",
        "crt_window",
    }
    assert {c.claim_id for c in CLAIMS} == tested


def test_without_the_papers_sweeps_every_claim_is_not_measured() -> None:
    smoke = _rows("smoke", _scaled(bce=0.5, l2=1.0, dcs=1.0, mm=1.0, ice=0.5, isam2_ppp=1.0, ekf_ppp=1.0))
    table = claims_table(smoke, NO_EPOCHS, {})
    assert len(table) == len(CLAIMS) and (table["holds"] == "not measured").all()
    assert table["measured"].isna().all() and (table["n_seeds"] == 0).all()
    assert (claims_table(smoke.iloc[:0], NO_EPOCHS)["holds"] == "not measured").all()


def _convergence_epochs(isam2_early: float, ekf_early: float) -> pd.DataFrame:
    t = np.array([0.0, 300.0, 600.0, CONVERGENCE_S, 1500.0])
    rows = [
        pd.DataFrame(
            {
                "sweep": "ch4_convergence",
                "estimator": name,
                "seed": seed,
                "t": t,
                # after the window both are 100 m: only the first 15 minutes may count
                "error_3d": np.where(t < CONVERGENCE_S, early * BASE[seed], 100.0),
            }
        )
        for name, early in (("isam2_ppp", isam2_early), ("ekf_ppp", ekf_early))
        for seed in range(6)
    ]
    return pd.concat(rows, ignore_index=True)


def test_ch4_convergence_holds_only_when_isam2_is_lower_early() -> None:
    summary = _rows("ch4_convergence", _scaled(isam2_ppp=1.0, ekf_ppp=1.0), "error_3d_median")
    row = _verdict(summary, "ch4_convergence", _convergence_epochs(0.25, 1.0))
    assert row["holds"] == "holds" and row["measured"] == pytest.approx(0.25) and row["n_seeds"] == 6
    assert row["ci_high"] < 1.0
    row = _verdict(summary, "ch4_convergence", _convergence_epochs(1.0, 1.0))
    assert row["holds"] == "does not hold" and row["measured"] == pytest.approx(1.0)
    assert _verdict(summary, "ch4_convergence", NO_EPOCHS)["holds"] == "not measured"


def test_ch4_overall_median_reads_the_ionosphere_free_variant() -> None:
    iono_free = {"ionosphere": "free"}  # the sweep's only variant: no default rows exist
    similar = _rows("ch4_convergence", _scaled(isam2_ppp=1.05, ekf_ppp=1.0), "error_3d_median", overrides=iono_free)
    row = _verdict(similar, "ch4_overall_median")
    assert row["holds"] == "holds" and row["measured"] == pytest.approx(1.05)
    far = _rows("ch4_convergence", _scaled(isam2_ppp=2.0, ekf_ppp=1.0), "error_3d_median", overrides=iono_free)
    row = _verdict(far, "ch4_overall_median")
    assert row["holds"] == "does not hold" and row["measured"] == pytest.approx(2.0)


def test_ch5_bce_low_holds_only_when_bce_is_clearly_lower() -> None:
    lower = _rows("ch5_bce", _scaled(bce=0.7, l2=1.0, dcs=1.1, mm=0.9))
    row = _verdict(lower, "ch5_bce_low")
    assert row["holds"] == "holds"
    assert row["measured"] == pytest.approx(0.7 / 0.9) and row["ci_high"] < 1.0
    same = _rows("ch5_bce", _scaled(bce=1.0, l2=1.01, dcs=1.1, mm=1.0))
    assert _verdict(same, "ch5_bce_low")["holds"] == "does not hold"
    # the high receiver's rows are another claim's
    assert (
        _verdict(_rows("ch5_bce", _scaled(bce=0.7, l2=1.0, dcs=1.1, mm=0.9), receiver="high"), "ch5_bce_low")["holds"]
        == "not measured"
    )


def _sensitivity(medians: dict[str, list[float]]) -> pd.DataFrame:
    """ch5_sensitivity rows: per estimator one median per prior scale 0.1, 1 (the default) and 10."""
    frames = []
    for i, scale in enumerate((0.1, 1.0, 10.0)):
        overrides = {} if scale == 1.0 else {"prior_scale": scale}
        frames.append(_rows("ch5_sensitivity", {name: [v[i]] * 3 for name, v in medians.items()}, overrides=overrides))
    return pd.concat(frames, ignore_index=True)


def test_ch5_sensitivity_holds_when_bce_varies_least_over_the_prior_scales() -> None:
    flat = _sensitivity({"bce": [5.0, 5.0, 5.0], "l2": [4.0, 5.0, 8.0], "dcs": [5.0, 6.0, 7.0], "mm": [5.0, 5.5, 6.0]})
    row = _verdict(flat, "ch5_sensitivity")
    assert row["holds"] == "holds" and row["measured"] == pytest.approx(1.0 / 1.2) and row["n_seeds"] == 3
    steep = _sensitivity({"bce": [3.0, 5.0, 9.0], "l2": [4.0, 5.0, 8.0], "dcs": [5.0, 6.0, 7.0], "mm": [5.0, 5.5, 6.0]})
    row = _verdict(steep, "ch5_sensitivity")
    assert row["holds"] == "does not hold" and row["measured"] == pytest.approx(3.0 / 1.2)


def test_ch5_runtime_holds_when_bce_is_the_slowest() -> None:
    for bce, holds, measured in ((4.0, "holds", 2.0), (1.0, "does not hold", 0.5)):
        factors = {"bce": bce, "l2": 1.0, "dcs": 2.0, "mm": 1.5}
        rows = _rows("ch5_bce", {name: BASE * f * 1e-5 for name, f in factors.items()}, "time_per_obs_s")
        row = _verdict(rows, "ch5_runtime")
        assert row["holds"] == holds and row["measured"] == pytest.approx(measured)


def test_ch6_bce_ad_holds_when_it_is_below_bce() -> None:
    row = _verdict(_rows("ch6_bce_ad", _scaled(bce_ad=0.8, bce=1.0, l2=1.2)), "ch6_bce_ad")
    assert row["holds"] == "holds" and row["measured"] == pytest.approx(0.8) and row["ci_high"] < 1.0
    row = _verdict(_rows("ch6_bce_ad", _scaled(bce_ad=1.1, bce=1.0, l2=1.2)), "ch6_bce_ad")
    assert row["holds"] == "does not hold" and row["measured"] == pytest.approx(1.1)


#: The estimators of a sweep whose claims :func:`test_a_ratio_claim_holds_or_not_by_the_medians` checks.
SWEEP_ESTIMATORS = {"ch5_bce": ("bce", "l2", "dcs", "mm"), "ch7_ice": ("ice", "isam2_ppp", "isam2_dcs", "isam2_mm")}


@pytest.mark.parametrize(
    "claim, sweep, receiver, medians, holds, measured",
    [  # each claim once where it holds and once where it does not; medians in SWEEP_ESTIMATORS order
        ("ch5_high_comparable", "ch5_bce", "high", (1.0, 1.05, 1.1, 1.12), "holds", 0.12),
        ("ch5_high_comparable", "ch5_bce", "high", (1.0, 1.05, 1.3, 1.0), "does not hold", 0.3),
        ("ch7_ice_low", "ch7_ice", "low", (0.6, 1.0, 0.8, 0.9), "holds", 0.75),
        ("ch7_ice_low", "ch7_ice", "low", (0.9, 1.0, 0.8, 0.9), "does not hold", 0.9 / 0.8),
        ("ch7_high_comparable", "ch7_ice", "high", (1.0, 1.1, 1.0, 1.05), "holds", 0.1),
        ("ch7_high_comparable", "ch7_ice", "high", (1.0, 1.5, 1.0, 1.05), "does not hold", 0.5),
    ],
)
def test_a_ratio_claim_holds_or_not_by_the_medians(
    claim: str, sweep: str, receiver: str, medians: tuple[float, ...], holds: str, measured: float
) -> None:
    scales = dict(zip(SWEEP_ESTIMATORS[sweep], medians))
    row = _verdict(_rows(sweep, _scaled(**scales), receiver=receiver), claim)
    assert row["holds"] == holds and row["measured"] == pytest.approx(measured)


def test_adaptation_claim_reads_the_ice_diagnostics() -> None:
    model = AdaptiveNoiseModel(IceConfig(cluster_threshold=99))
    model.n_residuals = 1000
    diag = model.diagnostics()  # no adaptation, 1000 // 100 = 10 naive ones
    jobs = {"ice": [{"job": {"sweep": "ch7_ice"}, "diagnostics": diag}] * 3}
    out = adaptation_outcome(jobs)
    assert out is not None and out.measured == 0.0 and out.holds and "0 adaptations vs 30 naive" in out.note
    assert adaptation_outcome({"ice": [{"job": {"sweep": "smoke"}, "diagnostics": diag}]}) is None


def test_ch7_adaptations_holds_when_ice_adapts_less_often_than_the_naive_rule() -> None:
    summary = _rows("ch7_ice", _scaled(ice=1.0))

    def jobs(adaptations: int, naive: int) -> dict:
        diag = {"n_adaptations": adaptations, "naive_adaptations": naive}
        return {"ice": [{"job": {"sweep": "ch7_ice"}, "diagnostics": diag}] * 2}

    row = _verdict(summary, "ch7_adaptations", diagnostics=jobs(3, 12))
    assert row["holds"] == "holds" and row["measured"] == pytest.approx(0.25) and row["n_seeds"] == 2
    assert not row["vacuous"]
    row = _verdict(summary, "ch7_adaptations", diagnostics=jobs(12, 12))
    assert row["holds"] == "does not hold" and row["measured"] == pytest.approx(1.0)
    assert _verdict(summary, "ch7_adaptations", diagnostics={})["holds"] == "not measured"
    # 0 against 6: fewer, but nothing was adapted at all -- a pass that says nothing, flagged
    row = _verdict(summary, "ch7_adaptations", diagnostics=jobs(0, 3))
    assert row["holds"] == "holds" and row["vacuous"] and "vacuous" in row["note"]


def test_a_ci_straddling_the_threshold_is_inconclusive_and_the_cell_says_so() -> None:
    # BCE-AD 0.95 of BCE on average, but seed by seed from 0.6 to 1.3: the CI holds 1
    noisy = np.array([0.6, 1.3, 0.7, 1.25, 0.8, 1.05, 0.65, 1.3, 0.9, 1.1, 0.75, 1.0])
    summary = _rows("ch6_bce_ad", {"bce_ad": BASE * noisy, "bce": BASE})
    row = _verdict(summary, "ch6_bce_ad")
    assert row["ci_low"] < 1.0 < row["ci_high"] and row["holds"] == "inconclusive"
    cell = claims_by_world(claims_table(summary, NO_EPOCHS, {})).set_index("claim_id").loc["ch6_bce_ad", "urban"]
    assert cell.endswith("inconclusive") and f"{row['measured']:.3g}" in cell
    # the same mean with every seed below 1 decides
    steady = _rows("ch6_bce_ad", {"bce_ad": BASE * 0.9, "bce": BASE})
    assert _verdict(steady, "ch6_bce_ad")["holds"] == "holds"


def test_every_claim_states_a_published_number_or_why_none_beside_its_rule() -> None:
    for claim in CLAIMS:
        assert claim.rule and claim.published
        assert any(ch.isdigit() for ch in claim.published) or "no number" in claim.published


def test_crt_accuracy_order_holds_for_crt_below_iekf_below_ekf_at_the_default_window() -> None:
    ordered = _rows("crt_window", _scaled(crt_lss=0.5, iekf_ins=0.8, ekf_ins=1.0), "error_3d_p95")
    # a non-default window variant of CRT-LSS is not the claim's CRT-LSS
    worse_window = _rows("crt_window", _scaled(crt_lss=5.0), "error_3d_p95", overrides={"window": 1})
    row = _verdict(pd.concat([ordered, worse_window], ignore_index=True), "crt_accuracy_order")
    assert row["holds"] == "holds" and row["measured"] == pytest.approx(0.5) and row["ci_high"] < 1.0
    swapped = _rows("crt_window", _scaled(crt_lss=0.5, iekf_ins=0.4, ekf_ins=1.0), "error_3d_p95")
    row = _verdict(swapped, "crt_accuracy_order")
    assert row["holds"] == "does not hold" and row["measured"] == pytest.approx(0.5)


def _windows(p95_by_window: dict[int, float]) -> pd.DataFrame:
    """crt_window rows of CRT-LSS: window 10 is the dataclass default, so its rows carry no override."""
    return pd.concat(
        [
            _rows(
                "crt_window",
                {"crt_lss": [p95] * 3},
                "error_3d_p95",
                overrides={} if window == 10 else {"window": window},
            )
            for window, p95 in p95_by_window.items()
        ],
        ignore_index=True,
    )


def test_crt_window_reads_the_window_from_the_overrides_column() -> None:
    # the default rows sit at L = 10 only if the window comes from the Config default
    row = _verdict(_windows({2: 4.0, 5: 3.0, 10: 2.0, 20: 1.0}), "crt_window")
    assert row["holds"] == "holds" and row["measured"] == pytest.approx(-1.0)
    assert "L=10: 2.00 m" in row["note"] and "L=20: 1.00 m" in row["note"]
    row = _verdict(_windows({2: 1.0, 5: 2.0, 10: 3.0, 20: 4.0}), "crt_window")
    assert row["holds"] == "does not hold" and row["measured"] == pytest.approx(1.0)
    # a label that disagrees with the overrides is not read: the verdict follows the structured column
    relabelled = _windows({2: 4.0, 5: 3.0, 10: 2.0, 20: 1.0}).assign(variant="window=99")
    assert _verdict(relabelled, "crt_window")["measured"] == pytest.approx(-1.0)
    assert _verdict(_windows({5: 3.0, 10: 2.0}), "crt_window")["holds"] == "not measured"  # 2 windows: no trend


def test_convergence_statistics_use_the_first_15_minutes_only() -> None:
    from simbench.analysis.tables import convergence_statistics

    t = np.arange(1800.0)
    rows = [
        pd.DataFrame(
            {
                "estimator": name,
                "variant": "",
                "overrides": "{}",
                "seed": seed,
                "t": t,
                "error_3d": np.where(t < 900.0, early + seed, 0.1),
            }
        )
        for name, early in (("slow", 2.0), ("fast", 1.0))
        for seed in range(3)
    ]
    table = convergence_statistics(pd.concat(rows)).set_index("estimator")
    assert table.loc["slow", "error_3d_mean"] == 3.0 and table.loc["fast", "error_3d_mean"] == 2.0
    assert table.loc["slow", "error_3d_max"] == 3.0 and table.loc["slow", "n_seeds"] == 3
    short = pd.concat(rows).query("t < 1200")
    assert convergence_statistics(short).empty


def _on(world: str, rows: pd.DataFrame) -> pd.DataFrame:
    return rows.assign(scenario=world)


def test_each_claim_gets_one_verdict_per_world_from_that_worlds_rows_alone() -> None:
    from simbench.analysis.claims import NOT_RUN, claims_by_world

    summary = pd.concat(
        [
            _on("urban", _rows("ch5_bce", _scaled(bce=0.7, l2=1.0, dcs=1.1, mm=0.9))),
            _on("morgantown1", _rows("ch5_bce", _scaled(bce=1.2, l2=1.0, dcs=1.1, mm=0.9))),
            _on(
                "flight",
                _rows(
                    "ch4_convergence",
                    _scaled(isam2_ppp=1.05, ekf_ppp=1.0),
                    "error_3d_median",
                    overrides={"ionosphere": "free"},
                ),
            ),
        ],
        ignore_index=True,
    )
    epochs = _convergence_epochs(0.25, 1.0).assign(scenario="flight")
    table = claims_table(summary, epochs, {}).set_index(["claim_id", "world"])
    assert table.loc[("ch5_bce_low", "urban"), "holds"] == "holds"
    assert table.loc[("ch5_bce_low", "urban"), "measured"] == pytest.approx(0.7 / 0.9)
    assert table.loc[("ch5_bce_low", "morgantown1"), "holds"] == "does not hold"
    assert table.loc[("ch5_bce_low", "morgantown1"), "measured"] == pytest.approx(1.2 / 0.9)
    assert table.loc[("ch5_bce_low", "urban"), "n_seeds"] == len(BASE)  # not pooled with the other world
    assert table.loc[("ch4_convergence", "flight"), "measured"] == pytest.approx(0.25)
    # the high receiver did not run: measured nowhere, but the world is named
    assert table.loc[("ch5_high_comparable", "urban"), "holds"] == "not measured"
    assert table.loc[("ch7_ice_low", ""), "holds"] == "not measured"  # its sweep ran on no world

    wide = claims_by_world(claims_table(summary, epochs, {})).set_index("claim_id")
    assert list(wide.columns) == ["published", "rule", "flight", "morgantown1", "urban"]
    assert wide.loc["ch5_bce_low", "urban"].startswith("0.778 [") and wide.loc["ch5_bce_low", "urban"].endswith(
        "] holds"
    )
    assert wide.loc["ch5_bce_low", "morgantown1"].endswith("does not hold")
    assert wide.loc["ch5_bce_low", "flight"] == NOT_RUN and wide.loc["ch4_overall_median", "urban"] == NOT_RUN
    assert wide.loc["ch4_overall_median", "flight"] == "1.05 [1.05, 1.05] holds"
    assert (wide.loc["ch7_ice_low", ["flight", "morgantown1", "urban"]] == NOT_RUN).all()


def test_diagnostics_and_prior_scales_are_split_by_world() -> None:
    def jobs(world: str, adaptations: int, naive: int) -> list[dict]:
        diag = {"n_adaptations": adaptations, "naive_adaptations": naive}
        return [{"job": {"sweep": "ch7_ice", "scenario": world}, "diagnostics": diag}] * 2

    flat = _on(
        "urban",
        _sensitivity({"bce": [5.0, 5.0, 5.0], "l2": [4.0, 5.0, 8.0], "dcs": [5.0, 6.0, 7.0], "mm": [5.0, 5.5, 6.0]}),
    )
    steep = _on(
        "urban_deep",
        _sensitivity({"bce": [3.0, 5.0, 9.0], "l2": [4.0, 5.0, 8.0], "dcs": [5.0, 6.0, 7.0], "mm": [5.0, 5.5, 6.0]}),
    )
    ice = pd.concat([_on(w, _rows("ch7_ice", _scaled(ice=1.0))) for w in ("urban", "urban_deep")])
    table = claims_table(
        pd.concat([flat, steep, ice], ignore_index=True),
        NO_EPOCHS,
        {"ice": jobs("urban", 3, 12) + jobs("urban_deep", 12, 12)},
    ).set_index(["claim_id", "world"])
    assert table.loc[("ch5_sensitivity", "urban"), "measured"] == pytest.approx(1.0 / 1.2)
    assert table.loc[("ch5_sensitivity", "urban_deep"), "measured"] == pytest.approx(3.0 / 1.2)
    assert table.loc[("ch7_adaptations", "urban"), "measured"] == pytest.approx(0.25)
    assert table.loc[("ch7_adaptations", "urban"), "holds"] == "holds"
    assert table.loc[("ch7_adaptations", "urban_deep"), "holds"] == "does not hold"
