"""Run estimators on a scenario and score them.

An estimator whose declared needs (``Estimator.needs``) the scenario cannot
meet -- carrier phase on a code-only log, an IMU table, error labels on real
data -- or that cannot run here (``Estimator.unavailable_reason``, e.g. a
missing external program) is not run: its row has ``status = "skipped"`` and
a one-line reason.
A failing estimator does not stop the others: its exception becomes a status
row (``status = "failed"`` and the one-line message) and the run goes on.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

import estimators
from estimators.base import COVARIANCE_COLUMNS, COVARIANCE_INDEX
from simbench.analysis.metrics import (
    enu_errors,
    local_enu,
    nearest_reference_distance,
    nees,
    reference_stats,
    summary_stats,
)
from simbench.contract import Need, Scenario, available_needs, unmet_needs_reason
from simbench.errors import one_line
from simbench.source_registry import SIMULATED
from simbench.typed import to_typed

#: A 3-D error beyond this marks a run as diverged (no receiver is that wrong while working) [m].
DIVERGENCE_M = 10_000.0

#: Columns of ``summary.parquet`` (one row per scenario x receiver x seed x estimator).
SUMMARY_COLUMNS: dict[str, str] = {
    "sweep": "str, sweep name ('' for a single run)",
    "scenario": "str, scenario name",
    "source": "str, where the data come from: simulated, rinex, gnsslogger or librsf (a real log), or a plug-in "
    "source's name (scenario.source; simbench.source_registry)",
    "receiver": "str, receiver preset (describes the data only when source is simulated)",
    "seed": "int, scenario seed",
    "scenario_key": "str, hash of the resolved scenario config (same key = byte-identical data)",
    "estimator": "str, estimator name",
    "gnss_model": "str, the gnss_model preset the estimator ran under (conf/gnss_model/, e.g. urban or "
    "dissertation; empty for a foreign solution)",
    "variant": "str, display label of the overrides, k=v,... ('' for the defaults); never parsed",
    "overrides": "str, JSON object of the estimator settings that differ from its Config dataclass defaults "
    "under the gnss_model preset (sorted keys; '{}' for the defaults); read with simbench.analysis.variants",
    "uses_labels": "bool, the estimator read error labels (oracle)",
    "status": "str, ok | diverged | failed | skipped (the scenario lacks data the estimator needs: "
    "carrier phase, IMU, labels, L2, RINEX files; or a program it runs is not installed)",
    "message": "str, why, when not ok",
    "n_epochs": "int, reference epochs: epochs with truth (every epoch when simulated; on a real log those "
    "with a reference position)",
    "n_solved": "int, reference epochs with a solution",
    "availability": "-, n_solved / n_epochs",
    "n_obs": "int, observation rows",
    "horizontal_median": "m, median over the solved epochs (so are the columns down to error_3d_max: read them "
    "with availability)",
    "horizontal_mean": "m",
    "horizontal_var": "m^2",
    "horizontal_std": "m",
    "horizontal_p95": "m",
    "horizontal_max": "m",
    "error_3d_median": "m",
    "error_3d_mean": "m",
    "error_3d_var": "m^2",
    "error_3d_std": "m",
    "error_3d_p95": "m",
    "error_3d_max": "m",
    "horizontal_median_ref": "m, median over all n_epochs reference epochs, an unsolved epoch counting as an "
    "infinite error (simbench.analysis.metrics.reference_percentile); inf when availability < 0.5",
    "horizontal_p95_ref": "m, 95th percentile over the reference epochs (as horizontal_median_ref); "
    "inf when availability < 0.95",
    "error_3d_median_ref": "m, 3-D median over the reference epochs (as horizontal_median_ref)",
    "error_3d_p95_ref": "m, 3-D 95th percentile over the reference epochs (as horizontal_p95_ref)",
    "total_s": "s, wall time of the estimator run",
    "time_per_obs_s": "s, total_s / n_obs",
    "update_median_s": "s, median per-epoch update time",
    "update_p95_s": "s, 95th percentile update time",
}

#: Columns of ``epochs.parquet`` (one row per solved epoch).
EPOCH_COLUMNS: dict[str, str] = {
    "sweep": "str",
    "scenario": "str",
    "source": "str, the scenario's source (as in summary.parquet)",
    "receiver": "str",
    "seed": "int",
    "scenario_key": "str",
    "estimator": "str",
    "gnss_model": "str, as in summary.parquet",
    "variant": "str",
    "overrides": "str, JSON (as in summary.parquet)",
    "epoch": "int, epoch index",
    "t": "s, since scenario start",
    "x": "m, estimated antenna position, ECEF x",
    "y": "m, estimated ECEF y",
    "z": "m, estimated ECEF z",
    "east": "m, estimated position in the local east-north-up frame at the scenario's first reference point",
    "north": "m, as east",
    "up": "m, as east",
    **{name: f"{meaning} (NaN where the estimator gives none)" for name, meaning in COVARIANCE_COLUMNS.items()},
    "nees": "-, normalised estimation error squared of the position, d^T P^-1 d with d the ECEF error and P the "
    "covariance above (chi-square with 3 degrees of freedom when consistent); NaN without a covariance",
    "e": "m, east error",
    "n": "m, north error",
    "u": "m, up error",
    "horizontal": "m, sqrt(e^2 + n^2)",
    "error_3d": "m",
    "error_3d_nearest": "m, 3-D distance to the nearest reference point of the run, whatever its time (libRSF's "
    "published statistic is the RMS of it: simbench.analysis.metrics.nearest_reference_distance)",
    "update_s": "s, update wall time",
}


@dataclass
class RunResult:
    summary: pd.DataFrame
    epochs: pd.DataFrame
    diagnostics: dict[str, dict[str, Any]]


def run_estimators(
    scenario: Scenario, estimator_configs: Mapping[str, Any], *, receiver: str = "", progress: bool = True
) -> RunResult:
    """Run each named estimator on ``scenario`` and score it against truth.

    Parameters
    ----------
    scenario : Scenario
    estimator_configs : mapping of estimator name to its typed ``Config`` or its config node (dict, DictConfig, None)
    receiver : str
        Receiver preset name, recorded in the tables.
    progress : bool
        Show a progress bar over estimators.

    Returns
    -------
    RunResult
        Summary (:data:`SUMMARY_COLUMNS`), per-epoch errors (:data:`EPOCH_COLUMNS`)
        and each estimator's diagnostics.
    """
    classes = {name: estimators.get(name) for name in estimator_configs}  # unknown names fail first
    key = {
        "scenario": scenario.meta.get("name", ""),
        "source": scenario_source(scenario),
        "receiver": receiver,
        "seed": int(scenario.meta.get("seed", -1)),
    }
    rows, frames, diagnostics = [], [], {}
    data = scenario.receiver_view()
    offered = available_needs(scenario)  # once: every estimator is checked against the same data
    bar = tqdm(classes.items(), desc="estimators", disable=not progress, leave=False)
    for name, cls in bar:
        bar.set_postfix_str(name)
        row: dict[str, Any] = {
            **key,
            "estimator": name,
            "uses_labels": bool(cls.uses_labels),
            "n_epochs": scenario.n_epochs,
            "n_obs": len(scenario.observations),
        }
        try:
            given = estimator_configs[name]
            # a typed config (a job's plan) as it is; a node (dict, DictConfig, None) typed here
            typed = given if isinstance(given, cls.Config) else to_typed(given or {}, cls.Config, f"estimator.{name}")
            est = cls(typed)
            needs = est.needs()
            unmet = "; ".join(filter(None, (unmet_needs_reason(needs, offered), cls.unavailable_reason())))
            if unmet:
                row.update(status="skipped", message=unmet, n_solved=0, availability=0.0)
                rows.append(row)
                continue
            if Need.labels in needs:
                est.attach_labels(scenario.labels)
            sol = est.estimate(data)
        except Exception as exc:  # a failing estimator is a result, not a crash of the run
            row.update(status="failed", message=one_line(exc), n_solved=0, availability=0.0)
            rows.append(row)
            continue
        scores, err = score_solution(scenario, sol.epochs, sol.total_s)
        row.update(scores)
        rows.append(row)
        frames.append(err.assign(**key, estimator=name))
        diagnostics[name] = sol.diagnostics
    summary = pd.DataFrame(rows).reindex(columns=list(SUMMARY_COLUMNS))
    epochs = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    return RunResult(summary=summary, epochs=epochs.reindex(columns=list(EPOCH_COLUMNS)), diagnostics=diagnostics)


def score_solution(scenario: Scenario, solution: pd.DataFrame, total_s: float) -> tuple[dict[str, Any], pd.DataFrame]:
    """Score one solution against the scenario's truth, as every estimator is scored.

    Parameters
    ----------
    scenario : Scenario
    solution : pandas.DataFrame
        Columns ``epoch, t, x, y, z, update_s`` (ECEF m; update time s, NaN when unknown), and
        the ECEF position covariance (``cov_xx`` ... ``cov_zz`` [m^2]) where the estimator has one.
    total_s : float
        Wall time of the run that produced it [s]; NaN when unknown (a foreign solution).

    Returns
    -------
    scores : dict
        The :data:`SUMMARY_COLUMNS` from ``status`` to ``update_p95_s`` but ``uses_labels``,
        ``n_epochs`` and ``n_obs``: status (ok, diverged, or failed when nothing is finite),
        availability over the reference epochs and the error statistics.
    errors : pandas.DataFrame
        Per-epoch positions and errors: the :data:`EPOCH_COLUMNS` from ``epoch`` to ``update_s``.
    """
    solution = solution.reindex(columns=list(dict.fromkeys([*solution.columns, *COVARIANCE_COLUMNS])))
    err = enu_errors(solution, scenario.truth)
    origin = scenario.truth[["x", "y", "z"]].to_numpy(float)[0]
    position = err[["x", "y", "z"]].to_numpy(float)
    err["east"], err["north"], err["up"] = local_enu(position, origin).T
    truth = scenario.truth.set_index("epoch").loc[err["epoch"], ["x", "y", "z"]].to_numpy(float)
    covariance = np.zeros((len(err), 3, 3))
    for column, (i, j) in COVARIANCE_INDEX.items():
        covariance[:, i, j] = covariance[:, j, i] = err[column].to_numpy(float)
    err["nees"] = nees(position - truth, covariance)
    err["error_3d_nearest"] = nearest_reference_distance(position, scenario.truth[["x", "y", "z"]].to_numpy(float))
    horizontal = err["horizontal"].to_numpy()
    finite = np.isfinite(horizontal)
    status, message = "ok", ""
    if not finite.any():
        status, message = "failed", "no finite solution"
    elif not finite.all() or np.nanmax(err["error_3d"].to_numpy()) > DIVERGENCE_M:
        status, message = "diverged", f"non-finite or > {DIVERGENCE_M:.0f} m 3-D errors"
    update_s = solution["update_s"].to_numpy(dtype=float)
    timed = np.isfinite(update_s).any()  # a foreign solution has no update times
    scores = dict(
        status=status,
        message=message,
        n_solved=int(finite.sum()),
        availability=float(finite.sum()) / max(scenario.n_epochs, 1),
        **summary_stats(err["horizontal"], "horizontal"),
        **summary_stats(err["error_3d"], "error_3d"),
        **reference_stats(horizontal, scenario.n_epochs, "horizontal"),
        **reference_stats(err["error_3d"], scenario.n_epochs, "error_3d"),
        total_s=total_s,
        time_per_obs_s=total_s / max(len(scenario.observations), 1),
        update_median_s=float(np.nanmedian(update_s)) if timed else np.nan,
        update_p95_s=float(np.nanpercentile(update_s, 95)) if timed else np.nan,
    )
    return scores, err[list(EPOCH_COLUMNS)[list(EPOCH_COLUMNS).index("epoch") :]]


def scenario_source(scenario: Scenario) -> str:
    """Where ``scenario``'s data come from: the name of its source (:mod:`simbench.source_registry`).

    The readers of real logs record it in ``meta['source']``; the generator does not.
    """
    return str(scenario.meta.get("source") or SIMULATED)
