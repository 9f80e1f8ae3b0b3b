"""Several studies over several worlds (``+sweep=thesis``): each study in its own process, then one report."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import NamedTuple

import pandas as pd

from simbench.cli.terminal import compact_summary
from simbench.report.build import finalize
from simbench.runs.checks import ReportFormat
from simbench.runs.studies import STUDY_TIMES, StudiesConfig, plan, read_study_times


class StudyProcess(NamedTuple):
    """How a study's process ended."""

    exit_code: int
    #: peak resident memory of the largest process of the study's tree (the study process or one of its
    #: launcher's workers) [MB]; NaN where the platform cannot say (no ``os.wait4``)
    peak_rss_mb: float


#: Starts the study from a small process and reports, on the file descriptor in ``argv[1]``, its exit
#: code and the ``ru_maxrss`` of its tree. A child started straight from a large process (a notebook,
#: a pytest worker) inherits that process's high-water mark: ``vfork`` shares its address space until
#: ``exec``, and Linux then records the parent's peak as the child's (a 300 MB study read 1,176 MB).
_PEAK_SHIM = (
    "import os, sys\n"
    "try:\n"
    "    pid = os.posix_spawnp(sys.argv[2], sys.argv[2:], os.environ)\n"
    "except OSError as e:\n"
    "    sys.exit(f'cannot start {sys.argv[2]}: {e.strerror}')\n"
    "_, status, usage = os.wait4(pid, 0)\n"
    "code = os.waitstatus_to_exitcode(status)\n"
    "os.write(int(sys.argv[1]), f'{code} {usage.ru_maxrss}'.encode())\n"
)


def run_study_process(cmd: Sequence[str]) -> StudyProcess:
    """Run ``cmd`` and wait for it; its exit code and the peak memory of its process tree.

    ``os.wait4`` returns the child's resource usage with that of every descendant it
    waited for, and ``ru_maxrss`` is then the largest peak among them (Linux reports
    kibibytes, macOS bytes): a joblib or submitit-local worker counts, which is the
    per-worker peak a sweep has to fit into. The command is started from a small
    Python process (:data:`_PEAK_SHIM`), so the caller's own size does not count.
    """
    if not hasattr(os, "wait4"):  # Windows
        return StudyProcess(subprocess.Popen(list(cmd)).wait(), float("nan"))
    read, write = os.pipe()
    try:
        shim = subprocess.Popen([sys.executable, "-c", _PEAK_SHIM, str(write), *cmd], pass_fds=(write,))
    finally:
        os.close(write)
    with os.fdopen(read) as report:
        text = report.read().split()
    shim.wait()
    if len(text) != 2:  # the shim itself failed (the command could not be started)
        return StudyProcess(shim.returncode or 1, float("nan"))
    unit = 1.0 if sys.platform == "darwin" else 1024.0
    return StudyProcess(int(text[0]), float(text[1]) * unit / 2**20)


def run_studies(
    cfg: StudiesConfig, root: Path, args: Sequence[str], report_formats: Sequence[ReportFormat] = ("png",)
) -> int:
    """Run every study of :func:`plan` in its own process, then one aggregate over all of them.

    A study that exits with an error does not stop the others (its finished jobs
    are in the store); the return code is then 1. ``report_formats`` are the aggregate
    report's figure formats (``report.formats`` of the command line; each study's own
    report gets them through ``args``).

    Returns
    -------
    int
        0 when every study exited cleanly, else 1.
    """
    runs = plan(cfg, root, args)
    root.mkdir(parents=True, exist_ok=True)
    path = root / STUDY_TIMES
    # appended to: a second invocation into the same results_dir (another world, other seeds) keeps the first's
    earlier = read_study_times(root)  # a damaged one is one line naming it, before the first study
    earlier = pd.DataFrame() if earlier is None else earlier
    times = []
    for i, run in enumerate(runs, 1):
        print(
            f"=== study {run.study}" + (f" on {run.world}" if run.world else "") + f" ({i}/{len(runs)})",
            file=sys.stderr,
        )
        started, start = datetime.now(timezone.utc).isoformat(timespec="seconds"), time.perf_counter()
        ended = run_study_process([sys.executable, "-m", "simbench", *run.args])
        times.append(
            {
                "study": run.study,
                "world": run.world,
                "started": started,
                "wall_s": time.perf_counter() - start,
                "peak_rss_mb": ended.peak_rss_mb,
                "exit_code": ended.exit_code,
                "results_dir": str(run.results_dir),
            }
        )
        # written after every study: a killed run still says where its time went
        pd.concat([earlier, pd.DataFrame(times)], ignore_index=True).to_csv(path, index=False)
    report = finalize(root, {"studies": cfg.studies, "worlds": cfg.worlds, "args": list(args)}, formats=report_formats)
    if (root / "summary.parquet").is_file():
        print(compact_summary(pd.read_parquet(root / "summary.parquet")))
    print(f"results: {root.resolve()}  report: {report.resolve() / 'index.html'}", file=sys.stderr)
    failed = [f"{t['study']}" + (f" on {t['world']}" if t["world"] else "") for t in times if t["exit_code"]]
    if failed:
        print(f"error: studies {', '.join(failed)} exited with errors -- see their logs in {root}", file=sys.stderr)
    return 1 if failed else 0
