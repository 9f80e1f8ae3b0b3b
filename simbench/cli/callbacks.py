"""Hydra callbacks: the sweep's progress bar; build the run's aggregate, claims and report when jobs end, and
set the exit code."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any, cast

import pandas as pd
from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from simbench.cli.progress import end_sweep_bar, start_sweep_bar
from simbench.errors import SimbenchError
from simbench.report.build import finalize
from simbench.report.leaderboard import terminal_summary
from simbench.runs.run_dirs import keep_earlier_configs

#: Exit code of a run or sweep with a ``failed`` row (0: every row ``ok``, ``skipped`` or ``diverged``;
#: 2: a config refused before any job, :func:`simbench.cli.main.main`).
EXIT_FAILED_ROWS = 1


class FinalizeRun(Callback):
    """Aggregate job files, evaluate claims and build the report after a run or multirun.

    Before, an earlier run's Hydra config in the same folder is kept under a numbered name
    (:func:`~simbench.runs.run_dirs.keep_earlier_configs`).

    Every job has finished by then; when a row of the aggregated ``summary.parquet``
    failed (an exception, not a divergence), it prints how many on one line and ends
    the process with :data:`EXIT_FAILED_ROWS`, so a script or CI sees it.
    """

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        keep_earlier_configs(Path(config.hydra.run.dir))  # before Hydra writes this run's .hydra

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        keep_earlier_configs(Path(config.hydra.sweep.dir))
        if config.get("progress"):  # the sweep's one progress bar, from the first job to the last
            start_sweep_bar(config.hydra.sweep.dir)

    def on_run_end(self, config: DictConfig, **kwargs: Any) -> None:
        self._finalize(Path(config.results_dir), config, sweep=False)

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        end_sweep_bar(config.hydra.sweep.dir)  # at N/N before the summary prints
        self._finalize(Path(config.hydra.sweep.dir), config, sweep=True)

    @staticmethod
    def _finalize(run_dir: Path, config: DictConfig, sweep: bool) -> None:
        if not (run_dir / "jobs").is_dir():
            return  # nothing ran (e.g. a config error stopped the job)
        # the keys of the root config are strings, and so are those of the dict it becomes
        run_config = OmegaConf.masked_copy(config, cast(list[str], [k for k in config if k != "hydra"]))
        try:
            report = finalize(run_dir, cast(dict[str, Any], OmegaConf.to_container(run_config, resolve=True)))
        except SimbenchError as exc:  # e.g. report.formats: one line, not Hydra's callback warning
            print(f"error: {exc}", file=sys.stderr)
            raise SystemExit(2) from exc
        print(f"results: {run_dir.resolve()}  report: {report.resolve() / 'index.html'}", file=sys.stderr)
        summary_path = run_dir.resolve() / "summary.parquet"
        summary = pd.read_parquet(summary_path)
        if sweep:  # a single run printed its rows already; a sweep ends with each group's leaderboard, as the report's
            print(terminal_summary(report))
        status = summary["status"]
        failed = int((status == "failed").sum())
        if failed:
            print(f"{failed} of {len(status)} rows failed: see {summary_path}", file=sys.stderr)
            # SystemExit passes Hydra's callback guard, which turns exceptions into warnings
            raise SystemExit(EXIT_FAILED_ROWS)
