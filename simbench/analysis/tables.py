"""Statistics tables over seeds: bootstrap confidence intervals and paired comparisons.

A group is one (sweep, scenario, receiver); within it every estimator saw the
same seeds' data, so comparisons are paired by seed. Variants are told apart
by the structured ``overrides`` column; ``variant`` is carried along as their label.
Every table carries the availability (solved / reference epochs) beside its
errors; the percentiles ``*_ref`` are over all reference epochs
(:func:`simbench.analysis.metrics.reference_percentile`), so skipping hard epochs is not rewarded.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from functools import partial

import numpy as np
import pandas as pd
from scipy import stats

from simbench.analysis.claims import BOOTSTRAP_RESAMPLES, CONFIDENCE, CONVERGENCE_S, ratio_of_means
from simbench.analysis.metrics import block_bootstrap, reference_percentiles, rmse, row_rmse
from simbench.analysis.published import DRIVE_MEDIANS_BY_SWEEP, DRIVE_MEDIANS_M, DRIVE_SCENARIOS, PUBLISHED_FAMILY
from simbench.analysis.variants import NO_OVERRIDES, display_names, is_default
from simbench.source_registry import SIMULATED

#: Columns that identify a variant of an estimator: its gnss_model preset, the structured overrides
#: (relative to that preset, so a sweep over presets has a default row under each) and their label.
VARIANT = ["gnss_model", "overrides", "variant"]
#: Each variant column's value where it is missing: results from before the column, or no overrides.
VARIANT_FILL = {"gnss_model": "", "overrides": NO_OVERRIDES, "variant": ""}

GROUP = ["sweep", "scenario", "receiver"]

#: How a real log's format is named in labels (another source by its name).
SOURCE_NAMES = {"rinex": "RINEX", "gnsslogger": "GnssLogger", "librsf": "libRSF"}


def with_variant_columns(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with every :data:`VARIANT` column, missing values filled (:data:`VARIANT_FILL`)."""
    # object columns: an all-missing column read back is float, and strings do not fill a float column
    columns = {c: frame[c].astype(object) if c in frame else VARIANT_FILL[c] for c in VARIANT}
    return frame.assign(**columns).fillna(VARIANT_FILL)


def data_source(source: str | None) -> str:
    """The ``source`` column's value; a missing one (results from before the column) is simulated."""
    return source if isinstance(source, str) and source else SIMULATED


def data_label(scenario: str, receiver: str, source: str | None) -> str:
    """What a group's data are, for titles and tables.

    A simulated scenario is named with its receiver preset (``urban, low
    receiver``); a real log by its source (``hk_tst_2019 (real log, RINEX)``),
    since the receiver preset of the config says nothing about it.
    """
    kind = data_source(source)
    if kind == SIMULATED:
        return f"{scenario}, {receiver} receiver"
    if kind in SOURCE_NAMES:
        return f"{scenario} (real log, {SOURCE_NAMES[kind]})"
    return f"{scenario} (source {kind})"


def _mean_ci(values: np.ndarray) -> tuple[float, float, float]:
    values = values[np.isfinite(values)]
    if len(values) == 0:
        return np.nan, np.nan, np.nan
    if len(values) < 3 or np.ptp(values) == 0:
        return float(values.mean()), np.nan, np.nan
    res = stats.bootstrap(
        (values,),
        np.mean,
        n_resamples=BOOTSTRAP_RESAMPLES,
        confidence_level=CONFIDENCE,
        method="percentile",
        random_state=np.random.default_rng(0),
    )
    return float(values.mean()), float(res.confidence_interval.low), float(res.confidence_interval.high)


def _mean_ci_ref(values: np.ndarray) -> tuple[float, float, float]:
    """:func:`_mean_ci` of percentiles over reference epochs: one undefined (inf) seed makes the mean inf."""
    values = values[~np.isnan(values)]
    if np.isinf(values).any():
        return np.inf, np.nan, np.nan
    return _mean_ci(values)


