"""One job of a run or sweep: one scenario (config + seed), the selected estimators.

A job reads its scenario from the run's cache (generating it once), skips
estimators whose results are already in the store, and writes each
estimator's rows as soon as it finishes, so a killed sweep loses at most the
estimator that was running. In a sweep, a job that cannot even build its
scenario records a failed row for every estimator it was asked to run; a
single run stops with the one-line error instead.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol, cast

import pandas as pd
from omegaconf import DictConfig, OmegaConf
from threadpoolctl import threadpool_limits
from tqdm.auto import tqdm

import estimators
from simbench import source_registry as sources
from simbench.errors import SimbenchError, one_line
from simbench.runs.plan import JobPlan, plan_job
from simbench.runs.provenance import code_identity, provenance
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS, run_estimators
from simbench.runs.scenarios import check_scenario, input_digests, scenario_key, source_code
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
    plan = plan_job(cfg)  # the config typed once; the job reads only the plan
    opts = plan.options
    if bar is not None:
        with threadpool_limits(limits=opts.blas_threads or 1):
            return _run_job(cfg, plan, fail_fast=fail_fast, bar=bar)
    with (
        tqdm(total=len(plan.estimators), desc="estimators", unit="est", disable=not opts.progress, leave=False) as own,
        threadpool_limits(limits=opts.blas_threads or 1),
    ):
        return _run_job(cfg, plan, fail_fast=fail_fast, bar=own)


def _run_job(cfg: DictConfig, plan: JobPlan, *, fail_fast: bool, bar: Progress) -> pd.DataFrame:
    sim, opts = plan.settings, plan.options
    root = Path(opts.results_dir)
    key = scenario_key(sim)
    # an estimator's result is keyed by its code too, so an edited estimator is recomputed
    codes = {name: code_identity(estimators.get(name).__module__) for name in plan.estimators}
    stems = {name: result_stem(root, key, name, e.node, codes[name]) for name, e in plan.estimators.items()}
    pending = {name: e for name, e in plan.estimators.items() if not is_finished(stems[name])}
    # the overrides of a row are relative to its gnss_model preset (as shipped), so the preset joins the row
    tags = {"sweep": opts.sweep_name, "scenario_key": key, "gnss_model": plan.gnss_model}
    shared = [Path(p) for p in opts.shared_results if Path(p).resolve() != root.resolve()]
    for name in list(pending):
        if any(
            adopt_result(stems[name], result_stem(other, key, name, pending[name].node, codes[name]), tags)
            for other in shared
        ):
            del pending[name]
    if shared:
        adopt_cache(root, key, shared)
    bar.update(len(plan.estimators) - len(pending))  # found in the store: done
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
        for name, planned in pending.items():
            bar.set_postfix_str(f"{label} seed {sim.seed}: {name}")
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
                # the typed config; the node when it does not type-check (the runner's failed row says why)
                config = planned.config if planned.config is not None else planned.node
                result = run_estimators(scenario, {name: config}, receiver=receiver, progress=False)
                summary, epochs, diag = result.summary, result.epochs, result.diagnostics.get(name, {})
            columns = {**tags, "variant": planned.variant, "overrides": planned.overrides_text}
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
