"""The one interface every estimator implements.

An estimator is constructed from its typed config and maps
:class:`~simbench.contract.ReceiverData` to a :class:`Solution`: one row per
epoch it solved, with the wall time that epoch's update took. It never sees
truth; only an estimator that declares ``uses_labels = True`` (the oracle) is
handed the error labels, through :meth:`Estimator.attach_labels`.
"""
from __future__ import annotations

import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import pandas as pd

from simbench.contract import ReceiverData

#: Columns of :attr:`Solution.epochs`.
SOLUTION_COLUMNS: dict[str, str] = {
    "epoch": "int, GNSS epoch index",
    "t": "s, epoch time since scenario start",
    "x": "m, estimated antenna ECEF x", "y": "m, estimated ECEF y", "z": "m, estimated ECEF z",
    "update_s": "s, wall time of this epoch's update (batch estimators: total time / epochs)",
}


@dataclass
class Solution:
    """Per-epoch output of an estimator.

    Attributes
    ----------
    epochs : pandas.DataFrame
        :data:`SOLUTION_COLUMNS`; epochs the estimator could not solve are absent.
    total_s : float
        Wall time of the whole run [s].
    diagnostics : dict
        Estimator-specific records for the report (iteration tables, mixture
        history, adaptation counts); JSON-serialisable values.
    """

    epochs: pd.DataFrame
    total_s: float
    diagnostics: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        missing = set(SOLUTION_COLUMNS) - set(self.epochs.columns)
        if missing:
            raise ValueError(f"solution lacks columns {sorted(missing)}")


class Estimator(ABC):
    """Base class: subclasses set ``name`` and ``Config`` and implement :meth:`_estimate`."""

    name: ClassVar[str]
    #: Dataclass holding the estimator's parameters (read from ``conf/estimator/<name>.yaml``).
    Config: ClassVar[type]
    #: Only the oracle may read error labels.
    uses_labels: ClassVar[bool] = False

    def __init__(self, config: Any | None = None) -> None:
        self.config = config if config is not None else self.Config()
        self._labels: pd.DataFrame | None = None

    def attach_labels(self, labels: pd.DataFrame) -> None:
        """Hand the error labels to a label-using estimator (the oracle)."""
        if not self.uses_labels:
            raise PermissionError(f"estimator '{self.name}' does not use labels")
        self._labels = labels

    def estimate(self, data: ReceiverData) -> Solution:
        """Run on one scenario's receiver data and time the whole run."""
        start = time.perf_counter()
        epochs, diagnostics = self._estimate(data)
        total = time.perf_counter() - start
        return Solution(epochs=epochs, total_s=total, diagnostics=diagnostics)

    @abstractmethod
    def _estimate(self, data: ReceiverData) -> tuple[pd.DataFrame, dict[str, Any]]:
        """Return the per-epoch solution table and diagnostics."""


def solution_frame(epoch: np.ndarray, t: np.ndarray, pos: np.ndarray, update_s: np.ndarray) -> pd.DataFrame:
    """Assemble :data:`SOLUTION_COLUMNS` from arrays (pos is (n, 3) ECEF metres)."""
    return pd.DataFrame({"epoch": epoch.astype(np.int64), "t": t, "x": pos[:, 0], "y": pos[:, 1],
                         "z": pos[:, 2], "update_s": update_s})
