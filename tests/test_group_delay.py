"""The ``sat_dcb`` column of RINEX logs: broadcast group delay of the second signal minus the first's.

The expected values come from the navigation file's text, read here with a few lines of fixed-column
parsing (not the readers' code path), and the formulas of the contract (docs/contract.md): GPS/QZSS
L1/L2 ``(gamma - 1) c TGD``, Galileo ``(gamma - 1) c BGD`` of the pair, BeiDou B1I/B3I ``-c TGD1``,
B1I/B2I ``c (TGD2 - TGD1)``, GLONASS NaN.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import estimators
import simbench
from estimators.model.measurement import IonosphereMode
from simbench.analysis.metrics import enu_errors
from simbench.contract import OPTIONAL_OBSERVATION_COLUMNS, ReceiverData, Scenario
from simbench.core.constants import C_LIGHT, F_B1I, F_L1, F_L2
from simbench.data.broadcast import load_navigation
from simbench.data.rinex import load_rinex

F_E5A, F_E5B = 1_176.45e6, 1_207.14e6  # Galileo E5a, E5b carriers [Hz]
GALILEO_SOURCES_LINE, BGD_LINE = 5, 6  # continuation lines of a RINEX 3 record holding them


@pytest.fixture(scope="module")
def nagoya_dir(shared_data: Path) -> Path:
    return shared_data / "nagoya_static"


@pytest.fixture(scope="module")
def nagoya() -> Scenario:
    """The whole Nagoya open-sky log (GREC, 301 epochs; second signals GPS L2, E5a, B3I, G2)."""
    return simbench.scenario("nagoya_static")


def record_fields(nav: Path, sat: str, line: int) -> list[list[float]]:
    """The four numbers of continuation ``line`` (1-based) of every record of ``sat`` in RINEX 3 file ``nav``."""
    lines = nav.read_text().splitlines()
    starts = [i for i, ln in enumerate(lines) if ln.startswith(sat + " ")]
    return [[float(lines[i + line][4 + 19 * k : 23 + 19 * k].replace("D", "E")) for k in range(4)] for i in starts]


def one_value(values: list[float]) -> float:
    """The value all records of a satellite agree on (the test satellites are chosen so)."""
    assert len(set(values)) == 1, values
    return values[0]


def table_value(obs: pd.DataFrame, sat: str) -> float:
    """The one ``sat_dcb`` of ``sat``'s rows with a second signal (a constant per satellite)."""
    dcb = obs.loc[(obs["sat"] == sat) & obs["code_l2"].notna(), "sat_dcb"].to_numpy()
    assert dcb.size >= 5 and np.ptp(dcb) == 0.0, sat
    return float(dcb[0])


def test_sat_dcb_is_the_hand_formula_of_each_systems_nav_record(nagoya: Scenario, nagoya_dir: Path) -> None:
    nav, obs = nagoya_dir / "base.nav", nagoya.observations
    assert list(OPTIONAL_OBSERVATION_COLUMNS) == ["sat_dcb", "sat_dcb_sigma"]
    assert list(obs.columns)[-2:] == list(OPTIONAL_OBSERVATION_COLUMNS)
    tgd = one_value([f[2] for f in record_fields(nav, "G13", BGD_LINE)])
    gamma = (F_L1 / F_L2) ** 2
    assert table_value(obs, "G13") == pytest.approx((gamma - 1.0) * C_LIGHT * tgd, abs=1e-6)
    # Galileo: BGD(E1,E5a) is field 3 of the line in I/NAV and F/NAV records alike
    bgd_e5a = one_value([f[2] for f in record_fields(nav, "E10", BGD_LINE)])
    gamma = (F_L1 / F_E5A) ** 2
    assert table_value(obs, "E10") == pytest.approx((gamma - 1.0) * C_LIGHT * bgd_e5a, abs=1e-6)
    tgd1 = one_value([f[2] for f in record_fields(nav, "C01", BGD_LINE)])
    assert table_value(obs, "C01") == pytest.approx(-C_LIGHT * tgd1, abs=1e-6)
    glonass = obs["sat"].str.startswith("R") & obs["code_l2"].notna()
    assert glonass.sum() > 1000 and obs.loc[glonass, "sat_dcb"].isna().all()
    # rows without a second signal have none
    assert obs.loc[obs["code_l2"].isna(), "sat_dcb"].isna().all()


