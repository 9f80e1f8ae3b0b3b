"""A log without C/N0 (issue 44): every estimator falls back and says so, none crashes.

Two GEONET RINEX 2.10 files carry no S1/S2 observables: BCE-AD failed with scikit-learn's
``Input X contains NaN``. Here a cut of the Nagoya log (``../shared``) is written with its
signal-strength fields blank on every row, or on half the satellites, and every registered
estimator runs on it under the default run's configs; a simulated drive without C/N0 for the
GNSS/INS estimators, which a GNSS-only log skips.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf
from test_rinex_wild import NG_NAV, NG_OBS, NG_POINT, cut

import estimators
import simbench
from simbench.contract import Scenario
from simbench.data.rinex import load_rinex
from simbench.errors import SimbenchWarning
from simbench.runs.compose import compose_config
from simbench.runs.runner import RunResult, run_estimators

#: Epochs of the cut: enough for every estimator to run, few enough for all of them to run fast.
N_EPOCHS = 20
#: The estimator configs of the default run.
DEFAULT_RUN = compose_config([]).estimator


def blank_signal_strength(path: Path, keep: Callable[[str], bool]) -> Path:
    """Blank the signal-strength (``S..``) fields of RINEX 3 file ``path`` on every satellite but those
    ``keep`` accepts (RINEX: a blank field is a missing observation)."""
    lines = path.read_text().splitlines()
    end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    types: dict[str, list[str]] = {}
    for ln in lines[:end]:
        if ln[60:].strip() == "SYS / # / OBS TYPES":
            types.setdefault(ln[0] if ln[0] != " " else list(types)[-1], []).extend(ln[7:60].split())
    for i in range(end, len(lines)):
        ln = lines[i]
        if ln[:1] in types and not keep(ln[:3]):
            kinds = types[ln[0]]
            chars = list(ln.ljust(3 + 16 * len(kinds)))
            for j in (j for j, kind in enumerate(kinds) if kind.startswith("S")):
                chars[3 + 16 * j : 19 + 16 * j] = " " * 16
            lines[i] = "".join(chars).rstrip()
    path.write_text("\n".join(lines) + "\n")
    return path


def _log(directory: Path, keep: Callable[[str], bool]) -> Scenario:
    obs = blank_signal_strength(cut(NG_OBS, directory / "rover.obs", N_EPOCHS), keep)
    return load_rinex(obs, NG_NAV, NG_POINT, systems="GREC")


def _run_all(log: Scenario) -> RunResult:
    names = sorted(estimators.registered())
    configs = {n: OmegaConf.to_container(DEFAULT_RUN[n], resolve=True) for n in names}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SimbenchWarning)
        return run_estimators(log, configs, progress=False)


@pytest.mark.parametrize("blank", ["every row", "half the satellites"])
def test_every_estimator_runs_without_cn0_and_says_so(shared_data: Path, tmp_path: Path, blank: str) -> None:
    """No estimator fails (those that need an IMU or error labels are skipped); the rows without C/N0 are in the
    diagnostics of the C/N0-weighted estimators, and BCE-AD says what became of its C/N0 feature."""
    some = blank == "half the satellites"
    log = _log(tmp_path, (lambda sat: int(sat[1:]) % 2 == 0) if some else (lambda sat: False))
    cn0 = log.observations["cn0_l1"].to_numpy(float)
    assert np.isnan(cn0).all() != some and np.isnan(cn0).any()
    result = _run_all(log)
    summary = result.summary.set_index("estimator")
    assert not (summary["status"] == "failed").any(), summary.loc[summary["status"] == "failed", "message"]
    skipped = summary.index[summary["status"] == "skipped"]
    # what a GNSS log cannot offer: an IMU, or error labels (the oracle)
    assert all(("IMU" in m) or ("labels" in m) for m in summary.loc[skipped, "message"]), summary.loc[skipped]
    assert (summary.loc[summary["status"] != "skipped", "status"] == "ok").all(), summary["status"]
    for name in ("l2", "dcs", "bce", "ekf_ppp", "isam2_dcs", "ice", "wls_spp"):
        diag = result.diagnostics[name]
        share = diag["rows_without_cn0"] / diag["n_observations"]
        assert (0.2 < share < 0.8) if some else share == 1.0, (name, share)
    note = result.diagnostics["bce_ad"]["cn0_feature"]
    assert ("median" in note) if some else ("left out" in note), note
    chosen = {f for step in result.diagnostics["bce_ad"]["history"] for f in step["selected_features"]}
    assert some or "cn0" not in chosen, chosen


def test_a_log_without_cn0_warns_once_per_run(shared_data: Path, tmp_path: Path) -> None:
    """The C/N0 sigma model falls back to 1/sin(elevation) on rows without C/N0: one warning for the
    run, though every estimator prepares the rows."""
    log = _log(tmp_path, lambda sat: False)
    names = ["l2", "dcs", "wls_spp"]
    configs = {n: OmegaConf.to_container(DEFAULT_RUN[n], resolve=True) for n in names}
    with pytest.warns(SimbenchWarning) as caught:
        run_estimators(log, configs, progress=False)
    said = [str(w.message) for w in caught if "cn0_l1" in str(w.message)]
    assert len(said) == 1 and "1/sin(elevation)" in said[0], said


def test_gnss_ins_keeps_its_doppler_without_cn0() -> None:
    """The GNSS/INS Doppler sigma follows C/N0, and without it the elevation (as the code's does): every
    Doppler row is still used (before: none, silently) and the rows without C/N0 are in the diagnostics."""
    sim = simbench.simulate("open_sky", "high", seed=1000, **{"scenario.duration_s": 60})
    blank = dataclasses.replace(sim, observations=sim.observations.assign(cn0_l1=np.nan))
    config = {"ekf_ins": OmegaConf.to_container(DEFAULT_RUN["ekf_ins"], resolve=True)}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SimbenchWarning)
        measured, missing = (run_estimators(s, config, progress=False) for s in (sim, blank))
    assert (missing.summary["status"] == "ok").all(), missing.summary[["status", "message"]]
    with_cn0, without = measured.diagnostics["ekf_ins"], missing.diagnostics["ekf_ins"]
    assert without["doppler_rows"] == with_cn0["doppler_rows"] > 100, (without, with_cn0)
    assert without["rows_without_cn0"] == len(sim.observations) and with_cn0["rows_without_cn0"] == 0
