"""The robust measurement models the batch and incremental graph estimators share: their config fields
and checks (declared once, mixed into each estimator's ``Config``; the learned LOS/NLOS model's too,
:mod:`estimators.model.nlos_mixture`) and the max-mixture decision. Light (numpy only), so the command
line checks a value without the solvers.

DCS (dissertation eq. 3.18) scales a factor's covariance by its whitened residual with kernel width phi;
max-mixtures (eq. 3.20) pick, per measurement, the more likely of an inlier and a broad outlier component.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimators.model.ppp_config import GnssModelConfig
from simbench.errors import SimbenchError, require_at_least, require_positive
from simbench.typed import Choice

__all__ = [
    "Assignment",
    "DcsFields",
    "MaxMixtureFields",
    "NlosMixtureFields",
    "validate_dcs",
    "validate_max_mixture",
    "validate_nlos_mixture",
    "validate_robust",
    "max_mixture_outliers",
]


@dataclass
class DcsFields:
    """The DCS kernel of batch and incremental DCS."""

    kernel_width: float = 2.5  #: DCS kernel width (phi) [whitened units]


def validate_dcs(kernel_width: float, where: str) -> None:
    """One-line :class:`SimbenchError` for a kernel width that is not positive (batch and incremental DCS)."""
    require_positive(f"{where}.kernel_width", kernel_width, "give the DCS kernel width in whitened units (default 2.5)")


@dataclass
class MaxMixtureFields:
    """The static inlier/outlier model of batch and incremental MM."""

    #: outlier covariance = inlier covariance times this (a composed run takes it from its ``gnss_model``
    #: preset; ``dissertation``: the batch code's 1e6, the incremental code's 10)
    outlier_scale: float = GnssModelConfig.outlier_scale
    outlier_weight: float = 0.5  #: prior weight of the outlier component (equal weights)


def validate_max_mixture(outlier_scale: float, outlier_weight: float, where: str) -> None:
    """One-line :class:`SimbenchError` for a two-component model that is not one (batch and incremental MM)."""
    if not outlier_scale > 1:
        raise SimbenchError(
            f"{where}.outlier_scale",
            f"must exceed 1, got {outlier_scale}",
            "give the outlier/inlier covariance ratio, e.g. 1e6 (batch) or 10 (incremental)",
        )
    if not 0 < outlier_weight < 1:
        raise SimbenchError(
            f"{where}.outlier_weight",
            f"must be within (0, 1), got {outlier_weight}",
            "give the outlier component's prior weight, e.g. the default 0.5",
        )


def max_mixture_outliers(whitened: np.ndarray, outlier_scale: float, outlier_weight: float) -> np.ndarray:
    """Most likely component per measurement (eq. 3.20): True where the outlier wins.

    Inlier ``N(0, 1)`` with weight ``1 - w``, outlier ``N(0, s)`` with weight ``w``
    in whitened units; the outlier wins where
    ``w/sqrt(s) exp(-r^2/(2s)) > (1-w) exp(-r^2/2)``, i.e.
    ``r^2 (1 - 1/s) > log s + 2 log((1-w)/w)``.
    """
    threshold = (np.log(outlier_scale) + 2.0 * np.log((1.0 - outlier_weight) / outlier_weight)) / (
        1.0 - 1.0 / outlier_scale
    )
    return whitened**2 > threshold


class Assignment(Choice):
    """How a solve uses the mixture (member names are the YAML words)."""

    max = "max"  #: max-mixture: each row takes its more likely component's sigma and mean
    soft = "soft"  #: EM: each row takes the responsibility-weighted sum of both components


@dataclass
class NlosMixtureFields:
    """Config fields of an estimator that learns :class:`~estimators.model.nlos_mixture.NlosMixture` (mixed
    into its ``Config``)."""

    conditioned: bool = True  #: weights and NLOS mean depend on C/N0 and elevation (False: constants)
    one_sided: bool = True  #: the NLOS mean is late only (>= 0); False: either sign
    assignment: Assignment = Assignment.max  #: max-mixture or soft (EM) use of the model in the solve
    em_iterations: int = 5  #: EM iterations on the residuals per re-solve (warm-started)
    nlos_weight_init: float = 0.2  #: prior NLOS weight of the first fit [-]
    learn_los_scale: bool = True  #: learn k, the LOS scale on the a-priori sigmas (False: k = 1)


def validate_nlos_mixture(cfg: NlosMixtureFields, where: str) -> None:
    """One-line :class:`SimbenchError` for the first out-of-range field of :class:`NlosMixtureFields`."""
    require_at_least(f"{where}.em_iterations", cfg.em_iterations, 1, "give EM iterations per re-solve, e.g. 5")
    if not 0 < cfg.nlos_weight_init < 1:
        raise SimbenchError(
            f"{where}.nlos_weight_init",
            f"must be within (0, 1), got {cfg.nlos_weight_init}",
            "give the first fit's NLOS prior weight, e.g. the default 0.2",
        )


def validate_robust(cfg: object, where: str) -> None:
    """One-line :class:`SimbenchError` for the first out-of-range field of the robust-model fields mixed
    into ``cfg``'s class, checked in the order :class:`DcsFields`, :class:`MaxMixtureFields`,
    :class:`NlosMixtureFields`; a config without any of them passes.

    The batch and the incremental ``Config`` bases call it last in their ``validate``, so an estimator's
    ``Config`` that mixes in a model's fields is checked without a ``validate`` of its own.
    """
    if isinstance(cfg, DcsFields):
        validate_dcs(cfg.kernel_width, where)
    if isinstance(cfg, MaxMixtureFields):
        validate_max_mixture(cfg.outlier_scale, cfg.outlier_weight, where)
    if isinstance(cfg, NlosMixtureFields):
        validate_nlos_mixture(cfg, where)
