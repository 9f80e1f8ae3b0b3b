"""Street-canyon propagation: masking, knife-edge diffraction and facade reflections as rays.

Buildings are vertical facades parallel to the road on both sides, heights
measured from the antenna. For a satellite at azimuth ``az`` and elevation
``el`` with ``s = sin(az - heading)``, the *near* facade (distance ``d_n``,
height ``H_n``) is on the satellite's side, the *far* one (``d_f``, ``H_f``)
faces it. In the vertical plane across the street a ray climbs
``k = tan(el) / |s|`` per metre, so the near facade masks the satellite when
``k d_n < H_n`` (the elevation mask ``atan(H_n |s| / d_n)``). Three rays reach
the antenna (image method; Groves, *Principles of GNSS, Inertial, and
Multisensor Integrated Navigation Systems*, 2nd ed., sec. 10.4):

0. the direct ray, attenuated by knife-edge diffraction over the near roof
   edge (ITU-R P.526-15 eq. 31, ``J(v)``), which also carries it past a roof
   that masks it (a diffracted, slightly delayed ray);
1. one bounce off the far facade, extra path ``2 d_f cos(el) |s|``, where the
   facade reflects (a persistent random gate of probability
   ``reflection_probability``) and, for a visible satellite, the bounce point
   ``k d_f`` is below the far roof and the incoming ray clears the near roof
   (``k (2 d_f + d_n) > H_n``). A masked satellite keeps the canyon model's
   original rule (gate and a building on the far side, at any height): the
   block-side heights do not describe the taller buildings behind, the
   crossing streets or other reflectors, and the strict two-facade geometry
   alone would remove most delayed NLOS receptions of ``urban`` (13 % -> 4 % of
   the observations). Its reflecting building may stand ``reflector_beyond_m``
   beyond the far facade (a taller building behind a lower one, or across a
   crossing street), which adds ``2 (extra) cos(el) |s|`` to the delay. With
   ``masked_reflection: visible`` the rays must clear the roofs instead
   (:func:`visible_reflector_m`): the reflector stands no nearer than where the
   bounced ray clears the near roof, a reflector behind the far facade is seen
   only over the far roof, and none arrives from beyond ``reflector_max_m``; so
   the delay grows as the elevation falls until the low sky is not received;
2. far facade then near facade (only possible when the direct ray is masked),
   extra path ``2 (d_f + d_n) cos(el) |s|``, with the bounces at ``k (2 d_n + d_f)``
   on the far and ``k d_n`` on the near facade, clearing the near roof at
   ``k (3 d_n + 2 d_f)``.

A bounce multiplies the field by the Fresnel coefficients of the facade
(ITU-R P.2040-1 permittivity and conductivity at L1) for the incidence angle
``acos(cos(el) |s|)``, split into the co-polar (RHCP) and cross-polar (LHCP)
parts ``(Gamma_TE +- Gamma_TM) / 2``; the antenna rejects LHCP by
``lhcp_rejection_db`` at zenith, falling as ``sin(el)`` to nothing at the
horizon (a patch's axial ratio degrades towards the horizon), and a rough
facade scatters ``scattering_loss_db`` away per bounce. The far facade's relief (a Gauss-Markov offset along the
distance travelled, ``facade_relief_sigma_m`` over ``facade_relief_length_m``)
lengthens each of its bounces by ``2 offset cos(incidence)``: a parked car sees
frozen multipath, a moving one a fading one. Carrier phases are
``-2 pi (extra path) / lambda`` plus ``pi`` per bounce. Elevations are
preserved by vertical walls, so every ray sees the antenna gain of the direct one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import norm

from simbench.core.constants import F_L1, LAMBDA_L1
from simbench.sim.config import FacadeMaterial, MaskedReflection, NlosConfig
from simbench.sim.processes import Columns, gauss_markov

#: Persistence of a reflection path; reflections come and go as the car passes facades.
REFLECTION_TAU_S = 10.0
#: Number of rays per satellite: direct/diffracted, single bounce, double bounce.
N_RAYS = 3


@dataclass(frozen=True)
class CanyonRays:
    """Per (epoch, satellite) rays of the canyon model; ray arrays have shape (..., N_RAYS).

    ``...`` is (n, m) for the whole grid, or (k,) for a list of (epoch, satellite) cells.
    """

    blocked: np.ndarray  #: (...) direct ray below the near roof (received, if at all, NLOS)
    amplitude: np.ndarray  #: field amplitude relative to an unobstructed direct ray [-]; 0 = absent
    delay_m: np.ndarray  #: extra path length relative to the direct geometric path [m]
    phase_rad: np.ndarray  #: carrier phase relative to the direct geometric path [rad]

    @property
    def reference(self) -> np.ndarray:
        """(...) index of the ray a tracking loop locks to: the direct one if visible, else the strongest."""
        return np.where(self.blocked, np.argmax(self.amplitude, axis=-1), 0)


def knife_edge_loss_db(v: np.ndarray) -> np.ndarray:
    """Single knife-edge diffraction loss ``J(v)`` (ITU-R P.526-15, eq. 31).

    ``J(v) = 6.9 + 20 log10(sqrt((v - 0.1)^2 + 1) + v - 0.1)`` for ``v > -0.78``,
    0 below. ``J(0) = 6.0 dB`` (grazing), about 13.9 dB at ``v = 1``.

    Parameters
    ----------
    v : ndarray
        Fresnel-Kirchhoff diffraction parameter [-].

    Returns
    -------
    ndarray
        Loss [dB], >= 0.
    """
    w = np.maximum(v, -0.78) - 0.1
    return np.where(v > -0.78, 6.9 + 20.0 * np.log10(np.sqrt(w * w + 1.0) + w), 0.0)


def fresnel_circular(cos_incidence: np.ndarray, material: FacadeMaterial) -> tuple[np.ndarray, np.ndarray]:
    """Co- and cross-polar reflection coefficients of a circularly polarised wave off a facade.

    ``Gamma_TE = (c - r) / (c + r)``, ``Gamma_TM = (eps c - r) / (eps c + r)`` with
    ``c = cos(incidence)``, ``r = sqrt(eps - 1 + c^2)`` and the complex permittivity
    ``eps = eps_r - j 17.98 sigma / f_GHz`` (ITU-R P.2040-1 eqs. 9a/9b, 31-33).
    Co-polar ``(Gamma_TE + Gamma_TM) / 2`` keeps the handedness (all of it at
    grazing incidence), cross-polar ``(Gamma_TE - Gamma_TM) / 2`` flips it (all of
    it at normal incidence).

    Parameters
    ----------
    cos_incidence : ndarray
        Cosine of the angle between the ray and the facade normal [-].
    material : FacadeMaterial

    Returns
    -------
    co, cross : ndarray (complex)
    """
    facade = FacadeMaterial[str(material)]  # a member or its YAML word
    a, (c_coef, d_exp) = facade.permittivity, facade.conductivity
    f_ghz = F_L1 / 1e9
    eps = a - 1j * 17.98 * c_coef * f_ghz**d_exp / f_ghz
    c = np.clip(cos_incidence, 0.0, 1.0)
    r = np.sqrt(eps - 1.0 + c * c)
    te = (c - r) / (c + r)
    tm = (eps * c - r) / (eps * c + r)
    return 0.5 * (te + tm), 0.5 * (te - tm)


def canyon_rays(
    el_rad: np.ndarray,
    az_rad: np.ndarray,
    road_heading_rad: np.ndarray,
    wall_left_m: np.ndarray,
    wall_right_m: np.ndarray,
    height_left_m: np.ndarray,
    height_right_m: np.ndarray,
    travelled_m: np.ndarray,
    cfg: NlosConfig,
    dt_s: float,
    rng: np.random.Generator,
    where: np.ndarray | None = None,
    columns: Columns | None = None,
) -> CanyonRays:
    """Direct, single-bounce and double-bounce rays of every satellite in the street canyon.

    Parameters
    ----------
    el_rad, az_rad : ndarray, shape (n, m)
        Elevation and azimuth of each satellite [rad].
    road_heading_rad, wall_left_m, wall_right_m, height_left_m, height_right_m : ndarray, shape (n,)
        Street geometry at each epoch (road axis from north [rad]; facade
        distances and building heights above the antenna [m]; height 0 where a side is open).
    travelled_m : ndarray, shape (n,)
        Distance travelled since the start [m], non-decreasing: the facade relief is a function of it.
    cfg : NlosConfig
    dt_s : float
        Epoch interval [s], for the persistence of reflections.
    rng : numpy.random.Generator
    where : ndarray of bool, shape (n, m), optional
        The (epoch, satellite) pairs whose rays are wanted (by default all). The random
        processes are drawn for every pair either way, so the rays where wanted do not
        depend on ``where``.
    columns : Columns, optional
        Which satellites of the constellation the m columns are: the random processes are
        drawn across all ``columns.width`` (by default the m columns are the constellation).

    Returns
    -------
    CanyonRays
        Of shape (n, m) without ``where``; else of the wanted pairs, (k,) in the order of
        ``np.nonzero(where)`` (epoch-major).
    """
    n, m = el_rad.shape
    columns = Columns.every(m) if columns is None else columns
    # the rays of one pair depend on its own inputs only: the arithmetic runs on the wanted pairs, a
    # third of the grid for a ground receiver (satellites below the mask are most of it)
    ei, si = np.nonzero(np.ones((n, m), bool) if where is None else where)
    el = el_rad[ei, si]
    s = np.sin(az_rad[ei, si] - road_heading_rad[ei])
    right = s > 0.0
    abs_s = np.maximum(np.abs(s), 1e-9)
    wall_left, wall_right, height_left, height_right = (
        wall_left_m[ei],
        wall_right_m[ei],
        height_left_m[ei],
        height_right_m[ei],
    )
    d_near = np.where(right, wall_right, wall_left)
    h_near = np.where(right, height_right, height_left)
    d_far = np.where(right, wall_left, wall_right)
    h_far = np.where(right, height_left, height_right)
    k = np.tan(el) / abs_s  # climb per metre across the street
    blocked = k * d_near < h_near

    # Knife edge over the near roof, in the vertical plane across the street (normal to the edge).
    clearance = h_near - k * d_near  # > 0: the roof masks the direct ray
    cos_cross = 1.0 / np.sqrt(1.0 + k * k)
    slant = d_near / (abs_s * np.maximum(np.cos(el), 1e-9))  # antenna -> roof edge along the ray
    v = clearance * cos_cross * np.sqrt(2.0 / (LAMBDA_L1 * slant))
    a_direct = 10.0 ** (-knife_edge_loss_db(v) / 20.0)
    d_direct = np.where(blocked, (clearance * cos_cross) ** 2 / (2.0 * slant), 0.0)

    # A reflection persists for a while: threshold a slow unit Gauss-Markov process so that the
    # long-run fraction of facades offering a specular point is the configured one.
    unit = gauss_markov(n, columns.width, 1.0, REFLECTION_TAU_S, dt_s, rng, columns.keep)
    gate = unit[ei, si] < norm.ppf(cfg.reflection_probability)
    single = gate & (h_far > 0.0) & (blocked | ((k * d_far < h_far) & (k * (2.0 * d_far + d_near) > h_near)))
    double = (
        gate
        & blocked
        & (h_far > 0.0)
        & (k * (2.0 * d_near + d_far) < h_far)
        & (k * (3.0 * d_near + 2.0 * d_far) > h_near)
    )

    cos_inc = np.cos(el) * abs_s
    co, cross = fresnel_circular(cos_inc, cfg.facade_material)
    xpol = 10.0 ** (-cfg.lhcp_rejection_db * np.sin(np.maximum(el, 0.0)) / 20.0)
    rough = 10.0 ** (-cfg.scattering_loss_db / 20.0)
    # Powers of the two polarisations add (their phases differ with the geometry).
    a_single = rough * np.sqrt(np.abs(co) ** 2 + (xpol * np.abs(cross)) ** 2)
    # Two bounces: the handedness flips twice for cross * cross and once for the mixed terms.
    a_double = rough**2 * np.sqrt(np.abs(co * co + cross * cross) ** 2 + (xpol * np.abs(2.0 * co * cross)) ** 2)

    relief = _relief_m(travelled_m, columns, cfg, rng, ei, si)
    facade = np.maximum(d_far + relief, 0.5 * d_far)  # never behind the antenna
    horizontal = 2.0 * cos_inc
    beyond = np.where(blocked, _reflector_beyond_m(n, columns, cfg, dt_s, rng, ei, si), 0.0)
    if cfg.masked_reflection == MaskedReflection.visible:
        distance, reachable = visible_reflector_m(k, d_near, h_near, facade, h_far, beyond)
        reflector = np.where(blocked, distance, facade)
        single = np.where(blocked, gate & reachable & (distance <= cfg.reflector_max_m), single)
    else:
        reflector = facade + beyond
    amplitude = np.stack([a_direct, np.where(single, a_single, 0.0), np.where(double, a_double, 0.0)], axis=-1)
    delay = np.stack([d_direct, horizontal * reflector, horizontal * (facade + d_near)], axis=-1)
    phase = -2.0 * np.pi / LAMBDA_L1 * delay + np.pi * np.arange(N_RAYS)  # each bounce turns the carrier by pi
    shape = (n, m) if where is None else (len(ei),)
    return CanyonRays(
        blocked=blocked.reshape(shape),
        amplitude=amplitude.reshape(shape + (N_RAYS,)),
        delay_m=delay.reshape(shape + (N_RAYS,)),
        phase_rad=phase.reshape(shape + (N_RAYS,)),
    )


def visible_reflector_m(
    k: np.ndarray,
    d_near_m: np.ndarray,
    h_near_m: np.ndarray,
    facade_m: np.ndarray,
    h_far_m: np.ndarray,
    beyond_m: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Where a masked satellite's single bounce comes from, and whether it reaches the antenna at all.

    In the vertical plane across the street the bounced ray descends to the
    antenna at ``k = tan(el) / |s|`` per metre. Off a reflector at distance
    ``D`` on the far side it came over the near facade at height
    ``k (2 D + d_n)``, so it clears the near roof only from
    ``D >= D_min = (H_n / k - d_n) / 2``. The far facade (``d_f``) reflects
    when it is far enough (``D_min <= d_f``) and the bounce point ``k d_f``
    is below its roof; otherwise the reflector stands behind it, at
    ``max(d_f, D_min) + beyond``, and the bounced ray must pass over the far
    roof (``k d_f >= H_f``; an open side has ``H_f = 0``). So the extra path
    ``2 D cos(el) |s|`` is at least ``|s| cos(el) (H_n |s| / tan(el) - d_n)``
    and grows as the elevation falls, until no reflection gets over the roofs.

    Parameters
    ----------
    k : ndarray
        Climb of the ray per metre across the street, ``tan(el) / |s|`` [-], > 0.
    d_near_m, h_near_m : ndarray
        Distance of the near facade from the antenna and its height above it [m].
    facade_m, h_far_m : ndarray
        Distance of the far facade and its height [m] (0 where the side is open).
    beyond_m : ndarray
        How far behind the far facade (or behind ``D_min``) a reflector behind it stands [m].

    Returns
    -------
    distance_m : ndarray
        Distance of the reflecting surface across the street [m].
    reachable : ndarray of bool
        The bounced ray clears both roofs.
    """
    nearest = 0.5 * (h_near_m / k - d_near_m)
    own = (nearest <= facade_m) & (k * facade_m < h_far_m)
    behind = np.maximum(facade_m, nearest) + beyond_m
    return np.where(own, facade_m, behind), own | (k * facade_m >= h_far_m)


