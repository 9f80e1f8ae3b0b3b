"""Build a run's aggregate, ``claims.csv`` and ``report/`` (index.html, README.md, PNG figures).

The measured claims come first: they are what a reader wants to know; a run
that measures none (a single run, a real log) names them in one line at the
end instead. Then one section per (sweep, scenario, receiver) group -- a real
log titled by its source, not by the receiver preset -- with its figures,
statistics with bootstrap confidence intervals over seeds, paired comparisons
and the gap to the oracle, then run time and estimator diagnostics.

Every statistic is read with the availability beside it; distributions and
percentiles are over all reference epochs (an unsolved epoch counts as missed,
:mod:`simbench.analysis.metrics`), and a percentile the availability does not reach is
shown as '—'.
"""

from __future__ import annotations

import html
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from estimators import registered
from simbench.analysis.claims import CLAIMS, NOT_RUN, claims_by_world, claims_table
from simbench.analysis.tables import (
    CONVERGENCE_S,
    GROUP,
    convergence_statistics,
    data_label,
    data_source,
    drive_comparison,
    oracle_gap,
    paired_comparisons,
    seed_statistics,
)
from simbench.analysis.validation import MIN_ROWS_PER_CLOCK, comparison_table, residual_sample
from simbench.analysis.variants import NO_OVERRIDES, config_defaults, is_default, override_value
from simbench.contract import Scenario, write_bytes
from simbench.errors import SimbenchError
from simbench.report.figures import (
    box_figure,
    ecdf_figure,
    error_timeseries_figure,
    mixture_evolution_figure,
    runtime_figure,
    sensitivity_figure,
    validation_figure,
)
from simbench.runs.provenance import provenance
from simbench.runs.runner import SUMMARY_COLUMNS
from simbench.runs.store import aggregate, cached_scenarios, diagnostics
from simbench.runs.studies import STUDY_TIMES, time_budget
from simbench.runs.zero_baseline import TABLE_NAME as ZERO_BASELINE_TABLE
from simbench.source import SIMULATED

#: The comparison baseline when present (the a priori L2 estimator), else the first estimator.
BASELINES = ("l2", "isam2_ppp", "ekf_ppp")
LABEL_USERS_NOTE = "uses the true error labels: an accuracy floor, not an estimator one could deploy"
#: How a percentile over reference epochs that the availability does not reach is shown.
UNDEFINED = "—"
NOT_MEASURED = "not measured"

_CSS = """body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;font-size:13px;margin:0.5em 0 1.5em}td,th{border:1px solid #ccc;padding:3px 6px}
th{background:#f0f0f0}td.num{text-align:right;font-variant-numeric:tabular-nums}
.holds{background:#d8f5d0}.does{background:#f8d4d0}.not{background:#eee;color:#666}img{max-width:100%}
h2{border-bottom:2px solid #ddd;padding-bottom:3px}.note{color:#555;font-size:13px}"""


def finalize(run_dir: str | Path, config: dict[str, Any] | None) -> Path:
    """Aggregate job files, write ``claims.csv`` and build ``report/``; return the report directory."""
    run_dir = Path(run_dir)
    summary, epochs = aggregate(run_dir, provenance(config or {"run_dir": str(run_dir)}))
    # results written before a column existed (e.g. source) are shown with it empty
    summary = summary.reindex(columns=list(dict.fromkeys([*SUMMARY_COLUMNS, *summary.columns])))
    diag = diagnostics(run_dir)
    epochs = _ok_epochs(epochs, summary)  # figures and claims use the results the tables use
    claims = claims_table(summary, epochs, diag)
    write_bytes(run_dir / "claims.csv", claims.to_csv(index=False).encode())
    return build_report(run_dir, summary, epochs, claims, diag)


