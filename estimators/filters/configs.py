"""The filters' ``Config`` dataclasses: EKF-PPP (:mod:`.ekf_ppp`).

Kept apart from the filter (filterpy, scipy) so that the command line checks a value of
``estimator.<name>`` by importing this module only (:mod:`simbench.runs.schema_record`).
"""

from __future__ import annotations

from dataclasses import dataclass

from estimators.model.ppp_config import MotionModelConfig

__all__ = ["EkfPppConfig"]


@dataclass
class EkfPppConfig(MotionModelConfig):
    """EKF-PPP parameters: the shared model of :class:`~estimators.model.ppp_config.MotionModelConfig`.

    ``measurements = code`` makes it a code-only filter (no bias states);
    ``motion_model = constant_velocity`` adds velocity and clock drift states.
    """

    #: with carrier phase, run the code-only filter too and fall back to it wherever the phase
    #: filter's position departs from it beyond its covariance (:meth:`EkfPpp.run`'s ``anchor``)
    phase_guard: bool = True
