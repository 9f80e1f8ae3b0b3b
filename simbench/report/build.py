"""Build a run's aggregate, ``claims.csv`` and ``report/`` (index.html, README.md, figures, figures.json).

The page opens with what a reader wants first: a provenance box (what ran,
on what, with which code) and the leaderboard -- every estimator and variant
that ran, sorted by its median error, with seed CIs, availability and time
per epoch. Then the published claims the run measured (a run that measures
none names them in one line at the end instead), then one section per
(sweep, scenario, receiver) group -- a real log titled by its source, not by
the receiver preset -- with its figures: error ECDFs, box plot, the
trajectory, east/north/up error and the receiver's signal against time, the
covariance consistency where estimators give covariances, and run time. The
detailed tables (statistics over seeds, paired comparisons, gap to the
oracle) and the estimator diagnostics are collapsed (``<details>``).

Nothing is dropped: every estimator variant that ran is in every figure and
table, named by :func:`simbench.analysis.variants.display_names`. "Median" is
one number everywhere, legends included: the mean over seeds of each seed's
median over its reference epochs (:func:`simbench.analysis.tables.seed_statistics`).
Every statistic is read with the availability beside it; distributions and
percentiles are over all reference epochs (an unsolved epoch counts as missed,
:mod:`simbench.analysis.metrics`), and a percentile the availability does not reach is
shown as '—'. A blank cell is printed as ``n/a`` with the reason under its table.
"""

from __future__ import annotations

import html
import json
import re
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, cast

import numpy as np
import pandas as pd
from PIL import Image

from simbench.analysis.claims import CLAIMS, NOT_MEASURED, NOT_RUN, claims_by_world, claims_table
from simbench.analysis.tables import (
    CONVERGENCE_S,
    GROUP,
    WILCOXON_MIN_SEEDS,
    convergence_statistics,
    data_label,
    data_source,
    drive_comparison,
    epoch_intervals,
    oracle_gap,
    paired_comparisons,
    seed_statistics,
    with_rmse,
    with_variant_columns,
)
from simbench.analysis.validation import MIN_ROWS_PER_CLOCK, comparison_table, residual_sample
from simbench.analysis.variants import NO_OVERRIDES, display_names
from simbench.contract import Scenario, read_parquet_metadata, write_bytes
from simbench.errors import SimbenchError, warn
from simbench.gnss.navigation import UNREAD_SYSTEM_NAMES
from simbench.report.figures import (
    LABELS_MARK,
    PNG_DPI,
    FigureFile,
    Format,
    mixture_evolution_figure,
    validation_figure,
)
from simbench.report.group_figures import MIN_PARALLEL_GROUPS, GroupDrawing, GroupInputs
from simbench.report.leaderboard import leaderboards, ranked, to_csv, to_latex
from simbench.report.stale import check_report_dir, mark_stale, old_page
from simbench.report.style import UNDEFINED, sig3, use_style
from simbench.runs.checks import check_report_formats, check_report_style
from simbench.runs.files import os_fault, read_csv_table
from simbench.runs.provenance import provenance
from simbench.runs.runner import SUMMARY_COLUMNS
from simbench.runs.solutions import write_solutions
from simbench.runs.store import aggregate, cached_scenarios, diagnostics, intact_jobs, job_stems
from simbench.runs.studies import read_study_times, time_budget
from simbench.runs.zero_baseline import COLUMNS as ZERO_BASELINE_COLUMNS
from simbench.runs.zero_baseline import TABLE_NAME as ZERO_BASELINE_TABLE
from simbench.source_registry import SIMULATED

#: The comparison baseline when present (the a priori L2 estimator), else the first estimator.
BASELINES = ("l2", "isam2_ppp", "ekf_ppp")
LABEL_USERS_NOTE = "uses the true error labels: an accuracy floor, not an estimator one could deploy"
#: What a blank (NaN) cell shows; the reason is printed under its table.
BLANK = "n/a"
#: Why a column's cell can be blank, for the note under a table.
BLANK_REASONS: dict[str, str] = {
    "ci_low": "no bootstrap CI: fewer than 3 seeds, no spread between seeds, or an undefined (—) value",
    "ci_high": "as ci_low",
    "wilcoxon_p": f"no signed-rank test: fewer than {WILCOXON_MIN_SEEDS} seeds, or no difference on any seed",
    "measured": "not measured: the claim's sweep did not run here",
    "time_per_obs_s": "no run time: a solution scored from a file",
    "update_median_s": "no update times: a solution scored from a file",
    "ratio": "the published number is not defined for this drive",
}
#: Median definition, printed once under the leaderboard and used by every legend.
MEDIAN_DEFINITION = (
    "median = mean over seeds of each seed's median over its reference epochs (epochs with truth; an "
    "unsolved epoch counts as an infinite error), the same number in every legend; p95 likewise. "
    f"{UNDEFINED} = the availability is below the percentile (below 50 % for a median, 95 % for p95)."
)

_CSS = """body{font-family:system-ui,sans-serif;max-width:1180px;margin:1.5em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;font-size:13px;margin:0.5em 0 1em}td,th{border:1px solid #ccc;padding:3px 6px}
th{background:#f0f0f0;vertical-align:bottom}td.num{text-align:right;font-variant-numeric:tabular-nums}
td small{color:#666}.holds{background:#d8f5d0}.does{background:#f8d4d0}.inconclusive{background:#fbf0c8}
.not{background:#eee;color:#666}img{max-width:100%;height:auto}figure{margin:1em 0}
figcaption{font-size:13px;color:#333}.scroll{overflow-x:auto;max-width:100%}
h2{border-bottom:2px solid #ddd;padding-bottom:3px}.note{color:#555;font-size:13px}
.provenance{display:grid;grid-template-columns:max-content 1fr;gap:1px 12px;background:#f6f8fa;
border:1px solid #ddd;padding:0.5em 1em;font-size:13px}.provenance dt{font-weight:600}.provenance dd{margin:0}
details{margin:0.8em 0}.toc{font-size:13px;margin:0.8em 0}.toc ol{columns:3;margin:0.3em 0}
tr.apart td{border-top:2px solid #888}
summary{cursor:pointer;font-weight:600}"""


