"""Trajectories: kinematic limits, geometric consistency, street canyon, replay of a real drive."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pymap3d
import pytest
from scipy.spatial.transform import Rotation

from simbench.core.constants import G0_STD
from simbench.core.frames import dcm_body_to_ecef
from simbench.errors import SimbenchError
from simbench.sim.config import FlightConfig, NlosConfig, ReplayConfig, TrajectoryConfig, UrbanDriveConfig
from simbench.sim.trajectory import Trajectory, flight, replay, urban_drive

DRIVE_1 = Path(__file__).resolve().parents[2] / "shared" / "data" / "wvu_drives" / "drive_1.xyz"
RATE = 100.0


def _enu(traj: Trajectory, cfg: TrajectoryConfig) -> np.ndarray:
    return np.stack(pymap3d.ecef2enu(*traj.pos.T, cfg.origin_lat_deg, cfg.origin_lon_deg, cfg.origin_h_m), axis=-1)


def _enu_vectors(vec: np.ndarray, cfg: TrajectoryConfig) -> np.ndarray:
    return np.stack(pymap3d.ecef2enuv(*vec.T, cfg.origin_lat_deg, cfg.origin_lon_deg), axis=-1)


def _rate_mismatch(traj: Trajectory) -> np.ndarray:
    """|omega from finite differences of C_b^e - omega_eb_b| at interval midpoints [rad/s]."""
    c = dcm_body_to_ecef(traj.pos, traj.att)
    dt = traj.t[1] - traj.t[0]
    numeric = Rotation.from_matrix(np.swapaxes(c[:-1], 1, 2) @ c[1:]).as_rotvec() / dt
    return np.linalg.norm(numeric - 0.5 * (traj.omega_eb_b[:-1] + traj.omega_eb_b[1:]), axis=1)


@pytest.fixture(scope="module")
def drive() -> tuple[Trajectory, TrajectoryConfig]:
    cfg = TrajectoryConfig()
    return urban_drive(cfg, NlosConfig(), 600.0, RATE, np.random.default_rng(3)), cfg


@pytest.fixture(scope="module")
def uav() -> tuple[Trajectory, TrajectoryConfig]:
    cfg = TrajectoryConfig(flight=FlightConfig(start_static_s=10.0))
    return flight(cfg, 400.0, RATE, np.random.default_rng(5)), cfg


# --------------------------------------------------------------------------- urban drive


def test_urban_duration_and_determinism(drive):
    traj, cfg = drive
    assert len(traj.t) == 60_000 and traj.t[-1] == pytest.approx(600.0 - 1.0 / RATE)
    again = urban_drive(cfg, NlosConfig(), 600.0, RATE, np.random.default_rng(3))
    np.testing.assert_array_equal(again.pos, traj.pos)
    other = urban_drive(cfg, NlosConfig(), 600.0, RATE, np.random.default_rng(4))
    assert np.abs(other.pos - traj.pos).max() > 10.0
    assert traj.valid.all() and traj.street is not None


def test_urban_speed_and_acceleration_limits(drive):
    traj, cfg = drive
    u = cfg.urban_drive
    speed = np.linalg.norm(traj.vel, axis=1)
    assert speed.max() <= u.cruise_speed_mps + 0.1
    assert speed.max() > u.cruise_speed_mps - 0.1  # it does reach cruise
    dvdt = np.gradient(speed, 1.0 / RATE)
    assert np.abs(dvdt).max() <= u.max_accel_mps2 + 0.01
    # turns are taken at turn speed: lateral acceleration v^2 / R at most
    lateral = np.linalg.norm(np.cross(traj.acc, traj.vel), axis=1) / np.maximum(speed, 1e-9)
    assert lateral.max() <= u.turn_speed_mps**2 / u.turn_radius_m + 0.01


def test_urban_stays_in_grid_on_flat_ground(drive):
    traj, cfg = drive
    u = cfg.urban_drive
    enu = _enu(traj, cfg)
    assert np.abs(enu[:, 0]).max() <= u.n_blocks_east * u.block_length_m / 2 + 1e-6
    assert np.abs(enu[:, 1]).max() <= u.n_blocks_north * u.block_length_m / 2 + 1e-6
    assert np.abs(enu[:, 2]).max() < 1e-6  # the tangent plane of the origin
    assert np.ptp(enu[:, 0]) + np.ptp(enu[:, 1]) > 200.0  # it does drive around


def test_urban_static_start_and_stops(drive):
    traj, cfg = drive
    u = cfg.urban_drive
    speed = np.linalg.norm(traj.vel, axis=1)
    assert speed[traj.t < u.start_static_s].max() == 0.0
    assert speed[traj.t > u.start_static_s + 1.0].min() == 0.0
    stopped = np.r_[False, speed == 0.0, False].astype(np.int8)
    starts = np.nonzero(np.diff(stopped) == 1)[0]
    ends = np.nonzero(np.diff(stopped) == -1)[0]
    durations = (ends - starts)[1:] / RATE  # the first one is the static start
    assert len(durations) >= 2
    # interior stops last a stop_duration draw (the last may be cut by the end of the run)
    assert durations[:-1].min() >= u.stop_duration_s[0] - 0.02
    assert durations.max() <= u.stop_duration_s[1] + 0.02


def test_urban_derivatives_and_attitude_consistent(drive):
    traj, cfg = drive
    dt = 1.0 / RATE
    assert np.abs(np.gradient(traj.pos, dt, axis=0) - traj.vel)[1:-1].max() < 1e-3
    assert np.abs(np.gradient(traj.vel, dt, axis=0) - traj.acc)[1:-1].max() < 0.01
    assert _rate_mismatch(traj).max() < 2e-3
    # the car points along its velocity and stays level (tilt of the tangent plane only)
    c = dcm_body_to_ecef(traj.pos, traj.att)
    speed = np.linalg.norm(traj.vel, axis=1)
    moving = speed > 0.1
    along = np.einsum("ki,ki->k", c[moving, :, 0], traj.vel[moving]) / speed[moving]
    assert along.min() > 1.0 - 1e-12
    assert np.abs(traj.att[:, :2]).max() < 1e-4


def test_street_geometry(drive):
    traj, cfg = drive
    st = traj.street
    nl = NlosConfig()
    heading_deg = np.degrees(st.road_heading_rad)
    assert np.allclose(heading_deg, np.round(heading_deg / 90.0) * 90.0, atol=1e-9)
    for h in (st.height_left_m, st.height_right_m):
        built = h > 0.0
        assert built.mean() > 0.2
        assert h[built].min() >= nl.building_height_m[0] and h.max() <= nl.building_height_m[1]
    # on the block (car on the road axis) facades are at the drawn setback
    straight = np.abs(traj.omega_eb_b[:, 2]) < 1e-9
    for w in (st.wall_left_m, st.wall_right_m):
        assert w[straight].min() >= nl.wall_distance_m[0] - 1e-9
        assert w[straight].max() <= nl.wall_distance_m[1] + 1e-9
    # inside intersections both sides are open
    u = cfg.urban_drive
    enu = _enu(traj, cfg)
    near = np.hypot(*(enu[:, :2] - u.block_length_m * np.round(enu[:, :2] / u.block_length_m)).T) < 5.0
    assert near.any()
    assert (st.height_left_m[near] == 0.0).all() and (st.height_right_m[near] == 0.0).all()


def test_street_open_fraction():
    cfg = TrajectoryConfig()
    closed = urban_drive(cfg, NlosConfig(open_fraction=0.0), 300.0, 10.0, np.random.default_rng(1)).street
    opened = urban_drive(cfg, NlosConfig(open_fraction=1.0), 300.0, 10.0, np.random.default_rng(1)).street
    assert (opened.height_left_m == 0.0).all() and (opened.height_right_m == 0.0).all()
    assert (closed.height_left_m > 0).mean() > 0.4


def test_urban_bad_config():
    cfg = TrajectoryConfig(urban_drive=UrbanDriveConfig(turn_radius_m=80.0))
    with pytest.raises(SimbenchError, match="turn_radius_m"):
        urban_drive(cfg, NlosConfig(), 60.0, RATE, np.random.default_rng(0))
    with pytest.raises(SimbenchError, match="duration_s"):
        urban_drive(TrajectoryConfig(), NlosConfig(), -1.0, RATE, np.random.default_rng(0))


# --------------------------------------------------------------------------- flight


def test_flight_bank_angle_in_turns(uav):
    traj, cfg = uav
    f = cfg.flight
    vel, acc = _enu_vectors(traj.vel, cfg), _enu_vectors(traj.acc, cfg)
    v_h = np.hypot(vel[:, 0], vel[:, 1])
    # curvature of the ground track, positive turning right (clockwise seen from above)
    kappa = -(vel[:, 0] * acc[:, 1] - vel[:, 1] * acc[:, 0]) / np.maximum(v_h, 1e-9) ** 3
    on_arc = np.abs(np.abs(kappa) * f.turn_radius_m - 1.0) < 1e-3
    assert on_arc.sum() > 2000 and (kappa[on_arc] > 0).any() and (kappa[on_arc] < 0).any()
    expected = np.sign(kappa[on_arc]) * np.arctan(v_h[on_arc] ** 2 / (G0_STD * f.turn_radius_m))
    assert np.degrees(np.abs(traj.att[on_arc, 0] - expected)).max() < 1.0
    assert np.degrees(np.abs(expected)).min() > 15.0  # the bank is significant


@pytest.mark.parametrize("which", ["drive", "uav"])
def test_carried_attitude_matrix_is_that_of_the_euler_angles(which, request):
    """C_b^e built in the trajectory's NED0 frame (what the IMU model reads) is the rotation of the
    reported local roll, pitch and yaw, to float64 rounding, over a banked flight and a drive."""
    traj, _ = request.getfixturevalue(which)
    np.testing.assert_allclose(traj.c_b_e, dcm_body_to_ecef(traj.pos, traj.att), rtol=0, atol=1e-14)


def test_flight_profile(uav):
    traj, cfg = uav
    f = cfg.flight
    enu = _enu(traj, cfg)
    speed = np.linalg.norm(traj.vel, axis=1)
    ground = traj.t < f.start_static_s
    assert speed[ground].max() == 0.0 and np.abs(enu[ground]).max() < 1e-6
    assert enu[:, 2].max() == pytest.approx(f.cruise_altitude_m, abs=0.01)
    assert enu[:, 2].min() > -0.01
    # pitch follows the climb angle; the climb itself runs at climb_rate
    climb_angle = np.arctan(f.climb_rate_mps / f.airspeed_mps)
    assert np.degrees(traj.att[:, 1]).max() == pytest.approx(np.degrees(climb_angle), abs=0.05)
    assert np.gradient(enu[:, 2], 1.0 / RATE).max() == pytest.approx(f.climb_rate_mps, abs=1e-3)
    cruise = traj.t > 100.0
    assert np.abs(np.hypot(*_enu_vectors(traj.vel, cfg)[cruise, :2].T) - f.airspeed_mps).max() < 1e-9
    assert _rate_mismatch(traj).max() < 2e-3


def test_flight_stays_near_origin():
    cfg = TrajectoryConfig()
    traj = flight(cfg, 3600.0, 1.0, np.random.default_rng(0))
    enu = _enu(traj, cfg)
    assert np.hypot(enu[:, 0], enu[:, 1]).max() < 3_000.0
    assert traj.street is None


# --------------------------------------------------------------------------- replay

# the conftest fixture fails these tests when ../shared is missing (skips with SIMBENCH_ALLOW_MISSING_SHARED)
needs_drive = pytest.mark.usefixtures("shared_data")


@pytest.fixture(scope="module")
def replayed(shared_data) -> tuple[Trajectory, float, np.ndarray]:
    traj, t0_sow = replay(ReplayConfig(path=str(DRIVE_1)), RATE)
    return traj, t0_sow, np.loadtxt(DRIVE_1)


@needs_drive
def test_replay_reproduces_epochs(replayed):
    traj, t0_sow, data = replayed
    assert t0_sow == pytest.approx(math.ceil(data[0, 0] * RATE) / RATE)
    assert traj.t[-1] <= data[-1, 0] - t0_sow + 1e-9
    t_ep = data[:, 0] - t0_sow
    idx = np.round(t_ep * RATE).astype(int)
    on_grid = (np.abs(t_ep * RATE - idx) < 1e-4) & (idx >= 0) & (idx < len(traj.t))
    assert on_grid.mean() > 0.99
    # a smoothed path, not an interpolation: centimetres from the reference, decimetres where it jumps between fixes
    err = np.linalg.norm(traj.pos[idx[on_grid]] - data[on_grid, 1:], axis=1)
    assert np.median(err) < 0.03
    assert np.percentile(err, 95) < 0.3
    # the first two epochs are a 4.6 m RTK jump: dropped as outliers, the path starts at the third
    first = np.round(t_ep[:2] * RATE).astype(int)
    assert np.linalg.norm(traj.pos[first] - data[:2, 1:], axis=1).min() > 3.0
    assert not traj.valid[0] and traj.valid[traj.t >= t_ep[2] - 1e-9].all()  # drive 1 has no gap longer than 2 s


@needs_drive
def test_replay_static_start(replayed):
    traj, _, _ = replayed
    speed = np.linalg.norm(traj.vel, axis=1)
    start = (traj.t > 5.0) & (traj.t < 200.0)  # the first two epochs are a 4.6 m RTK jump
    assert np.median(speed[start]) < 0.1
    assert np.mean(speed[start] < 0.5) > 0.97
    # a standing car keeps its heading and is level
    assert np.ptp(traj.att[traj.t < 200.0, 2]) == 0.0
    assert np.abs(traj.att[0, 1]) < np.radians(10.0)
    assert speed.max() > 10.0  # and then it drives


@needs_drive
def test_replay_gaps_are_flagged(tmp_path):
    data = np.loadtxt(DRIVE_1)[:600]
    data = np.delete(data, np.s_[200:260], axis=0)  # a 6 s outage
    path = tmp_path / "gap.xyz"
    np.savetxt(path, data, fmt="%.5f %.4f %.4f %.4f")
    traj, t0_sow = replay(ReplayConfig(path=str(path), max_gap_s=2.0), RATE)
    gap = (traj.t > data[199, 0] - t0_sow + 1e-6) & (traj.t < data[200, 0] - t0_sow - 1e-6)
    assert gap.sum() > 500
    lead = traj.t < data[2, 0] - t0_sow - 1e-6  # before the third epoch: the first two are a 4.6 m RTK jump
    np.testing.assert_array_equal(traj.valid, ~(gap | lead))
    assert np.isfinite(traj.pos).all() and np.isfinite(traj.att).all()
    bridge = traj.pos[np.r_[np.nonzero(gap)[0][0] - 1, np.nonzero(gap)[0][-1] + 1]]
    assert np.linalg.norm(traj.pos[gap] - bridge.mean(axis=0), axis=1).max() < 50.0


def test_replay_errors(tmp_path):
    with pytest.raises(SimbenchError, match="scenario.trajectory.replay.path.*not found"):
        replay(ReplayConfig(path=str(tmp_path / "missing.xyz")), RATE)
    bad = tmp_path / "bad.xyz"
    bad.write_text("100.0 1 2 3\n100.1 1 2 3\n100.2 1 2\n")
    with pytest.raises(SimbenchError, match="line 3"):
        replay(ReplayConfig(path=str(bad)), RATE)
    bad.write_text("100.0 1 2 3\n100.1 1 x 3\n")
    with pytest.raises(SimbenchError, match="line 2"):
        replay(ReplayConfig(path=str(bad)), RATE)
    bad.write_text("# header\n100.0 1 2 3\n")
    with pytest.raises(SimbenchError, match="1 epoch"):
        replay(ReplayConfig(path=str(bad)), RATE)
    bad.write_text("100.0 1 2 3\n100.0 1 2 3\n")
    with pytest.raises(SimbenchError, match="does not increase at line 2") as info:
        replay(ReplayConfig(path=str(bad)), RATE)
    assert "\n" not in str(info.value)