def _reflector_beyond_m(
    n: int, columns: Columns, cfg: NlosConfig, dt_s: float, rng: np.random.Generator, ei: np.ndarray, si: np.ndarray
) -> np.ndarray:
    """How far beyond the far facade a masked satellite's reflecting building stands [m], at ``(ei, si)``.

    Uniform over ``reflector_beyond_m``, persistent like the reflection gate (a
    slow unit Gauss-Markov process through the normal CDF); zero, without a
    draw from ``rng``, when the range is ``(0, 0)``.
    """
    low, high = cfg.reflector_beyond_m
    if high <= 0.0:
        return np.zeros(len(ei))
    unit = gauss_markov(n, columns.width, 1.0, REFLECTION_TAU_S, dt_s, rng, columns.keep)
    return low + (high - low) * norm.cdf(unit[ei, si])


def _relief_m(
    travelled_m: np.ndarray,
    columns: Columns,
    cfg: NlosConfig,
    rng: np.random.Generator,
    ei: np.ndarray,
    si: np.ndarray,
) -> np.ndarray:
    """Offset of satellite ``si``'s specular point on the far facade at epoch ``ei`` [m].

    A Gauss-Markov process in distance (step an eighth of the correlation
    length), linearly interpolated at the distance travelled at each epoch.
    """
    step = cfg.facade_relief_length_m / 8.0
    span = float(travelled_m[-1] - travelled_m[0]) if len(travelled_m) else 0.0
    n_grid = int(span / step) + 2
    grid = gauss_markov(
        n_grid, columns.width, cfg.facade_relief_sigma_m, cfg.facade_relief_length_m, step, rng, columns.keep
    )
    u = (travelled_m - (travelled_m[0] if len(travelled_m) else 0.0)) / step
    i = np.minimum(u.astype(np.intp), n_grid - 2)
    frac = (u - i)[ei]
    return grid[i[ei], si] * (1.0 - frac) + grid[i[ei] + 1, si] * frac