def _ok_epochs(epochs: pd.DataFrame, summary: pd.DataFrame) -> pd.DataFrame:
    """Epoch rows of results whose status is ``ok`` (a diverged run is listed, not plotted)."""
    keys = ["scenario_key", "estimator", "overrides"]
    if epochs.empty or summary.empty:
        return epochs
    ok = summary.loc[summary["status"] == "ok", keys].fillna(NO_OVERRIDES).drop_duplicates()
    return epochs[pd.MultiIndex.from_frame(epochs[keys].fillna(NO_OVERRIDES)).isin(pd.MultiIndex.from_frame(ok))]


def build_report(
    run_dir: Path, summary: pd.DataFrame, epochs: pd.DataFrame, claims: pd.DataFrame, diag: dict[str, list[dict]]
) -> Path:
    out = run_dir / "report"
    out.mkdir(parents=True, exist_ok=True)
    page = _Page()
    page.h1("simbench report")
    page.p(
        f"Run directory <code>{html.escape(str(run_dir.resolve()))}</code>: {len(summary)} result rows, "
        f"{summary['estimator'].nunique() if len(summary) else 0} estimators, "
        f"{summary['seed'].nunique() if len(summary) else 0} seeds."
    )
    measured = claims["holds"] != NOT_MEASURED
    if measured.any():
        page.h2("Published claims")
        if claims.loc[measured, "world"].nunique() > 1:
            page.p(
                "One column per world (the scenario preset each claim's sweep ran on): measured value, 95 % "
                f"CI where the rule has one, verdict; {NOT_RUN} = the claim's sweep did not run on that world. "
                "Each verdict uses that world's rows alone; the table below has the notes.",
                cls="note",
            )
            page.table(claims_by_world(claims))
        page.table(claims[measured], classes=lambda r: r["holds"].split()[0])
        if not measured.all():
            page.p(_not_measured_line(claims), cls="note")
    if summary.empty:
        _unmeasured_claims_section(page, claims)
        return page.write(out)
    oracles = sorted(summary.loc[summary["uses_labels"].fillna(False).astype(bool), "estimator"].unique())
    if oracles:
        page.p(f"<b>{', '.join(oracles)}</b> {LABEL_USERS_NOTE}.", cls="note")
    failed = summary[summary["status"] != "ok"]
    if len(failed):
        page.h2("Jobs not ok (left out of the figures and statistics)")
        page.table(
            failed.assign(data=_labels(failed))[["sweep", "data", "seed", "estimator", "variant", "status", "message"]]
        )
    drives = drive_comparison(summary)
    if len(drives):
        page.h2("Morgantown drives: our medians beside the dissertation's")
        page.p(
            "median_ref = mean over seeds of the median horizontal error over reference epochs [m]; published = "
            "the dissertation's median on the real drive (Ch.7 tables and the ICE paper; Ch.6 Table 6.3.1 for "
            "ch6_bce_ad, which processed the collects again) for the same estimator family "
            "(batch and incremental variants are both set beside it); ratio = median_ref / published. Our drives "
            "are the recorded trajectories under the broadcast orbits of the day in a simulated suburban street, "
            "not the recorded observables.",
            cls="note",
        )
        page.table(drives)
    zero = run_dir / ZERO_BASELINE_TABLE
    if zero.exists():
        page.h2("Zero-baseline test: each preset's single-point solution against the geodetic receiver's")
        page.p(
            "Same scenario and seed for every receiver preset (identical sky, street and NLOS), code-only "
            "single-point fixes; mean and median 3-D difference from the geodetic fix over the epochs both "
            "fixed [m], beside the dissertation's Table 5.3.2 for the drive the scenario replays.",
            cls="note",
        )
        page.table(pd.read_csv(zero))
    stats = seed_statistics(summary)
    for keys, group in epochs.groupby(GROUP, dropna=False) if len(epochs) else []:
        sweep, scenario, receiver = keys
        in_group = summary[_in_group(summary, keys)]
        source = in_group["source"].iloc[0]
        name = data_label(scenario, receiver, source) + (f" (sweep {sweep})" if sweep else "")
        # file names too say what the data are: the source of a real log, the receiver of a simulation
        kind = receiver if data_source(source) == SIMULATED else data_source(source)
        tag = re.sub(r"[^A-Za-z0-9_-]+", "_", "_".join(str(k) for k in (sweep, scenario, kind) if k))
        page.h2(name)
        default = group[is_default(group["overrides"])]
        shown = (default if len(default) else group).copy()
        n_reference = _reference_epochs(in_group, shown)
        # figures mark the estimators that read truth labels, as the tables' note does
        marked = {e: f"{e} (truth labels)" if e in oracles else e for e in shown["estimator"].unique()}
        shown["estimator"] = shown["estimator"].map(marked)
        n_reference = {marked[e]: n for e, n in n_reference.items()}
        for metric, label in (("horizontal", "horizontal"), ("error_3d", "3-D")):
            page.img(
                ecdf_figure(
                    shown, metric, out / f"ecdf_{metric}_{tag}.png", f"ECDF of {label} error: {name}", n_reference
                )
            )
        page.img(box_figure(shown, out / f"box_{tag}.png", f"Horizontal error per estimator: {name}", n_reference))
        if shown["seed"].nunique() == 1:
            page.img(error_timeseries_figure(shown, out / f"error_time_{tag}.png", f"Horizontal error: {name}"))
        group_stats = stats[_in_group(stats, keys)]
        page.h3("Statistics over seeds (errors in m, availability beside them)")
        page.p(
            "availability = solved / reference epochs (epochs with truth). The <code>*_ref</code> percentiles "
            "are over all reference epochs, an unsolved epoch counting as an infinite error: "
            f"{UNDEFINED} when the availability is below the percentile (below 0.5 for a median, 0.95 for "
            "p95). horizontal_median_ref is the mean of per-seed medians with its 95 % bootstrap CI; "
            "<code>*_solved</code> and max are over the solved epochs only.",
            cls="note",
        )
        page.table(group_stats.drop(columns=GROUP + ["overrides"]))
        early = convergence_statistics(group)
        if len(early):
            page.h3(
                f"Convergence: 3-D error over the first {CONVERGENCE_S / 60:.0f} minutes (mean over seeds of "
                "each run's median, mean and max; 95 % bootstrap CI of the mean) [m]"
            )
            page.table(early.drop(columns=["overrides"]))
        sensitivity = _sensitivity_curves(group_stats)
        if sensitivity is not None:
            page.img(
                sensitivity_figure(
                    sensitivity, out / f"sensitivity_{tag}.png", f"Sensitivity to the a priori covariance: {name}"
                )
            )
        present = set(summary["estimator"])
        baseline = next((b for b in BASELINES if b in present), None)
        if baseline:
            pairs = paired_comparisons(summary[_in_group(summary, keys)], baseline)
            if len(pairs):
                page.h3(
                    f"Paired comparison with {baseline} on the same seeds (ratio of mean medians over the "
                    "solved epochs; wins = share of seeds with a lower median; read with both availabilities)"
                )
                page.table(pairs.drop(columns=GROUP))
        gap = oracle_gap(summary[_in_group(summary, keys)])
        if len(gap):
            page.h3(
                "Gap to the oracle (mean per-seed median over the solved epochs minus the oracle's, with "
                "both availabilities) [m]"
            )
            page.table(gap.drop(columns=GROUP))
        if group_stats["time_per_obs_s"].notna().any():
            page.img(runtime_figure(group_stats, out / f"runtime_{tag}.png", f"Run time: {name}"))
    _study_times_section(page, run_dir, summary)
    _validation_section(page, run_dir, out)
    _diagnostics_section(page, diag, out)
    if not measured.any():
        _unmeasured_claims_section(page, claims)
    return page.write(out)


