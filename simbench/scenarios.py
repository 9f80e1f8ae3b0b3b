"""Where a scenario comes from: the one function the CLI and sweeps call.

Simulated kinds go to the generator; real-data sources (RINEX, libRSF) plug in
here as further branches, so the CLI and the sweep cache need not know them.
"""
from __future__ import annotations

from simbench.config import SimConfig
from simbench.contract import Scenario
from simbench.sim.generator import generate


def build_scenario(cfg: SimConfig) -> Scenario:
    """Generate (or load) the scenario a typed config describes."""
    return generate(cfg)
