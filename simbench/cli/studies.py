"""Several studies over several worlds (``+sweep=thesis``): each study in its own process, then one report."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from simbench.cli.terminal import compact_summary
from simbench.report.build import finalize
from simbench.runs.checks import ReportFormat
from simbench.runs.studies import StudiesConfig, run_all


def run_studies(
    cfg: StudiesConfig, root: Path, args: Sequence[str], report_formats: Sequence[ReportFormat] = ("png",)
) -> int:
    """Run every study (:func:`simbench.runs.studies.run_all`), then one aggregate report over all of them.

    A study that exits with an error does not stop the others (its finished jobs
    are in the store); the return code is then 1. ``report_formats`` are the aggregate
    report's figure formats (``report.formats`` of the command line; each study's own
    report gets them through ``args``).

    Returns
    -------
    int
        0 when every study exited cleanly, else 1.
    """
    times = run_all(cfg, root, args)
    report = finalize(root, {"studies": cfg.studies, "worlds": cfg.worlds, "args": list(args)}, formats=report_formats)
    if (root / "summary.parquet").is_file():
        print(compact_summary(pd.read_parquet(root / "summary.parquet")))
    print(f"results: {root.resolve()}  report: {report.resolve() / 'index.html'}", file=sys.stderr)
    failed = [f"{t['study']}" + (f" on {t['world']}" if t["world"] else "") for t in times if t["exit_code"]]
    if failed:
        print(f"error: studies {', '.join(failed)} exited with errors -- see their logs in {root}", file=sys.stderr)
    return 1 if failed else 0