#: The percentile statistics of :func:`seed_statistics` with a bootstrap CI over seeds: summary column -> name.
CI_STATISTICS = {
    "horizontal_median_ref": "horizontal_median",
    "horizontal_p95_ref": "horizontal_p95",
    "error_3d_median_ref": "error_3d_median",
    "error_3d_p95_ref": "error_3d_p95",
    "horizontal_rmse": "horizontal_rmse",
    "error_3d_rmse": "error_3d_rmse",
    "error_3d_nearest_rmse": "error_3d_nearest_rmse",
}
#: Resamples of a block bootstrap over one run's epochs (each is a whole run: 1000 keep the 2.5 and 97.5 %
#: order statistics within a few per cent of their limit, at half the time of the seeds' 2000).
EPOCH_RESAMPLES = 1000
#: Columns that identify one job's result in both the summary and the epoch rows.
JOB = ["sweep", "scenario_key", "estimator", "gnss_model", "overrides"]
#: The error series of :data:`CI_STATISTICS` (the epoch column and the statistic of it).
SERIES_STATISTICS = {
    "horizontal_median_ref": ("horizontal", "median"),
    "horizontal_p95_ref": ("horizontal", "p95"),
    "error_3d_median_ref": ("error_3d", "median"),
    "error_3d_p95_ref": ("error_3d", "p95"),
    "horizontal_rmse": ("horizontal", "rmse"),
    "error_3d_rmse": ("error_3d", "rmse"),
    "error_3d_nearest_rmse": ("error_3d_nearest", "rmse"),
}
#: The epoch series :func:`with_rmse` takes the RMSE of (their summary column: ``<series>_rmse``).
RMSE_SERIES = tuple(series for series, kind in SERIES_STATISTICS.values() if kind == "rmse")


def with_rmse(summary: pd.DataFrame, epochs: pd.DataFrame) -> pd.DataFrame:
    """``summary`` with ``horizontal_rmse``, ``error_3d_rmse`` and ``error_3d_nearest_rmse`` [m] of each job
    (:data:`RMSE_SERIES`), over its solved epochs (:func:`~simbench.analysis.metrics.rmse`) in ``epochs``;
    NaN for a job without epoch rows, or where results written before a series existed lack it."""
    columns = [f"{series}_rmse" for series in RMSE_SERIES]
    if epochs.empty or summary.empty:
        return summary.assign(**dict.fromkeys(columns, np.nan))
    epochs = epochs.reindex(columns=list(dict.fromkeys([*epochs.columns, *RMSE_SERIES])))
    keyed = with_variant_columns(epochs)[JOB + list(RMSE_SERIES)].astype(dict.fromkeys(JOB, str))
    per_job = keyed.groupby(JOB, observed=True)[list(RMSE_SERIES)].agg(rmse)
    per_job.columns = columns
    keys = with_variant_columns(summary)[JOB].astype(str)
    found = per_job.reindex(pd.MultiIndex.from_frame(keys))
    return summary.assign(**{c: found[c].to_numpy() for c in per_job.columns})


def epoch_intervals(
    stats: pd.DataFrame, summary: pd.DataFrame, epochs: pd.DataFrame, reference: Mapping[str, np.ndarray]
) -> pd.DataFrame:
    """``stats`` (:func:`seed_statistics`) with a block-bootstrap CI over epochs
    (:func:`~simbench.analysis.metrics.block_bootstrap`) for each row of one seed, and ``ci_over``.

    A single run (or a real log) has no spread between seeds; its intervals resample blocks of
    its reference epochs instead (an unsolved epoch counting as an infinite error for the
    percentiles, left out of the RMSE).

    Parameters
    ----------
    stats : pandas.DataFrame
        :func:`seed_statistics` rows.
    summary, epochs : pandas.DataFrame
        The rows ``stats`` came from, and their solved epochs (columns :data:`JOB`, ``epoch``,
        ``horizontal``, ``error_3d``).
    reference : mapping of str to numpy.ndarray
        Scenario key to its reference epochs' indices, in time order; a row whose scenario is
        not in it keeps NaN intervals.

    Returns
    -------
    pandas.DataFrame
        ``stats`` with the CI columns of one-seed rows filled and ``ci_over``: ``seeds``
        (3 or more), ``epochs`` (block bootstrap over one run's epochs) or ``''`` (none).
    """
    out = stats.copy()
    out["ci_over"] = np.where(out["ci_low"].notna(), "seeds", "")
    if stats.empty or epochs.empty:
        return out
    jobs = with_variant_columns(summary[summary["status"] == "ok"])
    keyed = with_variant_columns(epochs).astype(dict.fromkeys(JOB, str))
    by_job = dict(iter(keyed.groupby(JOB, observed=True)))
    for i, row in with_variant_columns(out).iterrows():
        if row["n_seeds"] != 1:
            continue
        match = np.logical_and.reduce(
            [jobs[c].astype(str) == str(row[c]) for c in ["sweep", "scenario", "receiver", "estimator", *VARIANT[:2]]]
        )
        job = jobs[match]
        key = tuple(str(job[c].iloc[0]) for c in JOB) if len(job) == 1 else None
        if key is None or key[1] not in reference or key not in by_job:
            continue
        intervals = _epoch_intervals(by_job[key], np.asarray(reference[key[1]]))
        for column, (low, high) in intervals.items():
            low_column, high_column = (
                ("ci_low", "ci_high")
                if column == "horizontal_median_ref"
                else (
                    f"{column}_ci_low",
                    f"{column}_ci_high",
                )
            )
            out.loc[i, [low_column, high_column]] = [low, high]
        out.loc[i, "ci_over"] = "epochs"
    return out


