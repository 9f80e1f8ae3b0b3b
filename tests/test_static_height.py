"""The height of a static receiver (issue 44, item 5), on a GLONASS cut of the Nagoya log.

GLONASS shares one code pair over fourteen carriers (FDMA), and the receiver's delay differs per
carrier: each satellite's code carries metres of its own bias for the whole log, and those
biases differ with elevation as much as anything does. A zenith wet delay state is separated from
the height and the clock only by the mapping function's elevation dependence, so with one ZWD for
the whole log it took up those biases (counted as hundreds of independent epochs, they outweighed
its 0.3 m prior) and moved the height by several times as much; the per-epoch WLS, which has no
such state, did not move. ``wet_delay=auto`` (the default) sees that the estimate is no wet delay
and models it (the MOPS climatology); nothing absorbs the biases but the position, as in the WLS.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_rinex_wild import NG_NAV, NG_OBS, NG_POINT, cut

import simbench
from simbench.contract import Scenario
from simbench.errors import SimbenchWarning
from simbench.runs.runner import run_estimators

pytestmark = pytest.mark.usefixtures("shared_data")

#: Epochs of the cut: two minutes at 1 Hz, enough for the ZWD state to run away (8 m of height).
N_EPOCHS = 120


@pytest.fixture(scope="module")
def glonass(tmp_path_factory: pytest.TempPathFactory) -> Scenario:
    """The first two minutes of the Nagoya log, GLONASS only (L1/L2 C/A, ionosphere-free), surveyed point."""
    obs = cut(NG_OBS, tmp_path_factory.mktemp("glonass") / "rover.obs", N_EPOCHS)
    overrides = {"scenario.obs": obs, "scenario.nav": NG_NAV, "scenario.truth": NG_POINT, "scenario.systems": "R"}
    return simbench.scenario("rinex", **overrides)


def up_and_rmse(epochs: pd.DataFrame) -> pd.DataFrame:
    """Per estimator: median up error and 3-D RMSE [m]."""
    by = epochs.groupby("estimator")
    return pd.DataFrame({"up": by["u"].median(), "rmse": by["error_3d"].apply(lambda e: float(np.sqrt(np.mean(e**2))))})


def test_code_only_graph_and_filter_keep_the_height_of_the_per_epoch_fix(glonass: Scenario) -> None:
    """Code only, so nothing but the model ties the epochs: before the fix the ZWD state took the
    inter-frequency biases, batch L2's up error was -7.99 m (3-D RMSE 9.53 m) and the EKF's -4.65 m
    (7.54 m) against WLS's +1.26 m (5.14 m); now +0.50 m (4.98 m) and +0.64 m (5.11 m)."""
    code = {"measurements": "code"}
    result = run_estimators(glonass, {"wls_spp": {}, "l2": code, "ekf_ppp": code}, progress=False)
    assert (result.summary["status"] == "ok").all(), result.summary[["estimator", "message"]]
    table = up_and_rmse(result.epochs)
    wls = table.loc["wls_spp"]
    for name in ("l2", "ekf_ppp"):
        mine = table.loc[name]
        assert abs(mine["up"] - wls["up"]) < 1.5, f"{name} up {mine['up']:+.2f} m, wls_spp {wls['up']:+.2f} m"
        assert mine["rmse"] <= 1.1 * wls["rmse"], f"{name} 3-D RMSE {mine['rmse']:.2f} m, wls_spp {wls['rmse']:.2f} m"


def test_auto_keeps_the_wet_delay_state_only_where_its_estimate_is_a_wet_delay(tmp_path: Path) -> None:
    """``wet_delay=auto`` (the default): on GLONASS, code only, the L2 estimate is 2.87 m against the MOPS
    climatology's 0.22 m, so the wet delay is modelled, with a warning, and the EKF's state stays
    exactly at the modelled value; on GPS + Galileo + BeiDou of the same two minutes it is 0.25 m,
    a wet delay (Nagoya in June), and the state stays."""
    code = {"measurements": "code"}
    # the decision is said once per process and table: a table no other test builds (one epoch fewer)
    fresh = cut(NG_OBS, tmp_path / "glonass.obs", N_EPOCHS - 1)
    glonass = simbench.scenario(
        "rinex", **{"scenario.obs": fresh, "scenario.nav": NG_NAV, "scenario.truth": NG_POINT, "scenario.systems": "R"}
    )
    with pytest.warns(SimbenchWarning, match="wet_delay: auto: the log's zenith wet delay estimate") as said:
        result = run_estimators(glonass, {"ekf_ppp": code, "l2": code}, progress=False)
    assert sum("wet_delay: auto" in str(w.message) for w in said) == 1  # once for both estimators
    diag = result.diagnostics["ekf_ppp"]
    assert diag["wet_delay"] == "model" and diag["wet_delay_estimate_m"] > 2.0
    assert result.diagnostics["l2"]["wet_delay"] == "model"
    assert diag["final_zwd_m"] == pytest.approx(diag["wet_delay_climatology_m"], abs=1e-3)
    assert 0.2 < diag["wet_delay_climatology_m"] < 0.25
    overrides = {"scenario.obs": cut(NG_OBS, tmp_path / "rover.obs", N_EPOCHS), "scenario.nav": NG_NAV}
    gec = simbench.scenario("rinex", **overrides, **{"scenario.truth": NG_POINT, "scenario.systems": "GEC"})
    diag = run_estimators(gec, {"l2": code}, progress=False).diagnostics["l2"]
    assert diag["wet_delay"] == "estimate" and abs(diag["wet_delay_estimate_m"] - 0.25) < 0.05