def finalize(
    run_dir: str | Path,
    config: dict[str, Any] | None,
    formats: Sequence[Format] | None = None,
    figures: bool = True,
    style: str | None = None,
) -> Path:
    """Aggregate job files, write ``claims.csv`` and build ``report/``; return the report directory.

    Parameters
    ----------
    run_dir : path-like
        The run folder.
    config : dict, optional
        The run's resolved config (None: a rebuild; the page reads what it shows from the job files).
    formats : sequence of str, optional
        Figure formats; None: ``config['report']['formats']``, else PNG only.
    figures : bool
        False: the tables, claims and page without drawing a figure (most of the build time), e.g.
        to check a store; the page says so.
    style : str, optional
        The figures' size preset (:data:`~simbench.report.style.PRESETS`); None: ``config['report']['style']``,
        else ``screen``.

    Raises
    ------
    SimbenchError
        For a figure format not in :data:`~simbench.runs.checks.REPORT_FORMATS`, before any file is written
        (:func:`~simbench.runs.checks.check_report_formats`; a run checks it before its first job); a run
        folder or report folder that cannot be written (:func:`~simbench.report.stale.check_report_dir`),
        also before; a damaged ``study_times.csv``; a fault of the machine while writing (a full disk),
        naming the path. An old page that is not replaced is marked stale (:mod:`simbench.report.stale`).
    """
    start = time.perf_counter()
    if formats is None:
        formats = cast(Sequence[Format], ((config or {}).get("report") or {}).get("formats") or ("png",))
    check_report_formats(formats)
    style = style or ((config or {}).get("report") or {}).get("style") or "screen"
    check_report_style(style)
    run_dir = Path(run_dir)
    out = run_dir / "report"
    check_report_dir(out, run_dir)
    mark_stale(out, run_dir)  # a killed or failed rebuild leaves it marked; the new page replaces it
    try:
        return _finalize(run_dir, config, formats, figures, start, style)
    except OSError as exc:  # a full disk, a folder made read-only meanwhile: one line naming the path
        raise os_fault(exc, out, note=old_page(out, run_dir)) from None


def _finalize(
    run_dir: Path,
    config: dict[str, Any] | None,
    formats: Sequence[Format],
    figures: bool,
    start: float,
    style: str = "screen",
) -> Path:
    """:func:`finalize` once its folders are checked."""
    # the drawing workers import while this process verifies and reads the store. A group's jobs are in
    # one scenario folder per seed or more (jobs/<scenario key>/), so fewer folders than
    # MIN_PARALLEL_GROUPS cannot make enough groups to be worth the workers (a smoke sweep: 72 jobs, 4 folders)
    folders = {stem.parent for stem in job_stems(run_dir)}
    with GroupDrawing(parallel=figures and len(folders) >= MIN_PARALLEL_GROUPS) as drawing:
        jobs = intact_jobs(run_dir)  # verified once for the tables and the diagnostics
        summary, epochs = aggregate(run_dir, provenance(config or {"run_dir": str(run_dir)}), jobs)
        # results written before a column existed (e.g. source) are shown with it empty
        summary = summary.reindex(columns=list(dict.fromkeys([*SUMMARY_COLUMNS, *summary.columns])))
        diag = diagnostics(run_dir, jobs)
        epochs = _ok_epochs(epochs, summary)  # figures and claims use the results the tables use
        write_solutions(run_dir, summary, epochs)  # .pos and TUM for rtkplot, evo and simbench score
        # the report selects and groups the epoch rows many times: its labels as categories are an integer
        # take each, not an Arrow string take (about 8 s of a 5-world thesis report)
        text = epochs.select_dtypes(include=["string", "object"]).columns
        epochs = epochs.astype(dict.fromkeys(text, "category"))

        def claims() -> pd.DataFrame:
            table = claims_table(summary, epochs, diag)
            write_bytes(run_dir / "claims.csv", table.to_csv(index=False).encode())
            return table

        return build_report(
            run_dir,
            summary,
            epochs,
            claims,
            diag,
            formats=formats,
            started=start,
            figures=figures,
            drawing=drawing,
            style=style,
        )


def _ok_epochs(epochs: pd.DataFrame, summary: pd.DataFrame) -> pd.DataFrame:
    """Epoch rows of results whose status is ``ok`` (a diverged run is listed, not plotted)."""
    keys = ["scenario_key", "estimator", "overrides"]
    if epochs.empty or summary.empty:
        return epochs
    ok = summary.loc[summary["status"] == "ok", keys].fillna(NO_OVERRIDES).drop_duplicates()
    return epochs[pd.MultiIndex.from_frame(epochs[keys].fillna(NO_OVERRIDES)).isin(pd.MultiIndex.from_frame(ok))]


def _named(frame: pd.DataFrame, names: Mapping[tuple[str, str, str], str]) -> pd.DataFrame:
    """``frame`` with ``name``: its variant's display name (:func:`variant_names`)."""
    if frame.empty:
        return frame.assign(name=pd.Series(dtype=object))
    keys = with_variant_columns(frame)[["estimator", "gnss_model", "overrides"]].astype(str)
    # looked up once per distinct variant: the epoch table has a row per epoch (millions in a thesis run)
    codes, variants = pd.MultiIndex.from_frame(keys).factorize()
    return frame.assign(name=np.array([names[k] for k in variants], dtype=object)[codes])


