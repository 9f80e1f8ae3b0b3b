"""The Python API: :func:`scenario` builds any scenario (simulated or a real log), :func:`simulate` a
simulated one, :func:`run` a study from a notebook, with the command line's cache and store.

``simbench.run(...)`` composes the same ``conf/`` configuration the command
line composes for ``python -m simbench ... seed=0,1 -m``, runs each seed as one
job through :func:`simbench.runs.jobs.run_job` (the scenario from the run's cache,
finished results from the store) and rebuilds the aggregate, ``claims.csv`` and
``report/`` with :func:`simbench.report.build.finalize`, as the CLI's
:class:`~simbench.cli.callbacks.FinalizeRun` does. So a notebook and a sweep into the
same ``results_dir`` share scenarios and results: whichever runs second finds
the other's and skips them.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import pandas as pd
from omegaconf import OmegaConf
from tqdm.auto import tqdm

from simbench.contract import Scenario
from simbench.errors import SimbenchError
from simbench.report.build import finalize
from simbench.runs.checks import check_run
from simbench.runs.compose import compose_config, overrides_from_kwargs
from simbench.runs.jobs import run_job
from simbench.runs.run_dirs import unique_run_dir
from simbench.runs.scenarios import build_scenario, scenario_settings, simulate

__all__ = ["StudyResult", "run", "scenario", "simulate"]

#: Columns that identify one result (one estimator setting on one scenario) in the store.
RESULT_KEY = ["scenario_key", "estimator", "overrides"]


@dataclass(frozen=True)
class StudyResult:
    """What :func:`run` returns.

    Attributes
    ----------
    summary : pandas.DataFrame
        One row per seed x estimator of this study (:data:`~simbench.runs.runner.SUMMARY_COLUMNS`),
        freshly computed or found in the store.
    epochs : pandas.DataFrame
        Their per-epoch errors (:data:`~simbench.runs.runner.EPOCH_COLUMNS`).
    claims : pandas.DataFrame
        ``claims.csv`` of ``results_dir`` (every result in it, earlier studies included).
    report : Path
        The report directory (``index.html``, ``README.md``, figures) of ``results_dir``.
    results_dir : Path
        Where the cache, the store and the aggregate are.
    """

    summary: pd.DataFrame
    epochs: pd.DataFrame
    claims: pd.DataFrame
    report: Path
    results_dir: Path


def scenario(name: str, seed: int = 0, **overrides: Any) -> Scenario:
    """Build any scenario the way a run does: a simulated preset or a real log.

    Parameters
    ----------
    name : str
        A preset in ``conf/scenario/``: simulated (``urban``, ``open_sky``, ...) or a
        real log (``hk_tst_2019``, ``nagoya_static``, ``rinex`` with its files given).
    seed : int
        Random seed of a simulated scenario (a real log ignores it).
    **overrides
        Dotted config keys, e.g. ``receiver="high"``, ``**{"scenario.obs": "a.obs"}``,
        or with ``__`` for dots: ``scenario__systems="GC"``; a list value
        (``scenario__nav=["a.20n", "b.20n"]``) gives several files.

    Returns
    -------
    Scenario
        What a receiver gives (``receiver_view()``) beside the truth; a real log's ``labels`` is None.

    Raises
    ------
    SimbenchError
        An unknown preset or key, missing files of a real log, or any reader's one-line error.
    """
    cfg = compose_config([f"scenario={name}", f"seed={seed}", *overrides_from_kwargs(overrides)])
    return build_scenario(scenario_settings(cfg))


def run(
    scenario: str = "urban",
    receiver: str = "low",
    estimators: Sequence[str] | None = None,
    seeds: int | Iterable[int] = 0,
    imu: str = "consumer",
    overrides: Mapping[str, Any] | None = None,
    results_dir: str | Path | None = None,
    progress: bool = True,
) -> StudyResult:
    """Run the estimators on each seed of a scenario, score them and build the report.

    Parameters
    ----------
    scenario, receiver, imu : str
        Options of the config groups (files in ``conf/scenario/``, ``conf/receiver/``, ``conf/imu/``).
    estimators : sequence of str, optional
        Estimator names, e.g. ``["l2", "dcs"]``; None runs the default list of ``conf/config.yaml``.
    seeds : int or iterable of int
        Scenario seeds, e.g. ``range(5)``; each seed is one job.
    overrides : mapping, optional
        Dotted config keys and values as on the command line, e.g.
        ``{"scenario.duration_s": 60, "estimator.dcs.prior_scale": 2.0, "sweep_name": "nb"}``.
    results_dir : str or Path, optional
        Run directory; the command line's default (``results/run-<time>``, ``-2`` added when a run of the same
        second has it) when None.
        Give the ``results_dir`` of a sweep to reuse its scenarios and results.
    progress : bool
        Progress bars over seeds and estimators.

    Returns
    -------
    StudyResult

    Raises
    ------
    SimbenchError
        An unknown option, a malformed override or a value :func:`simbench.runs.checks.check_run`
        refuses (before any job); with a single seed also a scenario that cannot
        be built (with several, like a sweep, that seed's rows record the failure and the others run).
    """
    seed_list = [seeds] if isinstance(seeds, int) else [int(s) for s in seeds]
    if not seed_list:
        raise SimbenchError("seeds", "is empty", "give at least one seed, e.g. seeds=range(5)")
    names = [estimators] if isinstance(estimators, str) else estimators
    base = [
        f"scenario={scenario}",
        f"receiver={receiver}",
        f"imu={imu}",
        f"progress={str(progress).lower()}",
        *([f"estimator=[{','.join(names)}]"] if names is not None else []),
        *overrides_from_kwargs(dict(overrides or {})),
    ]
    # resolved once: each composition would give ${now:} another time; the default folder is claimed, so two
    # runs of one second get one each (simbench.runs.run_dirs)
    claimed: Path | None = None
    if results_dir is None:
        root = claimed = unique_run_dir(Path(compose_config(base).results_dir))
    else:
        root = Path(results_dir)
    base.append(f"results_dir={root}")
    try:
        configs = [compose_config([*base, f"seed={seed}"]) for seed in seed_list]
        for cfg in configs:  # every config error before any job
            check_run(cfg)
    except SimbenchError:
        if claimed is not None and not any(claimed.iterdir()):
            claimed.rmdir()
        raise
    rows = [
        run_job(cfg, fail_fast=len(configs) == 1)
        for cfg in tqdm(configs, desc="seeds", disable=not progress or len(configs) == 1)
    ]
    summary = pd.concat(rows, ignore_index=True)
    # a DictConfig becomes a dict with the config's (string) keys
    run_config = cast(dict[str, Any], OmegaConf.to_container(configs[0], resolve=True, enum_to_str=True))
    run_config["seed"] = seed_list
    report = finalize(root, run_config)
    everything = pd.read_parquet(root / "epochs.parquet")
    epochs = everything.merge(summary[RESULT_KEY], on=RESULT_KEY)
    return StudyResult(
        summary=summary, epochs=epochs, claims=pd.read_csv(root / "claims.csv"), report=report, results_dir=root
    )
