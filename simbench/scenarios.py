"""Where a scenario comes from: the one function the CLI and sweeps call.

Simulated kinds go to the generator; real-data sources (RINEX, libRSF) plug in
here as further branches, so the CLI and the sweep cache need not know them.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from simbench.config import ScenarioSource, SimConfig, to_typed, validate_sim
from simbench.contract import Scenario
from simbench.sim.generator import generate

#: The keys of a composed ``conf/config.yaml`` that describe the data (the rest picks estimators and output).
SIM_KEYS = ("scenario", "receiver", "imu", "seed")


def sim_config(cfg: Mapping[str, Any]) -> SimConfig:
    """The typed :class:`SimConfig` part of a composed ``conf/config.yaml``.

    Raises
    ------
    SimbenchError
        For a value that does not type-check, naming the key.
    """
    return to_typed({k: cfg[k] for k in SIM_KEYS}, SimConfig, "config")


def scenario_from_overrides(overrides: Sequence[str]) -> tuple[SimConfig, Scenario]:
    """Compose ``conf/config.yaml`` with command-line style overrides (``scenario=rinex``,
    ``receiver=high``, ``seed=3``) and build that scenario; return the typed config and the scenario."""
    from simbench.compose import compose_config  # imports the estimator registry: only when composing

    sim = sim_config(compose_config(list(overrides)))
    return sim, build_scenario(sim)


def build_scenario(cfg: SimConfig) -> Scenario:
    """Generate (or load) the scenario a typed config describes.

    ``scenario.source`` picks the branch: ``simulated`` runs the generator;
    ``rinex`` and ``librsf`` ingest a real log (:mod:`simbench.data`) with
    ``labels=None`` and an empty IMU table.
    """
    sc = validate_sim(cfg).scenario
    if sc.source == ScenarioSource.rinex:
        from simbench.data.rinex import load_rinex

        return load_rinex(sc.obs, sc.nav, sc.truth, systems=sc.systems, nav_bds_path=sc.nav_bds,
                          nav_glo_path=sc.nav_glo, nav_gal_path=sc.nav_gal, name=sc.name,
                          truth_max_gap_s=sc.truth_max_gap_s)
    if sc.source == ScenarioSource.librsf:
        from simbench.data.librsf import load_librsf

        return load_librsf(sc.obs, sc.truth or None, gps_week=sc.gps_week, start_sow_s=sc.start_sow_s,
                           name=sc.name, truth_max_gap_s=sc.truth_max_gap_s)
    return generate(cfg)
