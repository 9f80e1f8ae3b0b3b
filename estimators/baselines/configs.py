"""The per-epoch baselines' ``Config`` dataclasses and their range checks: WLS and Huber SPP
(:mod:`.spp`) and RTKLIB's ``rnx2rtkp`` (:mod:`.rtklib_spp`).

Kept apart from the solvers (pandas, the RINEX writer) so that the command line checks a value of
``estimator.<name>`` by importing this module only (:mod:`simbench.runs.schema_record`).
"""

from __future__ import annotations

from dataclasses import dataclass

from estimators.model.ppp_config import (
    GnssModelConfig,
    IonosphereMode,
    SigmaModel,
    StochasticModelConfig,
    VarianceComponents,
)
from simbench.contract import Need
from simbench.errors import require_at_least, require_elevation_mask, require_positive
from simbench.typed import Choice, check_choices

__all__ = ["HuberSppConfig", "IonosphereModel", "IrlsSppConfig", "RtklibSppConfig", "TroposphereModel", "WlsSppConfig"]


@dataclass
class WlsSppConfig:
    """Parameters of ``wls_spp``: the shared sigma model (defaults of :class:`GnssModelConfig` and
    :class:`StochasticModelConfig`), so the baseline weighs rows as the other estimators do."""

    code_sigma_m: float = StochasticModelConfig.code_sigma_m  #: zenith code sigma [m], scaled by ``sigma_model``
    #: per-row scaling of the sigma: elevation | cn0 | elevation_cn0
    sigma_model: SigmaModel = GnssModelConfig.sigma_model
    cn0_ref_dbhz: float = StochasticModelConfig.cn0_ref_dbhz  #: C/N0 at which the ``cn0`` factor is 1 [dB-Hz]
    elevation_mask_deg: float = StochasticModelConfig.elevation_mask_deg  #: [deg]
    #: auto | broadcast | free (:class:`~estimators.model.ppp_config.IonosphereMode`)
    ionosphere: IonosphereMode = GnssModelConfig.ionosphere
    #: none | system | system_cn0 (:class:`~estimators.model.ppp_config.VarianceComponents`)
    variance_components: VarianceComponents = GnssModelConfig.variance_components

    def validate(self, where: str) -> None:
        """Raise a one-line :class:`SimbenchError` for the first out-of-range field."""
        check_choices(self, where)
        require_positive(f"{where}.code_sigma_m", self.code_sigma_m, "give a standard deviation in metres")
        require_positive(f"{where}.cn0_ref_dbhz", self.cn0_ref_dbhz, "give a reference C/N0 in dB-Hz, e.g. 45")
        require_elevation_mask(
            f"{where}.elevation_mask_deg", self.elevation_mask_deg, "give an elevation mask in degrees, e.g. 7"
        )

    def needs(self) -> frozenset[Need]:
        """A second frequency for ``ionosphere=free``; nothing else (code only)."""
        return frozenset({Need.dual_frequency} if self.ionosphere == IonosphereMode.free else ())


@dataclass
class IrlsSppConfig(WlsSppConfig):
    """``wls_spp``'s parameters plus the passes of an M-estimator loss solved by iteratively reweighted
    least squares (IRLS); a subclass adds the loss's scale (``huber_spp``, the example plug-in's Cauchy)."""

    reweightings: int = 5  #: iteratively reweighted least-squares passes after the plain fit

    def validate(self, where: str) -> None:
        """The ``wls_spp`` checks, then the number of passes."""
        super().validate(where)
        require_at_least(f"{where}.reweightings", self.reweightings, 1, "give the number of IRLS passes, e.g. 5")


@dataclass
class HuberSppConfig(IrlsSppConfig):
    """Parameters of ``huber_spp``: the IRLS passes plus the Huber loss's threshold."""

    huber_k: float = 1.345  #: Huber threshold [standard deviations]: 95 % efficiency under Gaussian noise

    def validate(self, where: str) -> None:
        """The IRLS checks, then the loss's."""
        super().validate(where)
        require_positive(f"{where}.huber_k", self.huber_k, "give a threshold in standard deviations, e.g. 1.345")


class IonosphereModel(Choice):
    """Ionospheric correction RTKLIB applies (member names are the YAML words).

    The first three are :class:`~estimators.model.ppp_config.IonosphereMode`'s words, so the
    ``gnss_model`` preset's choice reaches RTKLIB as it reaches the other estimators.
    """

    auto = "auto"  #: ``free`` where every satellite above the mask has a second frequency, else ``broadcast``
    broadcast = "broadcast"  #: broadcast Klobuchar model (RTKLIB ``brdc``)
    free = "free"  #: dual-frequency ionosphere-free code (RTKLIB ``dual-freq``, ``pos1-frequency = l1+l2``)
    none = "none"  #: no correction (``off``)


class TroposphereModel(Choice):
    """Tropospheric correction RTKLIB applies (member names are the YAML words)."""

    saastamoinen = "saastamoinen"  #: Saastamoinen with standard atmosphere (RTKLIB ``saas``)
    none = "none"  #: no correction (``off``)


@dataclass
class RtklibSppConfig:
    """RTKLIB single-point settings (see the module docstring for the options file they become)."""

    elevation_mask_deg: float = 10.0  #: satellites below are not used [deg] (RTKLIB's default is 15)
    ionosphere: IonosphereModel = IonosphereModel.auto  #: auto | broadcast | free | none
    troposphere: TroposphereModel = TroposphereModel.saastamoinen  #: saastamoinen | none
    raim_fde: bool = False  #: RTKLIB's RAIM fault detection and exclusion (``pos1-posopt5``)
    timeout_s: float = 300.0  #: rnx2rtkp is stopped after this wall time [s]

    def validate(self, where: str) -> None:
        """Raise a one-line :class:`SimbenchError` for the first out-of-range field.

        Parameters
        ----------
        where : str
            Config node name, e.g. ``estimator.rtklib_spp``.
        """
        check_choices(self, where)
        require_elevation_mask(
            f"{where}.elevation_mask_deg", self.elevation_mask_deg, "give an elevation mask in degrees, e.g. 10"
        )
        require_positive(f"{where}.timeout_s", self.timeout_s, "give a wall-time limit in seconds, e.g. 300")
