"""Zero-baseline test (dissertation Table 5.3.2): one sky, one street, several receivers.

The dissertation fed one antenna and RF front end to a geodetic receiver and to
its software receiver run with the ``high`` and ``low`` tracking presets, and
reported the mean 3-D difference of each preset's single-point solution from
the geodetic one. Here the same scenario and seed are generated once per
receiver preset: every environment stream (orbits, atmosphere, street, NLOS,
fading) is drawn from the same named seed streams
(:func:`simbench.sim.processes.stream`), so only what the receiver does with
the signals differs. Each pair (preset, geodetic) is solved epoch by epoch on
the satellites both receivers track, as the published test's double
differences are, with the project's one single-point solver
(:func:`simbench.gnss.spp.solve_epochs`) on the shared measurement model
(:func:`estimators.model.measurement.prepare_ppp`, code only): a satellite only one
receiver keeps would change the geometry, not measure the receiver.

``python -m simbench zero-baseline morgantown1 morgantown2 morgantown3 --out DIR``
writes ``DIR/zero_baseline.csv``; the report of a run folder shows it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from estimators.model.measurement import prepare_ppp
from estimators.model.ppp_config import IonosphereMode, MeasurementMode, StochasticModelConfig
from simbench.analysis.metrics import enu_errors
from simbench.analysis.published import DRIVE_SCENARIOS, ZERO_BASELINE_MEAN_3D_M, Receiver
from simbench.contract import Scenario, write_bytes
from simbench.runs.files import os_fault
from simbench.runs.scenarios import simulate, simulation_config

#: File name of the table in a run folder.
TABLE_NAME = "zero_baseline.csv"
#: The reference receiver and the presets compared with it.
REFERENCE_PRESET = "geodetic"
PRESETS: tuple[Receiver, ...] = ("high", "low")
#: Post-fit RMS above which an epoch's single-point fix is not trusted (left out of the mean) [m].
MAX_RMS_M = 100.0
COLUMNS = [
    "scenario",
    "seed",
    "receiver",
    "n_epochs",
    "mean_3d_diff_m",
    "median_3d_diff_m",
    "mean_3d_error_m",
    "published_mean_3d_diff_m",
]


def single_point_positions(scenario: Scenario, keep: pd.MultiIndex | None = None) -> pd.DataFrame:
    """Code-only weighted single-point fix of every epoch with four or more satellites.

    Parameters
    ----------
    scenario : Scenario
        Only its receiver view is used.
    keep : pandas.MultiIndex, optional
        ``(epoch, sat)`` pairs to use; every observation when None.

    Returns
    -------
    pandas.DataFrame
        ``epoch, x, y, z`` [m, ECEF] of the trusted fixes.
    """
    noise = StochasticModelConfig()
    view = scenario.receiver_view()
    if keep is not None:
        rows = _pairs(view.observations).isin(keep)
        view = replace(view, observations=view.observations[rows].reset_index(drop=True))
    obs = prepare_ppp(
        view,
        ionosphere=IonosphereMode.broadcast,
        code_sigma_m=noise.code_sigma_m,
        phase_sigma_m=noise.phase_sigma_m,
        elevation_mask_deg=noise.elevation_mask_deg,
        measurements=MeasurementMode.code,
    )
    sol = obs.single_point(max_rms_m=MAX_RMS_M)
    ok = sol.trusted
    return pd.DataFrame({"epoch": obs.epoch_ids[ok], "x": sol.pos[ok, 0], "y": sol.pos[ok, 1], "z": sol.pos[ok, 2]})


def _pairs(observations: pd.DataFrame) -> pd.MultiIndex:
    """The ``(epoch, sat)`` pairs of an observation table, in its row order."""
    return pd.MultiIndex.from_frame(observations[["epoch", "sat"]])


def check_zero_baseline(scenario: str, seed: int = 0, **overrides: Any) -> None:
    """Check the config of every receiver's scenario :func:`zero_baseline` would simulate, generating none.

    Raises
    ------
    SimbenchError
        For an unknown preset, a preset of a real log or a value the simulator refuses, naming the key.
    """
    for preset in (REFERENCE_PRESET, *PRESETS):
        simulation_config(scenario, preset, seed=seed, **overrides)


def zero_baseline(scenario: str, seed: int = 0, **overrides: Any) -> pd.DataFrame:
    """Mean 3-D difference of each preset's single-point solution from the geodetic receiver's.

    Parameters
    ----------
    scenario : str
        A preset of ``conf/scenario``.
    seed : int
        Environment seed, the same for every receiver.
    **overrides
        Dotted config overrides as in :func:`simbench.runs.scenarios.simulate`.

    Returns
    -------
    pandas.DataFrame
        One row per preset (:data:`PRESETS`) with :data:`COLUMNS`: epochs both
        receivers fixed, mean and median 3-D difference from the geodetic fix,
        the preset's mean 3-D error against truth, and the published Table
        5.3.2 value for the dissertation drive the scenario replays (NaN otherwise) [m].
    """
    scenes = {preset: simulate(scenario, preset, seed=seed, **overrides) for preset in (REFERENCE_PRESET, *PRESETS)}
    reference = scenes[REFERENCE_PRESET]
    tracked = _pairs(reference.observations)
    drive = DRIVE_SCENARIOS.get(scenario)
    rows = []
    for preset in PRESETS:
        both = tracked.intersection(_pairs(scenes[preset].observations))
        fix = single_point_positions(scenes[preset], both).set_index("epoch")
        ref = single_point_positions(reference, both).set_index("epoch")
        common = fix.index.intersection(ref.index)
        diff = np.linalg.norm(
            fix.loc[common, ["x", "y", "z"]].to_numpy() - ref.loc[common, ["x", "y", "z"]].to_numpy(), axis=1
        )
        err = enu_errors(fix.reset_index(), reference.truth)["error_3d"].to_numpy()
        published = ZERO_BASELINE_MEAN_3D_M.get((preset, drive), np.nan) if drive else np.nan
        rows.append(
            {
                "scenario": scenario,
                "seed": seed,
                "receiver": preset,
                "n_epochs": len(common),
                "mean_3d_diff_m": float(diff.mean()) if len(diff) else np.nan,
                "median_3d_diff_m": float(np.median(diff)) if len(diff) else np.nan,
                "mean_3d_error_m": float(err.mean()) if len(err) else np.nan,
                "published_mean_3d_diff_m": published,
            }
        )
    return pd.DataFrame(rows, columns=COLUMNS)


def write_zero_baseline(names: Sequence[str], out: Path, seed: int = 0, **overrides: Any) -> tuple[pd.DataFrame, Path]:
    """The zero-baseline table of the scenario presets ``names``, written to ``out``/:data:`TABLE_NAME`.

    Every scenario's config is checked (:func:`check_zero_baseline`) before the first is
    generated; the table is written under another name and renamed, so a failed write leaves none.

    Returns
    -------
    (pandas.DataFrame, Path)
        The table (:data:`COLUMNS`, one row per scenario and receiver preset) and the file written.

    Raises
    ------
    SimbenchError
        A scenario config refused, or the file could not be written (one line naming it).
    """
    for name in names:
        check_zero_baseline(name, seed, **overrides)
    table = pd.concat(
        [zero_baseline(s, seed, **overrides) for s in tqdm(names, desc="zero baseline")], ignore_index=True
    )
    path = out / TABLE_NAME
    try:
        write_bytes(path, table.to_csv(index=False).encode())
    except OSError as exc:  # a full disk: one line, and no half-written table (written under another name)
        raise os_fault(exc, path) from None
    return table, path
