"""The report of a small run under the default gnss_model: nothing dropped, leaderboard first, time views.

One module-scoped run (60 s of the urban drive, four estimators, and a second variant of DCS
added to the same results_dir) feeds every test here; figures are checked from the series the
report reads back from each drawn figure (``report/figures.json``), not from pixels.
"""

from __future__ import annotations

import json
import re
import shutil
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from estimators.base import COVARIANCE_COLUMNS
from simbench.report import build, group_figures
from simbench.report.build import finalize
from simbench.report.leaderboard import leaderboard
from simbench.report.style import sig3
from simbench.runs.compose import compose_config
from simbench.runs.jobs import run_job

ESTIMATORS = ["l2", "dcs", "ekf_ins", "oracle"]
#: Every variant that ran, as the report names it: DCS twice, the oracle marked as a label reader.
NAMES = {"l2", "dcs", "dcs[prior_scale=10.0]", "ekf_ins", "oracle†"}
#: Figures that show a subset by design: only estimators with a position covariance.
SUBSET_FIGURES = ("consistency_",)


def run_into(root: Path, *overrides: str) -> None:
    """One job of the default config (gnss_model=urban) into ``root``, without a report (built once, below)."""
    run_job(compose_config(["scenario.duration_s=60", f"results_dir={root}", "progress=false", *overrides]))


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("report") / "run"
    run_into(root, f"estimator=[{','.join(ESTIMATORS)}]")
    # a second variant of one estimator, into the same folder: the report must show both
    run_into(root, "estimator=[dcs]", "estimator.dcs.prior_scale=10.0")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a matplotlib warning would reach the terminal
        finalize(root, None, formats=("png", "pdf"))
    return root


@pytest.fixture(scope="module")
def figures(run_dir: Path) -> list[dict]:
    return json.loads((run_dir / "report" / "figures.json").read_text())


@pytest.fixture(scope="module")
def page(run_dir: Path) -> str:
    return (run_dir / "report" / "index.html").read_text()


def test_the_run_is_under_the_default_gnss_model_and_has_two_dcs_variants(run_dir: Path) -> None:
    summary = pd.read_parquet(run_dir / "summary.parquet")
    assert set(summary["gnss_model"]) == {"urban"} and (summary["status"] == "ok").all()
    assert sorted(summary.loc[summary["estimator"] == "dcs", "overrides"]) == ['{"prior_scale":10.0}', "{}"]


def test_every_variant_is_in_every_figure(figures: list[dict]) -> None:
    kinds = {re.sub(r"_urban_low$", "", Path(f["file"]).stem) for f in figures}
    assert {"ecdf", "box", "trajectory", "enu_time", "signal_time", "runtime"} <= kinds
    for figure in figures:
        if figure["file"].startswith(SUBSET_FIGURES):
            continue
        assert NAMES <= set(figure["series"]), figure["file"]
        # a short tag, never the override JSON
        assert not any("{" in s or '"' in s for s in figure["series"]), figure["file"]


def test_the_consistency_figure_holds_the_estimators_with_a_covariance(figures: list[dict], page: str) -> None:
    consistency = next(f for f in figures if f["file"].startswith("consistency_"))
    assert consistency["series"] == ["ekf_ins"]
    assert "No position covariance (so no consistency check) from: dcs, dcs[prior_scale=10.0], l2, oracle†" in page


def test_every_variant_is_in_every_table(run_dir: Path, page: str) -> None:
    tables = re.findall(r"<table[^>]*>(.*?)</table>", page, flags=re.S)
    first_cells = [re.findall(r"<tr[^>]*><td[^>]*>(.*?)</td>", t) for t in tables]
    names_html = {n.replace("†", "†") for n in NAMES}
    leaderboard_rows, statistics_rows = first_cells[0], first_cells[1]
    assert set(leaderboard_rows) == names_html and set(statistics_rows) == names_html
    paired = next(rows for rows in first_cells if rows and set(rows) == names_html - {"l2"})
    gap = next(rows for rows in first_cells if rows and set(rows) == names_html - {"oracle†"})
    assert paired and gap


def _leaderboard(page: str) -> list[list[str]]:
    """The leaderboard's rows as cell texts (a CI on its second line joined with a space)."""
    table = re.search(r"<table id='leaderboard-table'>(.*?)</table>", page, flags=re.S)
    assert table is not None
    rows = re.findall(r"<tr[^>]*>(.*?)</tr>", table.group(1), flags=re.S)[1:]
    cells = [re.findall(r"<td[^>]*>(.*?)</td>", r, flags=re.S) for r in rows]
    return [[re.sub(r"<br><small>", " ", c).replace("</small>", "") for c in row] for row in cells]


def test_leaderboard_comes_first_sorted_by_the_legends_median(run_dir: Path, page: str, figures: list[dict]) -> None:
    assert page.index("class='provenance'") < page.index("id='leaderboard-table'") < page.index("<figure>")
    assert page.index("id='leaderboard-table'") < page.index("<details>")
    rows = _leaderboard(page)
    summary = pd.read_parquet(run_dir / "summary.parquet")
    medians = summary.groupby(["estimator", "overrides"])["horizontal_median_ref"].mean()
    oracle = summary.loc[summary["estimator"] == "oracle", "horizontal_median_ref"].mean()
    # sorted by median, the oracle (an accuracy floor) ranked apart at the end; one seed: a CI over epochs
    shown = [r[4].split(" [")[0] for r in rows]
    assert shown == [sig3(v) for v in sorted(medians[medians != oracle])] + [sig3(oracle)]
    assert rows[-1][0] == "oracle†" and all(" [" in r[4] for r in rows)
    family = {r[0]: r[1] for r in rows}
    assert family["ekf_ins"] == "GNSS/INS" and family["l2"] == "batch" and family["oracle†"] == "oracle"
    # the ECDF legend prints the leaderboard's medians (horizontal / 3-D), not other ones, in its order
    ecdf = next(f for f in figures if f["file"].startswith("ecdf_"))
    legend = ecdf["legend"]
    assert [t.split(" (")[0] for t in legend] == [r[0] for r in rows]
    for name, median in ((r[0], r[4].split(" [")[0]) for r in rows):
        assert any(t.startswith(f"{name} (") and f", median {median} / " in t for t in legend), name


