"""Where a scenario comes from: the one function the CLI and sweeps call.

Simulated kinds go to the generator; real-data sources (RINEX, libRSF) plug in
here as further branches, so the CLI and the sweep cache need not know them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from simbench.contract import Scenario
from simbench.data.librsf import load_librsf
from simbench.data.rinex import load_rinex
from simbench.runs.compose import compose_config, overrides_from_kwargs
from simbench.sim.config import ScenarioSource, SimConfig, validate_sim
from simbench.sim.generator import generate
from simbench.typed import to_typed

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
        return load_rinex(
            sc.obs,
            sc.nav,
            sc.truth,
            systems=sc.systems,
            nav_bds_path=sc.nav_bds,
            nav_glo_path=sc.nav_glo,
            nav_gal_path=sc.nav_gal,
            name=sc.name,
            truth_max_gap_s=sc.truth_max_gap_s,
        )
    if sc.source == ScenarioSource.librsf:
        return load_librsf(
            sc.obs,
            sc.truth or None,
            gps_week=sc.gps_week,
            start_sow_s=sc.start_sow_s,
            name=sc.name,
            truth_max_gap_s=sc.truth_max_gap_s,
        )
    return generate(cfg)


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
    return generate(sim_config(cfg))
