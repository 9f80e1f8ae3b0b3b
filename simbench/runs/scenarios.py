"""Where a scenario comes from: the one function the CLI and sweeps call.

``scenario.source`` names a registered source (:mod:`simbench.source_registry`): the
simulator, a RINEX or libRSF log, or a plug-in's. :func:`build_scenario` looks it
up by name, so the CLI and the sweep cache need not know any of them.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig, OmegaConf

from simbench import source_registry as sources
from simbench.contract import Scenario, config_key
from simbench.errors import SimbenchError
from simbench.paths import file_digest
from simbench.runs.compose import compose_config, overrides_from_kwargs
from simbench.runs.provenance import code_identity
from simbench.sim.config import ImuConfig, ReceiverConfig, ScenarioConfig, SimConfig, sim_config_of
from simbench.source_registry import SIMULATED, DataConfig, Source, SourceConfig
from simbench.typed import to_typed

#: The keys of a composed ``conf/config.yaml`` that describe the data (the rest picks estimators and output).
SIM_KEYS = ("scenario", "receiver", "imu", "seed")


@dataclass
class ScenarioSettings:
    """The typed data part of a composed config: the ``scenario`` node typed by its source's
    ``Config``, and the receiver, IMU and seed a simulating source uses."""

    scenario: SourceConfig = field(default_factory=ScenarioConfig)
    receiver: ReceiverConfig = field(default_factory=ReceiverConfig)
    imu: ImuConfig = field(default_factory=ImuConfig)
    seed: int = 0


def scenario_settings(cfg: Mapping[str, Any], config: type[SourceConfig] | None = None) -> ScenarioSettings:
    """The typed :class:`ScenarioSettings` of a composed ``conf/config.yaml``.

    ``config``: the ``Config`` of the source ``scenario.source`` names, when the caller has it
    (the command line's door, :mod:`simbench.runs.schema_record`); None: the registered source's.

    Raises
    ------
    SimbenchError
        For an unknown ``scenario.source``, or a value that does not type-check, naming the key.
    """
    node = cfg["scenario"]
    name = str(node.get("source", SIMULATED))
    config = config if config is not None else sources.get(name).Config
    preset = OmegaConf.get_type(node) if isinstance(node, DictConfig) else None
    if isinstance(preset, type) and dataclasses.is_dataclass(preset) and not issubclass(config, preset):
        raise SimbenchError(
            "scenario.source",
            f"source '{name}' cannot read a scenario preset of {preset.__name__}",
            f"pick the source with its own preset, e.g. scenario={name}",
        )
    scenario = to_typed(node, config, "scenario")
    rest = to_typed({k: cfg[k] for k in SIM_KEYS if k != "scenario"}, SimConfig, "")
    return ScenarioSettings(scenario=scenario, receiver=rest.receiver, imu=rest.imu, seed=rest.seed)


def sim_config(cfg: Mapping[str, Any]) -> SimConfig:
    """The typed :class:`SimConfig` of a composed ``conf/config.yaml`` with a simulated scenario.

    Raises
    ------
    SimbenchError
        For a value that does not type-check, naming the key, or a scenario of another source.
    """
    return sim_config_of(scenario_settings(cfg))


def scenario_key(cfg: ScenarioSettings) -> str:
    """The cache key of the scenario ``cfg`` describes (:func:`simbench.runs.store.config_key`): its
    settings, the code identity of its source (:func:`source_code`) and the content of every file the
    source reads (:func:`input_digests`), so a scenario is generated or read again once that code or
    an input file changes (a truth file edited in place; a relative path naming another file)."""
    code = source_code(cfg.scenario.source)
    return config_key({**dataclasses.asdict(cfg), "code": code, "inputs": input_digests(cfg)})


def input_digests(cfg: DataConfig) -> dict[str, list[str]]:
    """The content digest (:func:`simbench.paths.file_digest`) of each file the source of ``cfg`` reads, by
    setting; a file that does not exist (yet) is ``'missing'``, left to the source's own check."""
    files = sources.get(cfg.scenario.source)().input_files(cfg)
    return {key: [file_digest(p) if os.path.isfile(p) else "missing" for p in paths] for key, paths in files.items()}


def source_code(name: str) -> str:
    """The code identity (:func:`~simbench.runs.provenance.code_identity`) of the source registered as
    ``name``: its module and what that imports, e.g. the simulator's generator or the RINEX reader."""
    return code_identity(sources.get(name).__module__)


def scenario_from_overrides(overrides: Sequence[str]) -> tuple[ScenarioSettings, Scenario]:
    """Compose ``conf/config.yaml`` with command-line style overrides (``scenario=hk_tst_2019``,
    ``receiver=high``, ``seed=3``) and build that scenario; return the typed config and the scenario."""

    settings = scenario_settings(compose_config(list(overrides)))
    return settings, build_scenario(settings)


def check_scenario(cfg: DataConfig) -> Source:
    """The source ``cfg.scenario.source`` names, once it has checked ``cfg`` (:meth:`Source.check`).

    Raises
    ------
    SimbenchError
        For an unknown source or a config it cannot load, in one line.
    """
    found = sources.get(cfg.scenario.source)()
    found.check(cfg)
    return found


def build_scenario(cfg: DataConfig) -> Scenario:
    """Generate (or load) the scenario a typed config describes.

    ``cfg`` is a :class:`ScenarioSettings` or, for the simulator, a :class:`SimConfig`;
    ``scenario.source`` picks the source (:func:`simbench.source_registry.get`).
    """
    return check_scenario(cfg).load(cfg)


def simulate(
    scenario: str = "urban", receiver: str = "low", seed: int = 0, imu: str = "consumer", **overrides: Any
) -> Scenario:
    """Generate a scenario from the presets in ``conf/``.

    Parameters
    ----------
    scenario : str
        A file name in ``conf/scenario/`` (``urban``, ``open_sky``, ``flight``, ``replay``).
    receiver : str
        A tracking preset in ``conf/receiver/`` (``low``, ``high``, ``geodetic``).
    seed : int
        Random seed; the scenario is a deterministic function of config and seed.
    imu : str
        IMU grade in ``conf/imu/`` (``consumer``, ``industrial``, ``tactical``).
    **overrides
        Dotted config keys, e.g. ``**{"scenario.duration_s": 60}``, or with
        ``__`` for dots: ``scenario__duration_s=60``.

    Returns
    -------
    Scenario
        The observations, IMU, truth and the labels of every simulated error.

    Raises
    ------
    SimbenchError
        For a preset of a real log or another source (``rinex``, ``hk_tst_2019``), naming
        :func:`simbench.scenario`, which builds any source.
    """

    return build_scenario(simulation_config(scenario, receiver, seed, imu, **overrides))


def simulation_config(
    scenario: str = "urban", receiver: str = "low", seed: int = 0, imu: str = "consumer", **overrides: Any
) -> SimConfig:
    """The checked config :func:`simulate` generates a scenario from (arguments as there), without generating
    it: a command that simulates several scenarios checks them all before the first (``zero-baseline``).

    Raises
    ------
    SimbenchError
        As :func:`simulate`, for an unknown preset, a value the simulator refuses, or a preset of another source.
    """
    cfg = compose_config(
        [
            f"scenario={scenario}",
            f"receiver={receiver}",
            f"imu={imu}",
            f"seed={seed}",
            *overrides_from_kwargs(overrides),
        ]
    )
    settings = scenario_settings(cfg)
    if settings.scenario.source != SIMULATED:
        raise SimbenchError(
            "scenario",
            f"'{scenario}' is read by source '{settings.scenario.source}', not simulated",
            f"build it with simbench.scenario('{scenario}', ...), which builds real and simulated scenarios alike",
        )
    sim = sim_config_of(settings)
    check_scenario(sim)  # the simulator's check
    return sim


def replay_overrides(real: Scenario, folder: Path) -> list[str]:
    """Overrides that simulate a world on a real log's own street: its reference trajectory and sky.

    The log's reference positions are written to ``folder/reference.xyz`` (``SOW X Y
    Z``) and replayed (``trajectory.kind=replay``) in the log's GPS week under its
    GPS navigation file, for the log's span; appended to ``scenario=<world>``
    they give a simulated log that differs from the real one only in the street
    and the receiver (``benchmarks/calibrate_street_canyon.py``).

    Parameters
    ----------
    real : Scenario
        A real log with a reference trajectory and a GPS navigation file (``rinex`` source).
    folder : Path
        Where the trajectory file is written.

    Returns
    -------
    list of str
        Command-line style overrides.

    Raises
    ------
    SimbenchError
        When the log has no reference positions or no RINEX navigation file.
    """
    truth = real.truth.dropna(subset=["x", "y", "z"])
    if len(truth) < 2 or real.rinex is None or not real.rinex.nav:
        raise SimbenchError(
            f"scenario {real.meta.get('name', '')}",
            "has no reference trajectory or no RINEX navigation file to replay",
            "give a RINEX log with scenario.truth and scenario.nav",
        )
    sow = real.nav.start_sow_s + truth["t"].to_numpy(float)
    path = Path(folder) / "reference.xyz"
    np.savetxt(path, np.c_[sow, truth[["x", "y", "z"]].to_numpy(float)], fmt="%.3f")
    return [
        "scenario.trajectory.kind=replay",
        f"scenario.trajectory.replay.path={path}",
        f"scenario.trajectory.replay.gps_week={real.nav.gps_week}",
        f"scenario.gps_week={real.nav.gps_week}",
        "scenario.constellation.kind=broadcast",
        f"scenario.constellation.nav_path={real.rinex.nav[0]}",
        f"scenario.duration_s={float(sow[-1] - sow[0]) + 1.0}",
    ]
