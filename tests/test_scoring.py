"""Fair scoring over reference epochs, real logs labelled by their source, claims only where measured.

Hand-made errors where one estimator skips the hard epochs: its ECDF must end
at its availability and its percentiles over reference epochs must not beat
the estimator that solved everything with larger errors on the hard epochs.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from simbench.analysis.claims import CLAIMS, claims_table
from simbench.analysis.metrics import reference_ecdf, reference_percentile, reference_stats, summary_stats
from simbench.analysis.tables import data_label, seed_statistics
from simbench.data.librsf import load_librsf
from simbench.errors import SimbenchError
from simbench.report.build import UNDEFINED, build_report
from simbench.report.figures import ecdf_figure
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS, run_estimators

LIBRSF_FIXTURE = Path(__file__).resolve().parent / "data" / "librsf_small.txt"
N_REFERENCE = 100
#: Solves all 100 reference epochs: 1 m on the 80 easy ones, 10 m on the 20 hard ones.
SOLVER = np.r_[np.full(80, 1.0), np.full(20, 10.0)]
#: Solves only the 80 easy epochs, better there (0.5 m), and skips the hard ones.
SKIPPER = np.full(80, 0.5)
SOLVER_NAME, SKIPPER_NAME = "l2", "dcs"


def test_skipping_hard_epochs_is_not_rewarded() -> None:
    # over its solved epochs alone the skipper looks better at every percentile
    assert summary_stats(SKIPPER, "h")["h_p95"] == 0.5 < summary_stats(SOLVER, "h")["h_p95"] == 10.0
    x, p = reference_ecdf(SKIPPER, N_REFERENCE)
    assert x[-1] == 0.5 and p[-1] == pytest.approx(0.8)  # the curve stops at its availability
    x, p = reference_ecdf(SOLVER, N_REFERENCE)
    assert list(x) == [1.0, 10.0] and p == pytest.approx([0.8, 1.0])
    assert reference_percentile(SOLVER, N_REFERENCE, 95) == 10.0
    assert reference_percentile(SKIPPER, N_REFERENCE, 95) == np.inf  # not reached: no better than the solver
    assert reference_percentile(SKIPPER, N_REFERENCE, 80) == 0.5
    assert reference_percentile(SKIPPER, N_REFERENCE, 81) == np.inf
    # where both reach the percentile the comparison is a fair one
    assert reference_percentile(SKIPPER, N_REFERENCE, 50) == 0.5 < reference_percentile(SOLVER, N_REFERENCE, 50)
    # a non-finite error is an unsolved epoch
    assert reference_stats(np.r_[SKIPPER, np.full(20, np.nan)], N_REFERENCE, "h") == {
        "h_median_ref": 0.5,
        "h_p95_ref": np.inf,
    }


def test_every_epoch_solved_gives_numpys_inverted_cdf_percentile() -> None:
    v = np.random.default_rng(1).lognormal(0.0, 1.0, 37)
    for q in (1, 5, 50, 95, 100):
        assert reference_percentile(v, v.size, q) == np.percentile(v, q, method="inverted_cdf")
    assert reference_percentile(v, 2 * v.size, 50) == v.max()  # half the reference epochs solved
    assert np.isnan(reference_percentile(np.empty(0), 0, 50))


def test_more_solved_than_reference_epochs_is_one_line_error() -> None:
    with pytest.raises(SimbenchError, match="^n_reference: is 10, fewer than the 80 solved epochs"):
        reference_percentile(SKIPPER, 10, 50)
    with pytest.raises(SimbenchError, match="no reference epoch count for skipper"):
        ecdf_figure(
            pd.DataFrame({"estimator": "skipper", "horizontal": SKIPPER}),
            ["horizontal"],
            Path("/nonexistent/x.png"),
            "t",
            {},
        )


def _run(source: str, scenario: str, seeds: int = 2) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Summary and epoch rows of the solver and the skipper on ``seeds`` identical seeds.

    They carry the names of registered estimators: the report looks their configs up.
    """
    rows, frames = [], []
    for seed in range(seeds):
        for name, errors in ((SOLVER_NAME, SOLVER), (SKIPPER_NAME, SKIPPER)):
            key = {
                "sweep": "",
                "scenario": scenario,
                "source": source,
                "receiver": "low",
                "seed": seed,
                "scenario_key": f"k{seed}",
                "estimator": name,
                "gnss_model": "urban",
                "variant": "",
                "overrides": "{}",
            }
            rows.append(
                {
                    **key,
                    "uses_labels": False,
                    "status": "ok",
                    "message": "",
                    "n_epochs": N_REFERENCE,
                    "n_solved": errors.size,
                    "availability": errors.size / N_REFERENCE,
                    **summary_stats(errors, "horizontal"),
                    **summary_stats(errors, "error_3d"),
                    **reference_stats(errors, N_REFERENCE, "horizontal"),
                    **reference_stats(errors, N_REFERENCE, "error_3d"),
                    "total_s": 1.0,
                    "time_per_obs_s": 1e-4,
                    "update_median_s": 1e-3,
                    "update_p95_s": 2e-3,
                }
            )
            epoch = np.arange(errors.size)
            frames.append(
                pd.DataFrame(
                    {
                        **key,
                        "epoch": epoch,
                        "t": epoch.astype(float),
                        "e": errors,
                        "n": 0.0,
                        "u": 0.0,
                        "horizontal": errors,
                        "error_3d": errors,
                        "update_s": 1e-3,
                    }
                )
            )
    return (
        pd.DataFrame(rows, columns=list(SUMMARY_COLUMNS)),
        pd.concat(frames, ignore_index=True).reindex(columns=list(EPOCH_COLUMNS)),
    )


