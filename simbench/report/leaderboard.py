"""The leaderboard: one row per estimator variant of a group, on the page, in LaTeX and CSV, and in the terminal.

The page, ``leaderboard.csv``, ``leaderboard.tex`` (booktabs) and a sweep's
terminal summary are one table (:func:`leaderboard`) printed four ways, so they
show the same numbers. Rows are sorted by the median horizontal error over
reference epochs; an estimator that reads the true error labels (the oracle, an
accuracy floor) is ranked apart, under a rule after the others.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from tabulate import tabulate

from simbench.analysis.tables import GROUP, data_label
from simbench.report.style import LABELS_MARK, families, sig3, with_ci

#: What a blank cell (no run time) shows.
BLANK = "n/a"
#: Leaderboard columns: header (with unit) -> (statistic, CI low, CI high) of
#: :func:`~simbench.analysis.tables.seed_statistics`.
LEADERBOARD_STATISTICS = {
    "horizontal median [m]": ("horizontal_median_ref", "ci_low", "ci_high"),
    "horizontal p95 [m]": ("horizontal_p95_ref", "horizontal_p95_ref_ci_low", "horizontal_p95_ref_ci_high"),
    "horizontal RMSE [m]": ("horizontal_rmse", "horizontal_rmse_ci_low", "horizontal_rmse_ci_high"),
    "3-D median [m]": ("error_3d_median_ref", "error_3d_median_ref_ci_low", "error_3d_median_ref_ci_high"),
    "3-D p95 [m]": ("error_3d_p95_ref", "error_3d_p95_ref_ci_low", "error_3d_p95_ref_ci_high"),
    "3-D RMSE [m]": ("error_3d_rmse", "error_3d_rmse_ci_low", "error_3d_rmse_ci_high"),
    # libRSF's published statistic: each estimate against the nearest reference point, whatever its time
    "3-D RMSE, nearest reference [m]": (
        "error_3d_nearest_rmse",
        "error_3d_nearest_rmse_ci_low",
        "error_3d_nearest_rmse_ci_high",
    ),
}
#: Columns the terminal prints (the page's, less the CIs and the family).
TERMINAL_COLUMNS = (
    "estimator",
    "seeds",
    "availability [%]",
    "horizontal median [m]",
    "horizontal p95 [m]",
    "horizontal RMSE [m]",
    "3-D median [m]",
    "time per epoch [ms]",
)


def reads_labels(name: str) -> bool:
    """The curve name of an estimator that reads the true error labels (marked :data:`LABELS_MARK`)."""
    return name.endswith(LABELS_MARK)


def ranked(stats: pd.DataFrame) -> pd.DataFrame:
    """``stats`` (with ``name``) in leaderboard order: by median horizontal error (undefined last), then
    3-D median and name; the label readers after all others, in the same order among themselves."""
    apart = stats["name"].astype(str).map(reads_labels)
    return (
        stats.assign(_apart=apart)
        .sort_values(["_apart", "horizontal_median_ref", "error_3d_median_ref", "name"], na_position="last")
        .drop(columns="_apart")
    )


def leaderboard(stats: pd.DataFrame) -> pd.DataFrame:
    """One row per estimator variant of a group, in leaderboard order (:func:`ranked`).

    Parameters
    ----------
    stats : pandas.DataFrame
        :func:`~simbench.analysis.tables.seed_statistics` rows of one group, with ``name``
        (and ``ci_over`` where :func:`~simbench.analysis.tables.epoch_intervals` filled it).

    Returns
    -------
    pandas.DataFrame
        ``estimator`` (the variant's name), ``family``, ``seeds``, ``availability [%]``, the
        :data:`LEADERBOARD_STATISTICS` as ``value [CI]`` text (3 significant digits) and
        ``time per epoch [ms]``.
    """
    rows = ranked(stats)
    table = pd.DataFrame(
        {
            "estimator": rows["name"],
            "family": rows["estimator"].map(families(rows["estimator"].unique())),
            "seeds": rows["n_seeds"].astype(int),
            "availability [%]": [sig3(100 * a) for a in rows["availability"]],
        }
    )
    for header, (value, low, high) in LEADERBOARD_STATISTICS.items():
        columns = [rows[c] if c in rows else pd.Series(np.nan, index=rows.index) for c in (value, low, high)]
        table[header] = [with_ci(v, lo, hi) for v, lo, hi in zip(*columns)]
    table["time per epoch [ms]"] = [sig3(1e3 * t) if np.isfinite(t) else BLANK for t in rows["time_per_epoch_s"]]
    return table.reset_index(drop=True)


def group_title(keys: tuple, source: str | None) -> str:
    """The title of a (sweep, scenario, receiver) group, as its section on the page."""
    sweep, scenario, receiver = keys
    return data_label(scenario, receiver, source) + (f" (sweep {sweep})" if sweep else "")


def leaderboards(summary: pd.DataFrame, stats: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    """Each group's title and :func:`leaderboard`, groups in the order of ``stats``."""
    out = []
    for keys, rows in stats.groupby(GROUP, dropna=False, sort=True):
        match = np.logical_and.reduce([summary[k].fillna("") == (v if v == v else "") for k, v in zip(GROUP, keys)])
        out.append((group_title(keys, summary.loc[match, "source"].iloc[0]), leaderboard(rows)))
    return out


def to_csv(boards: Sequence[tuple[str, pd.DataFrame]]) -> str:
    """Every group's leaderboard in one CSV, a ``group`` column first; a value and its CI in two columns."""
    frames = []
    for title, table in boards:
        flat = table.copy()
        for header in LEADERBOARD_STATISTICS:
            text = flat[header].astype(str)
            flat[header] = text.str.split(" [", regex=False).str[0]
            flat[header.replace(" [m]", " 95% CI [m]")] = text.str.extract(r"\[(.*)\]", expand=False).fillna("")
        frames.append(flat.assign(rank=_ranks(table)).assign(group=title))
    columns = ["group", "rank", *frames[0].columns.drop(["group", "rank"])] if frames else []
    return pd.concat(frames, ignore_index=True)[columns].to_csv(index=False) if frames else ""


def _ranks(table: pd.DataFrame) -> list[str]:
    """1, 2, ... down the leaderboard; the label readers are not ranked (``floor``)."""
    out, rank = [], 0
    for name in table["estimator"]:
        rank += not reads_labels(str(name))
        out.append("floor" if reads_labels(str(name)) else str(rank))
    return out


def to_latex(boards: Sequence[tuple[str, pd.DataFrame]], note: str) -> str:
    """Every group's leaderboard as a LaTeX ``tabular`` with booktabs rules (``\\usepackage{booktabs}``).

    The CIs are left out (``leaderboard.csv`` has them); a group's title is a ``\\multicolumn``
    row; the label readers follow a ``\\midrule``. ``note`` ends the table as a comment.
    """
    columns = ["estimator", "availability [%]", *LEADERBOARD_STATISTICS, "time per epoch [ms]"]
    lines = [
        "% simbench leaderboard; needs \\usepackage{booktabs}. " + note,
        "\\begin{tabular}{l" + "r" * (len(columns) - 1) + "}",
        "\\toprule",
        " & ".join(_tex(c) for c in columns) + " \\\\",
    ]
    for title, table in boards:
        lines.append("\\midrule")
        if len(boards) > 1:
            lines.append(f"\\multicolumn{{{len(columns)}}}{{l}}{{\\emph{{{_tex(title)}}}}} \\\\")
        apart = False
        for _, row in table.iterrows():
            if reads_labels(str(row["estimator"])) and not apart:
                lines.append("\\midrule")
                apart = True
            cells = [str(row[c]).split(" [")[0] for c in columns]
            lines.append(" & ".join(_tex(c) for c in cells) + " \\\\")
    lines += ["\\bottomrule", "\\end{tabular}", ""]
    return "\n".join(lines)


def _tex(text: str) -> str:
    """``text`` with LaTeX's special characters escaped (``%``, ``_``, ``&``, ``#``, the labels mark, the dash)."""
    out = str(text)
    for plain, escaped in (
        ("\\", "\\textbackslash{}"),
        ("%", "\\%"),
        ("_", "\\_"),
        ("&", "\\&"),
        ("#", "\\#"),
        ("$", "\\$"),
        ("{", "\\{"),
        ("}", "\\}"),
        (LABELS_MARK, "$^\\dagger$"),
        ("—", "---"),
    ):
        out = out.replace(plain, escaped)
    return out


def terminal_text(boards: Sequence[tuple[str, pd.DataFrame]], width: int = 110) -> str:
    """Every group's leaderboard for the terminal: a title line, then its :data:`TERMINAL_COLUMNS` (no CIs)."""
    out = []
    for title, table in boards:
        shown = table[list(TERMINAL_COLUMNS)].copy()
        for header in LEADERBOARD_STATISTICS:
            if header in shown:
                shown[header] = shown[header].astype(str).str.split(" [", regex=False).str[0]
        text = tabulate(
            shown.rename(columns=lambda c: c.replace("horizontal ", "h ").replace("availability", "avail")),
            headers="keys",
            tablefmt="simple",
            showindex=False,
            disable_numparse=True,
            colalign=["left", *["right"] * (len(shown.columns) - 1)],
        )
        out += [title, *(line.rstrip()[:width] for line in text.splitlines()), ""]
    return "\n".join(out).rstrip()


def terminal_summary(report: Path) -> str:
    """The leaderboards a report wrote (``leaderboard.csv`` in ``report``) for the terminal, one per
    (sweep, scenario, receiver) group: the page's numbers, without CIs; ``''`` without the file."""
    path = report / "leaderboard.csv"
    if not path.is_file():
        return ""
    table = pd.read_csv(path, dtype=str, keep_default_na=False)
    boards = [(str(title), rows.drop(columns=["group"])) for title, rows in table.groupby("group", sort=False)]
    return terminal_text(boards)
