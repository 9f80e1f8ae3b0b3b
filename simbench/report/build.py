"""Write ``report/`` for a run directory: figures and a README with the summary table."""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from simbench.report.figures import ecdf_figure, error_timeseries_figure

SUMMARY_SHOWN = ["scenario", "receiver", "seed", "estimator", "status", "availability", "horizontal_median",
                 "horizontal_mean", "horizontal_p95", "horizontal_max", "error_3d_median", "update_median_s"]


def build_report(run_dir: str | Path) -> Path:
    """Build ``run_dir/report`` from ``summary.parquet`` and ``epochs.parquet``."""
    run_dir = Path(run_dir)
    summary = pd.read_parquet(run_dir / "summary.parquet")
    epochs = pd.read_parquet(run_dir / "epochs.parquet")
    out = run_dir / "report"
    figures = []
    for (scenario, receiver), group in epochs.groupby(["scenario", "receiver"]):
        tag = f"{scenario}_{receiver}"
        for metric, label in (("horizontal", "horizontal"), ("error_3d", "3-D")):
            figures.append(ecdf_figure(group, metric, out / f"ecdf_{metric}_{tag}.png",
                                       f"ECDF of {label} error: {scenario}, {receiver} receiver"))
        if group["seed"].nunique() == 1:
            figures.append(error_timeseries_figure(group, out / f"error_time_{tag}.png",
                                                   f"Horizontal error over time: {scenario}, {receiver}"))
    lines = ["# simbench report", "", "## Summary", "",
             summary.reindex(columns=SUMMARY_SHOWN).to_markdown(index=False, floatfmt=".3f"), "",
             "Errors in metres, update time in seconds.", "", "## Figures", ""]
    lines += [f"![{p.stem}]({p.name})" for p in figures]
    (out / "README.md").write_text("\n".join(lines) + "\n")
    return out
