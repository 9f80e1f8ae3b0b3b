"""The ionosphere mode of the shared measurement preparation: free, broadcast, auto.

Tables come from :func:`test_measurement.synthetic_data` (exact observations of a static
receiver): its second frequency is re-made for each carrier pair with a delay scaled by
``1/f**2``, so the ionosphere-free combination must leave only the modelled terms.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from test_measurement import synthetic_data

import simbench.contract
from estimators.model.measurement import SAT_DCB_COLUMN, klobuchar_scale, predict, prepare_ppp
from estimators.model.ppp_config import IonosphereMode
from simbench.contract import ReceiverData
from simbench.core.constants import F_B1I, F_L1, IONO_L2_SCALE
from simbench.core.frames import geodetic_from_ecef
from simbench.errors import SimbenchError

#: f1/f2 of the contract's carrier pairs: GPS L1/L2, L1/L5 (E1/E5a), E1/E5b, GLONASS, BeiDou B1I/B3I.
RATIOS = {
    "L1/L2": 154 / 120,
    "L1/L5": 154 / 115,
    "E1/E5b": 154 / 118,
    "G1/G2": 9 / 7,
    "B1I/B3I": 1561.098 / 1268.52,
}
KW = dict(code_sigma_m=2.5, phase_sigma_m=0.025, elevation_mask_deg=15.0)


def with_second_frequency(ratio: np.ndarray | float, n_epochs: int = 20) -> tuple[ReceiverData, dict]:
    """Noise-free data whose second frequency sits at f1/ratio: its code delay is ratio**2 times the first's."""
    data, truth = synthetic_data(n_epochs, dual=True, code_noise_m=0.0, phase_noise_m=0.0)
    o = data.observations.copy()
    iono = (o["code_l2"] - o["code_l1"]) / (IONO_L2_SCALE - 1.0)  # the table's first-frequency delay
    gamma = np.broadcast_to(np.asarray(ratio, float), len(o)) ** 2
    o["code_l2"] += (gamma - IONO_L2_SCALE) * iono
    o["phase_l2"] -= (gamma - IONO_L2_SCALE) * iono
    o["f1_f2_ratio"] = np.sqrt(gamma)
    return ReceiverData(o, data.imu, data.nav), truth


def _worst_code_residual(data: ReceiverData, truth: dict, **kw) -> float:
    obs = prepare_ppp(data, **{**KW, **kw})
    lat, _, h = geodetic_from_ecef(truth["pos"])
    worst = 0.0
    for k, rows in obs.iter_epochs():
        clock = truth["rx_clock"][obs.epoch_ids[k]]
        pred, _ = predict(obs.sat_pos[rows], truth["pos"], clock, truth["zwd"], obs.el[rows], lat, h, obs.doy)
        worst = max(worst, float(np.abs(obs.code[rows] - pred).max()))
    return worst


@pytest.mark.parametrize("pair", list(RATIOS))
def test_the_combination_removes_the_ionosphere_for_every_carrier_pair(pair: str) -> None:
    data, truth = with_second_frequency(RATIOS[pair])
    # a delay of 2-7 m on the first frequency: without the combination it stays in the code
    assert _worst_code_residual(data, truth, ionosphere=IonosphereMode.free) < 5e-3
    first_only = data.observations.drop(columns=["code_l2", "phase_l2", "f1_f2_ratio"])
    no_model = ReceiverData(first_only.assign(code_l2=np.nan, phase_l2=np.nan, f1_f2_ratio=np.nan), data.imu, data.nav)
    assert _worst_code_residual(no_model, truth, ionosphere=IonosphereMode.broadcast) > 2.0


def test_each_row_uses_its_own_carrier_ratio() -> None:
    data, truth = with_second_frequency(RATIOS["L1/L2"])
    sats = data.observations["sat"].to_numpy()
    per_row = np.where(pd.Series(sats).str[1:].astype(int) % 2 == 0, RATIOS["B1I/B3I"], RATIOS["G1/G2"])
    mixed, truth = with_second_frequency(per_row)
    assert _worst_code_residual(mixed, truth, ionosphere=IonosphereMode.free) < 5e-3


