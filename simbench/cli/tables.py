"""``python -m simbench tables RUN_DIR``: the lab notebook's tables of a run folder, as Markdown.

Prints what ``docs/notebook.md`` records from a run, read from the files the run
(or ``python -m simbench report RUN_DIR``) wrote, with the analysis functions the
report uses; nothing is computed here that the report does not show:

- ``claims``: the published claims, one column per world
  (:func:`simbench.analysis.claims.claims_by_world` of ``claims.csv``);
- ``drives``: our median on each Morgantown drive beside the published one,
  ``median_ref (published)`` per receiver and drive, one column per estimator,
  one table per published source (:func:`simbench.analysis.tables.drive_comparison`
  of ``summary.parquet``);
- ``times``: wall time per study and world (``study_times.csv`` of ``+sweep=thesis``)
  and the estimators' run time summed per sweep, world and estimator
  (:func:`simbench.runs.studies.time_budget`).

``--only NAME`` prints one of them. A table whose file the folder lacks is skipped
with a note; a folder with none of them is an error (exit code 2).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

from simbench.analysis.claims import claims_by_world
from simbench.analysis.published import DRIVE_MEDIANS_BY_SWEEP, PUBLISHED_FAMILY
from simbench.analysis.tables import drive_comparison
from simbench.cli.text import OneLineParser, plain_text
from simbench.errors import SimbenchError
from simbench.runs.files import read_csv_table
from simbench.runs.store import load_table
from simbench.runs.studies import STUDY_TIMES, read_study_times, time_budget

TABLES = ("claims", "drives", "times")
#: The published source of a drive table whose sweep has no own entry in DRIVE_MEDIANS_BY_SWEEP.
DEFAULT_DRIVE_SOURCE = "Ch.5 / Ch.7 tables and the ICE paper"
#: Titles of the sweeps that have a published drive table of their own (DRIVE_MEDIANS_BY_SWEEP).
SOURCE_TITLES = {"ch6_bce_ad": "Ch.6 Table 6.3.1"}
#: Rows of the time budget printed (largest first), as the report shows them.
BUDGET_ROWS = 20


def markdown(frame: pd.DataFrame) -> str:
    """A table as GitHub Markdown; ``(none)`` when empty."""
    return frame.to_markdown(index=False, floatfmt=".4g") if len(frame) else "(none)"


#: How to repair a damaged file of a run folder: every one is rebuilt from the verified job files.
REBUILD = "rebuild it: python -m simbench report RUN_DIR"
#: Columns of summary.parquet the drive and time tables read.
SUMMARY_READ = ("sweep", "scenario", "receiver", "estimator", "overrides", "status", "horizontal_median_ref", "total_s")
#: Columns of claims.csv that :func:`claims_by_world` reads.
CLAIMS_COLUMNS = ("claim_id", "world", "published", "measured", "holds", "ci_low", "ci_high")


def claims_section(run_dir: Path) -> str | None:
    path = run_dir / "claims.csv"
    if not path.is_file():
        return None
    claims = read_csv_table(path, CLAIMS_COLUMNS, REBUILD, numbers=("measured", "ci_low", "ci_high"))
    return f"## Claims per world (`{path}`)\n\n{markdown(claims_by_world(claims))}"


def drive_tables(summary: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """Per published source: rows receiver and drive, one column per estimator, ``median_ref (published)`` [m].

    Keys name the source and the sweeps read, e.g. ``Ch.6 Table 6.3.1 (sweep ch6_bce_ad)``. Rows
    ``low`` before ``high``; columns by sweep, then in :data:`PUBLISHED_FAMILY` order.
    """
    drives = drive_comparison(summary)
    out: dict[str, pd.DataFrame] = {}
    if drives.empty:
        return out
    family_order = {name: i for i, name in enumerate(PUBLISHED_FAMILY)}
    drives = drives.assign(
        source=drives["sweep"].map(lambda s: s if s in DRIVE_MEDIANS_BY_SWEEP else ""),
        rx_order=drives["receiver"].map({"low": 0, "high": 1}),
        est_order=drives["estimator"].map(family_order),
    ).sort_values(["source", "sweep", "est_order", "rx_order", "drive"], kind="stable")
    for source, group in drives.groupby("source", sort=True):
        # an estimator run by two sweeps of one source keeps them apart
        twice = group.groupby("estimator")["sweep"].nunique() > 1
        column = [f"{e} ({s})" if twice[e] else e for e, s in zip(group["estimator"], group["sweep"])]
        cell = [f"{m:.2f} ({p:.2f})" for m, p in zip(group["median_ref"], group["published"])]
        table = (
            group.assign(column=column, cell=cell)
            .sort_values(["rx_order", "drive"], kind="stable")
            .pivot_table(index=["receiver", "drive"], columns="column", values="cell", aggfunc="first", sort=False)
            .reset_index()
        )
        table.columns.name = None
        sweeps = ", ".join(dict.fromkeys(group["sweep"]))
        title = SOURCE_TITLES.get(str(source), DEFAULT_DRIVE_SOURCE)
        out[f"{title} (sweeps {sweeps})"] = table.fillna("")
    return out


def drives_section(run_dir: Path) -> str | None:
    path = run_dir / "summary.parquet"
    if not path.is_file():
        return None
    tables = drive_tables(load_table(path, REBUILD, SUMMARY_READ)[0])
    parts = [f"## Morgantown drives: median_ref (published) [m] (`{path}`)"]
    if not tables:
        parts.append("(no default-variant results on morgantown1..3 with a published counterpart)")
    parts += [f"### Published: {name}\n\n{markdown(table)}" for name, table in tables.items()]
    return "\n\n".join(parts)


def ran_once(times: pd.DataFrame) -> bool:
    """Each study x world of a ``study_times.csv`` ran once (several invocations into one folder repeat pairs)."""
    return not times.duplicated(["study", "world"]).any()


def study_times_table(times: pd.DataFrame, values: str = "wall_s") -> pd.DataFrame:
    """``values`` (a column of ``study_times.csv``: ``wall_s``, ``peak_rss_mb``) per study (rows) and world
    (columns) when each pair ran once (:func:`ran_once`), else the rows as written."""
    times = times.assign(world=times["world"].replace("", "(own scenario)"))
    if not ran_once(times):  # show each invocation, every column
        return times.drop(columns=["results_dir"], errors="ignore")
    table = times.pivot(index="study", columns="world", values=values)
    table = table.apply(pd.to_numeric, errors="coerce").round(0).reset_index()
    table.columns.name = None
    return table.astype(object).where(table.notna(), "")


def times_section(run_dir: Path) -> str | None:
    times_path, summary_path = run_dir / STUDY_TIMES, run_dir / "summary.parquet"
    parts = []
    times = read_study_times(run_dir)
    if times is not None:
        parts.append(
            f"## Wall time per study and world [s] (`{times_path}`; total {times['wall_s'].sum() / 60:.1f} min)"
            f"\n\n{markdown(study_times_table(times))}"
        )
        # an older study_times.csv has no such column; repeated pairs already show it in the rows above
        if "peak_rss_mb" in times.columns and ran_once(times):
            peak = pd.to_numeric(times["peak_rss_mb"], errors="coerce").max()
            parts.append(
                f"## Peak memory per study and world [MB] (largest process of each study: a launcher worker "
                f"or the study itself; largest {peak:.0f} MB)\n\n{markdown(study_times_table(times, 'peak_rss_mb'))}"
            )
    if summary_path.is_file():
        budget = time_budget(load_table(summary_path, REBUILD, SUMMARY_READ)[0])
        parts.append(
            f"## Estimator time per sweep, world and estimator (`time_budget`; "
            f"{budget['total_s'].sum():.0f} s in all, largest {BUDGET_ROWS})\n\n{markdown(budget.head(BUDGET_ROWS))}"
        )
    return "\n\n".join(parts) or None


SECTIONS = {"claims": claims_section, "drives": drives_section, "times": times_section}


def main(argv: list[str]) -> int:
    """Print the tables of the run folder ``argv`` names; the exit code (2 when it holds none of their files)."""
    parser = OneLineParser(
        prog="python -m simbench tables",
        description=plain_text(__doc__),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("run_dir", type=Path, help="a results directory written by python -m simbench")
    parser.add_argument("--only", choices=TABLES, help="print one table")
    args = parser.parse_args(argv)
    if args.run_dir.exists() and not args.run_dir.is_dir():
        fix = "give a directory written by python -m simbench"
        print(f"error: run_dir: {args.run_dir} is a file -- {fix}", file=sys.stderr)
        return 2
    printed = []
    for name in (args.only,) if args.only else TABLES:
        try:  # files read through the store's checks: a damaged one is one line naming it
            text = SECTIONS[name](args.run_dir)
        except SimbenchError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        if text is None:
            print(f"note: {name}: {args.run_dir} has no file for it", file=sys.stderr)
        else:
            printed.append(text)
    if not printed:
        print(
            f"error: run_dir: {args.run_dir} holds no claims.csv, summary.parquet or {STUDY_TIMES} -- give a "
            "directory written by python -m simbench (python -m simbench report RUN_DIR rebuilds claims.csv)",
            file=sys.stderr,
        )
        return 2
    print("\n\n".join(printed))
    return 0
