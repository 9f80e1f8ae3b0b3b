"""GNSS/INS error-state EKF and iterated EKF (the paper's comparison filters).

Both run on the window engine of :mod:`estimators.crt_lss` with one GNSS epoch
(L = 1), so the three estimators share the strapdown mechanisation (GTSAM IMU
preintegration in ECEF), the 17-state error vector (attitude, position,
velocity, accelerometer and gyro biases, receiver clock and drift), the
measurement models and the initialisation.

* ``ekf_ins``: the error-state EKF. The previous posterior (a Gaussian prior on
  ``x_{k-1}``), the preintegrated IMU factor and the clock model are
  linearised at the IMU prediction and the GNSS epoch is added; one
  Gauss-Newton step on this linear system is the EKF measurement update in
  information form (the covariance-form update with the same linearisation
  gives the same mean and covariance). It is done in square-root information
  form rather than with filterpy because the prediction covariance comes out
  of GTSAM's preintegration as a factor, not as ``F P F^T + Q``.
  Outlier handling is the usual innovation gate: a pseudorange or Doppler whose
  innovation exceeds ``gate`` innovation sigmas is not used.
* ``iekf_ins``: CRT-LSS with L = 1 (paper Sec. 5.2: "IEKF represents the
  iterated EKF, which is the same as the CRT with L = 1"): Gauss-Newton
  relinearisation to convergence with Algorithm 1's soft-thresholded S step.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pandas as pd

from estimators import register
from estimators.base import Estimator
from estimators.crt_lss import (
    GnssInsConfig,
    run_gnss_ins,
    validate_gnss_ins,
    validate_lss,
)
from simbench.contract import ReceiverData
from simbench.errors import SimbenchError

__all__ = ["EkfIns", "EkfInsConfig", "IekfIns", "IekfInsConfig"]


@dataclass
class EkfInsConfig(GnssInsConfig):
    """Error-state EKF parameters."""

    gate: float = 2.0  #: innovation gate [innovation sigmas]; rows beyond it are not used (best of 2/3/4 on seed 1000)


@dataclass
class IekfInsConfig(GnssInsConfig):
    """Iterated EKF = CRT-LSS with a one-epoch window."""

    lambda_rho: float = 1.0  #: pseudorange soft threshold [whitened units] (paper eq. 14; best of 0.5/1/2 on seed 1000)
    lambda_d: float = 1.0  #: Doppler soft threshold [whitened units]
    max_iterations: int = 20  #: Algorithm 1 iteration cap
    tol: float = 1e-3  #: convergence threshold on |dX|_2 and |dS|_2


@register
class EkfIns(Estimator):
    """GNSS/INS error-state extended Kalman filter with innovation gating."""

    name = "ekf_ins"
    Config = EkfInsConfig

    def _estimate(self, data: ReceiverData) -> tuple[pd.DataFrame, dict[str, Any]]:
        cfg: EkfInsConfig = self.config
        where = f"estimator.{self.name}"
        validate_gnss_ins(cfg, where)
        if not cfg.gate > 0:
            raise SimbenchError(f"{where}.gate", f"must be positive, got {cfg.gate}",
                                "give the gate in innovation sigmas, e.g. 3")
        return run_gnss_ins(data, cfg, mode="ekf", window=1, gate=cfg.gate)


@register
class IekfIns(Estimator):
    """Iterated EKF: CRT-LSS with L = 1 (Gauss-Newton to convergence plus the soft-threshold S step)."""

    name = "iekf_ins"
    Config = IekfInsConfig

    def _estimate(self, data: ReceiverData) -> tuple[pd.DataFrame, dict[str, Any]]:
        cfg: IekfInsConfig = self.config
        validate_lss(cfg, f"estimator.{self.name}", 1)
        return run_gnss_ins(data, cfg, mode="lss", window=1, lambdas=(cfg.lambda_rho, cfg.lambda_d),
                            max_iterations=cfg.max_iterations, tol=cfg.tol)
