"""The batch estimators' ``Config`` dataclasses and their range checks: L2, DCS, max-mixtures
(:mod:`.robust`), BCE and BCE-AD (:mod:`.bce`) and the oracle (:mod:`.oracle`).

Kept apart from the solvers (gtsam, scipy, sklearn) so that the command line checks a value of
``estimator.<name>`` by importing this module only (:mod:`simbench.runs.schema_record`).
"""

from __future__ import annotations

from dataclasses import dataclass

from estimators.model.ppp_config import PppGraphConfig
from estimators.model.robust_models import DcsFields, MaxMixtureFields, NlosMixtureFields, validate_robust
from simbench.errors import SimbenchError, require_at_least, require_positive

__all__ = [
    "FEATURES",
    "BatchConfig",
    "BceAdConfig",
    "BceConfig",
    "DcsConfig",
    "L2Config",
    "MmConfig",
    "MmEmConfig",
    "OracleConfig",
]


@dataclass
class BatchConfig(PppGraphConfig):
    """Parameters shared by the batch graph estimators (graph model: :class:`PppGraphConfig`)."""

    prior_scale: float = 1.0  #: s, multiplies the a-priori measurement covariance (Fig. 5.3.7 sensitivity)
    max_iterations: int = 100  #: robust re-weighting iterations at most
    rel_tol: float = 1e-5  #: stop when the relative change of the total error is below this
    lm_max_iterations: int = 100  #: iterations of the L2 solve (Gauss-Newton, else Levenberg-Marquardt)

    def validate(self, where: str) -> None:
        """One-line :class:`SimbenchError` for the first out-of-range field (``where``: config node name)."""
        super().validate(where)
        require_positive(
            f"{where}.prior_scale", self.prior_scale, "give a covariance scale factor such as 1, 0.1 or 10"
        )
        for name in ("max_iterations", "lm_max_iterations"):
            require_at_least(f"{where}.{name}", getattr(self, name), 1, "give an iteration limit, e.g. the default 100")
        validate_robust(self, where)


@dataclass
class L2Config(BatchConfig):
    """Batch L2 (a-priori Gaussian noise)."""


@dataclass
class DcsConfig(BatchConfig, DcsFields):
    """Batch dynamic covariance scaling."""


@dataclass
class MmConfig(BatchConfig, MaxMixtureFields):
    """Batch max-mixtures with a static inlier/outlier model."""


@dataclass
class MmEmConfig(BatchConfig, MaxMixtureFields, NlosMixtureFields):
    """Batch max-mixtures whose code model is learned from the residuals (:mod:`estimators.model.nlos_mixture`);
    the phase keeps MM's static inlier/outlier pair."""

    max_iterations: int = 50  #: solve / EM alternations at most


#: Augmented feature columns of BCE-AD, in order.
FEATURES = ("code_residual", "phase_residual", "elevation", "azimuth", "cn0")


@dataclass
class BceConfig(BatchConfig):
    """BCE parameters (graph model and stopping rule: :class:`BatchConfig`).

    ``lm_max_iterations`` bounds the first (a-priori) solve only; each re-weighted
    re-solve is one Gauss-Newton step.
    """

    max_iterations: int = 100  #: robust re-weighting iterations at most
    truncation: int = 10  #: largest number of DP-GMM components
    dpgmm_max_iter: int = 1000  #: variational iterations per fit at most
    #: lower-bound tolerance of the variational fit (per residual); 1e-4 stopped the warm-started
    #: fits after 3 iterations and gave higher medians on the tuning seeds
    dpgmm_tol: float = 1e-6
    #: fit the mixture on at most this many random residuals (0: all); all rows are assigned
    fit_sample: int = 5000
    seed: int = 0  #: random state of the sub-sampling and the k-means initialisation
    #: False: stop when the relative error change is below rel_tol (Sec. 5.2.3); True: also when
    #: the error rises (the decrease is below rel_tol, Sec. 6.2.5), see the module notes
    stop_on_increase: bool = False
    #: component weights conditioned on C/N0 and elevation (:func:`~estimators.model.clustering.conditioned_labels`):
    #: each row takes the component most likely under its own prior; False: one weight per component
    conditioned: bool = False

    def validate(self, where: str) -> None:
        """One-line :class:`SimbenchError` for the first out-of-range field (``where``: config node name)."""
        super().validate(where)
        for name, low in (("truncation", 1), ("dpgmm_max_iter", 1), ("fit_sample", 0)):
            require_at_least(
                f"{where}.{name}",
                getattr(self, name),
                low,
                f"the defaults are in {type(self).__name__} (estimators/batch/configs.py)",
            )


@dataclass
class BceAdConfig(BceConfig):
    """BCE-AD parameters."""

    # BCE-AD keeps the full-data fit and the looser tolerance: its accuracy was not re-checked
    # with BCE's faster defaults
    dpgmm_tol: float = 1e-4  #: lower-bound tolerance of the variational fit
    fit_sample: int = 0  #: fit the mixture on at most this many random residuals (0: all)
    n_features: int = 2  #: features kept by MCFS each iteration (of the 5 in FEATURES)
    mcfs_clusters: int = 3  #: eigenvectors of the MCFS spectral embedding
    mcfs_neighbors: int = 5  #: neighbours of the MCFS kNN graph
    feature_sample: int = 2000  #: MCFS runs on at most this many random rows (kNN graph cost)
    stop_on_increase: bool = True  #: stop when the error decrease is below rel_tol (Sec. 6.2.5)

    def validate(self, where: str) -> None:
        """One-line :class:`SimbenchError` for the first out-of-range field (``where``: config node name)."""
        super().validate(where)
        if not 1 <= self.n_features <= len(FEATURES):
            raise SimbenchError(
                f"{where}.n_features",
                f"must be 1..{len(FEATURES)}, got {self.n_features}",
                "choose how many of code/phase residual, elevation, azimuth, C/N0 to keep",
            )


@dataclass
class OracleConfig(BatchConfig):
    """Oracle parameters: the graph model; the measurement sigmas come from the labels.

    ``code_sigma_m`` and ``phase_sigma_m`` only serve preparing the data; the
    oracle weights with the label sigmas.
    """