def _labels(summary: pd.DataFrame) -> pd.Series:
    """:func:`~simbench.analysis.tables.data_label` of each row."""
    return pd.Series(
        [data_label(sc, rx, src) for sc, rx, src in zip(summary["scenario"], summary["receiver"], summary["source"])],
        index=summary.index,
        dtype=object,
    )


def _reference_epochs(summary: pd.DataFrame, epochs: pd.DataFrame) -> dict[str, int]:
    """Per estimator: the reference epochs (summed ``n_epochs``) of the ok jobs whose epochs are in ``epochs``."""
    keys = ["scenario_key", "estimator", "overrides"]
    jobs = epochs[keys].fillna(NO_OVERRIDES).drop_duplicates()
    rows = summary[summary["status"] == "ok"].fillna({"overrides": NO_OVERRIDES}).merge(jobs, on=keys)
    return {name: int(n) for name, n in rows.groupby("estimator")["n_epochs"].sum().items()}


def _not_measured_line(claims: pd.DataFrame) -> str:
    """One line: how many claims were not measured and the sweeps that measure them."""
    # a claim measured on some world is not missing; claims.csv has one row per claim and world
    missing = set(claims["claim_id"]) - set(claims.loc[claims["holds"] != NOT_MEASURED, "claim_id"])
    sweeps = [c.sweep for c in CLAIMS if c.claim_id in missing]
    per_sweep = ", ".join(f"{s} ({sweeps.count(s)})" for s in dict.fromkeys(sweeps))
    return (
        f"{len(missing)} of {claims['claim_id'].nunique()} published claims not measured here: their sweeps "
        f"did not run (<code>python -m simbench +sweep=NAME</code>, all: <code>+sweep=thesis</code>): {per_sweep}. "
        "claims.csv lists them."
    )


