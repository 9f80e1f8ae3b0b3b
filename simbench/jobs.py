"""One job of a run or sweep: one scenario (config + seed), the selected estimators.

A job reads its scenario from the run's cache (generating it once), skips
estimators whose results are already in the store, and writes each
estimator's rows as soon as it finishes, so a killed sweep loses at most the
estimator that was running. A job that cannot even build its scenario
records a failed row for every estimator it was asked to run.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pandas as pd
import yaml
from omegaconf import DictConfig, OmegaConf

from simbench.compose import CONF_DIR
from simbench.config import SimConfig, to_typed, validate_sim
from simbench.provenance import provenance
from simbench.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS, one_line, run_estimators
from simbench.scenarios import build_scenario
from simbench.store import cached_scenario, config_key, is_finished, result_stem, write_result


@dataclasses.dataclass
class RunOptions:
    """Top-level keys of ``conf/config.yaml`` besides the config groups."""

    results_dir: str = "results/run"
    progress: bool = True
    sweep_name: str = ""  #: name of the sweep this job belongs to ('' for a single run)


def run_job(cfg: DictConfig, *, fail_fast: bool = True) -> pd.DataFrame:
    """Run (or resume) one job; return the summary rows of every estimator it covers.

    Parameters
    ----------
    cfg : DictConfig
        The composed Hydra config of this job.
    fail_fast : bool
        Raise :class:`~simbench.errors.SimbenchError` for an invalid scenario
        config (a single run: the user gets one line). In a sweep (False) it
        becomes a failed row like any other job failure and the sweep goes on.
    """
    opts = to_typed({k: cfg[k] for k in ("results_dir", "progress", "sweep_name") if k in cfg}, RunOptions, "config")
    sim = to_typed({k: cfg[k] for k in ("scenario", "receiver", "imu", "seed")}, SimConfig, "config")
    root = Path(opts.results_dir)
    scenario_key = config_key(dataclasses.asdict(sim))
    estimator_cfgs: dict[str, Any] = OmegaConf.to_container(cfg.estimator, resolve=True) or {}
    stems = {name: result_stem(root, scenario_key, name, c) for name, c in estimator_cfgs.items()}
    pending = {name: c for name, c in estimator_cfgs.items() if not is_finished(stems[name])}
    if fail_fast:
        validate_sim(sim)
    meta = provenance(OmegaConf.to_container(cfg, resolve=True))
    tags = {"sweep": opts.sweep_name, "scenario_key": scenario_key}
    if pending:
        try:
            scenario = cached_scenario(root, scenario_key, lambda: build_scenario(sim))
        except Exception as exc:  # a scenario that cannot be built fails its estimators, not the sweep
            scenario, failure = None, one_line(exc)
        for name, est_cfg in pending.items():
            variant = variant_label(name, est_cfg)
            if scenario is None:
                summary = pd.DataFrame([{"scenario": sim.scenario.name, "receiver": sim.receiver.name,
                                         "seed": sim.seed, "estimator": name, "status": "failed",
                                         "message": failure}]).reindex(columns=list(SUMMARY_COLUMNS))
                epochs, diag = pd.DataFrame(columns=list(EPOCH_COLUMNS)), {}
            else:
                result = run_estimators(scenario, {name: est_cfg}, receiver=sim.receiver.name,
                                        progress=opts.progress)
                summary, epochs, diag = result.summary, result.epochs, result.diagnostics.get(name, {})
            summary = summary.assign(**tags, variant=variant)
            epochs = epochs.assign(**tags, variant=variant)
            write_result(stems[name], summary[list(SUMMARY_COLUMNS)], epochs[list(EPOCH_COLUMNS)], diag, meta)
    rows = [pd.read_parquet(stem.with_suffix(".summary.parquet")) for stem in stems.values()
            if stem.with_suffix(".summary.parquet").is_file()]
    return pd.concat(rows, ignore_index=True) if rows else pd.DataFrame(columns=list(SUMMARY_COLUMNS))


def variant_label(name: str, est_cfg: dict[str, Any]) -> str:
    """The estimator's settings that differ from its ``conf/estimator`` defaults, as ``k=v,...``."""
    path = CONF_DIR / "estimator" / f"{name}.yaml"
    defaults = (yaml.safe_load(path.read_text()) or {}).get(name, {}) if path.is_file() else {}
    changed = {k: v for k, v in (est_cfg or {}).items() if defaults.get(k, object()) != v}
    return ",".join(f"{k}={v}" for k, v in sorted(changed.items()))