def _epoch_intervals(rows: pd.DataFrame, reference: np.ndarray) -> dict[str, tuple[float, float]]:
    """Block-bootstrap intervals of every :data:`SERIES_STATISTICS` of one job's epoch rows."""
    position = pd.Series(np.arange(len(reference)), index=reference)
    out = {}
    for series in dict.fromkeys(series for series, _ in SERIES_STATISTICS.values()):
        if series not in rows:  # results written before the series existed
            continue
        errors = np.full(len(reference), np.inf)
        at = position.reindex(rows["epoch"].to_numpy()).to_numpy()
        values = rows[series].to_numpy(float)
        known = np.isfinite(at)
        errors[at[known].astype(int)] = values[known]
        wanted = {c: kind for c, (s, kind) in SERIES_STATISTICS.items() if s == series}
        functions: dict[str, Callable[[np.ndarray], np.ndarray]] = {
            c: (row_rmse if kind == "rmse" else partial(reference_percentiles, q=50.0 if kind == "median" else 95.0))
            for c, kind in wanted.items()
        }
        out.update(block_bootstrap(errors, functions, EPOCH_RESAMPLES, CONFIDENCE))
    return out


def seed_statistics(summary: pd.DataFrame) -> pd.DataFrame:
    """Per group, estimator and variant: mean over seeds of each statistic, with bootstrap CIs.

    "Median" here and everywhere in the report is the mean over seeds of each seed's median
    over its reference epochs (``horizontal_median_ref``): one number per seed, so seeds
    weigh alike whatever their length, and the CI is over seeds.

    Columns: group keys, estimator, overrides, variant, n_seeds, n_failed, availability;
    horizontal_median_ref with its bootstrap ci_low/ci_high; horizontal_p95_ref,
    error_3d_median_ref and error_3d_p95_ref, each with ``<name>_ci_low``/``_ci_high``
    (inf when a seed's availability is below the percentile; the CIs are NaN with fewer
    than 3 seeds or no spread); horizontal_median_solved and horizontal_max (over the solved
    epochs only), time_per_obs_s, update_median_s and time_per_epoch_s (the estimator's
    run time over its reference epochs) [s].
    """
    out = []
    summary = with_variant_columns(summary)
    for column in CI_STATISTICS:  # results written before a column existed have it missing
        if column not in summary:
            summary[column] = np.nan
    for keys, rows in summary.groupby(GROUP + ["estimator"] + VARIANT, dropna=False):
        ok = rows[rows["status"] == "ok"]
        cis = {c: _mean_ci_ref(ok[c].to_numpy(float)) for c in CI_STATISTICS}

        def mean(column: str, ok: pd.DataFrame = ok) -> float:
            return float(ok[column].mean()) if len(ok) and column in ok else np.nan

        med, lo, hi = cis["horizontal_median_ref"]
        per_epoch = ok["total_s"].to_numpy(float) / np.maximum(ok["n_epochs"].to_numpy(float), 1) if len(ok) else []
        out.append(
            {
                **dict(zip(GROUP + ["estimator"] + VARIANT, keys)),
                "n_seeds": len(ok),
                "n_failed": int((rows["status"] != "ok").sum()),
                "availability": mean("availability"),
                "horizontal_median_ref": med,
                "ci_low": lo,
                "ci_high": hi,
                **{
                    f"{c}{suffix}": value
                    for c in list(CI_STATISTICS)[1:]
                    for suffix, value in zip(("", "_ci_low", "_ci_high"), cis[c])
                },
                "horizontal_median_solved": mean("horizontal_median"),
                "horizontal_max": mean("horizontal_max"),
                "time_per_obs_s": mean("time_per_obs_s"),
                "update_median_s": mean("update_median_s"),
                "time_per_epoch_s": float(np.mean(per_epoch)) if len(per_epoch) else np.nan,
            }
        )
    return pd.DataFrame(out)


