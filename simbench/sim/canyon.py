"""Street-canyon visibility: building masks and non-line-of-sight (NLOS) receptions.

Buildings are vertical facades parallel to the road on both sides. Looking
along azimuth ``az`` the facade on that side lies at horizontal distance
``d / |sin(az - heading)|`` and masks elevations below
``atan(H |sin(az - heading)| / d)``. A masked satellite is either lost or,
when a reflection off the opposite facade exists, received NLOS with the
extra path of a specular reflection, ``2 d' cos(el) |sin(az - heading)|``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import norm

from simbench.config import NlosConfig
from simbench.sim.processes import gauss_markov

#: Persistence of a reflection path; reflections come and go as the car passes facades.
REFLECTION_TAU_S = 10.0


@dataclass(frozen=True)
class CanyonVisibility:
    """Per (epoch, satellite) outcome of the canyon model; arrays of shape (n, m)."""

    blocked: np.ndarray  #: direct signal masked by a building
    nlos: np.ndarray  #: blocked but received through a reflection
    nlos_delay_m: np.ndarray  #: extra path length of the reflection [m]; 0 where not NLOS


def canyon_visibility(el_rad: np.ndarray, az_rad: np.ndarray, road_heading_rad: np.ndarray,
                      wall_left_m: np.ndarray, wall_right_m: np.ndarray, height_left_m: np.ndarray,
                      height_right_m: np.ndarray, cfg: NlosConfig, dt_s: float,
                      rng: np.random.Generator) -> CanyonVisibility:
    """Mask satellites behind facades and decide which are received via reflections.

    Parameters
    ----------
    el_rad, az_rad : ndarray, shape (n, m)
        Elevation and azimuth of each satellite [rad].
    road_heading_rad, wall_left_m, wall_right_m, height_left_m, height_right_m : ndarray, shape (n,)
        Street geometry at each epoch (road axis from north [rad]; facade
        distances and building heights [m]; height 0 where a side is open).
    cfg : NlosConfig
    dt_s : float
        Epoch interval [s], for the persistence of reflections.
    rng : numpy.random.Generator

    Returns
    -------
    CanyonVisibility
    """
    s = np.sin(az_rad - road_heading_rad[:, None])
    right = s > 0.0
    dist = np.where(right, wall_right_m[:, None], wall_left_m[:, None])
    height = np.where(right, height_right_m[:, None], height_left_m[:, None])
    mask_el = np.arctan2(height * np.abs(s), dist)
    blocked = el_rad < mask_el
    # A reflection path persists for a while: threshold a slow unit Gauss-Markov process
    # so that the long-run fraction of masked satellites received NLOS is the configured one.
    n, m = el_rad.shape
    path = gauss_markov(n, m, 1.0, REFLECTION_TAU_S, dt_s, rng)
    reflector_height = np.where(right, height_left_m[:, None], height_right_m[:, None])
    has_reflector = reflector_height > 0.0
    nlos = blocked & has_reflector & (path < norm.ppf(cfg.reflection_probability))
    opposite = np.where(right, wall_left_m[:, None], wall_right_m[:, None])
    delay = np.where(nlos, 2.0 * opposite * np.cos(el_rad) * np.abs(s), 0.0)
    return CanyonVisibility(blocked=blocked, nlos=nlos, nlos_delay_m=delay)
