"""What the terminal shows after a run: a compact sorted summary of result rows (the lines of a command
line that need no result table are in :mod:`simbench.cli.text`)."""

from __future__ import annotations

import numpy as np
import pandas as pd
from tabulate import tabulate

from simbench.analysis.tables import with_variant_columns
from simbench.analysis.variants import display_names
from simbench.report.style import LABELS_MARK, sig3

#: Widest summary line [characters]: it fits a terminal of 100 columns.
SUMMARY_WIDTH = 100
#: Longest estimator name shown; longer variant names are cut with '…'.
NAME_WIDTH = 24


def compact_summary(summary: pd.DataFrame) -> str:
    """The result rows as one line per estimator variant, sorted by median error, with units.

    Parameters
    ----------
    summary : pandas.DataFrame
        ``summary.parquet`` rows (one run, or every seed and world of a sweep: values are
        means over the ``ok`` rows).

    Returns
    -------
    str
        A table at most :data:`SUMMARY_WIDTH` characters wide, the oracle (an estimator that reads the
        labels, marked :data:`~simbench.report.style.LABELS_MARK`) last: estimator, rows ok / run (:func:`ok_count`),
        availability [%], horizontal median and p95 and 3-D median over reference epochs [m]
        (— when the availability does not reach the percentile) and time per epoch [ms]; under the
        table, one line per variant with a row that is not ok: its status and message.
    """
    if summary.empty:
        return "(no result rows)"
    rows = with_variant_columns(summary)
    rows = rows.assign(name=display_names(rows), ok=rows["status"] == "ok")
    out = []
    for name, group in rows.groupby("name"):
        ok = group[group["ok"]]

        def mean(column: str, ok: pd.DataFrame = ok) -> float:
            values = ok[column].to_numpy(float) if column in ok else np.array([])
            return float(np.inf if np.isinf(values).any() else values.mean()) if len(values) else np.nan

        per_epoch = ok["total_s"].to_numpy(float) / np.maximum(ok["n_epochs"].to_numpy(float), 1)
        problem = group.loc[~group["ok"], "message"].fillna("").astype(str)
        # an estimator that reads the true error labels (the oracle) is a floor, not a contender: marked, last
        floor = bool(group["uses_labels"].any()) if "uses_labels" in group else False
        name = f"{name}{LABELS_MARK}" if floor else str(name)
        out.append(
            {
                "estimator": name if len(name) <= NAME_WIDTH else name[: NAME_WIDTH - 1] + "…",
                "ok": ok_count(group),
                "avail [%]": sig3(100 * mean("availability")),
                "h med [m]": sig3(mean("horizontal_median_ref")),
                "h p95 [m]": sig3(mean("horizontal_p95_ref")),
                "3D med [m]": sig3(mean("error_3d_median_ref")),
                "ms/epoch": sig3(1e3 * float(per_epoch.mean())) if len(per_epoch) else "",
                "_note": (group.loc[~group["ok"], "status"].iloc[0] + ": " + problem.iloc[0]) if len(problem) else "",
                "_key": mean("horizontal_median_ref"),
                "_floor": floor,
            }
        )
    table = pd.DataFrame(out).sort_values(["_floor", "_key", "estimator"], na_position="last")
    align = ["left", "right", "right", "right", "right", "right", "right"]
    text = tabulate(
        table.drop(columns=["_key", "_note", "_floor"]),
        headers="keys",
        tablefmt="simple",
        showindex=False,
        disable_numparse=True,
        colalign=align,
    )
    # why a row is not ok, under the table: a message is too long for a column
    notes = [f"{name}: {note}" for name, note in zip(table["estimator"], table["_note"]) if note]
    return "\n".join(line.rstrip()[:SUMMARY_WIDTH] for line in [*text.splitlines(), *notes])


def ok_count(group: pd.DataFrame) -> str:
    """``2/3``: rows ok of those that ran; ``skipped`` when none ran (the data lack what it needs).

    A skipped row is no failure, so it is not counted against the estimator: ``2/3 +1 skipped``.
    """
    skipped = int((group["status"] == "skipped").sum())
    ran = len(group) - skipped
    if not ran:
        return "skipped"
    text = f"{int(group['ok'].sum())}/{ran}"
    return f"{text} +{skipped} skipped" if skipped else text
