"""``python -m simbench``: simulate, run estimators, write results and a report.

The Hydra app composes ``conf/config.yaml``. Each Hydra job is one scenario
(config + seed) with the selected estimators (:func:`simbench.jobs.run_job`);
after a run or a multirun the :class:`simbench.callbacks.FinalizeRun` callback
aggregates the job files into ``summary.parquet``/``epochs.parquet`` and
builds ``claims.csv`` and ``report/``.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig, open_dict

from simbench.compose import CONF_DIR, check_group_choices, compose_config
from simbench.errors import SimbenchError

SHOWN = ["estimator", "variant", "status", "availability", "horizontal_median", "horizontal_mean",
         "horizontal_p95", "horizontal_max", "error_3d_median", "update_median_s", "message"]


@hydra.main(config_path=str(CONF_DIR), config_name="config", version_base="1.3")
def _app(cfg: DictConfig) -> None:
    from simbench.jobs import run_job

    hc = HydraConfig.get()
    if hc.mode == RunMode.MULTIRUN:
        # the sweep directory is resolved once by the launcher; a ${now:} in results_dir is not
        with open_dict(cfg):
            cfg.results_dir = hc.sweep.dir
    try:
        if cfg.progress:
            print(f"job: scenario={cfg.scenario.name} receiver={cfg.receiver.name} seed={cfg.seed} "
                  f"estimators={','.join(cfg.estimator)}", file=sys.stderr)
        rows = run_job(cfg, fail_fast=hc.mode != RunMode.MULTIRUN)
    except SimbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
    if hc.mode != RunMode.MULTIRUN:
        print(rows.reindex(columns=SHOWN).to_string(index=False, float_format=lambda v: f"{v:.3f}"))


def main() -> None:
    """Entry point: compose once up front so a bad override gets one line, not Hydra's error page."""
    args = sys.argv[1:]
    composable = not any(a.startswith("-") for a in args) and not any("," in a or "(" in a for a in args)
    try:
        # group options are checked for sweeps and flags too: Hydra would only say "Could not load"
        check_group_choices(a for a in args if not a.startswith("-"))
        cfg = compose_config(args) if composable else None
    except SimbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
    if cfg is not None and "studies" in cfg:
        sys.exit(run_studies(list(cfg.studies), Path(cfg.results_dir), args))
    _app()


def run_studies(studies: list[str], root: Path, args: list[str]) -> int:
    """Run several sweeps into ``root/<study>`` one after another, then one aggregate over all of them."""
    from simbench.report.build import finalize

    passed = [a for a in args if not a.startswith(("+sweep=", "sweep_name=", "results_dir="))]
    failed = []
    for study in studies:
        print(f"=== study {study}", file=sys.stderr)
        code = subprocess.call([sys.executable, "-m", "simbench", f"+sweep={study}",
                                f"results_dir={root / study}", *passed])
        if code:
            failed.append(study)  # its finished jobs are in the store; the others still run
    report = finalize(root, {"studies": studies, "args": passed})
    print(f"results: {root.resolve()}  report: {report.resolve() / 'index.html'}", file=sys.stderr)
    if failed:
        print(f"error: studies {', '.join(failed)} exited with errors -- see their logs in {root}", file=sys.stderr)
    return 1 if failed else 0