def variant_names(summary: pd.DataFrame, oracles: Sequence[str]) -> dict[tuple[str, str, str], str]:
    """(estimator, gnss_model, overrides) -> display name for every variant of the run.

    Names come from :func:`~simbench.analysis.variants.display_names` over the whole run, so a
    variant has one name in every group; an estimator that reads truth labels is marked with
    :data:`~simbench.report.figures.LABELS_MARK`.
    """
    keys = with_variant_columns(summary)[["estimator", "gnss_model", "overrides"]].astype(str).drop_duplicates()
    names = display_names(keys)
    marked = [n + LABELS_MARK if e in oracles else n for n, e in zip(names, keys["estimator"])]
    return dict(zip(keys.itertuples(index=False, name=None), marked))


def build_report(
    run_dir: Path,
    summary: pd.DataFrame,
    epochs: pd.DataFrame,
    claims: pd.DataFrame | Callable[[], pd.DataFrame],
    diag: dict[str, list[dict]],
    formats: Sequence[Format] = ("png",),
    started: float | None = None,
    figures: bool = True,
    drawing: GroupDrawing | None = None,
    style: str = "screen",
) -> Path:
    """Write ``report/`` of a run from its tables; return the directory.

    Parameters
    ----------
    run_dir : Path
    summary, epochs : pandas.DataFrame
        The run's aggregate (:data:`~simbench.runs.runner.SUMMARY_COLUMNS`) and its ok epochs.
    claims : pandas.DataFrame or callable
        ``claims.csv``'s table, or a call that computes (and writes) it: called once the figures
        are being drawn, so the two overlap.
    diag : dict
        Diagnostics by estimator (:func:`simbench.runs.store.diagnostics`).
    formats : sequence of str
        Figure formats beside the PNG the page shows, e.g. ``("png", "pdf")``.
    started : float, optional
        ``time.perf_counter()`` when the build began (the page gives the build time).
    figures : bool
        False: no figure is drawn (the page says so).
    drawing : GroupDrawing, optional
        Where the groups' figures are drawn (:class:`~simbench.report.group_figures.GroupDrawing`,
        open for this call); None: in this process.
    style : str
        The figures' size preset (:data:`~simbench.report.style.PRESETS`).
    """
    started = time.perf_counter() if started is None else started
    out = run_dir / "report"
    out.mkdir(parents=True, exist_ok=True)
    page = _Page(formats, draw=figures)
    page.h1("simbench report")
    if not figures:
        page.p("Built without figures (<code>figures=False</code>): tables and claims only.", cls="note")
    oracles = sorted(summary.loc[summary["uses_labels"].fillna(False).astype(bool), "estimator"].unique())
    names = variant_names(summary, oracles)
    summary = _named(summary, names)
    epochs = _named(epochs, names)
    scenarios = {d.name: d for d in cached_scenarios(run_dir)}
    summary = with_rmse(summary, epochs)
    stats = _named(seed_statistics(summary), names) if len(summary) else pd.DataFrame()
    if len(stats):
        stats = epoch_intervals(stats, summary, epochs, _reference_epoch_indices(scenarios, summary))
    grouped = epochs.groupby(GROUP, dropna=False) if len(epochs) else []
    groups = [_group_inputs(keys, group, summary, stats) for keys, group in grouped]
    drawn = (drawing or GroupDrawing(parallel=False)).start(
        groups, out, page.formats, scenarios, draw=page.draw, style=style
    )
    claims = claims() if callable(claims) else claims
    _provenance_box(page, run_dir, summary, scenarios)
    page.contents()
    if len(stats):
        _leaderboard_section(page, out, summary, stats, oracles)
    _claims_section(page, claims)
    if summary.empty:
        return page.write(out, started)
    _jobs_not_ok_section(page, summary)
    _drives_section(page, summary)
    _zero_baseline_section(page, run_dir)
    # what follows each group's figures is written while the workers draw them
    tables = [page.part() for _ in groups]
    for part, inputs in zip(tables, groups):
        _group_tables(part, inputs.name, inputs.group, inputs.in_group, summary, inputs.group_stats)
    tail = page.part()
    _study_times_section(tail, run_dir, summary)
    with use_style(style):
        _validation_section(tail, run_dir, out, list(scenarios.values()))
        _diagnostics_section(tail, diag, out)
    for inputs, items, part in zip(groups, drawn(), tables):
        page.h2(inputs.name)
        for item in items:
            if isinstance(item, FigureFile):
                page.figure(item)
            else:
                page.p(*item)
        page.extend(part)
    page.extend(tail)
    return page.write(out, started)


def _claims_section(page: _Page, claims: pd.DataFrame) -> None:
    """The published claims measured in the run, one column per world where there are several."""
    measured = claims["holds"] != NOT_MEASURED
    if measured.any():
        page.h2("Published claims")
        page.p(
            "published = the paper's number (or why it gives none), rule = what our measured value must meet. "
            "Verdicts: holds, does not hold, or inconclusive when the 95 % CI over seeds straddles the "
            "rule's threshold; a pass that says nothing (e.g. no adaptation at all) is marked vacuous.",
            cls="note",
        )
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


def _jobs_not_ok_section(page: _Page, summary: pd.DataFrame) -> None:
    """The jobs that did not end ``ok``, with their messages."""
    failed = summary[summary["status"] != "ok"]
    if len(failed):
        page.h2("Jobs not ok (left out of the figures and statistics)")
        page.table(
            failed.assign(data=_labels(failed))[["sweep", "data", "seed", "name", "status", "message"]].rename(
                columns={"name": "estimator"}
            )
        )