def test_e5b_b2i_and_qzss_second_signals(nagoya_dir: Path, tmp_path: Path) -> None:
    """Galileo E5b and BeiDou B2I (the E5a and B3I codes renamed to ones no reader knows), QZSS L2C."""
    src = nagoya_dir / "rover.obs"
    lines = src.read_text().splitlines()
    end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    stop = [i for i in range(end, len(lines)) if lines[i].startswith(">")][5]
    rename = {"E": ("C5Q L5Q D5Q S5Q", "C5D L5D D5D S5D"), "C": ("C6I L6I D6I S6I", "C6D L6D D6D S6D")}
    header = [ln.replace(*rename[ln[0]]) if ln[:1] in rename and "OBS TYPES" in ln else ln for ln in lines[:end]]
    cut = tmp_path / "rover5.obs"
    cut.write_text("\n".join(header + lines[end:stop]) + "\n")
    nav = nagoya_dir / "base.nav"
    obs = load_rinex(cut, nav, systems="ECJ").observations
    ratio = obs.dropna(subset=["code_l2"]).groupby(obs["sat"].str[0])["f1_f2_ratio"]
    assert ratio.min().to_dict() == pytest.approx(ratio.max().to_dict())
    assert ratio.min().to_dict() == pytest.approx({"E": F_L1 / F_E5B, "C": F_B1I / F_E5B, "J": F_L1 / F_L2})
    bgd_e5b = one_value([f[3] for f in record_fields(nav, "E10", BGD_LINE) if f[3] != 0.0])  # I/NAV records
    gamma = (F_L1 / F_E5B) ** 2
    assert table_value(obs, "E10") == pytest.approx((gamma - 1.0) * C_LIGHT * bgd_e5b, abs=1e-6)
    tgd1 = one_value([f[2] for f in record_fields(nav, "C01", BGD_LINE)])
    tgd2 = one_value([f[3] for f in record_fields(nav, "C01", BGD_LINE)])
    assert table_value(obs, "C01") == pytest.approx(C_LIGHT * (tgd2 - tgd1), abs=1e-6)
    tgd = one_value([f[2] for f in record_fields(nav, "J03", BGD_LINE)])
    gamma = (F_L1 / F_L2) ** 2
    assert table_value(obs, "J03") == pytest.approx((gamma - 1.0) * C_LIGHT * tgd, abs=1e-6)


def test_fnav_records_carry_no_e5b_group_delay(nagoya_dir: Path, tmp_path: Path) -> None:
    """RINEX writes 0 into an F/NAV record's BGD(E1,E5b) field: the reader takes it as missing."""
    lines = (nagoya_dir / "base.nav").read_text().splitlines()
    end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    fnav: list[str] = []
    for i in range(end, len(lines)):
        if lines[i].startswith("E") and float(lines[i + GALILEO_SOURCES_LINE][23:42]) == 258:  # F/NAV, E5a clock
            fnav += lines[i : i + 8]
    only_fnav = tmp_path / "fnav.rnx"
    only_fnav.write_text("\n".join(lines[:end] + fnav) + "\n")
    eph, delays = load_navigation("E", only_fnav)
    assert eph.sats.size > 5 and np.isnan(delays["bgd_e5b"]).all() and np.isfinite(delays["bgd_e5a"]).all()
    np.testing.assert_array_equal(eph.tgd, delays["bgd_e5a"])  # the F/NAV clock's own group delay


def _wls_horizontal(data: ReceiverData, truth: pd.DataFrame) -> np.ndarray:
    cls = estimators.get("wls_spp")
    sol = cls(cls.Config(ionosphere=IonosphereMode.free)).estimate(data)
    return enu_errors(sol.epochs, truth)["horizontal"].to_numpy()


def test_ionosphere_free_wls_needs_the_column(nagoya: Scenario) -> None:
    """Per-epoch WLS on the ionosphere-free code, all 301 epochs: horizontal median 0.34 m with
    ``sat_dcb``, 1.35 m without (measured 2026-11)."""
    with_dcb = _wls_horizontal(nagoya.receiver_view(), nagoya.truth)
    without = dataclasses.replace(nagoya, observations=nagoya.observations.drop(columns="sat_dcb"))
    no_dcb = _wls_horizontal(without.receiver_view(), nagoya.truth)
    assert len(with_dcb) == len(no_dcb) == len(nagoya.truth)
    assert np.median(with_dcb) < 1.0 and np.median(with_dcb) < 0.5 * np.median(no_dcb)