def _study_times_section(page: _Page, run_dir: Path, summary: pd.DataFrame) -> None:
    """Wall time per study x world of a run of several studies, and the estimators' time by sweep."""
    path = run_dir / STUDY_TIMES
    if not path.is_file():
        return
    page.h2("Where the time went")
    times = pd.read_csv(path, keep_default_na=False)
    page.p(
        f"Wall time per study and world (simbench.runs.studies; total {times['wall_s'].sum() / 60:.1f} min), then "
        "the estimators' own run time summed over jobs per sweep, world and estimator (largest first; "
        "scenario generation, process start and report are in the wall times only).",
        cls="note",
    )
    page.table(times.drop(columns=["results_dir"]))
    page.table(time_budget(summary).head(20))


def _unmeasured_claims_section(page: _Page, claims: pd.DataFrame) -> None:
    page.h2("Published claims")
    page.p(_not_measured_line(claims), cls="note")


def _in_group(summary: pd.DataFrame, keys: tuple) -> np.ndarray:
    return np.logical_and.reduce([summary[k].fillna("") == (v if v == v else "") for k, v in zip(GROUP, keys)])


def _sensitivity_curves(group_stats: pd.DataFrame) -> pd.DataFrame | None:
    """Median against the a priori covariance scale, for a group that ran at least two scales."""
    # a solution scored from a file (python -m simbench score) has no estimator class and no settings
    defaults = {
        name: config_defaults(name).get("prior_scale")
        for name in group_stats["estimator"].unique()
        if name in registered()
    }
    scaled = group_stats[group_stats["estimator"].map(defaults).notna()]
    if override_value(scaled["overrides"], "prior_scale", None).notna().sum() < 2:
        return None
    scale = pd.concat(
        [override_value(rows["overrides"], "prior_scale", defaults[name]) for name, rows in scaled.groupby("estimator")]
    ).astype(float)
    curves = scaled.assign(scale=scale)
    return curves[["estimator", "scale", "horizontal_median_ref", "ci_low", "ci_high"]]