def test_statistics_over_seeds_put_availability_beside_the_reference_percentiles() -> None:
    summary, _ = _run("simulated", "urban")
    stats = seed_statistics(summary).set_index("estimator")
    assert stats.loc[SKIPPER_NAME, "availability"] == pytest.approx(0.8)
    assert stats.loc[SKIPPER_NAME, "horizontal_p95_ref"] == np.inf
    assert stats.loc[SOLVER_NAME, "horizontal_p95_ref"] == 10.0 and stats.loc[SOLVER_NAME, "availability"] == 1.0
    assert stats.loc[SKIPPER_NAME, "horizontal_median_ref"] == 0.5
    assert stats.loc[SKIPPER_NAME, "horizontal_median_solved"] == 0.5  # shown, but labelled as solved-only


def test_a_real_log_report_is_labelled_by_source_and_has_no_claims_table_on_top(tmp_path: Path) -> None:
    summary, epochs = _run("rinex", "hk_tst_2019", seeds=1)
    claims = claims_table(summary, epochs)
    assert (claims["holds"] == "not measured").all()
    assert "its sweep ch5_bce was not run" in claims.set_index("claim_id").loc["ch5_bce_low", "note"]
    html = (build_report(tmp_path, summary, epochs, claims, {}) / "index.html").read_text()
    md = (tmp_path / "report" / "README.md").read_text()
    assert "hk_tst_2019 (real log, RINEX)" in html and "low receiver" not in html
    figures = {f.name for f in (tmp_path / "report").glob("*.png")}
    assert "ecdf_hk_tst_2019_rinex.png" in figures and not any("low" in f for f in figures)
    # no claim measured: no claims section at all (claims.csv lists them), not a line of twelve unmeasured
    assert "Published claims" not in html and "published claims not measured" not in html
    assert CLAIMS[0].statement not in html
    # the skipper's undefined p95 is shown as such in both formats
    skipper_row = next(line for line in md.splitlines() if line.startswith(f"| {SKIPPER_NAME} "))
    assert UNDEFINED in skipper_row and "inf" not in skipper_row
    assert html.count(f"<td class='num lb'>{UNDEFINED}</td>") == 2  # its horizontal and 3-D p95


def test_measured_claims_keep_the_table_on_top(tmp_path: Path) -> None:
    base = 5.0 + np.random.default_rng(0).normal(0, 0.3, 6)
    summary = pd.DataFrame(
        [
            {
                "sweep": "ch6_bce_ad",
                "scenario": "urban",
                "source": "simulated",
                "receiver": "low",
                "seed": seed,
                "estimator": name,
                "overrides": "{}",
                "variant": "",
                "uses_labels": False,
                "status": "ok",
                "horizontal_median": base[seed] * f,
            }
            for name, f in (("bce_ad", 0.7), ("bce", 1.0))
            for seed in range(6)
        ],
        columns=list(SUMMARY_COLUMNS),
    )
    claims = claims_table(summary, pd.DataFrame(columns=list(EPOCH_COLUMNS)))
    html = (
        build_report(tmp_path, summary, pd.DataFrame(columns=list(EPOCH_COLUMNS)), claims, {}) / "index.html"
    ).read_text()
    # right after the leaderboard, before any group's figures
    headings = re.findall(r"<h2[^>]*>(.*?)</h2>", html)
    assert headings[:2] == ["Leaderboard", "Published claims"] and headings.count("Published claims") == 1
    ch6 = next(c for c in CLAIMS if c.claim_id == "ch6_bce_ad")
    assert ch6.statement in html and CLAIMS[0].statement not in html
    assert f"{len(CLAIMS) - 1} of {len(CLAIMS)} published claims not measured" in html


def test_simulated_groups_keep_the_receiver_label() -> None:
    assert data_label("urban", "low", "simulated") == "urban, low receiver"
    assert data_label("urban", "high", None) == "urban, high receiver"  # results from before the column
    assert data_label("smartloc", "low", "librsf") == "smartloc (real log, libRSF)"


def test_a_real_log_run_records_its_source_and_reference_epochs() -> None:
    scenario = load_librsf(LIBRSF_FIXTURE, gps_week=2032, start_sow_s=475_200.0)
    result = run_estimators(scenario, {"l2": {}}, receiver="low", progress=False)
    row = result.summary.iloc[0]
    assert row["status"] == "ok" and row["source"] == "librsf"
    assert row["n_epochs"] == len(scenario.truth) > 0
    assert row["availability"] == pytest.approx(row["n_solved"] / len(scenario.truth))
    assert set(result.epochs["source"]) == {"librsf"}
    assert row["horizontal_median_ref"] == reference_percentile(result.epochs["horizontal"], len(scenario.truth), 50)