def test_auto_picks_free_only_when_every_satellite_has_a_second_frequency() -> None:
    data, _ = with_second_frequency(RATIOS["L1/L2"])
    auto = prepare_ppp(data, **KW)
    assert auto.ionosphere_free and auto.n_single_frequency_dropped == 0
    o = data.observations
    one_sat = o["sat"] == o["sat"].iloc[0]
    without_one = ReceiverData(o.assign(code_l2=o["code_l2"].where(~one_sat)), data.imu, data.nav)
    assert not prepare_ppp(without_one, **KW).ionosphere_free
    # a few rows without it (under 10 % of a satellite's): still free, those rows dropped
    few = one_sat & (o["epoch"] == o.loc[one_sat, "epoch"].iloc[0])
    sparse = ReceiverData(o.assign(code_l2=o["code_l2"].where(~few)), data.imu, data.nav)
    chosen = prepare_ppp(sparse, **KW)
    assert chosen.ionosphere_free and chosen.n_single_frequency_dropped == 1
    assert chosen.model_info()["single_frequency_rows_dropped"] == 1
    single, _ = synthetic_data(5, dual=False)
    assert not prepare_ppp(single, **KW).ionosphere_free
    forced = prepare_ppp(data, ionosphere=IonosphereMode.broadcast, **KW)
    assert not forced.ionosphere_free


def test_free_drops_the_rows_without_a_second_frequency() -> None:
    data, _ = with_second_frequency(RATIOS["L1/L5"])
    o = data.observations
    above = o["el"] > KW["elevation_mask_deg"]
    lacking = (o["sat"] == o["sat"].iloc[0]) | (o["sat"] == o["sat"].iloc[-1])
    half = ReceiverData(o.assign(f1_f2_ratio=o["f1_f2_ratio"].where(~lacking)), data.imu, data.nav)
    obs = prepare_ppp(half, ionosphere=IonosphereMode.free, **KW)
    assert obs.ionosphere_free and obs.n_single_frequency_dropped == int((lacking & above).sum()) > 0
    assert not set(o.loc[lacking, "sat"]) & set(obs.sat)
    assert obs.n_obs == int((above & ~lacking).sum())
    single, _ = synthetic_data(5, dual=False)
    with pytest.raises(SimbenchError, match="ionosphere"):
        prepare_ppp(single, ionosphere=IonosphereMode.free, **KW)


def test_the_broadcast_group_delays_move_the_clock_to_the_combination(monkeypatch: pytest.MonkeyPatch) -> None:
    """sat_clock is the first frequency's (c (dt - TGD)); a GPS TGD of 10 ns leaves -3 m in the combination
    unless the table's ``sat_dcb`` ((gamma - 1) c TGD) is applied."""
    monkeypatch.setattr(simbench.contract, "RECEIVER_COLUMNS", simbench.contract.RECEIVER_COLUMNS | {SAT_DCB_COLUMN})
    data, truth = with_second_frequency(RATIOS["L1/L2"])
    o = data.observations
    tgd_m = 299_792_458.0 * 10e-9
    gamma = o["f1_f2_ratio"] ** 2
    # the receiver sees L1 delayed by c TGD and L2 by gamma c TGD; the L1 clock removes c TGD
    biased = o.assign(
        code_l1=o["code_l1"] + tgd_m, code_l2=o["code_l2"] + gamma * tgd_m, sat_clock=o["sat_clock"] - tgd_m
    )
    without = ReceiverData(biased, data.imu, data.nav)
    assert _worst_code_residual(without, truth, ionosphere=IonosphereMode.free) == pytest.approx(tgd_m, abs=0.01)
    with_dcb = ReceiverData(biased.assign(**{SAT_DCB_COLUMN: (gamma - 1.0) * tgd_m}), data.imu, data.nav)
    assert _worst_code_residual(with_dcb, truth, ionosphere=IonosphereMode.free) < 5e-3


def test_klobuchar_is_carried_to_each_systems_first_carrier() -> None:
    scale = klobuchar_scale(np.array(["G01", "E11", "J02", "C08", "R05"]))
    np.testing.assert_allclose(scale[:3], 1.0)
    assert scale[3] == pytest.approx((F_L1 / F_B1I) ** 2) and scale[3] > 1.018
    assert scale[4] == pytest.approx((1575.42 / 1602.0) ** 2) and scale[4] < 0.968
