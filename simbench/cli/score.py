"""``python -m simbench score RUN_DIR --scenario-key KEY --name NAME --solution FILE``: another program's
solution scored as one more estimator of a run (:mod:`simbench.runs.foreign`), then the run's report rebuilt."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from simbench.cli.terminal import SHOWN
from simbench.contract import read_parquet_metadata
from simbench.errors import SimbenchError
from simbench.report.build import finalize
from simbench.runs.foreign import score_solution_file


def main(argv: list[str] | None = None) -> int:
    """Command line: score the file, then rebuild the run's aggregate, claims and report."""
    parser = argparse.ArgumentParser(prog="python -m simbench score", description=__doc__)
    parser.add_argument("run_dir", type=Path, help="results_dir of the run (or sweep) to add the solution to")
    parser.add_argument("--scenario-key", required=True, help="scenario_key of summary.parquet (folder of cache/)")
    parser.add_argument("--name", required=True, help="name of the solution in the tables, e.g. rtklib")
    parser.add_argument(
        "--solution",
        required=True,
        type=Path,
        help="RTKLIB .pos (ECEF or lat/lon/height), or CSV t,x,y,z or week,tow,lat,lon,h",
    )
    args = parser.parse_args(argv)
    try:
        row = score_solution_file(args.run_dir, args.scenario_key, args.name, args.solution)
    except SimbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(row.reindex(columns=SHOWN).to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    previous = args.run_dir / "summary.parquet"  # keep the run's own config in the rebuilt aggregate
    config = read_parquet_metadata(previous).get("simbench.config") if previous.is_file() else None
    report = finalize(args.run_dir, config)
    print(f"results: {args.run_dir.resolve()}  report: {report.resolve() / 'index.html'}", file=sys.stderr)
    return 0
