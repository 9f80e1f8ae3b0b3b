"""simbench: simulation-and-benchmark harness for robust GNSS and GNSS/INS estimation.

The notebook entry points are :func:`simulate` (one scenario) and :func:`run`
(a study: estimators x seeds, scored, with a report; :mod:`simbench.study`); the
command line is ``python -m simbench`` (a Hydra app, configs in the repository's ``conf/``).
"""
from __future__ import annotations

from typing import Any

from simbench.contract import NavInfo, ReceiverData, Scenario
from simbench.errors import SimbenchError

__all__ = ["simulate", "run", "StudyResult", "Scenario", "ReceiverData", "NavInfo", "SimbenchError"]


def __getattr__(name: str) -> Any:
    """:func:`run` and :class:`StudyResult` on first use: they load Hydra and every estimator."""
    if name in ("run", "StudyResult"):
        from simbench import study

        return getattr(study, name)
    raise AttributeError(f"module 'simbench' has no attribute '{name}'")


def simulate(scenario: str = "urban", receiver: str = "low", seed: int = 0, imu: str = "consumer",
             **overrides: Any) -> Scenario:
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
    from simbench.compose import compose_config, overrides_from_kwargs
    from simbench.scenarios import sim_config
    from simbench.sim.generator import generate

    cfg = compose_config([f"scenario={scenario}", f"receiver={receiver}", f"imu={imu}", f"seed={seed}",
                          *overrides_from_kwargs(overrides)])
    return generate(sim_config(cfg))
