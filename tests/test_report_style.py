"""Issue 46's style and numbers without a run: one colour per estimator name, TrueType fonts, paper sizes,
RMSE and intervals over epochs, the leaderboard as LaTeX, CSV and terminal text, the report's own settings."""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from estimators import built_in, registered
from simbench.analysis.metrics import block_bootstrap, block_length, reference_percentiles, rmse, row_rmse
from simbench.analysis.tables import epoch_intervals, with_rmse
from simbench.cli.report import report_settings
from simbench.errors import SimbenchError
from simbench.report.figures import ecdf_figure, log_ticks
from simbench.report.group_figures import shown_seeds
from simbench.report.leaderboard import leaderboard, terminal_summary, to_csv, to_latex
from simbench.report.style import (
    ESTIMATOR_COLORS,
    PRESETS,
    REFERENCE_COLOR,
    curve_styles,
    estimator_color,
    families,
    sig3,
    use_style,
)
from simbench.report.time_views import error_segments
from simbench.runs.checks import REPORT_STYLES


def _epochs(names: list[str], n: int = 200) -> tuple[pd.DataFrame, dict[str, int]]:
    rng = np.random.default_rng(1)
    rows = [
        pd.DataFrame(
            {
                "estimator": name,
                "horizontal": rng.lognormal(k * 0.3, 1.0, n),
                "error_3d": rng.lognormal(k * 0.3 + 0.5, 1.0, n),
            }
        )
        for k, name in enumerate(names)
    ]
    return pd.concat(rows, ignore_index=True), dict.fromkeys(names, n)


def test_every_built_in_estimator_has_its_own_colour_and_the_reference_none() -> None:
    names = sorted(registered())
    colors = [estimator_color(n) for n in names]
    assert len(set(colors)) == len(colors), dict(zip(names, colors))
    assert REFERENCE_COLOR not in colors and set(ESTIMATOR_COLORS) <= set(names)
    assert set(built_in()) <= set(ESTIMATOR_COLORS)  # a built-in's colour is chosen, not hashed
    of = families(names)
    assert of["oracle"] == "oracle" and of["huber_spp"] == of["wls_spp"] == of["rtklib_spp"] == "SPP baselines"


def test_a_colour_depends_on_the_name_not_on_which_estimators_ran() -> None:
    few = curve_styles({"rtklib_spp": "rtklib_spp", "l2": "l2"})
    many = curve_styles({n: n for n in registered()} | {"dcs[prior_scale=10]": "dcs"})
    for name in few:
        assert few[name] == many[name], name
    # a second variant keeps its estimator's colour and marker, with a line style of its own
    assert many["dcs[prior_scale=10]"]["color"] == many["dcs"]["color"]
    assert many["dcs[prior_scale=10]"]["linestyle"] != many["dcs"]["linestyle"]


def test_figures_record_each_series_colour_and_embed_no_type3_font(tmp_path, caplog) -> None:
    caplog.set_level(logging.INFO)  # as under Hydra: the font subsetting must not log a line per table
    first, n_first = _epochs(["l2", "rtklib_spp", "oracle†"])
    second, n_second = _epochs(["rtklib_spp", "wls_spp", "crt_lss", "l2"])
    a = ecdf_figure(first, ["horizontal"], tmp_path / "a.png", "a", n_first, formats=("png", "pdf", "svg"))
    b = ecdf_figure(second, ["horizontal"], tmp_path / "b.png", "b", n_second, formats=("png", "pdf"))
    assert a.styles["rtklib_spp"]["color"] == b.styles["rtklib_spp"]["color"] == ESTIMATOR_COLORS["rtklib_spp"].lower()
    assert a.styles["l2"] == b.styles["l2"] and a.styles["oracle†"]["color"] == ESTIMATOR_COLORS["oracle"].lower()
    pdf = (tmp_path / "a.pdf").read_bytes()
    assert b"/Subtype /Type3" not in pdf and b"/FontFile2" in pdf  # TrueType embedded, no Type 3
    assert b"<text" in (tmp_path / "a.svg").read_bytes()  # SVG keeps text as text
    assert Image.open(tmp_path / "a.png").info["dpi"][0] == pytest.approx(300, abs=1)
    assert not [r for r in caplog.records if r.name.startswith("fontTools")]


