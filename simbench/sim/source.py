"""The simulator as a scenario source (``scenario.source=simulated``, the default)."""

from __future__ import annotations

from simbench.contract import Scenario
from simbench.sim.config import ScenarioConfig, SimConfig, validate_sim
from simbench.sim.generator import generate
from simbench.source import SIMULATED, DataConfig, Source, scenario_config


class Simulator(Source):
    """Generate a scenario (:func:`simbench.sim.generator.generate`) from a :class:`ScenarioConfig`."""

    name = SIMULATED
    Config = ScenarioConfig

    def check(self, cfg: DataConfig) -> None:
        validate_sim(sim_config_of(cfg))

    def load(self, cfg: DataConfig) -> Scenario:
        return generate(sim_config_of(cfg))


def sim_config_of(cfg: DataConfig) -> SimConfig:
    """``cfg`` as the :class:`SimConfig` the generator takes.

    Raises
    ------
    SimbenchError
        When ``cfg.scenario`` is not a :class:`ScenarioConfig` (:func:`simbench.source.scenario_config`).
    """
    if isinstance(cfg, SimConfig):
        return cfg
    return SimConfig(scenario=scenario_config(cfg, ScenarioConfig), receiver=cfg.receiver, imu=cfg.imu, seed=cfg.seed)
