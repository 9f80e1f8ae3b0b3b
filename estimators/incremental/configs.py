"""The incremental estimators' ``Config`` dataclasses and their range checks: iSAM2-PPP, -DCS and -MM
(:mod:`.isam2`) and ICE (:mod:`.ice`).

Kept apart from the solvers (gtsam, scipy, sklearn) so that the command line checks a value of
``estimator.<name>`` by importing this module only (:mod:`simbench.runs.schema_record`).
"""

from __future__ import annotations

from dataclasses import dataclass

from estimators.model.ppp_config import GnssModelConfig, NlosModel, PppGraphConfig
from estimators.model.robust_models import DcsFields, MaxMixtureFields, validate_robust
from simbench.errors import SimbenchError, require_at_least, require_positive

__all__ = ["IceConfig", "IncrementalConfig", "Isam2DcsConfig", "Isam2MmConfig"]


@dataclass
class IncrementalConfig(PppGraphConfig):
    """iSAM2 settings on top of the graph model (:class:`PppGraphConfig`)."""

    ambiguity_sigma_m: float = 10.0  #: a priori arc bias sigma [m] (original iSAM2-PPP code; Table 4.4.2: 100)
    #: iSAM2 relinearisation threshold of the positions [m] (original code 0.01; see isam2_params)
    relinearize_threshold: float = 1.0
    relinearize_skip: int = 1  #: check for relinearisation every this many updates
    #: iSAM2 back-substitution stops where the update changes by less than this (GTSAM default 0.001)
    wildfire_threshold: float = 0.001
    #: check relinearisation only in the cliques an update touches (GTSAM default False)
    partial_relinearization_check: bool = False
    #: fixed-lag window [s]: keys last used longer ago are marginalised (estimators.incremental.fixed_lag);
    #: 0 keeps every epoch in plain iSAM2, whose update cost then grows with the run (module notes)
    lag_s: float = 10.0
    #: the window holds at least this many epochs, whatever the data interval (a 30 s station file)
    lag_min_epochs: int = 5

    def validate(self, where: str) -> None:
        """One-line :class:`SimbenchError` for the first out-of-range field (``where``: config node name)."""
        super().validate(where)
        require_positive(
            f"{where}.relinearize_threshold",
            self.relinearize_threshold,
            "give a threshold in metres, e.g. the default 1.0",
        )
        require_at_least(
            f"{where}.relinearize_skip", self.relinearize_skip, 1, "1 checks for relinearisation at every update"
        )
        require_at_least(f"{where}.lag_s", self.lag_s, 0, "give the fixed-lag window in seconds (0: keep every epoch)")
        require_at_least(
            f"{where}.lag_min_epochs", self.lag_min_epochs, 2, "the window keeps the previous epoch at least"
        )
        validate_robust(self, where)


@dataclass
class Isam2DcsConfig(IncrementalConfig, DcsFields):
    """Incremental dynamic covariance scaling (the kernel width as batch DCS's)."""


@dataclass
class Isam2MmConfig(IncrementalConfig, MaxMixtureFields):
    """Incremental max-mixtures with a static two-component model."""


@dataclass
class IceConfig(IncrementalConfig):
    """ICE parameters (REFERENCE.md, original implementation) on top of the iSAM2 loop.

    The measurement noise is ICE's mixture model; ``code_sigma_m`` and
    ``phase_sigma_m`` only weight the per-epoch residual prediction.
    """

    z_threshold: float = 3.0  #: T_r, z-test threshold per channel [sigmas]
    cluster_threshold: int = 1000  #: T_c, adapt when more outliers than this are buffered
    alpha: float = 0.05  #: significance of the W and Hotelling merge tests
    max_components: int = 20  #: components of the model at most
    min_cluster_points: int = 2  #: new clusters with fewer points are dropped
    #: the mixture models residuals divided by each row's sigma factor (``sigma_model``), not metres
    scaled_mixture: bool = GnssModelConfig.scaled_mixture
    prior_code_sigma_m: float = 2.5  #: a-priori model code sigma [m] (not elevation-scaled)
    prior_phase_sigma_m: float = 0.25  #: a-priori model phase sigma [m]
    dpgmm_truncation: int = 10  #: stick-breaking truncation of the DP-GMM fit
    #: a priori position sigma at the first epoch [m] (the graph's 1 m, Table 4.4.2, is a surveyed start):
    #: the z-test weighs each residual against the predicted position's uncertainty too, and a first
    #: fix of 3-4 urban satellites is tens of metres off (tuning seeds >= 1000, docs/notebook.md)
    pos_sigma_m: float = 100.0
    #: keep the per-epoch inlier/outlier residuals in the diagnostics (for a Fig. 7.3.2 scatter)
    record_residuals: bool = False
    #: late code rows: ``conditioned`` (a learned late-only NLOS mean and weight; the urban preset) or
    #: ``none`` (the dissertation's)
    nlos_model: NlosModel = GnssModelConfig.nlos_model
    nlos_window_s: float = 60.0  #: the NLOS model is fitted on the code rows of the last this many seconds [s]
    nlos_min_rows: int = 100  #: no NLOS model before the window holds this many code rows
    nlos_em_iterations: int = 2  #: EM iterations per epoch, warm-started from the last fit
    nlos_weight_init: float = 0.2  #: prior NLOS weight of the first fit [-]

    def validate(self, where: str) -> None:
        """One-line :class:`SimbenchError` for the first out-of-range field (``where``: config node name)."""
        super().validate(where)
        checks = (
            ("z_threshold", self.z_threshold > 0),
            ("cluster_threshold", self.cluster_threshold >= 1),
            ("alpha", 0 < self.alpha < 1),
            ("max_components", self.max_components >= 1),
            ("min_cluster_points", self.min_cluster_points >= 1),
            ("prior_code_sigma_m", self.prior_code_sigma_m > 0),
            ("prior_phase_sigma_m", self.prior_phase_sigma_m > 0),
            ("dpgmm_truncation", self.dpgmm_truncation >= 1),
            ("nlos_window_s", self.nlos_window_s > 0),
            ("nlos_min_rows", self.nlos_min_rows >= 10),
            ("nlos_em_iterations", self.nlos_em_iterations >= 1),
            ("nlos_weight_init", 0 < self.nlos_weight_init < 1),
        )
        for name, ok in checks:
            if not ok:
                raise SimbenchError(
                    f"{where}.{name}",
                    f"out of range: {getattr(self, name)}",
                    "the defaults are in IceConfig (estimators/incremental/configs.py)",
                )