@pytest.mark.parametrize("style", ["single", "double"])
def test_paper_presets_give_figures_a_column_wide(tmp_path, style: str) -> None:
    epochs, n = _epochs(sorted(registered())[:10])
    with use_style(style):
        figure = ecdf_figure(epochs, ["horizontal", "error_3d"], tmp_path / "e.png", "e", n)
    width_in = Image.open(figure.path).size[0] / 300
    assert 0.7 * PRESETS[style].width_in <= width_in <= 1.05 * PRESETS[style].width_in, width_in
    assert tuple(PRESETS) == REPORT_STYLES


def test_log_axes_label_decades_only_when_they_span_several() -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.set_xscale("log")
    ax.set_xlim(1e-2, 300)
    log_ticks(ax.xaxis)
    fig.canvas.draw()
    ticks = [*ax.xaxis.get_major_ticks(), *ax.xaxis.get_minor_ticks()]
    labels = [t.label1.get_text() for t in ticks if t.label1.get_text() and 1e-2 <= t.get_loc() <= 300]
    plt.close(fig)
    assert len(labels) == 5 and all("times" not in t for t in labels), labels  # 10^-2 ... 10^2


def test_rmse_is_the_root_mean_square_of_the_solved_epochs() -> None:
    values = np.array([3.0, 4.0, np.nan, 12.0])
    assert rmse(values) == pytest.approx(np.sqrt((9 + 16 + 144) / 3))
    summary = pd.DataFrame(
        {
            "sweep": "",
            "scenario_key": "k",
            "estimator": ["l2", "dcs"],
            "gnss_model": "urban",
            "overrides": "{}",
            "status": "ok",
        }
    )
    epochs = pd.DataFrame(
        {
            "sweep": "",
            "scenario_key": "k",
            "estimator": ["l2", "l2", "dcs"],
            "gnss_model": "urban",
            "overrides": "{}",
            "horizontal": [3.0, 4.0, 1.0],
            "error_3d": [6.0, 8.0, 2.0],
        }
    )
    out = with_rmse(summary, epochs).set_index("estimator")
    assert out.loc["l2", "horizontal_rmse"] == pytest.approx(np.sqrt(12.5))
    assert out.loc["l2", "error_3d_rmse"] == pytest.approx(np.sqrt(50.0)) and out.loc["dcs", "horizontal_rmse"] == 1.0


def test_block_bootstrap_holds_the_statistic_and_widens_with_correlation() -> None:
    rng = np.random.default_rng(3)
    white = rng.normal(0, 1, 2000)
    slow = np.convolve(rng.normal(0, 1, 2100), np.ones(100) / 10, mode="valid")[:2000]
    assert block_length(white) < 20 < block_length(slow)
    errors = np.abs(slow) + 0.1
    stats = {"median": lambda s: reference_percentiles(s, 50.0), "rmse": row_rmse}
    ci = block_bootstrap(errors, stats, resamples=500)
    assert ci["median"][0] < np.median(errors) < ci["median"][1]
    assert ci["rmse"][0] < rmse(errors) < ci["rmse"][1]
    assert ci == block_bootstrap(errors, stats, resamples=500)  # seeded: the same interval every build
    iid = block_bootstrap(rng.permutation(errors), stats, resamples=500)
    assert np.diff(ci["median"])[0] > np.diff(iid["median"])[0]  # correlated epochs: a wider interval
    # an unsolved epoch is an infinite error: a percentile its resamples may not reach is undefined, not 0
    missing = np.r_[errors[:900], np.full(1100, np.inf)]
    assert np.isnan(block_bootstrap(missing, stats, resamples=200)["median"]).all()


def _stats() -> pd.DataFrame:
    names = ["l2", "oracle†", "dcs"]
    return pd.DataFrame(
        {
            "name": names,
            "estimator": ["l2", "oracle", "dcs"],
            "n_seeds": 1,
            "availability": [1.0, 1.0, 0.9],
            "horizontal_median_ref": [2.0, 0.5, 1.0],
            "ci_low": [1.5, np.nan, 0.8],
            "ci_high": [2.5, np.nan, 1.2],
            **{
                f"{c}{s}": [3.0, 1.0, 2.0]
                for c in ("horizontal_p95_ref", "error_3d_median_ref", "error_3d_p95_ref", "error_3d_rmse")
                for s in ("", "_ci_low", "_ci_high")
            },
            "horizontal_rmse": [2.2345, 0.7, 1.5],
            "horizontal_rmse_ci_low": np.nan,
            "horizontal_rmse_ci_high": np.nan,
            "time_per_epoch_s": 1e-3,
        }
    )


