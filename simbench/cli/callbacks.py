"""Hydra callbacks: build the run's aggregate, claims and report when jobs end."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any, cast

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from simbench.report.build import finalize


class FinalizeRun(Callback):
    """Aggregate job files, evaluate claims and build the report after a run or multirun."""

    def on_run_end(self, config: DictConfig, **kwargs: Any) -> None:
        self._finalize(Path(config.results_dir), config)

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        self._finalize(Path(config.hydra.sweep.dir), config)

    @staticmethod
    def _finalize(run_dir: Path, config: DictConfig) -> None:
        if not (run_dir / "jobs").is_dir():
            return  # nothing ran (e.g. a config error stopped the job)
        # the keys of the root config are strings, and so are those of the dict it becomes
        run_config = OmegaConf.masked_copy(config, cast(list[str], [k for k in config if k != "hydra"]))
        report = finalize(run_dir, cast(dict[str, Any], OmegaConf.to_container(run_config, resolve=True)))
        print(f"results: {run_dir.resolve()}  report: {report.resolve() / 'index.html'}", file=sys.stderr)
