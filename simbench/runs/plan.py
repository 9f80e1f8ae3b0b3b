"""A job's plan: its composed config typed once, and what every later step reads instead of the config.

:func:`plan_job` turns one job's composed ``conf/config.yaml`` into a :class:`JobPlan`: the run
options, the typed scenario settings, the ``gnss_model`` preset, and per selected estimator its
node (the result key), its typed ``Config`` and the settings in which it differs from that
``Config``'s defaults under the preset (the ``overrides`` and ``variant`` columns). The job
(:func:`simbench.runs.jobs.run_job`) and the runner read the plan; none of them converts the
config again.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, cast

from omegaconf import DictConfig, OmegaConf

import estimators
from simbench.analysis.variants import overrides_json, overrides_of, variant_label
from simbench.errors import SimbenchError
from simbench.runs.compose import preset_estimator_config
from simbench.runs.scenarios import ScenarioSettings, scenario_settings
from simbench.typed import to_typed

__all__ = ["RunOptions", "EstimatorPlan", "JobPlan", "plan_job"]


@dataclass
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


@dataclass(frozen=True)
class EstimatorPlan:
    """One selected estimator of a job."""

    name: str
    #: the composed node, resolved, choices as their YAML words (None for ``estimator.<name>: null``): what
    #: the result is keyed by
    node: Any
    #: the node typed by the estimator's ``Config``; None when it does not type-check (the runner then
    #: records the failed row with the reason, from ``node``)
    config: Any
    #: the fields that differ from the ``Config`` defaults under the job's ``gnss_model`` preset
    overrides: dict[str, Any]

    @property
    def variant(self) -> str:
        """The ``variant`` column: a label of :attr:`overrides` (:func:`variant_label`)."""
        return variant_label(self.overrides)

    @property
    def overrides_text(self) -> str:
        """The ``overrides`` column: :attr:`overrides` as canonical JSON (:func:`overrides_json`)."""
        return overrides_json(self.overrides)


@dataclass(frozen=True)
class JobPlan:
    """A job's composed config, typed once (:func:`plan_job`)."""

    options: RunOptions
    settings: ScenarioSettings
    gnss_model: str  #: the preset the estimators' overrides are relative to (as shipped)
    estimators: dict[str, EstimatorPlan]


def plan_job(cfg: DictConfig) -> JobPlan:
    """Type a job's composed config once: options, scenario settings and each selected estimator.

    Raises
    ------
    SimbenchError
        For run options or scenario settings that do not type-check, ``blas_threads`` below 1, an unknown
        source or ``gnss_model`` preset, naming the key. An estimator node that does not type-check is
        no error here (:attr:`EstimatorPlan.config` is None).
    """
    names = [f.name for f in dataclasses.fields(RunOptions)]
    options = to_typed({k: cfg[k] for k in names if k in cfg}, RunOptions, "config")
    if options.blas_threads is not None and options.blas_threads < 1:
        raise SimbenchError("blas_threads", f"is {options.blas_threads}", "set blas_threads to 1 or more (or null)")
    gnss_model = str(cfg.gnss_model.name)
    nodes = cast(dict[str, Any], OmegaConf.to_container(cfg.estimator, resolve=True, enum_to_str=True) or {})
    return JobPlan(
        options=options,
        settings=scenario_settings(cfg),
        gnss_model=gnss_model,
        estimators={name: plan_estimator(name, node, gnss_model) for name, node in nodes.items()},
    )


def plan_estimator(name: str, node: Any, gnss_model: str) -> EstimatorPlan:
    """One estimator's plan: ``node`` typed by its ``Config``, and its overrides relative to that ``Config``'s
    defaults under ``gnss_model`` preset ``gnss_model`` (:func:`preset_estimator_config`); none when the
    node does not type-check (a failed row is in no statistic).

    Raises
    ------
    SimbenchError
        For an unknown estimator, or when ``conf/gnss_model/`` has no preset ``gnss_model``.
    """
    config_class: type[Any] = estimators.get(name).Config
    try:
        config = to_typed(node or {}, config_class, f"estimator.{name}")
    except SimbenchError:
        return EstimatorPlan(name=name, node=node, config=None, overrides={})
    overrides = overrides_of(config, preset_estimator_config(name, gnss_model))
    return EstimatorPlan(name=name, node=node, config=config, overrides=overrides)
