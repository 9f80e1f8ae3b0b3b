"""IMU: gravity, ideal output (checked by strapdown integration), error statistics, speed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from simbench.core.constants import DEG, OMEGA_EARTH
from simbench.core.frames import dcm_body_to_ecef, ecef_from_geodetic, geodetic_from_ecef
from simbench.errors import SimbenchError
from simbench.sim.config import FlightConfig, ImuConfig, NlosConfig, TrajectoryConfig, UrbanDriveConfig
from simbench.sim.imu import DPH, gravity_ecef, ideal_imu, simulate_imu
from simbench.sim.trajectory import Trajectory, flight, urban_drive

RATE = 100.0
ORIGIN = TrajectoryConfig()
TACTICAL = ImuConfig(
    grade="tactical",
    accel_bias_sigma_mps2=3e-3,
    gyro_bias_sigma_dph=1.0,
    accel_noise_mps2_rthz=3e-4,
    gyro_noise_dph_rthz=3.0,
    accel_bias_instability_mps2=1e-4,
    gyro_bias_instability_dph=0.1,
    bias_tau_s=3600.0,
)


def _static(duration_s: float, rate_hz: float = RATE, att=(0.0, 0.0, 0.0)) -> Trajectory:
    k = int(round(duration_s * rate_hz))
    pos = ecef_from_geodetic(ORIGIN.origin_lat_deg * DEG, ORIGIN.origin_lon_deg * DEG, ORIGIN.origin_h_m)
    zero = np.zeros((k, 3))
    return Trajectory(
        t=np.arange(k) / rate_hz,
        pos=np.tile(pos, (k, 1)),
        vel=zero,
        acc=zero,
        att=np.tile(att, (k, 1)),
        omega_eb_b=zero,
    )


def _strapdown(traj: Trajectory, f_b: np.ndarray, w_ib_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ECEF mechanisation from the true initial state; returns final position and velocity.

    Attitude: C+ = exp(-Omega_ie dt) C exp(w_ib dt) with the mean rate of the interval;
    velocity: trapezoidal specific force, gravity and Coriolis with a predictor step.
    """
    dt = traj.t[1] - traj.t[0]
    w_ie = np.array([0.0, 0.0, OMEGA_EARTH])
    earth = Rotation.from_rotvec(-w_ie * dt).as_matrix()
    body = Rotation.from_rotvec(0.5 * (w_ib_b[:-1] + w_ib_b[1:]) * dt).as_matrix()
    c = dcm_body_to_ecef(traj.pos[:1], traj.att[:1])[0]
    r, v = traj.pos[0].copy(), traj.vel[0].copy()
    for k in range(len(traj.t) - 1):
        c_next = earth @ c @ body[k]
        f_e = 0.5 * (c @ f_b[k] + c_next @ f_b[k + 1])
        g0 = gravity_ecef(r)
        v_pred = v + dt * (f_e + g0 - 2.0 * np.cross(w_ie, v))
        g = 0.5 * (g0 + gravity_ecef(r + 0.5 * dt * (v + v_pred)))
        v_next = v + dt * (f_e + g - np.cross(w_ie, v + v_pred))
        r = r + 0.5 * dt * (v + v_next)
        v, c = v_next, c_next
    return r, v


def _window(traj: Trajectory, start_s: float, length_s: float) -> Trajectory:
    sel = slice(int(round(start_s * RATE)), int(round((start_s + length_s) * RATE)) + 1)
    return Trajectory(
        t=traj.t[sel],
        pos=traj.pos[sel],
        vel=traj.vel[sel],
        acc=traj.acc[sel],
        att=traj.att[sel],
        omega_eb_b=traj.omega_eb_b[sel],
    )


# --------------------------------------------------------------------------- gravity, ideal IMU


