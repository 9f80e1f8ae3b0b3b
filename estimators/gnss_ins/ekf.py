"""GNSS/INS error-state EKF and iterated EKF (the paper's comparison filters).

Both run on the window engine of :mod:`estimators.gnss_ins.window_solver` through
:func:`estimators.gnss_ins.driver.run_gnss_ins` with one GNSS epoch (L = 1),
so the three estimators share the strapdown mechanisation (GTSAM IMU
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

from typing import Any

from estimators import register
from estimators.gnss_ins.config import EkfInsConfig, IekfInsConfig
from estimators.gnss_ins.driver import GnssInsEstimator, lss_arguments

__all__ = ["EkfIns", "IekfIns"]


@register
class EkfIns(GnssInsEstimator):
    """GNSS/INS error-state extended Kalman filter with innovation gating."""

    name = "ekf_ins"
    Config = EkfInsConfig

    def driver_arguments(self) -> dict[str, Any]:
        return {"mode": "ekf", "window": 1, "gate": self.config.gate}


@register
class IekfIns(GnssInsEstimator):
    """Iterated EKF: CRT-LSS with L = 1 (Gauss-Newton to convergence plus the soft-threshold S step)."""

    name = "iekf_ins"
    Config = IekfInsConfig

    def driver_arguments(self) -> dict[str, Any]:
        return lss_arguments(self.config, window=1)
