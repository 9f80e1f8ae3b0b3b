"""Build a run's aggregate, ``claims.csv`` and ``report/`` (index.html, README.md, PNG figures).

The claims table comes first: it is what a reader wants to know. Then one
section per (sweep, scenario, receiver) group with its figures, statistics
with bootstrap confidence intervals over seeds, paired comparisons and the
gap to the oracle, then run time and estimator diagnostics.
"""
from __future__ import annotations

import html
import re
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from simbench.claims import claims_table
from simbench.provenance import provenance
from simbench.report.figures import (
    box_figure,
    ecdf_figure,
    error_timeseries_figure,
    mixture_evolution_figure,
    runtime_figure,
    sensitivity_figure,
)
from simbench.store import aggregate, diagnostics
from simbench.tables import (
    CONVERGENCE_S,
    GROUP,
    convergence_statistics,
    oracle_gap,
    paired_comparisons,
    seed_statistics,
)
from simbench.variants import NO_OVERRIDES, config_defaults, is_default, override_value

#: The comparison baseline when present (the a priori L2 estimator), else the first estimator.
BASELINES = ("l2", "isam2_ppp", "ekf_ppp")
LABEL_USERS_NOTE = "uses the true error labels: an accuracy floor, not an estimator one could deploy"

_CSS = """body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;font-size:13px;margin:0.5em 0 1.5em}td,th{border:1px solid #ccc;padding:3px 6px}
th{background:#f0f0f0}td.num{text-align:right;font-variant-numeric:tabular-nums}
.holds{background:#d8f5d0}.does{background:#f8d4d0}.not{background:#eee;color:#666}img{max-width:100%}
h2{border-bottom:2px solid #ddd;padding-bottom:3px}.note{color:#555;font-size:13px}"""


def finalize(run_dir: str | Path, config: dict[str, Any] | None) -> Path:
    """Aggregate job files, write ``claims.csv`` and build ``report/``; return the report directory."""
    run_dir = Path(run_dir)
    summary, epochs = aggregate(run_dir, provenance(config or {"run_dir": str(run_dir)}))
    diag = diagnostics(run_dir)
    epochs = _ok_epochs(epochs, summary)  # figures and claims use the results the tables use
    claims = claims_table(summary, epochs, diag)
    tmp = run_dir / ".claims.csv.tmp"
    claims.to_csv(tmp, index=False)
    tmp.replace(run_dir / "claims.csv")
    return build_report(run_dir, summary, epochs, claims, diag)


def _ok_epochs(epochs: pd.DataFrame, summary: pd.DataFrame) -> pd.DataFrame:
    """Epoch rows of results whose status is ``ok`` (a diverged run is listed, not plotted)."""
    keys = ["scenario_key", "estimator", "overrides"]
    if epochs.empty or summary.empty:
        return epochs
    ok = summary.loc[summary["status"] == "ok", keys].fillna(NO_OVERRIDES).drop_duplicates()
    return epochs[pd.MultiIndex.from_frame(epochs[keys].fillna(NO_OVERRIDES)).isin(pd.MultiIndex.from_frame(ok))]


