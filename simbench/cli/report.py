"""``simbench report RUN_DIR [--formats png,pdf]``: rebuild aggregate, claims and report of a run at any time."""

from __future__ import annotations

import sys
from pathlib import Path

from simbench.cli.text import OneLineParser, plain_text
from simbench.errors import SimbenchError
from simbench.report.build import finalize
from simbench.runs.checks import check_report_formats
from simbench.runs.store import job_stems, run_folders


def main(argv: list[str]) -> int:
    """Rebuild the report of the run folder ``argv`` names; the exit code (2 with one line: a folder without
    jobs, a damaged study_times.csv, a folder that cannot be written, a full disk)."""
    parser = OneLineParser(prog="simbench report", description=plain_text(__doc__))
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
        # a study collection (+sweep=thesis) keeps each study's jobs/ in the folders its study_times.csv names
        if not any((folder / "jobs").is_dir() for folder in run_folders(args.run_dir)):
            raise SimbenchError(
                "run_dir", f"{args.run_dir} holds no jobs/ folder", "give a directory written by python -m simbench"
            )
        if not job_stems(args.run_dir):  # an empty page would look like a run whose estimators gave nothing
            raise SimbenchError(
                "run_dir",
                f"{args.run_dir} has a jobs/ folder but no finished job in it",
                "run python -m simbench into it first, or give the folder of a finished run",
            )
        report = finalize(args.run_dir, None, formats=args.formats)
    except SimbenchError as exc:  # also a damaged study_times.csv, a read-only folder or a full disk
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"report: {report.resolve() / 'index.html'}")
    return 0
