"""Claims evaluated on hand-made result rows: the numbers and the holds/does-not-hold rule."""
from __future__ import annotations

import numpy as np
import pandas as pd

from estimators.ice import AdaptiveNoiseModel, IceConfig
from simbench.claims import adaptation_outcome, claims_table


def _summary(medians: dict[str, list[float]], sweep: str = "ch5_bce", receiver: str = "low") -> pd.DataFrame:
    rows = [{"sweep": sweep, "scenario": "urban", "receiver": receiver, "seed": seed, "estimator": name,
             "variant": "", "status": "ok", "horizontal_median": value, "time_per_obs_s": 1e-4}
            for name, values in medians.items() for seed, value in enumerate(values)]
    return pd.DataFrame(rows)


NO_EPOCHS = pd.DataFrame(columns=["sweep", "t", "estimator", "seed", "error_3d"])


def test_bce_claim_holds_only_when_bce_is_clearly_lower() -> None:
    rng = np.random.default_rng(0)
    base = 5.0 + rng.normal(0, 0.3, 20)
    lower = _summary({"bce": list(base * 0.7), "l2": list(base), "dcs": list(base * 1.1), "mm": list(base * 0.9)})
    row = claims_table(lower, NO_EPOCHS).set_index("claim_id").loc["ch5_bce_low"]
    assert row["holds"] == "holds"
    assert abs(row["measured"] - 0.7 / 0.9) < 1e-9 and row["ci_high"] < 1.0
    same = _summary({"bce": list(base), "l2": list(base * 1.01), "dcs": list(base * 1.1), "mm": list(base)})
    row = claims_table(same, NO_EPOCHS).set_index("claim_id").loc["ch5_bce_low"]
    assert row["holds"] == "does not hold"


def test_adaptation_claim_reads_the_ice_diagnostics() -> None:
    model = AdaptiveNoiseModel(IceConfig(cluster_threshold=99))
    model.n_residuals = 1000
    diag = model.diagnostics()  # no adaptation, 1000 // 100 = 10 naive ones
    jobs = {"ice": [{"job": {"sweep": "ch7_ice"}, "diagnostics": diag}] * 3}
    out = adaptation_outcome(jobs)
    assert out is not None and out.measured == 0.0 and out.holds and "0 adaptations vs 30 naive" in out.note
    assert adaptation_outcome({"ice": [{"job": {"sweep": "smoke"}, "diagnostics": diag}]}) is None


def test_convergence_statistics_use_the_first_15_minutes_only() -> None:
    from simbench.tables import convergence_statistics

    t = np.arange(1800.0)
    rows = [pd.DataFrame({"estimator": name, "variant": "", "seed": seed, "t": t,
                          "error_3d": np.where(t < 900.0, early + seed, 0.1)})
            for name, early in (("slow", 2.0), ("fast", 1.0)) for seed in range(3)]
    table = convergence_statistics(pd.concat(rows)).set_index("estimator")
    assert table.loc["slow", "error_3d_mean"] == 3.0 and table.loc["fast", "error_3d_mean"] == 2.0
    assert table.loc["slow", "error_3d_max"] == 3.0 and table.loc["slow", "n_seeds"] == 3
    short = pd.concat(rows).query("t < 1200")
    assert convergence_statistics(short).empty