def _diagnostics_section(page: _Page, diag: dict[str, list[dict]], out: Path) -> None:
    """Each estimator's diagnostics from its first job: scalars, tables (lists of records), and the
    learned-mixture evolution and selected features where an estimator records them."""
    shown = False
    for estimator, jobs in sorted(diag.items()):
        first = jobs[0]["diagnostics"] if jobs else {}
        tables = {k: v for k, v in first.items() if isinstance(v, list) and v and isinstance(v[0], dict)}
        scalars = {k: v for k, v in first.items() if isinstance(v, (int, float, str, bool))}
        if not tables and not scalars:
            continue
        if not shown:
            page.h2("Estimator diagnostics (first job of each estimator)")
            shown = True
        job = jobs[0]["job"]
        where = f"{_job_label(job)}, seed {job.get('seed', '')}"
        page.h3(f"{estimator}: {where}")
        if scalars:
            page.table(pd.DataFrame([scalars]))
        if "model_history" in tables:  # ICE: the noise model after each adaptation (Fig. 7.3.2)
            del tables["model_history"]
            # the job that adapted most shows the most (the first one often never adapts)
            busiest = max(jobs, key=lambda j: len(j["diagnostics"].get("model_history", [])))
            history = [
                {"iteration": i, "mixture": {"weights": m["weights"], "covariances": m["covs"]}}
                for i, m in enumerate(busiest["diagnostics"]["model_history"])
            ]
            job = busiest["job"]
            page.img(
                mixture_evolution_figure(
                    history,
                    out / f"mixture_{estimator}.png",
                    f"{estimator}: noise model after each adaptation (0: a priori), {_job_label(job)}, "
                    f"seed {job.get('seed', '')}",
                    xlabel="adaptation",
                )
            )
        counts = _adaptation_counts(jobs)
        if counts is not None:
            page.p("<b>model adaptations in every job</b> (naive: one per T_c tested residuals)")
            page.table(counts)
        for key, records in tables.items():
            if any("mixture" in r for r in records):
                page.img(
                    mixture_evolution_figure(
                        records,
                        out / f"mixture_{estimator}.png",
                        f"{estimator}: learned noise mixture per iteration, {where}",
                    )
                )
            if any("selected_features" in r for r in records):
                page.p("<b>selected features per iteration</b>")
                page.table(
                    pd.DataFrame(
                        [
                            {"iteration": r.get("iteration"), "selected": ", ".join(r.get("selected_features", []))}
                            for r in records
                        ]
                    )
                )
            flat = pd.DataFrame(records)
            flat = flat[[c for c in flat.columns if not flat[c].map(lambda v: isinstance(v, (dict, list))).any()]]
            if flat.shape[1]:
                page.p(f"<b>{html.escape(key)}</b>")
                page.table(flat.head(40))


def _job_label(job: dict[str, Any]) -> str:
    """:func:`~simbench.analysis.tables.data_label` of a job's summary row (a dict)."""
    return data_label(job.get("scenario", ""), job.get("receiver", ""), job.get("source"))


def _adaptation_counts(jobs: list[dict]) -> pd.DataFrame | None:
    """Adaptation and naive counts per sweep/scenario/receiver over all jobs of an adaptive estimator."""
    rows = [
        {
            "sweep": j["job"].get("sweep", ""),
            "scenario": j["job"].get("scenario", ""),
            "receiver": j["job"].get("receiver", ""),
            "adaptations": j["diagnostics"]["n_adaptations"],
            "naive": j["diagnostics"]["naive_adaptations"],
            "outliers": j["diagnostics"].get("n_outliers", 0),
            "residuals": j["diagnostics"].get("n_residuals", 0),
        }
        for j in jobs
        if "n_adaptations" in j["diagnostics"] and "naive_adaptations" in j["diagnostics"]
    ]
    if not rows:
        return None
    table = pd.DataFrame(rows).groupby(["sweep", "scenario", "receiver"], dropna=False)
    return table.agg(
        jobs=("adaptations", "size"),
        adaptations=("adaptations", "sum"),
        naive=("naive", "sum"),
        outliers=("outliers", "sum"),
        residuals=("residuals", "sum"),
    ).reset_index()