def build_report(run_dir: Path, summary: pd.DataFrame, epochs: pd.DataFrame, claims: pd.DataFrame,
                 diag: dict[str, list[dict]]) -> Path:
    out = run_dir / "report"
    out.mkdir(parents=True, exist_ok=True)
    page = _Page()
    page.h1("simbench report")
    page.p(f"Run directory <code>{html.escape(str(run_dir.resolve()))}</code>: {len(summary)} result rows, "
           f"{summary['estimator'].nunique() if len(summary) else 0} estimators, "
           f"{summary['seed'].nunique() if len(summary) else 0} seeds.")
    page.h2("Published claims")
    page.table(claims, classes=lambda r: r["holds"].split()[0])
    if summary.empty:
        return page.write(out)
    oracles = sorted(summary.loc[summary["uses_labels"].fillna(False).astype(bool), "estimator"].unique())
    if oracles:
        page.p(f"<b>{', '.join(oracles)}</b> {LABEL_USERS_NOTE}.", cls="note")
    failed = summary[summary["status"] != "ok"]
    if len(failed):
        page.h2("Jobs not ok (left out of the figures and statistics)")
        page.table(failed[["sweep", "scenario", "receiver", "seed", "estimator", "variant", "status", "message"]])
    stats = seed_statistics(summary)
    for keys, group in epochs.groupby(GROUP, dropna=False) if len(epochs) else []:
        sweep, scenario, receiver = keys
        tag = re.sub(r"[^A-Za-z0-9_-]+", "_", "_".join(str(k) for k in keys if k))
        name = f"{scenario}, {receiver} receiver" + (f" (sweep {sweep})" if sweep else "")
        page.h2(name)
        default = group[is_default(group["overrides"])]
        shown = (default if len(default) else group).copy()
        # figures mark the estimators that read truth labels, as the tables' note does
        shown["estimator"] = shown["estimator"].map(lambda e: f"{e} (truth labels)" if e in oracles else e)
        for metric, label in (("horizontal", "horizontal"), ("error_3d", "3-D")):
            page.img(ecdf_figure(shown, metric, out / f"ecdf_{metric}_{tag}.png",
                                 f"ECDF of {label} error: {name}"))
        page.img(box_figure(shown, out / f"box_{tag}.png", f"Horizontal error per estimator: {name}"))
        if shown["seed"].nunique() == 1:
            page.img(error_timeseries_figure(shown, out / f"error_time_{tag}.png", f"Horizontal error: {name}"))
        group_stats = stats[_in_group(stats, keys)]
        page.h3("Statistics over seeds (errors in m; horizontal_median is the mean of per-seed medians, "
                "95 % bootstrap CI)")
        page.table(group_stats.drop(columns=GROUP + ["overrides"]))
        early = convergence_statistics(group)
        if len(early):
            page.h3(f"Convergence: 3-D error over the first {CONVERGENCE_S / 60:.0f} minutes (mean over seeds of "
                    "each run's median, mean and max; 95 % bootstrap CI of the mean) [m]")
            page.table(early.drop(columns=["overrides"]))
        sensitivity = _sensitivity_curves(group_stats)
        if sensitivity is not None:
            page.img(sensitivity_figure(sensitivity, out / f"sensitivity_{tag}.png",
                                        f"Sensitivity to the a priori covariance: {name}"))
        present = set(summary["estimator"])
        baseline = next((b for b in BASELINES if b in present), None)
        if baseline:
            pairs = paired_comparisons(summary[_in_group(summary, keys)], baseline)
            if len(pairs):
                page.h3(f"Paired comparison with {baseline} on the same seeds (ratio of mean medians; "
                        "wins = share of seeds with a lower median)")
                page.table(pairs.drop(columns=GROUP))
        gap = oracle_gap(summary[_in_group(summary, keys)])
        if len(gap):
            page.h3("Gap to the oracle (mean per-seed median minus the oracle's) [m]")
            page.table(gap.drop(columns=GROUP))
        if group_stats["time_per_obs_s"].notna().any():
            page.img(runtime_figure(group_stats, out / f"runtime_{tag}.png", f"Run time: {name}"))
    _diagnostics_section(page, diag, out)
    return page.write(out)


def _in_group(summary: pd.DataFrame, keys: tuple) -> np.ndarray:
    return np.logical_and.reduce([summary[k].fillna("") == (v if v == v else "") for k, v in zip(GROUP, keys)])


def _sensitivity_curves(group_stats: pd.DataFrame) -> pd.DataFrame | None:
    """Median against the a priori covariance scale, for a group that ran at least two scales."""
    defaults = {name: config_defaults(name).get("prior_scale") for name in group_stats["estimator"].unique()}
    scaled = group_stats[group_stats["estimator"].map(defaults).notna()]
    if override_value(scaled["overrides"], "prior_scale", None).notna().sum() < 2:
        return None
    scale = pd.concat([override_value(rows["overrides"], "prior_scale", defaults[name])
                       for name, rows in scaled.groupby("estimator")]).astype(float)
    curves = scaled.assign(scale=scale)
    return curves[["estimator", "scale", "horizontal_median", "ci_low", "ci_high"]]


