"""``simbench report RUN_DIR [report.formats=[png,pdf]] [report.style=double]``: rebuild aggregate, claims and
report of a run at any time. The settings are spelled as on a run; ``--formats png,pdf`` is kept as well."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from simbench.cli.text import OneLineParser, plain_text
from simbench.errors import SimbenchError
from simbench.report.build import finalize
from simbench.runs.checks import check_report_formats, check_report_style
from simbench.runs.store import job_stems, run_folders


def main(argv: list[str]) -> int:
    """Rebuild the report of the run folder ``argv`` names; the exit code (2 with one line: a folder without
    jobs, a damaged study_times.csv, a folder that cannot be written, a full disk)."""
    parser = OneLineParser(prog="simbench report", description=plain_text(__doc__))
    parser.add_argument("run_dir", type=Path, help="a results directory written by python -m simbench")
    parser.add_argument(
        "settings",
        nargs="*",
        metavar="report.KEY=VALUE",
        help="report.formats=[png,pdf] (figure formats; the page shows the PNG) and report.style=screen|single|double "
        "(figure size: the page, or a paper's 3.5 in or 7 in column), as on a run",
    )
    parser.add_argument(
        "--formats",
        type=lambda text: [f for f in text.split(",") if f],
        default=["png"],
        help="figure formats, comma-separated, e.g. png,pdf (the page shows the PNG; default: png)",
    )
    args = parser.parse_args(argv)
    try:
        settings = report_settings(args.settings)
        formats = settings.get("formats", args.formats)
        check_report_formats(formats)
        check_report_style(settings.get("style"))
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
        report = finalize(args.run_dir, None, formats=formats, style=settings.get("style"))
    except SimbenchError as exc:  # also a damaged study_times.csv, a read-only folder or a full disk
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"report: {report.resolve() / 'index.html'}")
    return 0


def report_settings(words: list[str]) -> dict[str, Any]:
    """``report.formats=[png,pdf]`` and ``report.style=double`` as a run spells them: key to value.

    Raises
    ------
    SimbenchError
        For a word that is not ``report.formats=...`` or ``report.style=...``.
    """
    out: dict[str, Any] = {}
    for word in words:
        key, _, value = word.partition("=")
        if key not in ("report.formats", "report.style") or not value:
            raise SimbenchError(word, "is not a report setting", "give report.formats=[png,pdf] or report.style=double")
        listed = value.startswith("[") and value.endswith("]")
        items = [v.strip() for v in value[1:-1].split(",") if v.strip()] if listed else value
        out[key.split(".")[1]] = items
    return out