def test_gravity_matches_normal_gravity():
    lat = np.radians(np.array([0.0, 39.6295, 60.0, 90.0]))
    h = np.array([0.0, 290.0, 1000.0, 0.0])
    g = gravity_ecef(ecef_from_geodetic(lat, 0.0 * lat, h))
    # Somigliana normal gravity with the free-air gradient
    s2 = np.sin(lat) ** 2
    normal = 9.7803253359 * (1 + 0.00193185265241 * s2) / np.sqrt(1 - 0.00669437999013 * s2) - 3.086e-6 * h
    np.testing.assert_allclose(np.linalg.norm(g, axis=1), normal, atol=2e-4)
    # and it points along the ellipsoid normal (down) to within 10 arc seconds
    down = -ecef_from_geodetic(lat, 0.0 * lat, 0.0 * h + 1.0) + ecef_from_geodetic(lat, 0.0 * lat, 0.0 * h)
    cos = np.einsum("ki,ki->k", g, down) / np.linalg.norm(g, axis=1)
    assert np.arccos(np.clip(cos, -1, 1)).max() < 10.0 / 3600.0 * DEG


def test_stationary_imu_reads_gravity_and_earth_rate():
    f_b, w_ib_b = ideal_imu(_static(1.0, att=(0.1, -0.2, 2.0)))
    assert np.linalg.norm(f_b, axis=1) == pytest.approx(9.80, abs=0.01)
    assert np.linalg.norm(w_ib_b, axis=1) == pytest.approx(7.2921151467e-5, rel=1e-9)
    level_f, level_w = ideal_imu(_static(1.0))
    assert level_f[0, 2] < -9.79 and np.abs(level_f[0, :2]).max() < 1e-3  # specific force points up
    lat = ORIGIN.origin_lat_deg * DEG
    np.testing.assert_allclose(level_w[0], OMEGA_EARTH * np.array([math.cos(lat), 0.0, -math.sin(lat)]), atol=1e-12)


@pytest.mark.parametrize("kind, start_s, bound_m", [("urban", 0.0, 0.02), ("flight", 60.0, 0.5)])
def test_strapdown_reproduces_trajectory(kind, start_s, bound_m):
    """60 s of noise-free IMU data integrated from the true initial state stay on the trajectory.

    Measured: urban 1e-3 m, flight (level-off, roll in/out of a 180 deg turn) 0.14 m.
    """
    cfg = TrajectoryConfig(urban_drive=UrbanDriveConfig(start_static_s=2.0), flight=FlightConfig(start_static_s=2.0))
    if kind == "urban":
        full = urban_drive(cfg, NlosConfig(), 61.0, RATE, np.random.default_rng(0))
    else:
        full = flight(cfg, start_s + 61.0, RATE, np.random.default_rng(0))
    traj = _window(full, start_s, 60.0)
    assert np.linalg.norm(traj.pos[-1] - traj.pos[0]) > 80.0  # it moved
    assert np.abs(traj.omega_eb_b).max() > 0.05  # and turned
    f_b, w_ib_b = ideal_imu(traj)
    r, v = _strapdown(traj, f_b, w_ib_b)
    assert np.linalg.norm(r - traj.pos[-1]) < bound_m
    assert np.linalg.norm(v - traj.vel[-1]) < bound_m / 10.0


def test_strapdown_detects_a_wrong_sign():
    """The check above can fail: dropping the Coriolis term of f_b costs metres in 60 s."""
    cfg = TrajectoryConfig(urban_drive=UrbanDriveConfig(start_static_s=2.0))
    traj = urban_drive(cfg, NlosConfig(), 60.0, RATE, np.random.default_rng(0))
    f_b, w_ib_b = ideal_imu(traj)
    c_b_e = dcm_body_to_ecef(traj.pos, traj.att)
    coriolis = 2.0 * np.cross(np.array([0.0, 0.0, OMEGA_EARTH]), traj.vel)
    wrong = f_b - np.einsum("kji,kj->ki", c_b_e, coriolis)
    r, _ = _strapdown(traj, wrong, w_ib_b)
    assert np.linalg.norm(r - traj.pos[-1]) > 0.05


# --------------------------------------------------------------------------- sensor errors


