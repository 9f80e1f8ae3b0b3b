"""Dual frequency only when it is consistent (issue 44, item 3): the code pairs' unbroadcast group delays.

The broadcast messages give a pair's group-delay difference for Galileo (BGD), BeiDou (TGD1, TGD2) and
GPS's P(Y) codes (TGD); a GPS C/A code differs from P1 by the satellite's P1-C1 bias and L2C from P2 by
another, which LNAV does not give (a RINEX 2 file of C1 and P2, a u-blox F9P's C1C and C2L). The reader
states their size (``sat_dcb_sigma``), and ``ionosphere=auto`` uses a system's second frequency only
where those biases are expected to move the position less than the broadcast model's error does.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from test_rinex_wild import NG_NAV, NG_OBS, NG_POINT, cut, rinex2

import simbench
from simbench.contract import Scenario
from simbench.data.rinex import CIVIL_CODE_BIAS_RMS_M, INTER_FREQUENCY_BIAS_RMS_M, second_group_delay_sigmas
from simbench.errors import SimbenchWarning
from simbench.runs.runner import run_estimators

pytestmark = pytest.mark.usefixtures("shared_data")

#: RINEX 2 types of the rewritten GPS rows: C/A code and the P(Y) code on L2, as a geodetic receiver without P1
GPS_C1_P2 = {"G": ["C1C", "L1C", "D1C", "S1C", "C2W", "L2W"]}


def scenario(obs: Path, systems: str) -> Scenario:
    """``obs`` with the Nagoya navigation file and surveyed point, ``systems`` only."""
    return simbench.scenario(
        "rinex",
        **{"scenario.obs": obs, "scenario.nav": NG_NAV, "scenario.truth": NG_POINT, "scenario.systems": systems},
    )


def quiet(log: Scenario, scale: float = 0.0) -> Scenario:
    """``log`` with its Klobuchar amplitude coefficients scaled (0: the model's 5 ns night-time floor only)."""
    nav = dataclasses.replace(log.nav, iono_alpha=tuple(a * scale for a in log.nav.iono_alpha))
    return dataclasses.replace(log, nav=nav)


def biased(log: Scenario, system: str, factor: float) -> Scenario:
    """``log`` with the stated biases of ``system``'s pairs ``factor`` times larger."""
    obs = log.observations.copy()
    rows = obs["sat"].str[0] == system
    obs.loc[rows, "sat_dcb_sigma"] *= factor
    return dataclasses.replace(log, observations=obs)


def test_the_stated_biases_follow_the_signals() -> None:
    """GPS/QZSS: C/A against P(Y) and L2C against P2 each 0.34 m (CODE's P1-C1 RMS, December 2018), L5 1.61 m
    (no L5 group delay in LNAV); P1/P2, Galileo and BeiDou 0; GLONASS and rows without a second code NaN."""
    sat = np.array(["G01", "G02", "G03", "G04", "J02", "E11", "C08", "R01", "G05"])
    first = np.array(["1C", "1C", "1W", "1C", "1C", "1C", "2I", "1C", "1C"])
    second = np.array(["2W", "2L", "2W", "5Q", "2L", "7Q", "7I", "2C", ""])
    got = second_group_delay_sigmas(sat, first, second)
    civil = CIVIL_CODE_BIAS_RMS_M
    want = [civil, np.hypot(civil, civil), 0.0, np.hypot(civil, INTER_FREQUENCY_BIAS_RMS_M), np.hypot(civil, civil)]
    np.testing.assert_allclose(got[:5], want)
    assert list(got[5:7]) == [0.0, 0.0] and np.isnan(got[7:]).all()
    assert civil == pytest.approx(0.2998 * 1.143, abs=0.005)  # the RMS of p1c1_12.DCB [ns] times c


def test_the_reader_writes_them_per_row(tmp_path: Path) -> None:
    """Nagoya (Septentrio, RINEX 3.04): GPS C/A with P2 (0.34 m) or, where L2C has more codes, L2C (0.48 m);
    Galileo and BeiDou 0; GLONASS NaN. The same rows as RINEX 2.11 C1 and P2: 0.34 m on every GPS row."""
    log = scenario(cut(NG_OBS, tmp_path / "rover.obs", 10), "GREC").observations
    by = log.groupby(log["sat"].str[0])["sat_dcb_sigma"]
    assert set(by.get_group("G").round(2)) <= {0.34, 0.48} and (by.get_group("G") == CIVIL_CODE_BIAS_RMS_M).any()
    assert (by.get_group("E") == 0).all() and (by.get_group("C") == 0).all() and by.get_group("R").isna().all()
    old = scenario(rinex2(NG_OBS, tmp_path / "rover.11o", 10, GPS_C1_P2), "G").observations
    assert (old["sat_dcb_sigma"] == CIVIL_CODE_BIAS_RMS_M).all()


def test_auto_keeps_the_broadcast_delay_where_the_pairs_are_expected_to_do_worse(tmp_path: Path) -> None:
    """RINEX 2.11, GPS C1 and P2, one minute of Nagoya: the pairs' stated biases are expected to move the
    fix by 1.07 m, the broadcast model's error by 5.89 m with the day's coefficients (June 2024, solar
    maximum): the ionosphere-free combination, as before. With the model's night-time floor only
    (1.36 m) and pairs 1.5 times as biased as stated, the first frequency with the broadcast delay, in
    one warning line. With Galileo and BeiDou beside GPS, only GPS keeps the broadcast delay."""
    log = scenario(rinex2(NG_OBS, tmp_path / "rover.11o", 60, GPS_C1_P2), "G")
    diag = run_estimators(log, {"wls_spp": {}}, progress=False).diagnostics["wls_spp"]
    assert diag["ionosphere"] == "free"
    assert diag["ionosphere_expected_m"]["G"] == pytest.approx([1.07, 5.89], abs=0.02)
    with pytest.warns(SimbenchWarning, match="gnss_model.ionosphere: auto: the code pairs' unbroadcast"):
        diag = run_estimators(biased(quiet(log), "G", 1.5), {"wls_spp": {}}, progress=False).diagnostics["wls_spp"]
    assert diag["ionosphere"] == "broadcast"
    pairs, model = diag["ionosphere_expected_m"]["G"]
    assert pairs == pytest.approx(1.5 * 1.07, abs=0.03) and model == pytest.approx(1.36, abs=0.02)

    mixed = biased(quiet(scenario(cut(NG_OBS, tmp_path / "rover.obs", 60), "GEC")), "G", 4.0)
    diag = run_estimators(mixed, {"wls_spp": {}}, progress=False).diagnostics["wls_spp"]
    assert diag["ionosphere"] == "measured" and set(diag["ionosphere_fits"]) == {"E", "C"}
