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

import pandas as pd

from simbench.cli.terminal import compact_summary
from simbench.cli.text import plain_text
from simbench.contract import read_parquet_metadata
from simbench.errors import SimbenchError
from simbench.report.build import finalize
from simbench.runs.foreign import score_solution_file

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
    rows = pd.read_parquet(path, columns=["scenario_key", *SELECTORS])
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
    """Command line: score the file, then rebuild the run's aggregate, claims and report."""
    parser = argparse.ArgumentParser(
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
        key = args.scenario_key or scenario_key_of(args.run_dir, args.selectors)
        row = score_solution_file(args.run_dir, key, args.name, args.solution)
    except SimbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(compact_summary(row))
    previous = args.run_dir / "summary.parquet"  # keep the run's own config in the rebuilt aggregate
    config = read_parquet_metadata(previous).get("simbench.config") if previous.is_file() else None
    report = finalize(args.run_dir, config)
    print(f"results: {args.run_dir.resolve()}  report: {report.resolve() / 'index.html'}", file=sys.stderr)
    return 0
