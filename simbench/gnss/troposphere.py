"""The modelled slant troposphere of the estimator-side measurement model."""

from __future__ import annotations

import numpy as np

from simbench.core import atmosphere

__all__ = ["troposphere_terms"]


def troposphere_terms(
    el: np.ndarray, lat: np.ndarray | float, h: np.ndarray | float, doy: float
) -> tuple[np.ndarray, np.ndarray]:
    """Modelled slant hydrostatic delay ``ZHD m_h`` [m] and wet mapping ``m_w`` [-] per satellite.

    Saastamoinen zenith hydrostatic delay with the standard atmosphere and
    Niell mappings. A metre of receiver position changes these by well under a
    millimetre, so callers evaluate them once per epoch (or once per row with
    per-row ``lat``/``h``) at a rough position.

    Parameters
    ----------
    el : np.ndarray, shape (k,)
        Elevations [rad].
    lat, h : float or np.ndarray broadcastable to (k,)
        Geodetic latitude [rad] and ellipsoidal height [m] of the receiver.
    doy : float
        Day of year (Niell seasonal term).

    Returns
    -------
    slant_hydrostatic_m : np.ndarray, shape (k,)
    wet_mapping : np.ndarray, shape (k,)
    """
    zhd, _ = atmosphere.saastamoinen_zenith_m(lat, h)
    m_h, m_w = atmosphere.niell_mapping(el, lat, h, doy)
    return zhd * m_h, m_w