#: Fewest seeds for the Wilcoxon signed-rank test of :func:`paired_comparisons` (its p cannot go below
#: 0.05 with fewer); with fewer, or no difference at all, ``wilcoxon_p`` is NaN.
WILCOXON_MIN_SEEDS = 6


def _named(summary: pd.DataFrame, baseline: str) -> tuple[pd.DataFrame, str | None]:
    """The ok rows with ``estimator`` replaced by the variant's display name, and the baseline's name.

    The names are a ``name`` column's where ``summary`` has one (the report's, over the whole run),
    else :func:`~simbench.analysis.variants.display_names` of these rows. The baseline is the
    estimator's default variant where it ran one, else its first variant.
    """
    ok = summary[summary["status"] == "ok"]
    ok = ok.assign(estimator=ok["name"] if "name" in ok else display_names(ok))
    rows = summary.loc[ok.index]
    of_baseline = ok[rows["estimator"] == baseline]
    if of_baseline.empty:
        return ok, None
    default = of_baseline[is_default(rows.loc[of_baseline.index, "overrides"])]
    return ok, str((default if len(default) else of_baseline)["estimator"].iloc[0])


def paired_comparisons(summary: pd.DataFrame, baseline: str) -> pd.DataFrame:
    """Each estimator variant against ``baseline`` on the same seeds.

    Every variant is compared, named as in figures (:func:`~simbench.analysis.variants.display_names`);
    the baseline is its default variant where it ran one. Columns: group keys, estimator,
    n_seeds, ratio (mean per-seed median over the solved epochs / baseline's), its bootstrap
    CI, wins (fraction of seeds with a lower median), the Wilcoxon signed-rank p-value
    (NaN below :data:`WILCOXON_MIN_SEEDS` seeds or without any difference), and the mean
    availability of the estimator and the baseline
    on those seeds (a ratio below 1 bought with a lower availability is no win).
    """
    out: list[dict] = []
    ok, name_of_baseline = _named(summary, baseline)
    if name_of_baseline is None:
        return pd.DataFrame(out)
    baseline = name_of_baseline
    for keys, rows in ok.groupby(GROUP, dropna=False):
        table = rows.pivot_table(index=["seed"], columns="estimator", values="horizontal_median", aggfunc="first")
        availability = rows.pivot_table(index=["seed"], columns="estimator", values="availability", aggfunc="first")
        if baseline not in table:
            continue
        for name in table.columns.drop(baseline):
            pair = table[[name, baseline]].dropna()
            if pair.empty:
                continue
            ratio, lo, hi = ratio_of_means(pair, name, baseline)
            diff = pair[name] - pair[baseline]
            testable = len(pair) >= WILCOXON_MIN_SEEDS and diff.abs().sum() > 0
            p = float(stats.wilcoxon(diff).pvalue) if testable else np.nan
            out.append(
                {
                    **dict(zip(GROUP, keys)),
                    "estimator": name,
                    "baseline": baseline,
                    "n_seeds": len(pair),
                    "ratio": ratio,
                    "ci_low": lo,
                    "ci_high": hi,
                    "wins": float((diff < 0).mean()),
                    "wilcoxon_p": p,
                    "availability": float(availability.loc[pair.index, name].mean()),
                    "baseline_availability": float(availability.loc[pair.index, baseline].mean()),
                }
            )
    return pd.DataFrame(out)


def oracle_gap(summary: pd.DataFrame, oracle: str = "oracle") -> pd.DataFrame:
    """Each estimator's mean per-seed median (solved epochs) minus the oracle's, per group [m].

    Every variant, named as in figures; the oracle's default variant where it ran one.
    With the mean availability of the estimator and of the oracle on the same seeds.
    """
    ok, name_of_oracle = _named(summary, oracle)
    out: list[dict] = []
    if name_of_oracle is None:
        return pd.DataFrame(out)
    oracle = name_of_oracle
    for keys, rows in ok.groupby(GROUP, dropna=False):
        table = rows.pivot_table(index="seed", columns="estimator", values="horizontal_median", aggfunc="first")
        availability = rows.pivot_table(index="seed", columns="estimator", values="availability", aggfunc="first")
        if oracle not in table:
            continue
        for name in table.columns.drop(oracle):
            pair = table[[name, oracle]].dropna()
            gap = (pair[name] - pair[oracle]).to_numpy()
            mean, lo, hi = _mean_ci(gap)
            out.append(
                {
                    **dict(zip(GROUP, keys)),
                    "estimator": name,
                    "n_seeds": len(pair),
                    "gap_m": mean,
                    "ci_low": lo,
                    "ci_high": hi,
                    "availability": float(availability.loc[pair.index, name].mean()),
                    "oracle_availability": float(availability.loc[pair.index, oracle].mean()),
                }
            )
    return pd.DataFrame(out)