def _diagnostics_section(page: "_Page", diag: dict[str, list[dict]], out: Path) -> None:
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
        where = f"{job.get('scenario', '')}, {job.get('receiver', '')}, seed {job.get('seed', '')}"
        page.h3(f"{estimator}: {where}")
        if scalars:
            page.table(pd.DataFrame([scalars]))
        if "model_history" in tables:  # ICE: the noise model after each adaptation (Fig. 7.3.2)
            del tables["model_history"]
            # the job that adapted most shows the most (the first one often never adapts)
            busiest = max(jobs, key=lambda j: len(j["diagnostics"].get("model_history", [])))
            history = [{"iteration": i, "mixture": {"weights": m["weights"], "covariances": m["covs"]}}
                       for i, m in enumerate(busiest["diagnostics"]["model_history"])]
            job = busiest["job"]
            page.img(mixture_evolution_figure(
                history, out / f"mixture_{estimator}.png",
                f"{estimator}: noise model after each adaptation (0: a priori), {job.get('scenario', '')}, "
                f"{job.get('receiver', '')}, seed {job.get('seed', '')}", xlabel="adaptation"))
        counts = _adaptation_counts(jobs)
        if counts is not None:
            page.p("<b>model adaptations in every job</b> (naive: one per T_c tested residuals)")
            page.table(counts)
        for key, records in tables.items():
            if any("mixture" in r for r in records):
                page.img(mixture_evolution_figure(records, out / f"mixture_{estimator}.png",
                                                  f"{estimator}: learned noise mixture per iteration, {where}"))
            if any("selected_features" in r for r in records):
                page.p("<b>selected features per iteration</b>")
                page.table(pd.DataFrame([{"iteration": r.get("iteration"),
                                          "selected": ", ".join(r.get("selected_features", []))} for r in records]))
            flat = pd.DataFrame(records)
            flat = flat[[c for c in flat.columns if not flat[c].map(lambda v: isinstance(v, (dict, list))).any()]]
            if flat.shape[1]:
                page.p(f"<b>{html.escape(key)}</b>")
                page.table(flat.head(40))


def _adaptation_counts(jobs: list[dict]) -> pd.DataFrame | None:
    """Adaptation and naive counts per sweep/scenario/receiver over all jobs of an adaptive estimator."""
    rows = [{"sweep": j["job"].get("sweep", ""), "scenario": j["job"].get("scenario", ""),
             "receiver": j["job"].get("receiver", ""), "adaptations": j["diagnostics"]["n_adaptations"],
             "naive": j["diagnostics"]["naive_adaptations"], "outliers": j["diagnostics"].get("n_outliers", 0),
             "residuals": j["diagnostics"].get("n_residuals", 0)}
            for j in jobs if "n_adaptations" in j["diagnostics"] and "naive_adaptations" in j["diagnostics"]]
    if not rows:
        return None
    table = pd.DataFrame(rows).groupby(["sweep", "scenario", "receiver"], dropna=False)
    return table.agg(jobs=("adaptations", "size"), adaptations=("adaptations", "sum"), naive=("naive", "sum"),
                     outliers=("outliers", "sum"), residuals=("residuals", "sum")).reset_index()


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
        self.md += [df.to_markdown(index=False, floatfmt=".4g") if len(df) else "(none)", ""]

    def write(self, out: Path) -> Path:
        page = (f"<!doctype html><html><head><meta charset='utf-8'><title>simbench report</title>"
                f"<style>{_CSS}</style></head><body>{''.join(self.html)}</body></html>")
        for name, text in (("index.html", page), ("README.md", "\n".join(self.md) + "\n")):
            tmp = out / f".{name}.tmp"
            tmp.write_text(text)
            tmp.replace(out / name)
        return out


def _cell(value: Any) -> str:
    if isinstance(value, (float, np.floating)):
        text = "" if not np.isfinite(value) else f"{value:.4g}"
        return f"<td class='num'>{text}</td>"
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return f"<td class='num'>{value}</td>"
    return f"<td>{html.escape(str(value))}</td>"