def _drives_section(page: _Page, summary: pd.DataFrame) -> None:
    """Our medians on the Morgantown drives beside the dissertation's, where the run has them."""
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


def _zero_baseline_section(page: _Page, run_dir: Path) -> None:
    """The run folder's zero-baseline table (``simbench zero-baseline``), where there is one."""
    zero = _zero_baseline(run_dir)
    if zero is not None:
        page.h2("Zero-baseline test: each preset's single-point solution against the geodetic receiver's")
        page.p(
            "Same scenario and seed for every receiver preset (identical sky, street and NLOS), code-only "
            "single-point fixes; mean and median 3-D difference from the geodetic fix over the epochs both "
            "fixed [m], beside the dissertation's Table 5.3.2 for the drive the scenario replays.",
            cls="note",
        )
        page.table(zero)


def _zero_baseline(run_dir: Path) -> pd.DataFrame | None:
    """The run folder's zero-baseline table; None, with a one-line warning naming it when it is damaged."""
    path = run_dir / ZERO_BASELINE_TABLE
    if not path.exists():
        return None
    try:
        return read_csv_table(path, ZERO_BASELINE_COLUMNS, "", numbers=("mean_3d_diff_m",))
    except SimbenchError as exc:
        warn(exc.field, exc.problem, "left out of the report; rerun python -m simbench zero-baseline to rebuild it")
        return None


def _group_inputs(keys: tuple, group: pd.DataFrame, summary: pd.DataFrame, stats: pd.DataFrame) -> GroupInputs:
    sweep, scenario, receiver = keys
    in_group = summary[_in_group(summary, keys)]
    source = in_group["source"].iloc[0]
    name = data_label(scenario, receiver, source) + (f" (sweep {sweep})" if sweep else "")
    # file names too say what the data are: the source of a real log, the receiver of a simulation
    kind = receiver if data_source(source) == SIMULATED else data_source(source)
    tag = re.sub(r"[^A-Za-z0-9_-]+", "_", "_".join(str(k) for k in (sweep, scenario, kind) if k))
    return GroupInputs(
        name,
        tag,
        group,
        group.assign(estimator=group["name"]),
        in_group,
        _reference_epochs(in_group, group),
        stats[_in_group(stats, keys)],
    )


def _group_tables(
    page: _Page,
    name: str,
    group: pd.DataFrame,
    in_group: pd.DataFrame,
    summary: pd.DataFrame,
    group_stats: pd.DataFrame,
) -> None:
    """A group's detailed tables, collapsed: statistics over seeds, convergence, paired comparisons, oracle gap."""
    page.details_open(f"Statistics over seeds, paired comparisons and gap to the oracle: {name}")
    page.h3("Statistics over seeds beyond the leaderboard (errors in m)")
    page.p(
        "In leaderboard order; what the leaderboard does not show: failed seeds, the median and maximum over "
        "the solved epochs only (mean over seeds; read them with the leaderboard's availability) and the "
        "two other timings.",
        cls="note",
    )
    page.table(ranked(group_stats)[list(DETAIL_COLUMNS)].rename(columns={"name": "estimator"}))
    early = convergence_statistics(group)
    if len(early):
        page.h3(
            f"Convergence: 3-D error over the first {CONVERGENCE_S / 60:.0f} minutes (mean over seeds of "
            "each run's median, mean and max; 95 % bootstrap CI of the mean) [m]"
        )
        page.table(early.drop(columns=["overrides"]))
    present = set(summary["estimator"])
    baseline = next((b for b in BASELINES if b in present), None)
    if baseline:
        pairs = paired_comparisons(in_group, baseline)
        if len(pairs):
            page.h3(
                f"Paired comparison with {baseline} on the same seeds (ratio of mean medians over the "
                "solved epochs; wins = share of seeds with a lower median; read with both availabilities)"
            )
            page.table(pairs.drop(columns=GROUP))
    gap = oracle_gap(in_group)
    if len(gap):
        page.h3(
            "Gap to the oracle (mean per-seed median over the solved epochs minus the oracle's, with "
            "both availabilities) [m]"
        )
        page.table(gap.drop(columns=GROUP))
    page.details_close()


def _provenance_box(page: _Page, run_dir: Path, summary: pd.DataFrame, scenarios: Mapping[str, Path]) -> None:
    """What ran on what with which code: the first thing on the page."""
    job_meta = _first_job_metadata(run_dir)
    config = job_meta.get("simbench.config") or {}
    rows: dict[str, str] = {"run directory": f"<code>{html.escape(str(run_dir.resolve()))}</code>"}
    if len(summary):
        simulated = summary["source"].fillna(SIMULATED).astype(str) == SIMULATED
        rows["scenarios"] = ", ".join(sorted(map(str, summary["scenario"].dropna().unique())))
        rows["sources"] = ", ".join(sorted(map(str, summary["source"].fillna(SIMULATED).unique())))
        receivers = sorted(map(str, summary.loc[simulated, "receiver"].dropna().unique()))
        if receivers:
            rows["receiver (simulated data only)"] = ", ".join(receivers)
        durations = sorted({_duration(d) for key, d in scenarios.items() if key in set(summary["scenario_key"])})
        shown = [f"{sig3(d)} s" for d in durations if np.isfinite(d)]
        if shown:
            rows["duration"] = ", ".join(shown)
        models = sorted(str(m) for m in summary["gnss_model"].dropna().unique() if str(m))
        rows["gnss_model"] = ", ".join(models) or "n/a (results from before the column)"
        variants = with_variant_columns(summary)
        explicit = variants.loc[variants["overrides"] != NO_OVERRIDES, ["name", "overrides"]].drop_duplicates()
        rows["overrides"] = (
            "; ".join(f"{html.escape(n)}: <code>{html.escape(o)}</code>" for n, o in explicit.itertuples(index=False))
            or "none (every estimator at its gnss_model preset's defaults)"
        )
        seeds = sorted(int(s) for s in summary["seed"].dropna().unique())
        rows["seeds"] = f"{len(seeds)} ({_ranges(seeds)})"
        rows["estimators"] = f"{summary['name'].nunique()} variants of {summary['estimator'].nunique()} estimators"
        rows["estimator time"] = f"{sig3(summary['total_s'].sum())} s (sum over jobs of the estimators' own run time)"
        times = read_study_times(run_dir)
        if times is not None:
            rows["wall time"] = f"{sig3(pd.to_numeric(times['wall_s']).sum())} s (all studies)"
    notes = [_system_notes(d) for key, d in scenarios.items() if key in set(summary.get("scenario_key", []))]
    for text in dict.fromkeys(n for n in notes if n):
        rows.setdefault("GNSS systems", "")
        rows["GNSS systems"] += ("<br>" if rows["GNSS systems"] else "") + text
    rows["git SHA"] = f"<code>{html.escape(str(job_meta.get('simbench.git_sha', 'unknown')))}</code>"
    versions = job_meta.get("simbench.versions") or {}
    rows["package versions"] = ", ".join(f"{html.escape(k)} {html.escape(str(v))}" for k, v in versions.items())
    rows["results written"] = html.escape(str(job_meta.get("simbench.created", "unknown")))
    rows["report built"] = datetime.now(timezone.utc).isoformat(timespec="seconds")
    if config.get("seed") is not None and not len(summary):
        rows["seeds"] = str(config["seed"])
    page.provenance(rows)


