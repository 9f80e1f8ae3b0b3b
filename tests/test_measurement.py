"""The shared PPP measurement model: arcs, prediction and Jacobian, observation preparation.

:func:`synthetic_data` builds exact receiver data without the generator (a
static receiver under the nominal constellation); ``tests/test_ekf_ppp.py``
uses it too.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pymap3d
import pytest

from estimators.model.measurement import arc_ids, predict, prepare_ppp, sigma_factor
from estimators.model.ppp_config import IonosphereMode, MeasurementMode, SigmaModel, VarianceComponents
from simbench.contract import NavInfo, ReceiverData
from simbench.core import atmosphere
from simbench.core.constants import DEG, F_L1, F_L2, IONO_L2_SCALE, LAMBDA_L1, LAMBDA_L2, SECONDS_PER_WEEK
from simbench.core.frames import geodetic_from_ecef
from simbench.core.gpstime import day_of_year
from simbench.core.orbits import NominalConstellation
from simbench.errors import SimbenchError, SimbenchWarning
from simbench.gnss.arcs import doppler_phase_jumps
from simbench.gnss.geometry import sagnac_range
from simbench.sim.geometry import line_of_sight

ALPHA = (8.382e-09, -1.490e-08, -5.960e-08, 1.192e-07)
BETA = (9.421e04, -1.311e05, -1.311e05, 8.520e05)
LAT, LON, H = 39.6295, -79.9559, 290.0  # deg, deg, m
WEEK, SOW0 = 2032, 475_200.0  # 2018-12-21 12:00 GPST


def synthetic_data(
    n_epochs: int = 600,
    *,
    dual: bool = True,
    seed: int = 0,
    code_noise_m: float = 0.3,
    phase_noise_m: float = 0.003,
    slip: tuple[int, str] | None = None,
    flag_slip: bool = True,
    mask_deg: float = 10.0,
    iono_drift_mps: float = 0.0,
) -> tuple[ReceiverData, dict]:
    """Exact observations of a static receiver, 1 Hz, following the observation-table conventions.

    code = range + rx_clock - sat_clock + tropo + iono + noise; phase likewise with
    -iono + lambda N. Dual frequency: an arbitrary ionosphere that the IF
    combination removes; single: exactly the broadcast Klobuchar delay.
    ``slip = (epoch, sat)`` adds +7 L1 / -3 L2 cycles from that epoch on,
    flagged with LLI when ``flag_slip``. ``iono_drift_mps`` adds a slant ionosphere
    the Klobuchar model does not know: a ramp at +-that rate, random sign per satellite.
    """
    rng = np.random.default_rng(seed)
    rx = np.array(pymap3d.geodetic2ecef(LAT, LON, H))
    t = np.arange(n_epochs, dtype=float)
    los = line_of_sight(np.tile(rx, (n_epochs, 1)), None, WEEK * SECONDS_PER_WEEK + SOW0 + t, NominalConstellation())
    el, az = los.el_rad, los.az_rad
    n, m = el.shape
    zhd, zwd_model = atmosphere.saastamoinen_zenith_m(LAT * DEG, H)
    zwd = 1.3 * float(zwd_model)
    m_h, m_w = atmosphere.niell_mapping(el, LAT * DEG, H, day_of_year(WEEK, SOW0))
    tropo = zhd * m_h + zwd * m_w
    rx_clock = 1.0e4 + 30.0 * t
    sat_clock = rng.uniform(-2e5, 2e5, m)[None, :] + 0.01 * t[:, None]
    if dual:
        iono = 2.0 + 5.0 * np.cos(el)
    else:
        iono = atmosphere.klobuchar_l1_delay_m(SOW0 + t[:, None], LAT * DEG, LON * DEG, el, az, ALPHA, BETA)
    iono = iono + iono_drift_mps * t[:, None] * rng.choice([-1.0, 1.0], m)[None, :]
    n1 = np.repeat(rng.integers(-(10**6), 10**6, m)[None, :], n, axis=0)
    n2 = np.repeat(rng.integers(-(10**6), 10**6, m)[None, :], n, axis=0)
    lli = np.zeros((n, m), bool)
    if slip is not None:
        k, name = slip
        j = list(los.sats).index(name)
        n1[k:, j] += 7
        n2[k:, j] -= 3
        lli[k, j] = flag_slip
    common = los.range_m + rx_clock[:, None] - sat_clock + tropo
    code1 = common + iono + code_noise_m * rng.standard_normal((n, m))
    phase1 = common - iono + LAMBDA_L1 * n1 + phase_noise_m * rng.standard_normal((n, m))
    code2 = common + IONO_L2_SCALE * iono + code_noise_m * rng.standard_normal((n, m))
    phase2 = common - IONO_L2_SCALE * iono + LAMBDA_L2 * n2 + phase_noise_m * rng.standard_normal((n, m))
    if not dual:
        code2[:], phase2[:] = np.nan, np.nan
    ei, si = np.nonzero(el > mask_deg * DEG)
    sats = np.asarray(los.sats)
    obs = pd.DataFrame(
        {
            "epoch": ei.astype(np.int64),
            "t": t[ei],
            "sat": sats[si],
            "code_l1": code1[ei, si],
            "phase_l1": phase1[ei, si],
            "doppler_l1": 0.0,
            "cn0_l1": 45.0,
            "lli_l1": lli[ei, si],
            "code_l2": code2[ei, si],
            "phase_l2": phase2[ei, si],
            "lli_l2": lli[ei, si],
            "f1_f2_ratio": np.where(np.isfinite(code2[ei, si]), F_L1 / F_L2, np.nan),
            "sat_x": los.sat_pos_tx[ei, si, 0],
            "sat_y": los.sat_pos_tx[ei, si, 1],
            "sat_z": los.sat_pos_tx[ei, si, 2],
            "sat_vx": los.sat_vel_tx[ei, si, 0],
            "sat_vy": los.sat_vel_tx[ei, si, 1],
            "sat_vz": los.sat_vel_tx[ei, si, 2],
            "sat_clock": sat_clock[ei, si],
            "sat_clock_drift": 0.01,
            "el": np.degrees(el[ei, si]),
            "az": np.degrees(az[ei, si]),
        }
    )
    imu = pd.DataFrame({c: np.zeros(0) for c in ("t", "ax", "ay", "az", "gx", "gy", "gz")})
    data = ReceiverData(obs, imu, NavInfo(WEEK, SOW0, ALPHA, BETA, dual))
    truth = {"pos": rx, "zwd": zwd, "rx_clock": rx_clock, "lat": LAT, "lon": LON, "h": H}
    return data, truth


def horizontal_error(epochs: pd.DataFrame, truth: dict) -> np.ndarray:
    """Horizontal error [m] of a solution table w.r.t. the static truth position."""
    e, n, _ = pymap3d.ecef2enu(epochs["x"], epochs["y"], epochs["z"], truth["lat"], truth["lon"], truth["h"])
    return np.hypot(np.asarray(e), np.asarray(n))


# --------------------------------------------------------------------------- arcs


def _arc_table() -> pd.DataFrame:
    rows = [(e, "G01", False, False) for e in (0, 1, 2, 4, 5)]  # gap: epoch 3 missing
    rows += [(e, "G02", e == 3, False) for e in range(6)]  # L1 loss of lock at epoch 3
    rows += [(e, "G03", False, e == 2) for e in range(4)]  # L2 loss of lock at epoch 2
    df = pd.DataFrame(rows, columns=["epoch", "sat", "lli_l1", "lli_l2"])
    return df.sample(frac=1.0, random_state=3).reset_index(drop=True)  # any row order


def test_arc_ids_gap_and_lli() -> None:
    df = _arc_table()
    arc = pd.Series(arc_ids(df), index=df.index)
    key = dict(zip(zip(df["sat"], df["epoch"]), arc))
    # numbered by (start epoch, satellite): G01@0, G02@0, G03@0, G02@3, G01@4
    assert [key["G01", e] for e in (0, 1, 2, 4, 5)] == [0, 0, 0, 4, 4]
    assert [key["G02", e] for e in range(6)] == [1, 1, 1, 3, 3, 3]
    assert [key["G03", e] for e in range(4)] == [2, 2, 2, 2]  # L2 flag ignored in single frequency


def test_arc_ids_l2_flag_and_gap_tolerance() -> None:
    df = _arc_table()
    key = dict(zip(zip(df["sat"], df["epoch"]), arc_ids(df, use_l2=True)))
    assert key["G03", 1] != key["G03", 2] == key["G03", 3]
    key = dict(zip(zip(df["sat"], df["epoch"]), arc_ids(df, max_gap_epochs=2)))
    assert len({key["G01", e] for e in (0, 1, 2, 4, 5)}) == 1  # a one-epoch hole is tolerated
    assert key["G02", 2] != key["G02", 3]  # the loss of lock still breaks the arc


def test_arc_ids_empty_and_nan_flags() -> None:
    assert arc_ids(_arc_table().iloc[:0]).shape == (0,)
    df = pd.DataFrame({"epoch": [0, 1, 2], "sat": ["G01"] * 3, "lli_l1": [None, np.nan, True]})
    assert arc_ids(df).tolist() == [0, 0, 1]


# --------------------------------------------------------------------------- prediction


def _one_epoch() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rx = np.array(pymap3d.geodetic2ecef(LAT, LON, H))
    los = line_of_sight(rx[None], None, np.array([WEEK * SECONDS_PER_WEEK + SOW0]), NominalConstellation())
    up = los.el_rad[0] > 10 * DEG
    return rx, los.sat_pos_tx[0, up], los.el_rad[0, up]


def test_predict_value() -> None:
    rx, sat, el = _one_epoch()
    doy = day_of_year(WEEK, SOW0)
    lat, _, h = geodetic_from_ecef(rx)
    pred, _ = predict(sat, rx, 123.0, 0.15, el, lat, h, doy)
    expected = sagnac_range(sat, rx) + 123.0 + atmosphere.tropo_slant_m(el, lat, h, doy, 0.15)
    np.testing.assert_allclose(pred, expected, rtol=0, atol=1e-6)


def test_predict_jacobian_matches_finite_differences() -> None:
    rx, sat, el = _one_epoch()
    doy = day_of_year(WEEK, SOW0)
    lat, _, h = geodetic_from_ecef(rx)  # the troposphere's lat/h are inputs, held fixed
    state = np.r_[rx + [3.0, -2.0, 1.0], 50.0, 0.2]

    def f(s: np.ndarray) -> np.ndarray:
        return predict(sat, s[:3], s[3], s[4], el, lat, h, doy)[0]

    _, H = predict(sat, state[:3], state[3], state[4], el, lat, h, doy)
    assert H.shape == (len(sat), 5)
    num = np.empty_like(H)
    for i, step in enumerate((1.0, 1.0, 1.0, 1.0, 0.1)):  # ranges of 2e7 m: large steps beat roundoff
        d = np.zeros(5)
        d[i] = step
        num[:, i] = (f(state + d) - f(state - d)) / (2 * step)
    np.testing.assert_allclose(H, num, rtol=0, atol=1e-7)
    assert np.abs(H[:, 0] - num[:, 0]).max() < 1e-7  # includes the ~6e-6 Sagnac partial


def test_geodetic_matches_pymap3d() -> None:
    for lat, lon, h in ((LAT, LON, H), (-33.9, 151.2, 50.0), (78.2, 15.6, 3000.0), (0.0, 0.0, -20.0)):
        p = np.array(pymap3d.geodetic2ecef(lat, lon, h))
        la, lo, hh = geodetic_from_ecef(p)
        assert abs(np.degrees(la) - lat) < 1e-9 and abs(np.degrees(lo) - lon) < 1e-9 and abs(hh - h) < 1e-4


# --------------------------------------------------------------------------- preparation


@pytest.mark.parametrize("dual", [True, False])
def test_prepare_ppp_corrections_leave_only_noise(dual: bool) -> None:
    data, truth = synthetic_data(30, dual=dual, code_noise_m=0.0, phase_noise_m=0.0)
    obs = prepare_ppp(
        data, ionosphere="free" if dual else "broadcast", code_sigma_m=2.5, phase_sigma_m=0.025, elevation_mask_deg=15.0
    )
    assert np.all(np.diff(obs.epoch) >= 0) and np.all(obs.el > 15 * DEG)
    np.testing.assert_allclose(obs.sigma_code, 2.5 / np.sin(obs.el))
    np.testing.assert_allclose(obs.sigma_phase, 0.025 / np.sin(obs.el))
    lat, _, h = geodetic_from_ecef(truth["pos"])
    worst_code, biases = 0.0, {}
    for k, rows in obs.iter_epochs():
        assert len(set(obs.epoch[rows])) == 1 and obs.epoch_t[k] == obs.t[rows][0]
        pred, _ = predict(
            obs.sat_pos[rows],
            truth["pos"],
            truth["rx_clock"][obs.epoch_ids[k]],
            truth["zwd"],
            obs.el[rows],
            lat,
            h,
            obs.doy,
        )
        worst_code = max(worst_code, np.abs(obs.code[rows] - pred).max())
        for a, b in zip(obs.arc[rows], obs.phase[rows] - pred):
            biases.setdefault(a, []).append(b)
    assert worst_code < 5e-3  # Sagnac model vs exact rotation, rough Klobuchar pierce points
    assert max(np.ptp(v) for v in biases.values()) < 5e-3  # one constant bias per arc
    assert obs.n_arcs == len(obs.sat_names) == len(biases)


def test_prepare_ppp_drops_epochs_below_min_satellites() -> None:
    data, _ = synthetic_data(5, dual=False)
    o = data.observations
    counts = o[o["el"] > 10].groupby("epoch").size()
    need = int(counts.max())
    obs = prepare_ppp(
        data, ionosphere="broadcast", code_sigma_m=2.5, phase_sigma_m=0.025, elevation_mask_deg=10, min_satellites=need
    )
    assert set(obs.epoch_ids) == set(counts.index[counts >= need])


def test_prepare_ppp_errors() -> None:
    single, _ = synthetic_data(3, dual=False)
    kw = dict(code_sigma_m=2.5, phase_sigma_m=0.025, elevation_mask_deg=7.0)
    with pytest.raises(SimbenchError, match="ionosphere"):
        prepare_ppp(single, ionosphere="free", **kw)
    with pytest.raises(SimbenchError, match="no epoch has"):
        prepare_ppp(single, ionosphere="broadcast", **{**kw, "elevation_mask_deg": 89.0})
    broken = ReceiverData(single.observations.drop(columns=["sat_clock"]), single.imu, single.nav)
    with pytest.raises(SimbenchError, match="sat_clock"):
        prepare_ppp(broken, ionosphere="broadcast", **kw)
    with pytest.raises(SimbenchError, match="code_sigma_m"):
        prepare_ppp(single, ionosphere="broadcast", **{**kw, "code_sigma_m": 0.0})


def test_sigma_models_follow_elevation_and_cn0() -> None:
    """Each model's per-row factor against its formula; rows without a C/N0 fall back to the elevation,
    with a warning."""
    data, _ = synthetic_data(3, dual=False)
    o = data.observations
    cn0 = np.where(np.arange(len(o)) % 4 == 0, np.nan, 25.0 + (np.arange(len(o)) % 25))
    data = ReceiverData(o.assign(cn0_l1=cn0), data.imu, data.nav)
    kw = dict(ionosphere="broadcast", code_sigma_m=2.5, phase_sigma_m=0.025, elevation_mask_deg=7.0)
    by_el = prepare_ppp(data, **kw)
    np.testing.assert_allclose(by_el.sigma_code, 2.5 / np.sin(by_el.el))
    with_cn0 = by_el.cn0
    assert np.isnan(with_cn0).any() and np.isfinite(with_cn0).any()
    ratio = np.where(np.isfinite(with_cn0), 10.0 ** ((40.0 - with_cn0) / 20.0), np.nan)
    with pytest.warns(SimbenchWarning, match=r"cn0_l1: missing on \d+ of \d+ rows -- their sigmas follow 1/sin"):
        by_cn0 = prepare_ppp(data, **kw, sigma_model=SigmaModel.cn0, cn0_ref_dbhz=40.0)
    np.testing.assert_allclose(by_cn0.sigma_code, np.where(np.isfinite(ratio), 2.5 * ratio, by_el.sigma_code))
    np.testing.assert_allclose(by_cn0.sigma_phase / by_cn0.sigma_code, 0.01)
    # 20 dB below the reference: ten times the sigma (a hundred times the variance)
    assert sigma_factor(np.array([0.3]), np.array([20.0]), SigmaModel.cn0, 40.0) == pytest.approx(10.0)
    with pytest.warns(SimbenchWarning, match="follow the elevation alone"):
        both = prepare_ppp(data, **kw, sigma_model=SigmaModel.elevation_cn0, cn0_ref_dbhz=40.0)
    np.testing.assert_allclose(both.sigma_code, by_el.sigma_code * np.where(np.isfinite(ratio), ratio, 1.0))
    np.testing.assert_allclose(both.sigma_scale, both.sigma_code / 2.5)


def test_doppler_breaks_arcs_at_unflagged_slips_but_not_at_clock_jumps() -> None:
    """Phase steps that follow the Doppler stay one arc, a jump common to every satellite (a receiver
    clock that keeps within a millisecond by jumps) too; a 1.5 m step on one satellite breaks its arc."""
    rng = np.random.default_rng(4)
    sats = ["G01", "G02", "G03", "C11"]
    n = 20
    t = np.arange(n) * 1.0
    rows = []
    for j, sat in enumerate(sats):
        lam = 299_792_458.0 / (1_561.098e6 if sat[0] == "C" else 1_575.42e6)
        rate = -800.0 + 300.0 * j + 0.5 * t  # range rate [m/s], accelerating
        rng_m = 2.2e7 + np.cumsum(np.r_[0.0, 0.5 * (rate[1:] + rate[:-1])])  # exact trapezoid integral
        phase = rng_m + 0.003 * rng.standard_normal(n)
        phase[12:] += 299_792.458  # a 1 ms receiver clock jump at epoch 12, on every satellite
        if sat == "G02":
            phase[7:] += 1.5  # an unflagged slip
        doppler = -rate / lam + 0.2 * rng.standard_normal(n)
        rows += [(k, t[k], sat, phase[k], doppler[k], False) for k in range(n)]
    df = pd.DataFrame(rows, columns=["epoch", "t", "sat", "phase_l1", "doppler_l1", "lli_l1"])
    jumps = doppler_phase_jumps(df)
    assert np.isnan(jumps[df["epoch"] == 0]).all()
    slip = (df["sat"] == "G02") & (df["epoch"] == 7)
    assert jumps[slip][0] == pytest.approx(1.5, abs=0.3)  # the median of four is the clean pair's mean
    assert np.nanmax(jumps[~slip & (df["epoch"] != 7)]) < 0.3
    arcs = pd.Series(arc_ids(df, doppler_slip_m=1.0), index=df.index).groupby(df["sat"]).nunique()
    assert arcs.to_dict() == {"C11": 1, "G01": 1, "G02": 2, "G03": 1}
    assert (pd.Series(arc_ids(df), index=df.index).groupby(df["sat"]).nunique() == 1).all()  # check off


#: prepare_ppp settings of the variance-component tests: code only, broadcast ionosphere, the C/N0
#: sigma model with a 1 m a-priori sigma (its factor is 1 at 45 dB-Hz).
CODE_CN0_1M = dict(
    ionosphere=IonosphereMode.broadcast,
    code_sigma_m=1.0,
    phase_sigma_m=0.01,
    elevation_mask_deg=10.0,
    measurements=MeasurementMode.code,
    sigma_model=SigmaModel.cn0,
)


def test_variance_components_recover_each_systems_noise() -> None:
    """GPS rows with 0.5 m code noise, Galileo rows with 1.5 m (each satellite's geometry serves both,
    a dozen rows per epoch), both given a 1 m a-priori sigma: the estimated factors' ratio is 3
    within 5 %, and the rows' sigmas follow."""
    data, _ = synthetic_data(300, dual=False, code_noise_m=0.0)
    o = data.observations
    rng = np.random.default_rng(7)
    gps = o.assign(code_l1=o["code_l1"] + 0.5 * rng.standard_normal(len(o)))
    galileo = o.assign(sat="E" + o["sat"].str[1:], code_l1=o["code_l1"] + 1.5 * rng.standard_normal(len(o)))
    two_systems = ReceiverData(pd.concat([gps, galileo], ignore_index=True), data.imu, data.nav)
    # C/N0 45 dB-Hz on every row: the cn0 model's factor is 1, the a-priori sigma 1 m everywhere
    kw = CODE_CN0_1M
    obs = prepare_ppp(two_systems, variance_components=VarianceComponents.system, **kw)
    factors = obs.variance_factors
    assert set(factors) == {"G", "E"}
    # relative factors: their geometric mean over the rows is 1 (here sqrt(0.5 1.5) -> 1)
    assert factors["E"] / factors["G"] == pytest.approx(3.0, rel=0.05)
    assert np.sqrt(factors["E"] * factors["G"]) == pytest.approx(1.0, rel=0.01)
    is_e = np.array([s.startswith("E") for s in obs.sat])
    np.testing.assert_allclose(obs.sigma_code, np.where(is_e, factors["E"], factors["G"]), rtol=1e-3)
    # the C/N0 bins of one level are the system's groups; without components the sigmas stay a priori
    by_bin = prepare_ppp(two_systems, variance_components=VarianceComponents.system_cn0, **kw).variance_factors
    assert set(by_bin) == {"G 45-50 dB-Hz", "E 45-50 dB-Hz"}
    assert by_bin["E 45-50 dB-Hz"] == pytest.approx(factors["E"], rel=1e-6)
    plain = prepare_ppp(two_systems, **kw)
    assert plain.variance_factors == {} and np.allclose(plain.sigma_code, 1.0)


