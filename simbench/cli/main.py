"""``python -m simbench``: simulate, run estimators, write results and a report; and the subcommands.

The Hydra app composes ``conf/config.yaml``. Each Hydra job is one scenario
(config + seed) with the selected estimators (:func:`simbench.runs.jobs.run_job`);
after a run or a multirun the :class:`simbench.cli.callbacks.FinalizeRun` callback
aggregates the job files into ``summary.parquet``/``epochs.parquet`` and
builds ``claims.csv`` and ``report/``.
"""

from __future__ import annotations

import inspect
import sys
from collections.abc import Callable
from pathlib import Path

import hydra
import pandas as pd
from hydra.core.hydra_config import HydraConfig
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException
from hydra.types import RunMode
from omegaconf import DictConfig, open_dict
from tabulate import tabulate

import estimators
from simbench.cli import export, report, score, tables, validate, zero_baseline
from simbench.cli.studies import run_studies
from simbench.cli.terminal import SHOWN, one_line_warnings
from simbench.errors import SimbenchError
from simbench.runs.compose import CONF_DIR, check_group_choices, compose_config, register_schemas
from simbench.runs.jobs import run_job
from simbench.runs.studies import StudiesConfig

#: ``python -m simbench NAME ...``: the commands beside Hydra runs and sweeps, each ``main(argv) -> exit code``.
SUBCOMMANDS: dict[str, Callable[[list[str]], int]] = {
    "report": report.main,
    "export": export.main,
    "score": score.main,
    "tables": tables.main,
    "validate": validate.main,
    "zero-baseline": zero_baseline.main,
}


@hydra.main(config_path=str(CONF_DIR), config_name="config", version_base="1.3")
def _app(cfg: DictConfig) -> None:
    one_line_warnings()  # again: a launcher may run the job in another process
    hc = HydraConfig.get()
    with open_dict(cfg):
        if hc.mode == RunMode.MULTIRUN:
            # the sweep directory is resolved once by the launcher; a ${now:} in results_dir is not
            cfg.results_dir = hc.sweep.dir
        if cfg.blas_threads is None:  # a cluster job uses the CPUs its launcher reserved (submitit)
            cfg.blas_threads = hc.launcher.get("cpus_per_task")
    try:
        if cfg.progress:
            print(
                f"job: scenario={cfg.scenario.name} receiver={cfg.receiver.name} seed={cfg.seed} "
                f"estimators={','.join(cfg.estimator)}",
                file=sys.stderr,
            )
        rows = run_job(cfg, fail_fast=hc.mode != RunMode.MULTIRUN)
    except SimbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
    if hc.mode != RunMode.MULTIRUN:
        print(rows.reindex(columns=SHOWN).to_string(index=False, float_format=lambda v: f"{v:.3f}"))


def main() -> None:
    """Entry point: a subcommand (:data:`SUBCOMMANDS`), or a Hydra run or sweep.

    A run is composed once up front so a bad override gets one line, not Hydra's error page.
    """
    one_line_warnings()
    args = sys.argv[1:]
    if args and args[0] in SUBCOMMANDS:
        sys.exit(SUBCOMMANDS[args[0]](args[1:]))
    try:
        register_schemas()  # a broken plug-in estimator stops here, in one line naming its package
        if "--estimators" in args:
            print(tabulate(estimator_table(), headers="keys", tablefmt="plain", showindex=False))
            return
        # group options are checked for sweeps and flags too: Hydra would only say "Could not load"
        check_group_choices(a for a in args if not a.startswith("-"))
        shaping = config_overrides(args)
        cfg = compose_config(shaping) if shaping is not None else None
        if cfg is not None and "studies" in cfg:  # a sweep of sweeps (thesis): studies x worlds
            sys.exit(run_studies(StudiesConfig.from_config(cfg), Path(cfg.results_dir), args))
    except SimbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
    _app()


def config_overrides(args: list[str]) -> list[str] | None:
    """The command-line arguments that shape the config: all but sweeps and ``hydra.*`` settings.

    Hydra expands sweeps per job and applies its own settings itself; a setting like
    ``hydra.sweeper.params.seed=0`` does not even compose for a sweep file without
    sweeper params (``thesis``, whose studies it is meant for).

    None when there is a flag (``-m``, ``--help``) or an argument Hydra's parser
    rejects: Hydra then handles the command line itself.
    """
    if any(a.startswith("-") for a in args):
        return None
    try:
        parsed = OverridesParser.create().parse_overrides(args)
    except HydraException:
        return None
    return [a for a, o in zip(args, parsed) if not o.is_sweep_override() and not o.key_or_group.startswith("hydra.")]


def estimator_table() -> pd.DataFrame:
    """The registered estimators (``python -m simbench --estimators``).

    Returns
    -------
    pandas.DataFrame
        Columns ``name``, ``family`` (the module defining the class, without the
        ``estimators.`` prefix of the built-ins), ``source`` (``built-in`` or the
        plug-in's package) and ``description`` (the first line of the class docstring).
    """
    rows = [
        {
            "name": name,
            "family": cls.__module__.removeprefix("estimators."),
            "source": estimators.source(name),
            "description": (inspect.getdoc(cls) or "").partition("\n")[0],
        }
        for name, cls in estimators.registered().items()
    ]
    return pd.DataFrame(rows, columns=["name", "family", "source", "description"])