def _validation_section(page: _Page, run_dir: Path, out: Path) -> None:
    """Sim-vs-real statistics (:mod:`simbench.analysis.validation`) of the run's cached scenarios, when the cache
    holds both a real log with a reference trajectory and a simulation; nothing otherwise."""
    dirs = cached_scenarios(run_dir)
    n_real = sum(not (d / "labels.parquet").is_file() for d in dirs)  # real logs have no error labels
    if not 0 < n_real < len(dirs):
        return
    samples = []
    for d in dirs:
        try:
            samples.append(residual_sample(Scenario.load(d)))
        except SimbenchError:
            continue  # a real log without a reference trajectory has no residuals
    if not 0 < sum(s.real for s in samples) < len(samples):
        return
    counts: dict[str, int] = {}
    for i, sample in enumerate(samples):  # two cached configs of one preset (e.g. two durations) stay apart
        counts[sample.name] = counts.get(sample.name, 0) + 1
        if counts[sample.name] > 1:
            samples[i] = replace(sample, name=f"{sample.name} #{counts[sample.name]}")
    table = comparison_table(samples)
    page.h2("Simulated worlds against real logs")
    page.p(
        "One procedure for every world (<code>simbench.analysis.validation</code>): code + satellite clock - "
        "Sagnac range to the reference - Saastamoinen/Niell - Klobuchar, minus the per-epoch, per-system median "
        "(epochs with "
        f"at least {MIN_ROWS_PER_CLOCK} satellites of the system). KS = two-sample Kolmogorov-Smirnov distance "
        "of the |residual| and "
        f"C/N0 distributions against <b>{html.escape(str(table['ks_against'].iloc[0]))}</b>. "
        "<code>python -m simbench validate</code> gives the same table for any worlds.",
        cls="note",
    )
    page.table(table.drop(columns=["ks_against"]))
    page.img(
        validation_figure(
            samples, out / "validation.png", "Sim vs real: |code residual|, C/N0 against elevation, tracked satellites"
        )
    )


class _Page:
    """Accumulates the report as HTML and Markdown side by side."""

    def __init__(self) -> None:
        self.html: list[str] = []
        self.md: list[str] = []

    def h1(self, text: str) -> None:
        self.html.append(f"<h1>{html.escape(text)}</h1>")
        self.md += [f"# {text}", ""]

    def h2(self, text: str) -> None:
        self.html.append(f"<h2>{html.escape(text)}</h2>")
        self.md += [f"## {text}", ""]

    def h3(self, text: str) -> None:
        self.html.append(f"<h3>{html.escape(text)}</h3>")
        self.md += [f"### {text}", ""]

    def p(self, text: str, cls: str = "") -> None:
        self.html.append(f"<p class='{cls}'>{text}</p>")
        self.md += [re.sub(r"<[^>]+>", "", text), ""]

    def img(self, path: Path) -> None:
        self.html.append(f"<p><img src='{path.name}' alt='{path.stem}'></p>")
        self.md += [f"![{path.stem}]({path.name})", ""]

    def table(self, df: pd.DataFrame, classes: Any = None) -> None:
        head = "".join(f"<th>{html.escape(str(c))}</th>" for c in df.columns)
        body = []
        for _, row in df.iterrows():
            cls = f" class='{classes(row)}'" if classes else ""
            cells = "".join(_cell(v) for v in row)
            body.append(f"<tr{cls}>{cells}</tr>")
        self.html.append(f"<table><tr>{head}</tr>{''.join(body)}</table>")
        shown = df.copy()
        for column in df.columns[df.isin([np.inf]).any()]:  # tabulate would print 'inf'
            shown[column] = [_text(v) for v in df[column]]
        self.md += [shown.to_markdown(index=False, floatfmt=".4g") if len(df) else "(none)", ""]

    def write(self, out: Path) -> Path:
        page = (
            f"<!doctype html><html><head><meta charset='utf-8'><title>simbench report</title>"
            f"<style>{_CSS}</style></head><body>{''.join(self.html)}</body></html>"
        )
        for name, text in (("index.html", page), ("README.md", "\n".join(self.md) + "\n")):
            write_bytes(out / name, text.encode())
        return out


def _text(value: Any) -> str:
    """A float as the report shows it: 4 significant digits, '—' for an undefined percentile (inf)."""
    return UNDEFINED if value == np.inf else "" if not np.isfinite(value) else f"{value:.4g}"


def _cell(value: Any) -> str:
    if isinstance(value, (float, np.floating)):
        return f"<td class='num'>{_text(value)}</td>"
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return f"<td class='num'>{value}</td>"
    return f"<td>{html.escape(str(value))}</td>"
