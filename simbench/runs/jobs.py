"""One job of a run or sweep: one scenario (config + seed), the selected estimators.

A job reads its scenario from the run's cache (generating it once), skips
estimators whose results are already in the store, and writes each
estimator's rows as soon as it finishes, so a killed sweep loses at most the
estimator that was running. In a sweep, a job that cannot even build its
scenario records a failed row for every estimator it was asked to run; a
single run stops with the one-line error instead.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Protocol, cast

import pandas as pd
from omegaconf import DictConfig, OmegaConf
from threadpoolctl import threadpool_limits
from tqdm.auto import tqdm

import estimators
from simbench import source_registry as sources
from simbench.analysis.variants import overrides_json, overrides_of, variant_label
from simbench.errors import SimbenchError, one_line
from simbench.runs.compose import preset_estimator_config
from simbench.runs.provenance import code_identity, provenance
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS, run_estimators
from simbench.runs.scenarios import check_scenario, input_digests, scenario_key, scenario_settings, source_code
from simbench.runs.store import (
    adopt_cache,
    adopt_result,
    cache_damaged,
    cached_scenario,
    is_finished,
    result_stem,
    write_result,
)
from simbench.source_registry import SIMULATED
from simbench.typed import to_typed


@dataclasses.dataclass
class RunOptions:
    """Top-level keys of ``conf/config.yaml`` besides the config groups."""

    results_dir: str = "results/run"
    progress: bool = True
    sweep_name: str = ""  #: name of the sweep this job belongs to ('' for a single run)
    #: BLAS/OpenMP threads of the job's process; None: 1, or under the command line the
    #: launcher's CPUs per job (``hydra.launcher.cpus_per_task`` of submitit) when set. Our matrices
    #: are small, so extra threads only spin: two jobs with OpenBLAS's default two threads each
    #: on 2 cores ran BCE-AD 13x slower (151 s against 11 s) than with one thread each.
    blas_threads: int | None = None
    #: results_dirs of other runs whose finished results (same scenario, estimator, config and code)
    #: and cached scenarios this run copies instead of computing them: the studies of one world
    #: (``+sweep=thesis``, :func:`simbench.runs.studies.plan`) share their rows this way
    shared_results: list[str] = dataclasses.field(default_factory=list)


class Progress(Protocol):
    """Where a job reports its progress: a tqdm bar, or anything with its two methods (simbench.cli.progress)."""

    def update(self, n: int = 1) -> object: ...

    def set_postfix_str(self, s: str) -> object: ...


def run_job(cfg: DictConfig, *, fail_fast: bool = True, bar: Progress | None = None) -> pd.DataFrame:
    """Run (or resume) one job; return the summary rows of every estimator it covers.

    Parameters
    ----------
    cfg : DictConfig
        The composed Hydra config of this job.
    fail_fast : bool
        Raise :class:`~simbench.errors.SimbenchError` for an invalid scenario
        config or a scenario that cannot be built, e.g. a missing or malformed
        input file (a single run: the user gets one line). In a sweep (False)
        it becomes a failed row like any other job failure and the sweep goes on.
    bar : Progress, optional
        Advanced by one per estimator of this job (a finished one too), its postfix set to the
        step under way (building the scenario, an estimator); None: with ``progress`` set, a
        tqdm bar over this job's estimators.
    """
    opts = to_typed(
        {k: cfg[k] for k in (f.name for f in dataclasses.fields(RunOptions)) if k in cfg}, RunOptions, "config"
    )
    if opts.blas_threads is not None and opts.blas_threads < 1:
        raise SimbenchError("blas_threads", f"is {opts.blas_threads}", "set blas_threads to 1 or more (or null)")
    if bar is not None:
        with threadpool_limits(limits=opts.blas_threads or 1):
            return _run_job(cfg, opts, fail_fast=fail_fast, bar=bar)
    with (
        tqdm(total=len(cfg.estimator), desc="estimators", unit="est", disable=not opts.progress, leave=False) as own,
        threadpool_limits(limits=opts.blas_threads or 1),
    ):
        return _run_job(cfg, opts, fail_fast=fail_fast, bar=own)


def _run_job(cfg: DictConfig, opts: RunOptions, *, fail_fast: bool, bar: Progress) -> pd.DataFrame:
    sim = scenario_settings(cfg)
    root = Path(opts.results_dir)
    key = scenario_key(sim)
    estimator_cfgs = cast(dict[str, Any], OmegaConf.to_container(cfg.estimator, resolve=True, enum_to_str=True) or {})
    # an estimator's result is keyed by its code too, so an edited estimator is recomputed
    codes = {name: code_identity(estimators.get(name).__module__) for name in estimator_cfgs}
    stems = {name: result_stem(root, key, name, c, codes[name]) for name, c in estimator_cfgs.items()}
    pending = {name: c for name, c in estimator_cfgs.items() if not is_finished(stems[name])}
    # the overrides of a row are relative to its gnss_model preset (as shipped), so the preset joins the row
    gnss_model = str(cfg.gnss_model.name)
    tags = {"sweep": opts.sweep_name, "scenario_key": key, "gnss_model": gnss_model}
    shared = [Path(p) for p in opts.shared_results if Path(p).resolve() != root.resolve()]
    for name in list(pending):
        if any(
            adopt_result(stems[name], result_stem(other, key, name, pending[name], codes[name]), tags)
            for other in shared
        ):
            del pending[name]
    if shared:
        adopt_cache(root, key, shared)
    bar.update(len(estimator_cfgs) - len(pending))  # found in the store: done
    meta = provenance(cast(dict[str, Any], OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)))
    meta["simbench.inputs"] = input_digests(sim)  # the content of each file read (also in the scenario key)
    # a damaged cached scenario is rebuilt even when every result is finished: later jobs and the report read it
    # a receiver preset describes simulated data only; a log's receiver is in its own files
    receiver = sim.receiver.name if sim.scenario.source == SIMULATED else ""
    label = sources.get(sim.scenario.source)().label(sim)
    if pending or cache_damaged(root, key):
        try:
            # the job's one check of its data config (the source's, e.g. validate_sim); loading trusts it
            source = check_scenario(sim)
            bar.set_postfix_str(f"{label} seed {sim.seed}: reading or building the scenario")
            scenario = cached_scenario(root, key, lambda: source.load(sim))
        except Exception as exc:
            if fail_fast:  # a single run ends with one line instead of a failed row per estimator
                if isinstance(exc, SimbenchError):
                    raise
                raise SimbenchError(
                    "scenario", f"cannot be built: {one_line(exc)}", "check the scenario settings and input files"
                ) from exc
            # in a sweep it fails this job's estimators, not the sweep
            scenario, failure = None, one_line(exc)
        for name, est_cfg in pending.items():
            bar.set_postfix_str(f"{label} seed {sim.seed}: {name}")
            overrides = estimator_overrides(name, est_cfg, gnss_model)
            if scenario is None:
                summary = pd.DataFrame(
                    [
                        {
                            "scenario": label,
                            "source": sim.scenario.source,
                            "receiver": receiver,
                            "seed": sim.seed,
                            "estimator": name,
                            "status": "failed",
                            "message": failure,
                        }
                    ]
                ).reindex(columns=list(SUMMARY_COLUMNS))
                epochs, diag = pd.DataFrame(columns=list(EPOCH_COLUMNS)), {}
            else:
                result = run_estimators(scenario, {name: est_cfg}, receiver=receiver, progress=False)
                summary, epochs, diag = result.summary, result.epochs, result.diagnostics.get(name, {})
            columns = {**tags, "variant": variant_label(overrides), "overrides": overrides_json(overrides)}
            summary = summary.assign(**columns)
            epochs = epochs.assign(**columns)
            code = {"estimator": codes[name], "source": source_code(sim.scenario.source)}
            write_result(
                stems[name],
                summary[list(SUMMARY_COLUMNS)],
                epochs[list(EPOCH_COLUMNS)],
                diag,
                {**meta, "simbench.code": code},
            )
            bar.update(1)
    rows = [
        pd.read_parquet(stem.with_suffix(".summary.parquet"))
        for stem in stems.values()
        if stem.with_suffix(".summary.parquet").is_file()
    ]
    return pd.concat(rows, ignore_index=True) if rows else pd.DataFrame(columns=list(SUMMARY_COLUMNS))


def estimator_overrides(name: str, est_cfg: dict[str, Any], gnss_model: str) -> dict[str, Any]:
    """The settings of one estimator's composed config that differ from its ``Config`` dataclass
    defaults under ``gnss_model`` preset ``gnss_model`` (:func:`preset_estimator_config`).

    A config that does not type-check has none: the runner records it as a
    failed row with the one-line reason, and a failed row is in no statistic.

    Raises
    ------
    SimbenchError
        When ``conf/gnss_model/`` has no preset ``gnss_model``.
    """
    try:
        typed: object = to_typed(est_cfg or {}, estimators.get(name).Config, f"estimator.{name}")
    except SimbenchError:
        return {}
    return overrides_of(typed, preset_estimator_config(name, gnss_model))
