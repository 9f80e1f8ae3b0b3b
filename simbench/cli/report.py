"""``simbench report RUN_DIR [--formats png,pdf]``: rebuild aggregate, claims and report of a run at any time."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from simbench.cli.text import plain_text
from simbench.errors import SimbenchError
from simbench.report.build import finalize
from simbench.runs.checks import check_report_formats
from simbench.runs.store import run_folders


def main(argv: list[str]) -> int:
    """Rebuild the report of the run folder ``argv`` names; the exit code (2 for a folder without jobs)."""
    parser = argparse.ArgumentParser(prog="simbench report", description=plain_text(__doc__))
    parser.add_argument("run_dir", type=Path, help="a results directory written by python -m simbench")
    parser.add_argument(
        "--formats",
        type=lambda text: [f for f in text.split(",") if f],
        default=["png"],
        help="figure formats, comma-separated, e.g. png,pdf (the page shows the PNG; default: png)",
    )
    args = parser.parse_args(argv)
    try:
        check_report_formats(args.formats)
    except SimbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    # a study collection (+sweep=thesis) keeps each study's jobs/ in the folders its study_times.csv names
    if not any((folder / "jobs").is_dir() for folder in run_folders(args.run_dir)):
        print(
            f"error: run_dir: {args.run_dir} holds no jobs/ folder -- give a directory written by python -m simbench",
            file=sys.stderr,
        )
        return 2
    report = finalize(args.run_dir, None, formats=args.formats)
    print(f"report: {report.resolve() / 'index.html'}")
    return 0