def test_white_noise_matches_density():
    cfg = ImuConfig()
    traj = _static(600.0)
    imu = simulate_imu(traj, cfg, np.random.default_rng(1))
    f_b, w_ib_b = ideal_imu(traj)
    gyro_noise = imu.gyro - w_ib_b - imu.gyro_bias
    accel_noise = imu.accel - f_b - imu.accel_bias
    assert gyro_noise.std() == pytest.approx(cfg.gyro_noise_dph_rthz * DPH * math.sqrt(RATE), rel=0.05)
    assert accel_noise.std() == pytest.approx(cfg.accel_noise_mps2_rthz * math.sqrt(RATE), rel=0.05)
    assert np.abs(gyro_noise.mean(axis=0)).max() < 0.05 * gyro_noise.std()


def test_bias_gauss_markov_statistics():
    cfg = ImuConfig(bias_tau_s=1.0, gyro_bias_sigma_dph=0.0, accel_bias_sigma_mps2=0.0)
    imu = simulate_imu(_static(2000.0), cfg, np.random.default_rng(2))
    lag = int(round(cfg.bias_tau_s * RATE))
    for drift, sigma in (
        (imu.gyro_bias / DPH, cfg.gyro_bias_instability_dph),
        (imu.accel_bias, cfg.accel_bias_instability_mps2),
    ):
        x = drift - drift.mean(axis=0)
        rho = np.mean(x[:-lag] * x[lag:]) / np.mean(x * x)
        assert rho == pytest.approx(math.exp(-1.0), abs=0.1)
        assert x.std() == pytest.approx(sigma, rel=0.15)
        assert np.abs(x[0]).max() < 5 * sigma  # stationary start, not a transient


def test_turn_on_bias_is_constant_and_scaled():
    cfg = ImuConfig(gyro_bias_instability_dph=0.0, accel_bias_instability_mps2=0.0)
    turn_on = np.array([simulate_imu(_static(0.1), cfg, np.random.default_rng(s)).gyro_bias[0] for s in range(400)])
    assert np.ptp(simulate_imu(_static(10.0), cfg, np.random.default_rng(0)).gyro_bias, axis=0).max() == 0.0
    assert (turn_on / DPH).std() == pytest.approx(cfg.gyro_bias_sigma_dph, rel=0.1)


def test_tactical_grade_is_quieter_than_consumer():
    traj = _static(300.0)
    f_b, w_ib_b = ideal_imu(traj)
    errors = {}
    for name, cfg in (("consumer", ImuConfig()), ("tactical", TACTICAL)):
        imu = simulate_imu(traj, cfg, np.random.default_rng(3))
        errors[name] = (
            np.std(imu.gyro - w_ib_b - imu.gyro_bias),
            np.std(imu.accel - f_b - imu.accel_bias),
            np.abs(imu.gyro_bias).max(),
            np.abs(imu.accel_bias).max(),
        )
    assert all(t < 0.2 * c for t, c in zip(errors["tactical"], errors["consumer"]))


def test_imu_deterministic_and_rate_checked():
    traj = _static(10.0)
    a = simulate_imu(traj, ImuConfig(), np.random.default_rng(7))
    b = simulate_imu(traj, ImuConfig(), np.random.default_rng(7))
    np.testing.assert_array_equal(a.gyro, b.gyro)
    assert a.accel.shape == (1000, 3) and a.t is traj.t
    with pytest.raises(SimbenchError, match="imu.rate_hz"):
        simulate_imu(traj, ImuConfig(rate_hz=200.0), np.random.default_rng(7))
    with pytest.raises(SimbenchError, match="imu.bias_tau_s"):
        simulate_imu(traj, ImuConfig(bias_tau_s=0.0), np.random.default_rng(7))


def test_one_hour_has_every_sample_and_stays_near_the_origin():
    cfg = TrajectoryConfig()
    rng = np.random.default_rng(0)
    traj = urban_drive(cfg, NlosConfig(), 3600.0, RATE, rng)
    imu = simulate_imu(traj, ImuConfig(), rng)
    assert len(imu.t) == 360_000
    lat, _, _ = geodetic_from_ecef(traj.pos[:1])
    assert abs(lat[0] / DEG - cfg.origin_lat_deg) < 0.01
