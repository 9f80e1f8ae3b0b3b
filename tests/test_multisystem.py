"""Multi-constellation: BeiDou broadcast orbits, the inter-system bias of the shared model, Hong Kong GPS+BDS."""

from __future__ import annotations

import dataclasses
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import dissertation

from estimators.filters.ekf_ppp import EkfPpp
from estimators.model.measurement import prepare_ppp
from simbench.contract import ReceiverData
from simbench.core.frames import geodetic_from_ecef
from simbench.core.gpstime import datetime64_to_gps
from simbench.data.broadcast import read_navigation
from simbench.data.log_sources import RinexConfig
from simbench.data.rinex import load_rinex
from simbench.errors import SimbenchError
from simbench.gnss.geometry import sagnac_range
from simbench.runs.scenarios import ScenarioSettings, build_scenario

if "test_measurement" not in sys.modules:
    _spec = importlib.util.spec_from_file_location("test_measurement", Path(__file__).with_name("test_measurement.py"))
    _mod = importlib.util.module_from_spec(_spec)
    sys.modules["test_measurement"] = _mod
    _spec.loader.exec_module(_mod)
from test_measurement import horizontal_error, synthetic_data

HK = Path(__file__).resolve().parents[2] / "shared" / "data" / "hk_tst_2019"
BDS_NAV = HK / "hksc1180.19b"
# the conftest fixture fails these tests when ../shared is missing (skips with SIMBENCH_ALLOW_MISSING_SHARED)
needs_hk = pytest.mark.usefixtures("shared_data")


def _as_two_systems(data: ReceiverData, isb_m: float) -> ReceiverData:
    """Relabel every other satellite as BeiDou and give it a receiver clock offset of ``isb_m``."""
    obs = data.observations.copy()
    sats = sorted(obs["sat"].unique())
    other = obs["sat"].isin(sats[1::2])
    obs.loc[other, "sat"] = "C" + obs.loc[other, "sat"].str[1:]
    for col in ("code_l1", "phase_l1", "code_l2", "phase_l2"):
        obs.loc[other, col] += isb_m
    return dataclasses.replace(data, observations=obs)


def test_inter_system_bias_state() -> None:
    data, truth = synthetic_data(300, dual=True, seed=5)
    mixed = _as_two_systems(data, 40.0)
    prep = prepare_ppp(mixed, ionosphere="free", code_sigma_m=2.5, phase_sigma_m=0.025, elevation_mask_deg=7)
    assert prep.systems == ("G", "C") and prep.n_isb == 1
    assert set(np.unique(prep.system_index)) == {0, 1}
    sol = EkfPpp(dissertation("ekf_ppp", ionosphere="free")).estimate(mixed)
    err = np.median(horizontal_error(sol.epochs, truth)[-100:])
    assert err < 0.3
    assert sol.diagnostics["inter_system_bias_m"]["C"] == pytest.approx(40.0, abs=0.5)
    # one system: no extra state, the same convergence
    one = EkfPpp(dissertation("ekf_ppp", ionosphere="free")).estimate(data)
    assert one.diagnostics["inter_system_bias_m"] == {}
    assert np.median(horizontal_error(one.epochs, truth)[-100:]) < 0.3
    # ignoring the bias (every satellite called GPS) costs metres
    ignored = _as_two_systems(data, 40.0)
    ignored = dataclasses.replace(
        ignored, observations=ignored.observations.assign(sat="G" + ignored.observations["sat"].str[1:])
    )
    bad = np.median(
        horizontal_error(EkfPpp(dissertation("ekf_ppp", ionosphere="free")).estimate(ignored).epochs, truth)[-100:]
    )
    assert bad > 1.0 > err


@needs_hk
def test_beidou_orbits_geo_igso_meo() -> None:
    eph = read_navigation("C", BDS_NAV)
    t = float(datetime64_to_gps(np.datetime64("2019-04-28T12:50:00")))
    st = eph.states(np.array([t, t + 1.0]))
    sats = eph.sats.tolist()
    lat, lon, h = (np.degrees(a) if k < 2 else a for k, a in enumerate(geodetic_from_ecef(st.pos[0])))
    geo = [sats.index(s) for s in ("C01", "C03", "C04")]
    # geostationary: 35 786 km up, over their assigned longitudes (140, 110.5, 160 E)
    assert np.all(np.abs(h[geo] - 35_786e3) < 100e3)
    np.testing.assert_allclose(lon[geo], [140.0, 110.5, 160.0], atol=1.0)
    assert np.all(np.abs(lat[geo]) < 3.0) and np.all(np.linalg.norm(st.vel[0, geo], axis=1) < 300.0)
    meo = sats.index("C11")
    assert abs(h[meo] - 21_528e3) < 200e3
    # velocities (incl. the GEO frame rotation) are the derivative of the positions
    ok = st.valid.all(axis=0)
    fd = st.pos[1, ok] - st.pos[0, ok]
    mid = 0.5 * (st.vel[0, ok] + st.vel[1, ok])
    assert np.abs(fd - mid).max() < 1e-3


@needs_hk
def test_hong_kong_gps_plus_beidou() -> None:
    sc = load_rinex(
        HK / "COM3_190428_124409.obs",
        HK / "hksc1180.19n",
        HK / "groundTruth_TST.csv",
        systems="GC",
        nav_bds_path=BDS_NAV,
    )
    obs = sc.observations
    assert set(obs["sat"].str[0]) == {"G", "C"}
    assert obs.groupby("epoch")["sat"].size().median() >= 10
    # residuals at the reference, GPS clock removed: BeiDou sits at one common offset
    # (the inter-system bias) for GEO, IGSO and MEO alike -- a wrong GEO rotation would be km
    truth = sc.truth.set_index("epoch")
    rows = obs[obs["epoch"].isin(truth.index)]
    ref = truth.loc[rows["epoch"], ["x", "y", "z"]].to_numpy()
    r = (
        rows["code_l1"].to_numpy()
        + rows["sat_clock"].to_numpy()
        - sagnac_range(rows[["sat_x", "sat_y", "sat_z"]].to_numpy(), ref)
    )
    rows = rows.assign(r=r)
    gps_clock = rows[rows["sat"].str[0] == "G"].groupby("epoch")["r"].median()
    rows = rows.assign(r=rows["r"] - gps_clock.reindex(rows["epoch"]).to_numpy())
    per_sat = rows[rows["sat"].str[0] == "C"].groupby("sat")["r"].median()
    kinds = {"geo": ["C01", "C02", "C03", "C04"], "igso": ["C06", "C08", "C13", "C16"], "meo": ["C11", "C14"]}
    medians = {k: float(per_sat.reindex(v).median()) for k, v in kinds.items()}
    assert max(medians.values()) - min(medians.values()) < 8.0, medians
    assert all(abs(v) < 20.0 for v in medians.values()), medians


def test_beidou_needs_its_navigation_file(tmp_path: Path) -> None:
    obs, nav, truth = (tmp_path / name for name in ("a.obs", "a.19n", "a.csv"))
    for path in (obs, nav, truth):  # the door checks that every named file exists
        path.touch()
    cfg = ScenarioSettings(scenario=RinexConfig(obs=str(obs), nav=str(nav), truth=str(truth), systems="GC"))
    with pytest.raises(SimbenchError, match="scenario.nav_bds"):
        build_scenario(cfg)