def test_variance_components_leave_a_log_without_redundancy_at_its_a_priori_sigmas() -> None:
    """Three GPS and two Galileo satellites per epoch and two clocks: every redundancy number is
    zero up to rounding (+-1e-16), and the Helmert ratio would divide one rounding error by another
    (on a canyon drive with four satellites it made every sigma NaN and ekf_ppp fail). Both factors
    stay 1; with five Galileo satellites the log has redundancy (three per epoch) and the weight moves
    away from the noisier system (1.5 m against 0.5 m; measured factor ratio 1.5 with these few rows)."""
    data, _ = synthetic_data(120, dual=False, code_noise_m=0.0)
    o = data.observations
    rng = np.random.default_rng(3)
    rank = o.groupby("epoch").cumcount()
    gps = o[rank < 3].assign(code_l1=lambda d: d["code_l1"] + 0.5 * rng.standard_normal(len(d)))
    galileo = o[(rank >= 3) & (rank < 8)]
    galileo = galileo.assign(
        sat="E" + galileo["sat"].str[1:], code_l1=galileo["code_l1"] + 1.5 * rng.standard_normal(len(galileo))
    )
    kw = dict(CODE_CN0_1M, variance_components=VarianceComponents.system)
    two_galileo = galileo[galileo.groupby("epoch").cumcount() < 2]
    none = prepare_ppp(ReceiverData(pd.concat([gps, two_galileo], ignore_index=True), data.imu, data.nav), **kw)
    assert none.variance_factors == {"G": 1.0, "E": 1.0}
    np.testing.assert_allclose(none.sigma_code, 1.0)
    some = prepare_ppp(ReceiverData(pd.concat([gps, galileo], ignore_index=True), data.imu, data.nav), **kw)
    assert some.variance_factors["E"] / some.variance_factors["G"] > 1.3