def test_leaderboard_cells_have_three_significant_digits_and_units_in_headers() -> None:
    stats = pd.DataFrame(
        {
            "name": ["a", "b"],
            "estimator": ["l2", "dcs"],
            "n_seeds": [3, 3],
            "availability": [0.9983, 1.0],
            "horizontal_median_ref": [2.664, np.inf],
            "ci_low": [2.1, np.nan],
            "ci_high": [3.0412, np.nan],
            **{
                f"{c}{s}": [1.0, 2.0]
                for c in ("horizontal_p95_ref", "error_3d_median_ref", "error_3d_p95_ref")
                for s in ("", "_ci_low", "_ci_high")
            },
            "time_per_epoch_s": [2.664e-05, np.nan],
        }
    )
    table = leaderboard(stats)
    assert list(table["estimator"]) == ["a", "b"]  # undefined (inf) medians last
    row = table.iloc[0]
    assert row["availability [%]"] == "99.8" and row["horizontal median [m]"] == "2.66 [2.10, 3.04]"
    assert row["time per epoch [ms]"] == "0.0266" and table.iloc[1]["horizontal median [m]"] == "—"
    assert all(re.search(r"\[(m|%|ms)\]$", c) for c in table.columns[3:])


def test_provenance_box_says_what_ran_and_with_which_code(page: str) -> None:
    box = page[page.index("class='provenance'") : page.index("</dl>")]
    for item in ("urban", "low", "60.0 s", "gnss_model", "git SHA", "numpy", "seeds", "prior_scale"):
        assert item in box, item


def test_epochs_store_positions_and_the_ekf_covariance(run_dir: Path) -> None:
    epochs = pd.read_parquet(run_dir / "epochs.parquet")
    ekf, l2 = epochs[epochs["estimator"] == "ekf_ins"], epochs[epochs["estimator"] == "l2"]
    # the local frame starts at the first reference point: the drive stays within a few hundred metres
    assert l2[["east", "north", "up"]].abs().max().max() < 500 and np.isfinite(l2[["x", "y", "z"]]).all().all()
    assert np.hypot(l2["x"], l2["y"]).min() > 4e6  # ECEF, not local
    assert l2[list(COVARIANCE_COLUMNS)].isna().all().all() and l2["nees"].isna().all()
    assert ekf[list(COVARIANCE_COLUMNS)].notna().all().all() and (ekf["cov_xx"] > 0).all()
    assert (ekf["nees"] > 0).all()
    # NEES from the stored columns: d^T P^-1 d, with d the ECEF error rebuilt from the local ENU error
    row = ekf.iloc[10]
    P = np.array([[row[f"cov_{a}{b}" if a <= b else f"cov_{b}{a}"] for b in "xyz"] for a in "xyz"])
    lat, lon = np.radians(39.63), np.radians(-79.96)  # the urban drive's origin; the error frame is local
    R = np.array(
        [
            [-np.sin(lon), np.cos(lon), 0.0],
            [-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)],
            [np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)],
        ]
    )
    d = R.T @ row[["e", "n", "u"]].to_numpy(float)
    assert row["nees"] == pytest.approx(d @ np.linalg.solve(P, d), rel=1e-3)


def test_pdf_figures_are_written_beside_the_png(run_dir: Path, figures: list[dict]) -> None:
    for figure in figures:
        assert figure["files"] == [figure["file"], figure["file"].replace(".png", ".pdf")]
        assert (run_dir / "report" / figure["files"][1]).read_bytes()[:4] == b"%PDF"


def test_no_blank_cell_and_no_nan_text(page: str) -> None:
    text = re.sub(r"<[^>]+>", " ", page)
    assert not re.search(r"\b(nan|NaN|None)\b", text)
    assert "<td></td>" not in page and "<td class='num'></td>" not in page
    # one seed: no CI over seeds, an interval over the run's epochs instead, and the page says which
    assert "block bootstrap over the run's reference epochs" in page and "CI over seeds (3 or more" not in page


def test_worker_processes_draw_the_figures_drawn_in_process(
    run_dir: Path, figures: list[dict], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A large run's figures are drawn by spawned workers (:class:`GroupDrawing`): same files, series, legends."""
    started: list[bool] = []

    class Recorded(group_figures.GroupDrawing):
        def __init__(self, parallel: bool) -> None:
            started.append(parallel)
            super().__init__(parallel)

    monkeypatch.setattr(build, "GroupDrawing", Recorded)
    monkeypatch.setattr(build, "MIN_PARALLEL_GROUPS", 1)
    monkeypatch.setattr(group_figures, "MIN_PARALLEL_GROUPS", 1)
    copy = tmp_path / "run"
    shutil.copytree(run_dir, copy)
    finalize(copy, None, formats=("png", "pdf"))
    assert started == [True]
    drawn = json.loads((copy / "report" / "figures.json").read_text())
    assert drawn == figures