def _first_job_metadata(run_dir: Path) -> dict[str, Any]:
    """The provenance metadata of the run's first readable job file (code and versions of its results)."""
    for stem in job_stems(run_dir):
        try:
            return read_parquet_metadata(stem.with_suffix(".summary.parquet"))
        except (OSError, ValueError):  # damaged: aggregate() warned about it and left it out already
            continue
    return {}


def _scenario_meta(cache: Path) -> dict[str, Any]:
    """``Scenario.meta`` of a cached scenario, read from its Parquet metadata alone (no table)."""
    stored = read_parquet_metadata(cache / "observations.parquet").get("simbench.scenario") or {}
    return cast(dict[str, Any], stored.get("meta") or {})


def _duration(cache: Path) -> float:
    """The scenario's span of reference epochs [s] (first to last, plus one interval); NaN without any."""
    t = pd.read_parquet(cache / "truth.parquet", columns=["t"])["t"].to_numpy(float)
    if t.size == 0:
        return np.nan
    step = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    return float(t.max() - t.min() + step)


def _system_notes(cache: Path) -> str:
    """The systems a real log was asked for and used, and why any was left out (``''`` when the meta has none)."""
    meta = _scenario_meta(cache)
    if not any(k in meta for k in ("systems_asked", "systems_used", "system_notes")):
        return ""
    parts = [f"{meta.get('name', cache.name)}: asked {meta.get('systems_asked', 'n/a')}"]
    parts.append(f"used {meta.get('systems_used', 'n/a')}")
    parts += [str(n) for n in meta.get("system_notes") or []]
    unread = meta.get("unread_systems") or {}
    if unread:
        names = ", ".join(f"{UNREAD_SYSTEM_NAMES.get(s, s)} ({n} satellite lines)" for s, n in unread.items())
        parts.append(f"not read (no model for them): {names}")
    return html.escape("; ".join(str(p) for p in parts))


def _ranges(values: Sequence[int]) -> str:
    """``0-4, 7, 9-10`` for sorted integers."""
    out: list[str] = []
    for v in values:
        if out and out[-1].split("-")[-1] == str(v - 1):
            out[-1] = f"{out[-1].split('-')[0]}-{v}"
        else:
            out.append(str(v))
    return ", ".join(out)


#: Columns of the collapsed statistics table: what the leaderboard does not show.
DETAIL_COLUMNS = (
    "name",
    "gnss_model",
    "n_failed",
    "horizontal_median_solved",
    "horizontal_max",
    "time_per_obs_s",
    "update_median_s",
)
#: CSS pixels per inch: a figure is shown at the size it was drawn for.
CSS_DPI = 96
#: Files the leaderboard is exported to, beside index.html (:mod:`simbench.report.leaderboard`).
LEADERBOARD_FILES = ("leaderboard.csv", "leaderboard.tex")


def _leaderboard_section(
    page: _Page, out: Path, summary: pd.DataFrame, stats: pd.DataFrame, oracles: Sequence[str]
) -> None:
    """The leaderboard of every group, and its export as CSV and LaTeX (booktabs) beside the page."""
    page.h2("Leaderboard", anchor="leaderboard")
    boards = leaderboards(summary, stats)
    for title, table in boards:
        if len(boards) > 1:
            page.h3(title)
        page.leaderboard(table)
    over = set(stats.get("ci_over", pd.Series(dtype=str)))
    intervals = " ".join(
        text
        for kind, text in (
            ("seeds", "[low, high] = 95 % bootstrap CI over seeds (3 or more seeds)."),
            ("epochs", EPOCH_CI_NOTE),
        )
        if kind in over
    )
    note = (
        f"{MEDIAN_DEFINITION} {intervals} RMSE = root mean square over the solved epochs only (it cannot count "
        "an unsolved epoch: read it with the availability), mean over seeds. Sorted by horizontal median; "
        "availability = solved / reference epochs; time per epoch = the estimator's run time over its "
        "reference epochs (a batch estimator's total spread over them)."
        + (f" {', '.join(oracles)} ({LABELS_MARK}, below the rule, not ranked) {LABEL_USERS_NOTE}." if oracles else "")
    )
    page.p(note + " Also as " + ", ".join(f"<a href='{f}'>{f}</a>" for f in LEADERBOARD_FILES) + ".", cls="note")
    write_bytes(out / LEADERBOARD_FILES[0], to_csv(boards).encode())
    write_bytes(out / LEADERBOARD_FILES[1], to_latex(boards, re.sub(r"<[^>]+>", "", note)).encode())