def convergence_statistics(epochs: pd.DataFrame, t_max: float = CONVERGENCE_S) -> pd.DataFrame:
    """3-D error statistics over the first ``t_max`` seconds of each run (dissertation Table 4.4.5).

    Per estimator and variant: the mean over seeds of each run's median, mean and maximum 3-D
    error for ``t < t_max`` [m], with a bootstrap CI of the mean error. Empty when no run is
    longer than 1.5 ``t_max`` (the window would be most of the run, not its convergence).
    """
    if epochs.empty or epochs["t"].max() < 1.5 * t_max:
        return pd.DataFrame()
    early = with_variant_columns(epochs[epochs["t"] < t_max])
    per_run = early.groupby(["estimator"] + VARIANT + ["seed"], dropna=False)["error_3d"].agg(["median", "mean", "max"])
    out = []
    for (name, gnss_model, overrides, variant), runs in per_run.groupby(level=["estimator"] + VARIANT, dropna=False):
        mean, lo, hi = _mean_ci(runs["mean"].to_numpy(float))
        out.append(
            {
                "estimator": name,
                "gnss_model": gnss_model,
                "overrides": overrides,
                "variant": variant,
                "n_seeds": len(runs),
                "error_3d_median": float(runs["median"].mean()),
                "error_3d_mean": mean,
                "ci_low": lo,
                "ci_high": hi,
                "error_3d_max": float(runs["max"].mean()),
            }
        )
    return pd.DataFrame(out)


def drive_comparison(summary: pd.DataFrame) -> pd.DataFrame:
    """Our median horizontal error on the Morgantown drives beside the dissertation's.

    Parameters
    ----------
    summary : pandas.DataFrame
        Result rows; only default variants of ``morgantownN`` scenarios with a
        published counterpart are used: the sweep's table
        (:data:`simbench.analysis.published.DRIVE_MEDIANS_BY_SWEEP`, Ch.6 for ``ch6_bce_ad``,
        else Ch.5/Ch.7's) has the estimator's family
        (:data:`simbench.analysis.published.PUBLISHED_FAMILY`) for that receiver and drive.

    Returns
    -------
    pandas.DataFrame
        One row per receiver, drive and estimator: ``sweep``, ``receiver``,
        ``drive``, ``estimator``, ``published_as``, ``n_seeds``, ``availability``,
        ``median_ref`` (mean over seeds of the median over reference epochs) [m],
        ``published`` [m] and ``ratio`` = median_ref / published. Empty when no row qualifies.
    """
    columns = [
        "sweep",
        "receiver",
        "drive",
        "estimator",
        "published_as",
        "n_seeds",
        "availability",
        "median_ref",
        "published",
        "ratio",
    ]
    if summary.empty:
        return pd.DataFrame(columns=columns)
    rows = summary[
        summary["scenario"].isin(list(DRIVE_SCENARIOS))
        & summary["estimator"].isin(list(PUBLISHED_FAMILY))
        & summary["receiver"].isin(["low", "high"])
    ]
    rows = rows[is_default(rows["overrides"].fillna(NO_OVERRIDES))]
    out = []
    for (sweep, receiver, scenario, estimator), group in rows.groupby(
        ["sweep", "receiver", "scenario", "estimator"], dropna=False
    ):
        drive = DRIVE_SCENARIOS[scenario]
        family = PUBLISHED_FAMILY[estimator]
        published = DRIVE_MEDIANS_BY_SWEEP.get(sweep, DRIVE_MEDIANS_M).get((receiver, drive), {}).get(family)
        if published is None:  # e.g. BCE-AD outside Ch.6, or Ch.6's high receiver: not published
            continue
        ok = group[group["status"] == "ok"]
        median = _mean_ci_ref(ok["horizontal_median_ref"].to_numpy(float))[0] if len(ok) else np.nan
        out.append(
            {
                "sweep": sweep,
                "receiver": receiver,
                "drive": drive,
                "estimator": estimator,
                "published_as": family,
                "n_seeds": len(ok),
                "availability": float(ok["availability"].mean()) if len(ok) else np.nan,
                "median_ref": median,
                "published": published,
                "ratio": median / published,
            }
        )
    return pd.DataFrame(out, columns=columns).sort_values(
        ["sweep", "receiver", "drive", "estimator"], ignore_index=True
    )
