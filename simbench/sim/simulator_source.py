"""The simulator as a scenario source (``scenario.source=simulated``, the default)."""

from __future__ import annotations

from simbench.contract import Scenario
from simbench.sim.config import (
    ConstellationKind,
    ScenarioConfig,
    TrajectoryKind,
    check_simulation,
    sim_config_of,
)
from simbench.sim.generator import generate
from simbench.sim.trajectory_file import REPLAY_PATH_FIELD
from simbench.source_registry import SIMULATED, DataConfig, Source

__all__ = ["Simulator", "sim_config_of"]


class Simulator(Source):
    """Generate a scenario (:func:`simbench.sim.generator.generate`) from a :class:`ScenarioConfig`."""

    name = SIMULATED
    Config = ScenarioConfig
    #: a function of the schema's module, so the command line checks without importing the generator
    check = staticmethod(check_simulation)

    def input_files(self, cfg: DataConfig) -> dict[str, tuple[str, ...]]:
        s = sim_config_of(cfg).scenario
        replay = s.trajectory.replay.path if s.trajectory.kind == TrajectoryKind.replay else ""
        nav = s.constellation.nav_path if s.constellation.kind == ConstellationKind.broadcast else ""
        files = {REPLAY_PATH_FIELD: replay, "scenario.constellation.nav_path": nav}
        return {key: (path,) if path else () for key, path in files.items()}

    def load(self, cfg: DataConfig) -> Scenario:
        return generate(sim_config_of(cfg))