#: How a single run's intervals are made, under the leaderboard.
EPOCH_CI_NOTE = (
    "With one seed, [low, high] = 95 % circular block bootstrap over the run's reference epochs (blocks as long as "
    "the errors' autocorrelation time, simbench.analysis.metrics.block_bootstrap): the spread of this run's "
    "epochs, not of other seeds."
)


def _reference_epoch_indices(scenarios: Mapping[str, Path], summary: pd.DataFrame) -> dict[str, np.ndarray]:
    """Scenario key to its reference epochs (epochs with truth) in time order, for the cached scenarios
    that ran one seed of some estimator (where the intervals come from epochs)."""
    keys = set(summary["scenario_key"].dropna().astype(str)) & set(scenarios)
    return {
        key: pd.read_parquet(scenarios[key] / "truth.parquet", columns=["epoch"])["epoch"].to_numpy()
        for key in sorted(keys)
    }


def _labels(summary: pd.DataFrame) -> pd.Series:
    """:func:`~simbench.analysis.tables.data_label` of each row."""
    return pd.Series(
        [data_label(sc, rx, src) for sc, rx, src in zip(summary["scenario"], summary["receiver"], summary["source"])],
        index=summary.index,
        dtype=object,
    )


def _reference_epochs(summary: pd.DataFrame, epochs: pd.DataFrame) -> dict[str, int]:
    """Per variant name: the reference epochs (summed ``n_epochs``) of the ok jobs whose epochs are in ``epochs``."""
    keys = ["scenario_key", "estimator", "gnss_model", "overrides"]
    jobs = with_variant_columns(epochs)[keys].drop_duplicates()
    rows = with_variant_columns(summary[summary["status"] == "ok"]).merge(jobs, on=keys)
    return {str(name): int(n) for name, n in rows.groupby("name")["n_epochs"].sum().items()}


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
    times = read_study_times(run_dir)
    if times is None:
        return
    page.h2("Where the time went")
    page.p(
        f"Wall time per study and world (simbench.runs.studies; total {times['wall_s'].sum() / 60:.1f} min), then "
        "the estimators' own run time summed over jobs per sweep, world and estimator (largest first; "
        "scenario generation, process start and report are in the wall times only).",
        cls="note",
    )
    page.table(times.drop(columns=["results_dir"], errors="ignore"))
    page.table(time_budget(summary).head(20))


def _in_group(summary: pd.DataFrame, keys: tuple) -> np.ndarray:
    return np.logical_and.reduce([summary[k].fillna("") == (v if v == v else "") for k, v in zip(GROUP, keys)])


def _diagnostics_section(page: _Page, diag: dict[str, list[dict]], out: Path) -> None:
    """Each estimator's diagnostics from its first job, collapsed: scalars, tables (lists of records), and
    the learned-mixture evolution and selected features where an estimator records them."""
    _diagnostics_body(
        page, diag, out, lambda: page.details_open("Estimator diagnostics (first job of each estimator)", level=2)
    )
    if page.open_details:
        page.details_close()


