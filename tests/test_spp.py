"""The one single-point solver (simbench.gnss.spp) and the one Sagnac gradient (simbench.gnss.geometry)."""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest

from simbench.core import atmosphere
from simbench.core.constants import DEG, SECONDS_PER_WEEK
from simbench.core.gpstime import day_of_year
from simbench.core.orbits import NominalConstellation
from simbench.errors import SimbenchError
from simbench.gnss.geometry import sagnac_range, sagnac_range_gradient
from simbench.gnss.spp import position_gains, solve_epochs
from simbench.sim.geometry import line_of_sight

LAT, LON, H = 39.6295, -79.9559, 290.0  # deg, deg, m
WEEK, SOW0 = 2032, 475_200.0


def _epochs(n: int, *, moving: bool = True) -> dict[str, np.ndarray]:
    """Exact geometry of a receiver driving east at 10 m/s (or standing), 1 Hz, satellites above 10 deg."""
    rx0 = np.array(pymap3d.geodetic2ecef(LAT, LON, H))
    east = np.array([-np.sin(LON * DEG), np.cos(LON * DEG), 0.0])
    t = np.arange(n, dtype=float)
    rx = rx0 + 10.0 * float(moving) * t[:, None] * east
    los = line_of_sight(rx, None, WEEK * SECONDS_PER_WEEK + SOW0 + t, NominalConstellation())
    e, j = np.nonzero(los.el_rad > 10 * DEG)
    return {
        "rx": rx,
        "epoch": e,
        "sat_j": j,
        "sat_pos": los.sat_pos_tx[e, j],
        "el": los.el_rad[e, j],
        "range": los.range_m[e, j],
    }


def test_sagnac_gradient_matches_finite_differences() -> None:
    g = _epochs(1)
    rx = g["rx"][0]
    rho, grad = sagnac_range_gradient(g["sat_pos"], rx)
    assert np.allclose(rho, sagnac_range(g["sat_pos"], rx), atol=1e-9)
    for k in range(3):
        d = np.zeros(3)
        d[k] = 1.0
        fd = (sagnac_range(g["sat_pos"], rx + d) - sagnac_range(g["sat_pos"], rx - d)) / 2.0
        assert np.allclose(grad[:, k], fd, atol=1e-9)
    # the Sagnac term is in it: it differs from the plain unit vector by omega_e |s| / c ~ 6e-6
    plain = -(g["sat_pos"] - rx) / np.linalg.norm(g["sat_pos"] - rx, axis=1)[:, None]
    assert np.abs(grad - plain).max() > 2e-6


def test_many_epochs_from_earth_centre_with_troposphere() -> None:
    """Exact codes with the modelled hydrostatic delay: every epoch recovered to a millimetre, clock too."""
    g = _epochs(120)
    doy = day_of_year(WEEK, SOW0)
    lat, _, h = (np.asarray(v) for v in zip(*(pymap3d.ecef2geodetic(*p) for p in g["rx"][g["epoch"]])))
    slant = atmosphere.tropo_slant_m(g["el"], lat * DEG, h, doy, 0.0)
    clock = 500.0 + 3.0 * g["epoch"]
    code = sagnac_range(g["sat_pos"], g["rx"][g["epoch"]]) + clock + slant
    shuffle = np.random.default_rng(0).permutation(len(code))  # rows in any order
    sol = solve_epochs(g["epoch"][shuffle], g["sat_pos"][shuffle], code[shuffle], el=g["el"][shuffle], doy=doy)
    assert sol.trusted.all() and sol.pos.shape == (120, 3)
    assert np.abs(sol.pos - g["rx"]).max() < 1e-3
    assert np.abs(sol.clock_m[:, 0] - (500.0 + 3.0 * np.arange(120))).max() < 1e-3
    assert sol.rms_m.max() < 1e-3


def test_inter_system_bias_and_weights() -> None:
    """Two systems with a 40 m offset: recovered per epoch; noisy rows with large sigma barely matter."""
    g = _epochs(60, moving=False)
    rng = np.random.default_rng(1)
    system = (g["sat_j"] % 2).astype(np.int64)
    noise = np.where(system == 1, 0.3, 0.1) * rng.standard_normal(len(system))
    code = sagnac_range(g["sat_pos"], g["rx"][g["epoch"]]) + 100.0 + 40.0 * system + noise
    sol = solve_epochs(g["epoch"], g["sat_pos"], code, sigma=np.where(system == 1, 0.3, 0.1), system_index=system)
    isb = sol.clock_m[:, 1] - sol.clock_m[:, 0]
    assert abs(np.median(isb) - 40.0) < 0.2
    one_clock = solve_epochs(g["epoch"], g["sat_pos"], code)  # the bias leaks into the position
    assert np.median(np.linalg.norm(one_clock.pos - g["rx"], axis=1)) > 5 * np.median(
        np.linalg.norm(sol.pos - g["rx"], axis=1)
    )


