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
(:func:`estimators.measurement.prepare_ppp`, code only): a satellite only one
receiver keeps would change the geometry, not measure the receiver.

``python -m simbench.zero_baseline morgantown1 morgantown2 morgantown3 --out DIR``
writes ``DIR/zero_baseline.csv``; the report of a run folder shows it.
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

import simbench
from estimators.measurement import prepare_ppp
from estimators.ppp_config import MeasurementMode, StochasticModelConfig
from simbench.contract import Scenario
from simbench.errors import SimbenchError
from simbench.gnss.spp import solve_epochs
from simbench.metrics import enu_errors
from simbench.published import DRIVE_SCENARIOS, ZERO_BASELINE_MEAN_3D_M

#: File name of the table in a run folder.
TABLE_NAME = "zero_baseline.csv"
#: The reference receiver and the presets compared with it.
REFERENCE_PRESET = "geodetic"
PRESETS = ("high", "low")
#: Post-fit RMS above which an epoch's single-point fix is not trusted (left out of the mean) [m].
MAX_RMS_M = 100.0
COLUMNS = ["scenario", "seed", "receiver", "n_epochs", "mean_3d_diff_m", "median_3d_diff_m", "mean_3d_error_m",
           "published_mean_3d_diff_m"]


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
    obs = prepare_ppp(view, ionosphere_free=False, code_sigma_m=noise.code_sigma_m,
                      phase_sigma_m=noise.phase_sigma_m, elevation_mask_deg=noise.elevation_mask_deg,
                      measurements=MeasurementMode.code)
    k = np.searchsorted(obs.epoch_ids, obs.epoch)
    sol = solve_epochs(k, obs.sat_pos, obs.code, n_epochs=obs.n_epochs, sigma=obs.sigma_code,
                       system_index=obs.system_index, el=obs.el, doy=obs.doy, max_rms_m=MAX_RMS_M)
    ok = sol.trusted
    return pd.DataFrame({"epoch": obs.epoch_ids[ok], "x": sol.pos[ok, 0], "y": sol.pos[ok, 1],
                         "z": sol.pos[ok, 2]})


def _pairs(observations: pd.DataFrame) -> pd.MultiIndex:
    """The ``(epoch, sat)`` pairs of an observation table, in its row order."""
    return pd.MultiIndex.from_frame(observations[["epoch", "sat"]])


def zero_baseline(scenario: str, seed: int = 0, **overrides: object) -> pd.DataFrame:
    """Mean 3-D difference of each preset's single-point solution from the geodetic receiver's.

    Parameters
    ----------
    scenario : str
        A preset of ``conf/scenario``.
    seed : int
        Environment seed, the same for every receiver.
    **overrides
        Dotted config overrides as in :func:`simbench.simulate`.

    Returns
    -------
    pandas.DataFrame
        One row per preset (:data:`PRESETS`) with :data:`COLUMNS`: epochs both
        receivers fixed, mean and median 3-D difference from the geodetic fix,
        the preset's mean 3-D error against truth, and the published Table
        5.3.2 value for the dissertation drive the scenario replays (NaN otherwise) [m].
    """
    scenes = {preset: simbench.simulate(scenario, preset, seed=seed, **overrides)
              for preset in (REFERENCE_PRESET, *PRESETS)}
    reference = scenes[REFERENCE_PRESET]
    tracked = _pairs(reference.observations)
    drive = DRIVE_SCENARIOS.get(scenario)
    rows = []
    for preset in PRESETS:
        both = tracked.intersection(_pairs(scenes[preset].observations))
        fix = single_point_positions(scenes[preset], both).set_index("epoch")
        ref = single_point_positions(reference, both).set_index("epoch")
        common = fix.index.intersection(ref.index)
        diff = np.linalg.norm(fix.loc[common, ["x", "y", "z"]].to_numpy() - ref.loc[common, ["x", "y", "z"]].to_numpy(),
                              axis=1)
        err = enu_errors(fix.reset_index(), reference.truth)["error_3d"].to_numpy()
        published = ZERO_BASELINE_MEAN_3D_M.get((preset, drive), np.nan) if drive else np.nan
        rows.append({"scenario": scenario, "seed": seed, "receiver": preset, "n_epochs": len(common),
                     "mean_3d_diff_m": float(diff.mean()) if len(diff) else np.nan,
                     "median_3d_diff_m": float(np.median(diff)) if len(diff) else np.nan,
                     "mean_3d_error_m": float(err.mean()) if len(err) else np.nan,
                     "published_mean_3d_diff_m": published})
    return pd.DataFrame(rows, columns=COLUMNS)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m simbench.zero_baseline SCENARIO... [KEY=VALUE...] [--seed N] [--out DIR]``."""
    parser = argparse.ArgumentParser(prog="python -m simbench.zero_baseline", description=__doc__.split("\n")[0])
    parser.add_argument("scenarios", nargs="+", help="presets of conf/scenario, e.g. morgantown1 morgantown2, and "
                        "dotted config overrides, e.g. scenario.duration_s=300")
    parser.add_argument("--seed", type=int, default=0, help="environment seed (default 0)")
    parser.add_argument("--out", type=Path, default=Path("results/zero_baseline"), help="folder for zero_baseline.csv")
    args = parser.parse_args(argv)
    names = [a for a in args.scenarios if "=" not in a]
    overrides = dict(a.split("=", 1) for a in args.scenarios if "=" in a)
    try:
        table = pd.concat([zero_baseline(s, args.seed, **overrides) for s in tqdm(names, desc="zero baseline")],
                          ignore_index=True)
    except SimbenchError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / TABLE_NAME
    tmp = path.with_name(f".{path.name}.tmp")
    table.to_csv(tmp, index=False)
    tmp.replace(path)
    print(table.to_string(index=False))
    print(f"written: {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
