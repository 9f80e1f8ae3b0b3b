"""Calibration of a simulated world against a real log's statistics (issue 14: the ``urban_deep`` preset).

A world is summarised by :func:`simbench.analysis.validation.world_statistics`; several
seeds of a simulated world are pooled into one sample (:func:`pool_samples`) so
that a statistic is not the luck of one street grid. :data:`TOLERANCES` are the
issue's acceptance bands for a preset against the log it is calibrated on;
:func:`misfit` measures a world against a target in units of those bands (the
calibration objective of ``benchmarks/calibrate_urban_deep.py``), and
:func:`within_tolerance` says which statistics hold.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from functools import reduce
from typing import Literal

import numpy as np
import pandas as pd

from simbench.analysis.validation import ValidationSample, WorldStatistics, residual_sample, world_statistics
from simbench.errors import SimbenchError
from simbench.sim.config import SimConfig, validate_sim
from simbench.sim.generator import generate

__all__ = ["TOLERANCES", "Tolerance", "misfit", "pool_samples", "seeds_statistics", "with_changes", "within_tolerance"]


@dataclass(frozen=True)
class Tolerance:
    """How far a statistic of :class:`WorldStatistics` may be from the target's."""

    statistic: str  #: field of WorldStatistics
    width: float  #: allowed difference: absolute in the statistic's unit, or relative (0.3 = 30 %)
    kind: Literal["absolute", "relative"]

    def error(self, value: float, target: float) -> float:
        """Difference of ``value`` from ``target`` in units of the allowed width (|error| <= 1 holds)."""
        diff = value - target
        return diff / (self.width * abs(target)) if self.kind == "relative" else diff / self.width


#: Issue 14's tolerances for ``urban_deep`` against the Hong Kong log.
TOLERANCES: tuple[Tolerance, ...] = (
    Tolerance("sats_median", 1.0, "absolute"),  # tracked satellites per epoch [-]
    Tolerance("residual_p50_m", 0.3, "relative"),
    Tolerance("residual_p90_m", 0.3, "relative"),
    Tolerance("share_over_10m", 0.05, "absolute"),
    Tolerance("cn0_p50", 3.0, "absolute"),  # [dB-Hz]
)


def pool_samples(samples: Sequence[ValidationSample], name: str) -> ValidationSample:
    """One sample holding the rows of several (seeds of a) world, epochs kept apart.

    Parameters
    ----------
    samples : sequence of ValidationSample
        With the same epoch interval.
    name : str
        Label of the pooled world.

    Returns
    -------
    ValidationSample
        Epoch indices of the k-th sample offset by the sum of the epoch ranges
        before it; phase arc ids likewise, so arcs stay distinct.

    Raises
    ------
    SimbenchError
        For no samples, or samples with different epoch intervals.
    """
    if not samples:
        raise SimbenchError("samples", "nothing to pool", "give at least one ValidationSample")
    intervals = {s.interval_s for s in samples}
    if len(intervals) > 1:
        raise SimbenchError(
            "samples", f"epoch intervals differ: {sorted(intervals)} s", "pool only seeds of one world at one rate"
        )
    rows, epochs = [], []
    epoch_offset = arc_offset = 0
    for s in samples:
        r = s.rows.copy()
        r["epoch"] += epoch_offset
        r.loc[r["arc"] >= 0, "arc"] += arc_offset
        rows.append(r)
        epochs.append(s.reference_epochs + epoch_offset)
        last_epoch = max(int(s.reference_epochs.max(initial=-1)), int(s.rows["epoch"].max()) if len(s.rows) else -1)
        epoch_offset += last_epoch + 1
        arc_offset += int(s.rows["arc"].max()) + 1 if len(s.rows) else 0
    return ValidationSample(
        name=name,
        rows=pd.concat(rows, ignore_index=True),
        reference_epochs=np.concatenate(epochs),
        interval_s=samples[0].interval_s,
        real=all(s.real for s in samples),
    )


def with_changes(config: SimConfig, changes: Mapping[str, object]) -> SimConfig:
    """A copy of ``config`` with attributes set by dotted path, e.g. ``scenario.errors.cn0.constant_db``.

    Changing the typed config directly is what lets a calibration grid compose
    the Hydra configuration once.
    """
    config = copy.deepcopy(config)
    for key, value in changes.items():
        *parents, name = key.split(".")
        setattr(reduce(getattr, parents, config), name, value)
    return config


def seeds_statistics(config: SimConfig, seeds: Sequence[int], name: str) -> WorldStatistics:
    """Statistics of one simulated world over several seeds, pooled (:func:`pool_samples`).

    Parameters
    ----------
    config : SimConfig
        The world; its ``seed`` is replaced by each of ``seeds``.
    seeds : sequence of int
    name : str
        Label of the pooled world.

    Raises
    ------
    SimbenchError
        For a config :func:`~simbench.sim.config.validate_sim` rejects.
    """
    validate_sim(config)  # once: the seeds change nothing it checks, and the generator trusts it
    samples = [residual_sample(generate(replace(config, seed=int(seed)))) for seed in seeds]
    return world_statistics(pool_samples(samples, name))


def misfit(
    stats: WorldStatistics, target: WorldStatistics, tolerances: Sequence[Tolerance] = TOLERANCES
) -> dict[str, float]:
    """Each statistic's difference from the target in units of its tolerance (|value| <= 1 holds)."""
    return {
        t.statistic: t.error(float(getattr(stats, t.statistic)), float(getattr(target, t.statistic)))
        for t in tolerances
    }


def within_tolerance(
    stats: WorldStatistics, target: WorldStatistics, tolerances: Sequence[Tolerance] = TOLERANCES
) -> dict[str, bool]:
    """Which statistics of ``stats`` are within their tolerance of ``target``'s."""
    return {name: bool(abs(err) <= 1.0) for name, err in misfit(stats, target, tolerances).items()}
