"""``simbench score RUN_DIR [scenario=NAME seed=N ...] --name NAME --solution FILE``: another program's
solution scored as one more estimator of a run (:mod:`simbench.runs.foreign`), then the run's report rebuilt.

The scenario is named by ``--scenario-key KEY`` (the ``scenario_key`` column of summary.parquet) or by
``key=value`` selectors on summary.parquet's columns (``scenario``, ``seed``, ``receiver``, ``sweep``)
that pick exactly one scenario of the run.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from simbench.cli.callbacks import EXIT_FAILED_ROWS
from simbench.cli.terminal import compact_summary
from simbench.cli.text import OneLineParser, plain_text
from simbench.errors import SimbenchError
from simbench.report.build import finalize
from simbench.report.stale import check_report_dir
from simbench.runs.files import check_output_dir, os_fault
from simbench.runs.foreign import score_solution_file
from simbench.runs.store import load_table

#: How to repair a damaged summary.parquet: the report rebuilds it from the verified job files.
REBUILD = "rebuild it: python -m simbench report RUN_DIR"
#: summary.parquet columns a ``key=value`` selector may name.
SELECTORS = ("scenario", "seed", "receiver", "sweep", "source")


def scenario_key_of(run_dir: Path, selectors: list[str]) -> str:
    """The one ``scenario_key`` of the run whose summary rows match every ``key=value`` selector.

    Raises
    ------
    SimbenchError
        For a malformed selector, a run without summary.parquet, or no or several matching scenarios.
    """
    wanted: dict[str, str] = {}
    for item in selectors:
        key, sep, value = item.partition("=")
        if not sep or key not in SELECTORS:
            raise SimbenchError(
                "selector",
                f"'{item}' is not key=value with a key of {', '.join(SELECTORS)}",
                "e.g. scenario=urban seed=0",
            )
        wanted[key] = value
    path = run_dir / "summary.parquet"
    if not path.is_file():
        raise SimbenchError(
            "run_dir", f"{run_dir} has no summary.parquet", "give a results directory of a finished run"
        )
    rows = load_table(path, f"{REBUILD}, or name the scenario with --scenario-key", ["scenario_key", *wanted])[0]
    for key, value in wanted.items():
        rows = rows[rows[key].astype(str) == value]
    keys = sorted(rows["scenario_key"].dropna().unique())
    if len(keys) != 1:
        problem = "match no scenario" if not keys else f"match {len(keys)} scenarios"
        raise SimbenchError(
            "selector", f"{' '.join(selectors) or '(none)'} {problem} of {run_dir}", "add seed=, receiver= or sweep="
        )
    return str(keys[0])


def main(argv: list[str] | None = None) -> int:
    """Command line: score the file, then rebuild the run's aggregate, claims and report.

    Exit codes: 0 when the row is ``ok`` (or ``diverged``), 1 when it ``failed`` (no solution within
    half an epoch of a scenario epoch), 2 with one line for bad input, a damaged store file, a run
    folder that cannot be written or a fault of the machine (a full disk).
    """
    parser = OneLineParser(
        prog="simbench score", description=plain_text(__doc__), formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("run_dir", type=Path, help="results_dir of the run (or sweep) to add the solution to")
    parser.add_argument("selectors", nargs="*", help="key=value on summary.parquet, e.g. scenario=urban seed=0")
    parser.add_argument("--scenario-key", help="scenario_key of summary.parquet (folder of cache/)")
    parser.add_argument("--name", required=True, help="name of the solution in the tables, e.g. rtklib")
    parser.add_argument(
        "--solution",
        required=True,
        type=Path,
        help="RTKLIB .pos (ECEF or lat/lon/height), or CSV t,x,y,z or week,tow,lat,lon,h",
    )
    args = parser.parse_args(argv)
    try:
        check_run_dir(args.run_dir)
        key = args.scenario_key or scenario_key_of(args.run_dir, args.selectors)
        try:
            row = score_solution_file(args.run_dir, key, args.name, args.solution)
        except OSError as exc:  # a full disk, a read-only store
            raise os_fault(exc, args.run_dir / "jobs" / key) from None
        print(compact_summary(row))
        report = finalize(args.run_dir, run_config(args.run_dir))
    except SimbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"results: {args.run_dir.resolve()}  report: {report.resolve() / 'index.html'}", file=sys.stderr)
    if (row["status"] == "failed").any():  # as a run with a failed row (simbench.cli.callbacks.EXIT_FAILED_ROWS)
        print(f"{args.name}: {row['message'].iloc[0]}", file=sys.stderr)
        return EXIT_FAILED_ROWS
    return 0


def check_run_dir(run_dir: Path) -> None:
    """Raise a one-line :class:`SimbenchError` unless ``run_dir`` is a run folder whose store and report can
    be written: checked before the solution is read and scored."""
    if not run_dir.is_dir():
        raise SimbenchError("RUN_DIR", f"'{run_dir}' is not a directory", "give the results_dir of a run or sweep")
    check_output_dir("RUN_DIR", run_dir, "the results_dir of a run you can write")
    check_report_dir(run_dir / "report", run_dir)


def run_config(run_dir: Path) -> dict | None:
    """The run's own config, from the metadata of its summary.parquet, kept in the rebuilt aggregate; None
    (a rebuild's provenance) when the file is missing or damaged: the report rebuilds it from the job files."""
    path = run_dir / "summary.parquet"
    if not path.is_file():
        return None
    try:
        return load_table(path, REBUILD)[1].get("simbench.config")
    except SimbenchError:
        return None
