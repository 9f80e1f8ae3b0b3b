"""Score a solution from another program (RTKLIB, a phone pipeline, MATLAB) as one more estimator of a run.

::

    python -m simbench score RUN_DIR --scenario-key KEY --name rtklib --solution FILE

``FILE`` is (:func:`read_solution`)

* an RTKLIB ``.pos`` file, ECEF or latitude/longitude/height, GPS time
  (:mod:`simbench.data.rtklib_pos`), recognised by its ``%`` header lines;
* a CSV file ``t,x,y,z``: ``t`` continuous GPS seconds since 1980-01-06
  (GPS week x 604800 + seconds of week) [s], ``x, y, z`` ECEF [m];
* a CSV file ``week,tow,lat,lon,h``: GPS week, GPS seconds of week [s],
  WGS-84 latitude and longitude [deg] and ellipsoidal height [m] (the layout
  of the reference trajectory ``python -m simbench export`` writes);

* a ``SOW X Y Z`` file (GPS seconds of the scenario's week, ECEF [m]);

the last three with an optional header line and one solution per row, read by
:func:`simbench.data.reference.read_reference`. ``KEY`` is a scenario key of the run
(the ``scenario_key`` column of ``summary.parquet``, a folder of
``RUN_DIR/cache/``). Each solution is paired with the scenario epoch nearest
in GPS time (at most half the epoch interval away, one solution per epoch, as
for ``rtklib_spp``) and scored against the cached truth by the runner's own
scoring (:func:`simbench.runs.runner.score_solution`): availability over the
reference epochs, the same statistics and status. The row and its epoch
errors are written into the run's store like an estimator's result, under
the name given, and the aggregate, ``claims.csv`` and ``report/`` are rebuilt,
so the report shows the solution beside the built-in estimators. A solution
whose times fit the truth clearly better shifted by whole seconds (UTC times
under a GPST header: 18 s) is scored as written, with a warning naming the
shift (:func:`check_time_system`). Scoring
another file under the same name replaces the earlier result; run times are
unknown (NaN).
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import numpy as np
import pandas as pd

import estimators
from estimators.base import solution_frame
from simbench.analysis.variants import overrides_json, variant_label
from simbench.contract import Scenario
from simbench.data.reference import read_reference
from simbench.data.rtklib_pos import parse_rtklib_pos
from simbench.data.solution_times import OFFSETS_S, best_time_offset, match_receiver_epochs, receiver_epoch_times
from simbench.errors import SimbenchError, warn
from simbench.runs.provenance import provenance
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS, scenario_source, score_solution
from simbench.runs.store import cache_problem, read_job, result_stem, write_result

__all__ = ["read_solution", "score_solution_file", "check_time_system"]

#: The config a foreign result is keyed by: one result per name and scenario, replaced by a rescore.
FOREIGN_CONFIG = {"foreign_solution": True}
#: Allowed result names: the store separates name and key with '-'.
NAME_PATTERN = re.compile(r"[A-Za-z0-9_]+")


def read_solution(path: str | Path, gps_week: int) -> tuple[pd.DataFrame, str]:
    """Read a solution file in any layout of the module docstring.

    Parameters
    ----------
    path : str or Path
    gps_week : int
        GPS week of the scenario, for a file with seconds of week and no week (``SOW X Y Z``).

    Returns
    -------
    solution : pandas.DataFrame
        Columns ``t_gps`` (continuous GPS seconds [s]) and ``x, y, z`` (ECEF [m]).
    layout : str
        ``rtklib_pos`` or ``csv``.

    Raises
    ------
    SimbenchError
        A missing file or one in no known layout, naming ``--solution``.
    """
    field = "--solution"
    p = Path(path)
    text = p.read_text(errors="replace") if p.is_file() else ""
    if text.lstrip().startswith("%"):
        return parse_rtklib_pos(text, f"{field} '{p}'")[["t_gps", "x", "y", "z"]], "rtklib_pos"
    ref = read_reference(p, week_hint=gps_week, field=field)
    return pd.DataFrame({"t_gps": ref.t_gps, "x": ref.xyz[:, 0], "y": ref.xyz[:, 1], "z": ref.xyz[:, 2]}), "csv"


#: A shifted solution's mean error must be below this fraction of the unshifted one to be reported.
SHIFT_GAIN = 0.5


def check_time_system(pos: pd.DataFrame, scenario: Scenario, max_offset_s: float, path: str | Path) -> float:
    """Warn when the solution fits the truth far better with its times shifted (UTC under a GPST header).

    Parameters
    ----------
    pos : pandas.DataFrame
        The solution (:func:`read_solution`).
    scenario : Scenario
        The cached scenario it is scored on.
    max_offset_s : float
        Largest distance in time of a solution from its epoch [s].
    path : str or Path
        The solution file, for the warning.

    Returns
    -------
    float
        The best whole-second shift [s] (0 when no shift fits clearly better); the solution is scored as written.
    """
    # both by epoch index: a log's grid has gaps, and epochs without a reference have no truth row
    epochs = scenario.truth["epoch"].to_numpy()
    t_epoch = receiver_epoch_times(scenario.receiver_view())
    n = max(t_epoch.size, int(epochs.max()) + 1 if epochs.size else 0)
    t_epoch = np.pad(t_epoch, (0, n - t_epoch.size), constant_values=np.nan)
    truth = np.full((n, 3), np.nan)
    truth[epochs] = scenario.truth[["x", "y", "z"]].to_numpy()
    best, mean = best_time_offset(
        pos["t_gps"].to_numpy(), pos[["x", "y", "z"]].to_numpy(), t_epoch, truth, max_offset_s
    )
    at_zero = float(mean[OFFSETS_S == 0][0])
    at_best = float(mean[OFFSETS_S == best][0])
    if best == 0 or not at_best < SHIFT_GAIN * at_zero:
        return 0.0
    leap = " (GPS-UTC is 18 s since 2017: UTC times under a GPST header?)" if abs(best) == 18 else ""
    warn(
        f"--solution '{path}'",
        f"its times fit the reference best shifted by {best:+g} s: mean 3-D error {at_best:.3g} m, against "
        f"{at_zero:.3g} m as written{leap}",
        "scored as written; write the solution in GPS time",
    )
    return best


def _find_cache(run_dir: Path, scenario_key: str) -> Path:
    """The cached scenario ``scenario_key`` below ``run_dir`` (a run, a sweep, or a root of several studies)."""
    if not run_dir.is_dir():
        raise SimbenchError("RUN_DIR", f"'{run_dir}' is not a directory", "give the results_dir of a run or sweep")
    found = sorted(p for p in run_dir.glob(f"**/cache/{scenario_key}") if (p / "observations.parquet").is_file())
    if not found:
        known = sorted({p.name for p in run_dir.glob("**/cache/*") if not p.name.startswith(".")})
        fix = (
            f"choose one of {', '.join(known)} (column scenario_key of summary.parquet)"
            if known
            else "run the scenario into RUN_DIR first: it has no cached scenario"
        )
        raise SimbenchError("--scenario-key", f"no cached scenario '{scenario_key}' in '{run_dir}'", fix)
    return found[0]


def _row_key(sweep_dir: Path, scenario_key: str, scenario: Scenario) -> dict[str, object]:
    """The identifying columns of a result on this scenario: those of a row already in the store
    (same sweep tag and receiver as the estimators it is compared with), else from the scenario."""
    for path in sorted((sweep_dir / "jobs" / scenario_key).glob("*.summary.parquet")):
        # through the store's checks: a damaged job is named in one warning and the next one asked
        rows = read_job(path.with_name(path.name.removesuffix(".summary.parquet")), "not used for the row's columns")
        if rows is not None and len(rows):
            first = rows.iloc[0]
            return {k: first[k] for k in ("sweep", "scenario", "source", "receiver", "seed")}
    receiver = (scenario.meta.get("config") or {}).get("receiver") or {}
    return {
        "sweep": "",
        "scenario": scenario.meta.get("name", ""),
        "source": scenario_source(scenario),
        "receiver": receiver.get("name", ""),
        "seed": int(scenario.meta.get("seed", -1)),
    }


def score_solution_file(run_dir: str | Path, scenario_key: str, name: str, solution: str | Path) -> pd.DataFrame:
    """Score a solution file against a run's cached scenario and write it into the run's store.

    Parameters
    ----------
    run_dir : str or Path
        The run's ``results_dir`` (or a sweep's, or the root of several studies).
    scenario_key : str
        Key of a cached scenario of the run (``scenario_key`` column of ``summary.parquet``).
    name : str
        The name the solution appears under, e.g. ``rtklib`` (letters, digits, ``_``; not a registered
        estimator's name).
    solution : str or Path
        An RTKLIB ``.pos`` or CSV file (:func:`read_solution`).

    Returns
    -------
    pandas.DataFrame
        The summary row written (:data:`~simbench.runs.runner.SUMMARY_COLUMNS`).

    Raises
    ------
    SimbenchError
        A bad name, an unknown scenario key or an unreadable solution file, in one line.
    """
    if not NAME_PATTERN.fullmatch(name):
        raise SimbenchError(
            "--name",
            f"'{name}' has characters other than letters, digits and '_'",
            "give a name like rtklib or phone_pipeline",
        )
    if name in estimators.registered():
        raise SimbenchError(
            "--name",
            f"'{name}' is the name of a registered estimator",
            "give the foreign solution a name of its own, e.g. rtklib",
        )
    cache = _find_cache(Path(run_dir), scenario_key)
    problem = cache_problem(cache)
    if problem:
        raise SimbenchError("--scenario-key", f"cached scenario damaged: {problem}", "rerun the run to rebuild it")
    sweep_dir = cache.parent.parent
    scenario = Scenario.load(cache)
    pos, layout = read_solution(solution, scenario.nav.gps_week)
    data = scenario.receiver_view()
    si, ei, max_offset = match_receiver_epochs(data, pos["t_gps"].to_numpy())
    check_time_system(pos, scenario, max_offset, solution)
    epochs = solution_frame(ei, data.epoch_times[ei], pos[["x", "y", "z"]].to_numpy()[si], np.full(si.size, np.nan))
    scores, errors = score_solution(scenario, epochs, float("nan"))
    if not si.size:
        scores.update(
            status="failed",
            message=f"no solution within {max_offset:g} s of a scenario epoch "
            "(times must be GPS time of the scenario's days)",
        )
    columns = {
        **_row_key(sweep_dir, scenario_key, scenario),
        "scenario_key": scenario_key,
        "estimator": name,
        "gnss_model": "",  # a foreign solution ran under no preset of ours
        "variant": variant_label({}),
        "overrides": overrides_json({}),
    }
    summary = pd.DataFrame(
        [
            {
                **columns,
                "uses_labels": False,
                "n_epochs": scenario.n_epochs,
                "n_obs": len(scenario.observations),
                **scores,
            }
        ]
    ).reindex(columns=list(SUMMARY_COLUMNS))
    epoch_rows = errors.assign(**columns).reindex(columns=list(EPOCH_COLUMNS))
    digest = hashlib.sha256(Path(solution).read_bytes()).hexdigest()
    source = {"file": str(Path(solution).resolve()), "format": layout, "sha256": digest}
    diagnostics = {**source, "n_solutions": len(pos), "n_matched": int(si.size)}
    meta = provenance(
        {
            "scored_solution": {**source, "name": name, "scenario_key": scenario_key},
            **(scenario.meta.get("config") or {}),
        }
    )
    write_result(result_stem(sweep_dir, scenario_key, name, FOREIGN_CONFIG), summary, epoch_rows, diagnostics, meta)
    return summary