def test_the_leaderboard_ranks_the_oracle_apart_and_exports_latex_csv_and_terminal(tmp_path) -> None:
    table = leaderboard(_stats())
    assert list(table["estimator"]) == ["dcs", "l2", "oracle†"]  # the floor last, whatever its median
    assert table.loc[1, "horizontal RMSE [m]"] == sig3(2.2345) == "2.23"
    boards = [("urban, low receiver", table)]
    tex = to_latex(boards, "note")
    assert "\\toprule" in tex and "\\bottomrule" in tex and "l2 & 100 & 2.00 & 3.00 & 2.23" in tex
    assert tex.index("dcs &") < tex.rindex("\\midrule") < tex.index("oracle$^\\dagger$")
    csv = tmp_path / "leaderboard.csv"
    csv.write_text(to_csv(boards))
    rows = pd.read_csv(csv, dtype=str)
    assert list(rows["rank"]) == ["1", "2", "floor"]
    assert rows.loc[0, "horizontal median 95% CI [m]"] == "0.800, 1.20"
    text = terminal_summary(tmp_path)
    assert text.splitlines()[0] == "urban, low receiver" and "2.23" in text and "[0.800" not in text


def test_report_settings_are_spelled_as_on_a_run() -> None:
    assert report_settings(["report.formats=[png,pdf]", "report.style=double"]) == {
        "formats": ["png", "pdf"],
        "style": "double",
    }
    with pytest.raises(SimbenchError, match="report.formats=\\[png,pdf\\]"):
        report_settings(["formats=pdf"])


def test_a_trajectory_line_never_crosses_an_unsolved_epoch() -> None:
    reference = pd.DataFrame({"epoch": np.arange(6)})
    rows = pd.DataFrame({"epoch": [0, 1, 2, 4, 5], "east": [0.0, 1, 2, 4, 5], "north": 0.0, "horizontal": 1.0})
    lines = error_segments(rows, reference, None)
    starts = sorted(float(s[0, 0]) for s in lines.get_segments())
    assert starts == [0.0, 1.0, 4.0]  # 0-1, 1-2, 4-5: none over epoch 3
    # without the reference epochs, a jump in the epoch index is the gap
    assert len(error_segments(rows, None, None).get_segments()) == 3


def test_several_seeds_show_the_worst_and_the_best() -> None:
    shown = pd.DataFrame({"seed": [0, 0, 1, 1, 2, 2], "horizontal": [2.0, 3.0, 9.0, 8.0, 0.5, 0.7]})
    assert [s for s, _ in shown_seeds(shown)] == [1, 2]
    assert shown_seeds(shown.iloc[:2]) == [(0, "")]


def test_one_seed_gets_intervals_over_its_epochs() -> None:
    rng = np.random.default_rng(5)
    n = 300
    errors = np.abs(rng.normal(0, 2, n))
    solved = np.arange(n) % 10 != 0  # every tenth epoch unsolved
    keys = {"sweep": "", "scenario": "urban", "receiver": "low", "estimator": "l2", "gnss_model": "urban"}
    summary = pd.DataFrame([{**keys, "scenario_key": "k", "overrides": "{}", "variant": "", "status": "ok"}])
    epochs = pd.DataFrame(
        {**keys, "scenario_key": "k", "overrides": "{}", "epoch": np.flatnonzero(solved), "horizontal": errors[solved]}
    ).assign(error_3d=lambda f: 2 * f["horizontal"])
    stats = pd.DataFrame(
        [{**keys, "overrides": "{}", "variant": "", "n_seeds": 1, "ci_low": np.nan, "ci_high": np.nan}]
    )
    out = epoch_intervals(stats, summary, epochs, {"k": np.arange(n)}).iloc[0]
    median = reference_percentiles(np.sort(np.where(solved, errors, np.inf))[None, :], 50.0)[0]
    assert out["ci_over"] == "epochs" and out["ci_low"] < median < out["ci_high"]
    assert out["horizontal_rmse_ci_low"] < rmse(errors[solved]) < out["horizontal_rmse_ci_high"]
    assert np.isnan(out["horizontal_p95_ref_ci_low"])  # 90 % solved: a p95 no resample reaches
