"""The one interface every estimator implements.

An estimator is constructed from its typed config and maps
:class:`~simbench.contract.ReceiverData` to a :class:`Solution`: one row per
epoch it solved, with the wall time that epoch's update took. It never sees
truth; only an estimator whose ``requires`` holds :attr:`Need.labels` (the
oracle) is handed the error labels, through :meth:`Estimator.attach_labels`.

Each estimator declares what it needs from the data (``requires``, refined per
config by :meth:`Estimator.needs`); the runner skips, with a reason, an
estimator whose needs a scenario cannot meet. Its config dataclass has one
``validate(where)`` entry point, called at construction.
"""

from __future__ import annotations

import dataclasses
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import pandas as pd

from simbench.bounds import FINITE_ONLY, check_bounds
from simbench.contract import Need, ReceiverData

#: Columns of :attr:`Solution.epochs`.
SOLUTION_COLUMNS: dict[str, str] = {
    "epoch": "int, GNSS epoch index",
    "t": "s, epoch time since scenario start",
    "x": "m, estimated antenna ECEF x",
    "y": "m, estimated ECEF y",
    "z": "m, estimated ECEF z",
    "update_s": "s, wall time of this epoch's update (batch estimators: total time / epochs)",
}

#: Optional columns of :attr:`Solution.epochs`: the 3x3 ECEF position covariance of an estimator that has
#: one (its 6 unique entries); absent, or NaN on an epoch, where it has none.
COVARIANCE_COLUMNS: dict[str, str] = {
    "cov_xx": "m^2, ECEF position covariance, x x",
    "cov_xy": "m^2, x y",
    "cov_xz": "m^2, x z",
    "cov_yy": "m^2, y y",
    "cov_yz": "m^2, y z",
    "cov_zz": "m^2, z z",
}
#: Where each of :data:`COVARIANCE_COLUMNS` sits in the 3x3 matrix.
COVARIANCE_INDEX: dict[str, tuple[int, int]] = {
    "cov_xx": (0, 0),
    "cov_xy": (0, 1),
    "cov_xz": (0, 2),
    "cov_yy": (1, 1),
    "cov_yz": (1, 2),
    "cov_zz": (2, 2),
}


@dataclass
class Solution:
    """Per-epoch output of an estimator.

    Attributes
    ----------
    epochs : pandas.DataFrame
        :data:`SOLUTION_COLUMNS` (and :data:`COVARIANCE_COLUMNS` where the estimator has a
        position covariance); epochs the estimator could not solve are absent.
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


def validate_config(config: Any, where: str) -> None:
    """Refuse a NaN or infinite parameter, then call ``config.validate(where)`` when the config has one
    (a plug-in's may not).

    Raises
    ------
    SimbenchError
        In one line naming the field under ``where`` (e.g. ``estimator.dcs``).
    """
    if dataclasses.is_dataclass(config):
        check_bounds(config, where, FINITE_ONLY)
    validate = getattr(config, "validate", None)
    if validate is not None:
        validate(where)


class Estimator(ABC):
    """Base class: subclasses set ``name`` and ``Config`` and implement :meth:`_estimate`."""

    name: ClassVar[str]
    #: Dataclass holding the estimator's parameters (read from ``conf/estimator/<name>.yaml``);
    #: its ``validate(where)`` method, when present, checks them at construction.
    Config: ClassVar[type]
    #: What the estimator needs from the data under any config; :meth:`needs` may narrow
    #: or widen it per config. Only the oracle may require :attr:`Need.labels`.
    requires: ClassVar[frozenset[Need]] = frozenset()
    #: Derived from ``requires`` (never set it directly): the summary's ``uses_labels`` column.
    uses_labels: ClassVar[bool] = False

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "uses_labels" in vars(cls):
            raise TypeError(f"{cls.__name__} sets uses_labels; declare Need.labels in requires instead")
        cls.uses_labels = Need.labels in cls.requires

    def __init__(self, config: Any | None = None) -> None:
        self.config = config if config is not None else self.Config()
        validate_config(self.config, f"estimator.{self.name}")  # before any data work
        self._labels: pd.DataFrame | None = None

    @classmethod
    def unavailable_reason(cls) -> str:
        """Why this estimator cannot run in this environment (e.g. an external program is not
        installed), as one line for a skipped row; ``""`` when it can run."""
        return ""

    def needs(self) -> frozenset[Need]:
        """What this configured estimator needs from the data.

        ``requires`` plus whatever the config's own ``needs()`` adds (e.g. L2 for
        ``ionosphere_free``); estimators whose config can drop a need override this.
        """
        config_needs = getattr(self.config, "needs", None)
        return self.requires | (config_needs() if config_needs is not None else frozenset())

    def attach_labels(self, labels: pd.DataFrame) -> None:
        """Hand the error labels to a label-using estimator (the oracle)."""
        if Need.labels not in self.needs():
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


def solution_frame(
    epoch: np.ndarray, t: np.ndarray, pos: np.ndarray, update_s: np.ndarray, cov: np.ndarray | None = None
) -> pd.DataFrame:
    """Assemble :data:`SOLUTION_COLUMNS` from arrays.

    Parameters
    ----------
    epoch, t, update_s : numpy.ndarray
        Epoch indices, times [s] and update wall times [s], one per solved epoch.
    pos : numpy.ndarray
        (n, 3) ECEF positions [m].
    cov : numpy.ndarray, optional
        (n, 3, 3) ECEF position covariances [m^2]: adds :data:`COVARIANCE_COLUMNS`.
    """
    frame = pd.DataFrame(
        {"epoch": epoch.astype(np.int64), "t": t, "x": pos[:, 0], "y": pos[:, 1], "z": pos[:, 2], "update_s": update_s}
    )
    if cov is not None:
        for column, (i, j) in COVARIANCE_INDEX.items():
            frame[column] = cov[:, i, j]
    return frame