def _diagnostics_body(page: _Page, diag: dict[str, list[dict]], out: Path, begin: Callable[[], None]) -> None:
    """:func:`_diagnostics_section`'s content; ``begin()`` opens the section before the first estimator's."""
    shown = False
    for estimator, jobs in sorted(diag.items()):
        first = jobs[0]["diagnostics"] if jobs else {}
        tables = {k: v for k, v in first.items() if isinstance(v, list) and v and isinstance(v[0], dict)}
        scalars = {k: v for k, v in first.items() if isinstance(v, (int, float, str, bool))}
        if not tables and not scalars:
            continue
        if not shown:
            begin()
            shown = True
        job = jobs[0]["job"]
        where = f"{_job_label(job)}, seed {job.get('seed', '')}"
        page.h3(f"{estimator}: {where}")
        if scalars:
            page.table(pd.DataFrame([scalars]))
        # ICE: the noise model after each adaptation (Fig. 7.3.2), a figure rather than a table
        if tables.pop("model_history", None) is not None and page.draw:
            # the job that adapted most shows the most (the first one often never adapts)
            busiest = max(jobs, key=lambda j: len(j["diagnostics"].get("model_history", [])))
            history = [
                {"iteration": i, "mixture": {"weights": m["weights"], "covariances": m["covs"]}}
                for i, m in enumerate(busiest["diagnostics"]["model_history"])
            ]
            job = busiest["job"]
            page.figure(
                mixture_evolution_figure(
                    history,
                    out / f"mixture_{estimator}.png",
                    f"{estimator}: noise model after each adaptation (0: a priori), {_job_label(job)}, "
                    f"seed {job.get('seed', '')}",
                    xlabel="adaptation",
                    formats=page.formats,
                )
            )
        counts = _adaptation_counts(jobs)
        if counts is not None:
            page.p("<b>model adaptations in every job</b> (naive: one per T_c tested residuals)")
            page.table(counts)
        for key, records in tables.items():
            if page.draw and any("mixture" in r for r in records):
                page.figure(
                    mixture_evolution_figure(
                        records,
                        out / f"mixture_{estimator}.png",
                        f"{estimator}: learned noise mixture per iteration, {where}",
                        formats=page.formats,
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


def _validation_section(page: _Page, run_dir: Path, out: Path, dirs: list[Path]) -> None:
    """Sim-vs-real statistics (:mod:`simbench.analysis.validation`) of the run's cached scenarios ``dirs``, when
    they hold both a real log with a reference trajectory and a simulation; nothing otherwise."""
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
    if not page.draw:
        return
    page.figure(
        validation_figure(
            samples,
            out / "validation.png",
            "Sim vs real: |code residual|, C/N0 against elevation, tracked satellites",
            formats=page.formats,
        )
    )


class _Page:
    """Accumulates the report as HTML and Markdown side by side, and the figures it shows."""

    def __init__(self, formats: Sequence[Format] = ("png",), draw: bool = True) -> None:
        self.draw = draw  #: False: figures are left out (build_report's ``figures``)
        self.html: list[str] = []
        self.md: list[str] = []
        self.formats: tuple[Format, ...] = tuple(dict.fromkeys(("png", *formats)))
        self.figures: list[FigureFile] = []
        self.open_details = 0
        self.sections: list[tuple[str, str]] = []  #: (title, anchor) of each h2, for the contents
        self.contents_at: int | None = None  #: where the contents go in :attr:`html`

    def part(self) -> _Page:
        """An empty page with this one's formats, for a section written ahead of its place (:meth:`extend`)."""
        return _Page(self.formats, draw=self.draw)

    def extend(self, part: _Page) -> None:
        """Append what ``part`` (from :meth:`part`) holds; its ``<details>`` must be closed."""
        if part.open_details:
            raise ValueError("a page part ends inside <details>")
        self.html += part.html
        self.md += part.md
        self.figures += part.figures
        self.sections += part.sections

    @property
    def fmt(self) -> dict[str, Any]:
        """``formats=`` keyword of the figure functions."""
        return {"formats": self.formats}

    def h1(self, text: str) -> None:
        self.html.append(f"<h1>{html.escape(text)}</h1>")
        self.md += [f"# {text}", ""]

    def h2(self, text: str, anchor: str = "") -> None:
        """A section heading; it is listed in the contents (:meth:`contents`) under ``anchor`` (default: a slug)."""
        anchor = anchor or re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")
        taken = {a for _, a in self.sections}
        anchor = next(a for a in (anchor, *(f"{anchor}-{k}" for k in range(2, 1000))) if a not in taken)
        self.sections.append((text, anchor))
        self.html.append(f"<h2 id='{anchor}'>{html.escape(text)}</h2>")
        self.md += [f"## {text}", ""]

    def contents(self) -> None:
        """Mark where the table of contents goes: it lists every h2 of the finished page (:meth:`write`)."""
        self.contents_at = len(self.html)

    def h3(self, text: str) -> None:
        self.html.append(f"<h3>{html.escape(text)}</h3>")
        self.md += [f"### {text}", ""]

    def p(self, text: str, cls: str = "") -> None:
        self.html.append(f"<p class='{cls}'>{text}</p>")
        self.md += [re.sub(r"<[^>]+>", "", text), ""]

    def details_open(self, summary: str, level: int = 3) -> None:
        """Start a collapsed part (``<details>``); Markdown gets a heading instead."""
        self.open_details += 1
        anchor = ""
        if level == 2:  # a top-level part: listed in the contents like a section
            anchor = re.sub(r"[^a-z0-9]+", "-", summary.lower()).strip("-")
            self.sections.append((summary, anchor))
            anchor = f" id='{anchor}'"
        self.html.append(f"<details{anchor}><summary>{html.escape(summary)}</summary>")
        self.md += [f"{'#' * level} {summary}", ""]

    def details_close(self) -> None:
        self.open_details -= 1
        self.html.append("</details>")

    def figure(self, figure: FigureFile) -> None:
        """The PNG with its caption (the title, not drawn in the image) and links to the other formats."""
        self.figures.append(figure)
        png = figure.path.name
        links = " ".join(f"<a href='{f.name}'>{f.suffix[1:].upper()}</a>" for f in figure.files[1:])
        caption = html.escape(figure.title) + (f" ({links})" if links else "")
        # shown at its size in inches (CSS pixels are 1/96 in), not stretched to the page: a 300 dpi PNG
        # has three times the pixels it needs on a screen
        with Image.open(figure.path) as image:
            width = round(image.size[0] * CSS_DPI / PNG_DPI)
        self.html.append(
            f"<figure><img src='{png}' width='{width}' alt='{html.escape(figure.path.stem)}'>"
            f"<figcaption>{caption}</figcaption></figure>"
        )
        self.md += [f"![{figure.title}]({png})", ""]

    def provenance(self, rows: Mapping[str, str]) -> None:
        """The provenance box: one line per item (values are HTML)."""
        body = "".join(f"<dt>{html.escape(k)}</dt><dd>{v}</dd>" for k, v in rows.items())
        self.html.append(f"<dl class='provenance'>{body}</dl>")
        self.md += [f"- **{k}**: {re.sub(r'<[^>]+>', ' ', v).strip()}" for k, v in rows.items()] + [""]

    def leaderboard(self, table: pd.DataFrame) -> None:
        """The leaderboard: text cells, a value's CI on a second line in HTML."""

        def cell(value: Any) -> str:
            text = str(value)
            value_text, _, ci = text.partition(" [")
            if ci:
                return f"<td class='num lb'>{html.escape(value_text)}<br><small>[{html.escape(ci)}</small></td>"
            numeric = text.replace(".", "", 1).replace("e", "").replace("-", "").replace("+", "").isdigit()
            return f"<td class='{'num lb' if numeric or text == UNDEFINED else 'lb'}'>{html.escape(text)}</td>"

        head = "".join(f"<th>{html.escape(str(c))}</th>" for c in table.columns)
        apart = [str(n).endswith(LABELS_MARK) for n in table["estimator"]] if len(table) else []
        # the first label reader starts below a rule: ranked apart from the estimators
        first = apart.index(True) if True in apart and not all(apart) else -1
        body = "".join(
            ("<tr class='apart'>" if i == first else "<tr>") + "".join(cell(v) for v in row) + "</tr>"
            for i, row in enumerate(table.itertuples(index=False))
        )
        ident = "" if any("id='leaderboard-table'" in h for h in self.html) else " id='leaderboard-table'"
        self.html.append(f"<div class='scroll'><table{ident}><tr>{head}</tr>{body}</table></div>")
        # the cells are formatted text: tabulate would parse '8.80' back into 8.8
        self.md += [table.to_markdown(index=False, disable_numparse=True) if len(table) else "(none)", ""]

    def table(self, df: pd.DataFrame, classes: Any = None) -> None:
        """A table under human column names (:func:`human_name`); a blank (NaN) cell shows :data:`BLANK`
        and the note under the table says why."""
        why = {human_name(c): BLANK_REASONS[str(c)] for c in df.columns if str(c) in BLANK_REASONS}
        df = df.rename(columns=human_name)
        head = "".join(f"<th>{html.escape(str(c))}</th>" for c in df.columns)
        body = []
        for _, row in df.iterrows():
            cls = f" class='{classes(row)}'" if classes else ""
            cells = "".join(_cell(v) for v in row)
            body.append(f"<tr{cls}>{cells}</tr>")
        self.html.append(f"<div class='scroll'><table><tr>{head}</tr>{''.join(body)}</table></div>")
        shown = df.copy()
        for column in df.columns:
            values = df[column]
            if values.isin([np.inf]).any() or values.isna().any():  # tabulate would print 'inf' and 'nan'
                shown[column] = [_text(v) if isinstance(v, (float, np.floating)) else _blank(v) for v in values]
        self.md += [shown.to_markdown(index=False, floatfmt=".3g") if len(df) else "(none)", ""]
        blank = [str(c) for c in df.columns if df[c].map(_is_blank).any()]
        if blank:
            reasons = "; ".join(f"{c}: {why.get(c, 'not defined for that row')}" for c in blank)
            self.p(f"{BLANK} = {reasons}.", cls="note")

    def write(self, out: Path, started: float) -> Path:
        """Write index.html, README.md and figures.json; the page ends with the build time."""
        self.p(f"Report built in {time.perf_counter() - started:.1f} s.", cls="note")
        body = list(self.html)
        if self.contents_at is not None and self.sections:
            items = "".join(f"<li><a href='#{a}'>{html.escape(t)}</a></li>" for t, a in self.sections)
            body.insert(self.contents_at, f"<nav class='toc' id='contents'><b>Contents</b><ol>{items}</ol></nav>")
        page = (
            f"<!doctype html><html><head><meta charset='utf-8'><title>simbench report</title>"
            f"<meta name='viewport' content='width=device-width'><style>{_CSS}</style></head>"
            f"<body>{''.join(body)}</body></html>"
        )
        figures = [
            {
                "file": f.path.name,
                "files": [p.name for p in f.files],
                "title": f.title,
                "series": list(f.series),
                "legend": list(f.legend),
                "styles": f.styles,
            }
            for f in self.figures
        ]
        for name, text in (
            ("index.html", page),
            ("README.md", "\n".join(self.md) + "\n"),
            ("figures.json", json.dumps(figures, indent=1) + "\n"),
        ):
            write_bytes(out / name, text.encode())
        return out


#: Headers of the report's tables for their snake_case columns; a column not here keeps its name (it may be
#: a world or an estimator, e.g. ``urban_deep``, whose name is its identity).
COLUMN_NAMES = {
    "n_seeds": "seeds",
    "n_failed": "failed seeds",
    "gnss_model": "gnss_model preset",
    "horizontal_median_solved": "horizontal median, solved epochs [m]",
    "horizontal_max": "horizontal max, solved epochs [m]",
    "horizontal_median_ref": "horizontal median [m]",
    "horizontal_p95_ref": "horizontal p95 [m]",
    "error_3d_median_ref": "3-D median [m]",
    "time_per_obs_s": "run time per observation [s]",
    "update_median_s": "median update [s]",
    "time_per_epoch_s": "time per epoch [s]",
    "ci_low": "CI low",
    "ci_high": "CI high",
    "wilcoxon_p": "Wilcoxon p",
    "gap_m": "gap [m]",
    "oracle_availability": "oracle availability",
    "baseline_availability": "baseline availability",
    "error_3d_median": "3-D median [m]",
    "error_3d_mean": "3-D mean [m]",
    "error_3d_max": "3-D max [m]",
    "median_ref": "median [m]",
    "published_as": "published as",
    "wall_s": "wall time [s]",
    "exit_code": "exit code",
    "total_s": "total [s]",
    "n_adaptations": "adaptations",
    "ks_against": "KS against",
}


def human_name(column: Any) -> str:
    """A table header for a column: :data:`COLUMN_NAMES`, else its name."""
    return COLUMN_NAMES.get(str(column), str(column))


def _is_blank(value: Any) -> bool:
    return value is None or (isinstance(value, (float, np.floating)) and np.isnan(value))


def _blank(value: Any) -> Any:
    return BLANK if _is_blank(value) else value


def _text(value: Any) -> str:
    """A float as the report shows it: 3 significant digits, '—' for an undefined percentile (inf), n/a for NaN."""
    return BLANK if np.isnan(value) else sig3(value)


def _cell(value: Any) -> str:
    if isinstance(value, (float, np.floating)):
        return f"<td class='num'>{_text(value)}</td>"
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return f"<td class='num'>{value}</td>"
    return f"<td>{html.escape(str(_blank(value)))}</td>"