def test_trust_check_and_fill() -> None:
    """An epoch with 3 satellites and one with a kilometre blunder are not trusted; fill borrows a neighbour."""
    g = _epochs(10, moving=False)
    code = sagnac_range(g["sat_pos"], g["rx"][g["epoch"]]) + 50.0
    keep = ~((g["epoch"] == 4) & (np.arange(len(code)) >= np.flatnonzero(g["epoch"] == 4)[0] + 3))
    code[np.flatnonzero(g["epoch"] == 7)[0]] += 5_000.0
    e, s, c = g["epoch"][keep], g["sat_pos"][keep], code[keep]
    sol = solve_epochs(e, s, c, max_rms_m=300.0)
    assert sol.trusted.tolist() == [k not in (4, 7) for k in range(10)]
    assert np.isnan(sol.pos[4]).all() and sol.n_rows[4] == 3
    filled = solve_epochs(e, s, c, max_rms_m=300.0, fill_untrusted=True)
    assert np.abs(filled.pos[4] - g["rx"][4]).max() < 1e-3  # a static receiver: the neighbour is exact
    assert abs(filled.clock_m[4, 0] - 50.0) < 1e-3
    with pytest.raises(SimbenchError, match="trusted"):
        solve_epochs(e[e == 4], s[e == 4], c[e == 4], fill_untrusted=True)
    with pytest.raises(SimbenchError, match="epoch indices"):
        solve_epochs(e[:-1], s, c)


def test_five_systems_each_get_their_own_clock() -> None:
    """G, R, E, C and J rows with offsets 0, 30, -20, 55 and 10 m: every offset recovered, the position exact.

    Each satellite's geometry serves twice (two systems), so that every epoch has rows of all five."""
    g = _epochs(30, moving=False)
    epoch = np.concatenate([g["epoch"], g["epoch"]])
    sat_pos = np.concatenate([g["sat_pos"], g["sat_pos"]])
    system = np.concatenate([g["sat_j"] % 5, (g["sat_j"] + 2) % 5]).astype(np.int64)
    offsets = np.array([0.0, 30.0, -20.0, 55.0, 10.0])
    code = sagnac_range(sat_pos, g["rx"][epoch]) + 200.0 + offsets[system]
    sol = solve_epochs(epoch, sat_pos, code, system_index=system)
    seen = np.zeros((30, 5), bool)
    seen[epoch, system] = True
    full = sol.trusted & seen.all(axis=1)
    assert sol.clock_m.shape == (30, 5) and full.sum() > 20
    np.testing.assert_allclose(sol.clock_m[full] - sol.clock_m[full, :1], np.tile(offsets, (full.sum(), 1)), atol=1e-3)
    assert np.abs(sol.pos[sol.trusted] - g["rx"][sol.trusted]).max() < 1e-3


def test_huber_reweighting_and_redundancy_numbers() -> None:
    """A 60 m blunder on one row per epoch (7-8 satellites): plain least squares moves by tens of
    metres, Huber IRLS by a tenth of that; the redundancy numbers of an epoch sum to rows minus unknowns."""
    g = _epochs(40, moving=False)
    rng = np.random.default_rng(4)
    code = sagnac_range(g["sat_pos"], g["rx"][g["epoch"]]) + 100.0 + 0.3 * rng.standard_normal(len(g["epoch"]))
    first = np.unique(g["epoch"], return_index=True)[1]
    code[first] += 60.0
    sigma = np.full(len(code), 0.3)
    plain = solve_epochs(g["epoch"], g["sat_pos"], code, sigma=sigma)
    huber = solve_epochs(g["epoch"], g["sat_pos"], code, sigma=sigma, huber_k=1.345, reweightings=8)
    err_plain = np.linalg.norm(plain.pos - g["rx"], axis=1)
    err_huber = np.linalg.norm(huber.pos - g["rx"], axis=1)
    assert np.median(err_plain) > 20.0 and np.median(err_huber) < 0.1 * np.median(err_plain)
    assert np.all(huber.weight[first] < 0.05) and np.median(np.delete(huber.weight, first)) > 0.9
    sums = np.bincount(g["epoch"], plain.redundancy)
    np.testing.assert_allclose(sums, plain.n_rows - 4, atol=1e-9)
    assert np.allclose(
        plain.residual_m, code - sagnac_range(g["sat_pos"], plain.pos[g["epoch"]]) - plain.clock_m[g["epoch"], 0]
    )


def test_position_gains_are_how_range_errors_move_the_fix() -> None:
    """Small range errors move the weighted two-system fix by sum_r g_r d_r (to 1e-6 m); an error common to
    one system's rows moves it by nothing (its clock takes it)."""
    g = _epochs(30)
    rng = np.random.default_rng(2)
    system = (g["sat_j"] % 2).astype(np.int64)
    sigma = rng.uniform(0.5, 3.0, len(system))
    code = sagnac_range(g["sat_pos"], g["rx"][g["epoch"]]) + 100.0 + 40.0 * system
    error = rng.normal(0.0, 0.5, len(system))
    fit = {"sigma": sigma, "system_index": system, "x0": g["rx"][0]}
    moved = (
        solve_epochs(g["epoch"], g["sat_pos"], code + error, **fit).pos
        - solve_epochs(g["epoch"], g["sat_pos"], code, **fit).pos
    )
    gains = position_gains(g["epoch"], g["sat_pos"], g["rx"][g["epoch"]], sigma, system)
    predicted = np.stack([np.bincount(g["epoch"], gains[:, i] * error, 30) for i in range(3)], axis=1)
    assert np.abs(moved - predicted).max() < 1e-6 and np.abs(moved).max() > 0.1
    common = np.stack([np.bincount(g["epoch"], gains[:, i] * (system == 1), 30) for i in range(3)], axis=1)
    assert np.abs(common).max() < 1e-9
