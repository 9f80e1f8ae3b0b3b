"""Report build time at the size of the 5-world thesis sweep (issue 26: at most 60 s).

Running the thesis sweep takes about 40 min on 2 cores (3 seeds), so this builds a results
store of its shape instead: one short real job (60 s of the urban drive under
``gnss_model=dissertation``, every estimator the thesis runs) is the template, and its job
files are replicated with the store's own writers (:func:`simbench.runs.store.write_result`,
:meth:`simbench.contract.Scenario.save`) into every job of the thesis plan.

The plan is the real one: :func:`simbench.runs.studies.plan` over ``conf/sweep/thesis.yaml``
(5 worlds, 6 studies, ``world_studies``, ``own_scenario``, ``study_args``), each study's
sweeper params expanded (receivers, prior scales, CRT-LSS windows) and the seeds of the
command line (``seed=range(0,N)``; the recorded run of docs/notebook.md used 3). Each job's
scenario key, result stem, overrides and labels are computed from its composed config as a
job computes them; an estimator whose config does not change across a study's swept values
(EKF-INS and IEKF-INS across CRT-LSS windows) is one stored result, as in the real store.
Each result has the epochs of its scenario (600 s urban and urban_deep, 1,209 / 1,736 /
1,771 s for the drives, 1,200 s under ``ch7_ice``, 1,800 s for the Ch.4 flights, at 1 Hz):
the template's epochs tiled in time, errors scaled by a factor per job (so seeds differ),
and each cached scenario is the template's scenario tiled to that length.

Then it times ``finalize`` (what ``python -m simbench report DIR`` calls) and prints the
time and the top 10 functions of a cProfile run of a second build.

    python benchmarks/report_build.py [--seeds 3] [--out DIR] [--formats png] [--no-profile]
"""

from __future__ import annotations

import argparse
import cProfile
import itertools
import json
import math
import os
import pstats
import shutil
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any, cast

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import pandas as pd
import yaml
from hydra.core.override_parser.overrides_parser import OverridesParser
from omegaconf import DictConfig, OmegaConf

import estimators
from simbench import source_registry as sources
from simbench.analysis.variants import overrides_json, variant_label
from simbench.contract import Scenario
from simbench.report.build import finalize
from simbench.runs.compose import compose_config, config_groups
from simbench.runs.jobs import estimator_overrides, run_job
from simbench.runs.provenance import code_identity, provenance
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS
from simbench.runs.scenarios import scenario_key, scenario_settings, source_code
from simbench.runs.store import result_stem, write_result
from simbench.runs.studies import STUDY_TIMES, StudiesConfig, plan

TARGET_S = 60.0
#: Every estimator a thesis study runs (with ``study_args``: ch5_bce without BCE-AD).
THESIS_ESTIMATORS = (
    "l2,dcs,mm,bce,bce_ad,oracle,isam2_ppp,isam2_dcs,isam2_mm,ice,ekf_ins,iekf_ins,crt_lss,ekf_ppp".split(",")
)
TEMPLATE_S = 60
#: Summary columns in metres (scaled with the job's error factor); the variances scale with its square.
LINEAR = [c for c, unit in SUMMARY_COLUMNS.items() if unit.startswith("m") and not unit.startswith("m^2")]
SQUARED = [c for c, unit in SUMMARY_COLUMNS.items() if unit.startswith("m^2")]
ERRORS = ["e", "n", "u", "horizontal", "error_3d"]


def template(directory: Path) -> Path:
    """One real 60 s job of every thesis estimator (reused when ``directory`` holds it already)."""
    if not list(directory.glob("jobs/*/*.summary.parquet")):
        run_job(
            compose_config(
                [
                    f"scenario.duration_s={TEMPLATE_S}",
                    "gnss_model=dissertation",
                    f"estimator=[{','.join(THESIS_ESTIMATORS)}]",
                    f"results_dir={directory}",
                    "progress=false",
                ]
            )
        )
    return directory


def load_template(directory: Path) -> tuple[dict[str, tuple[pd.DataFrame, pd.DataFrame, str]], Scenario]:
    """Per estimator: its summary row, epochs and diagnostics text; and the cached scenario."""
    jobs = {}
    for path in directory.glob("jobs/*/*.summary.parquet"):
        stem = path.with_name(path.name.removesuffix(".summary.parquet"))
        summary = pd.read_parquet(path)
        jobs[str(summary["estimator"].iloc[0])] = (
            summary,
            pd.read_parquet(stem.with_suffix(".epochs.parquet")),
            stem.with_suffix(".diagnostics.json").read_text(),
        )
    return jobs, Scenario.load(next(p for p in directory.glob("cache/*") if p.is_dir()))


def tiled(frame: pd.DataFrame, n_epochs: int, has_epoch: bool = True) -> pd.DataFrame:
    """``frame`` (rows of the template's epochs 0..TEMPLATE_S-1, 1 Hz) repeated in time up to ``n_epochs`` [s]."""
    copies = []
    for k in range(math.ceil(n_epochs / TEMPLATE_S)):
        part = frame.assign(t=frame["t"] + k * TEMPLATE_S)
        if has_epoch:
            part = part.assign(epoch=part["epoch"] + k * TEMPLATE_S)
        copies.append(part)
    out = pd.concat(copies, ignore_index=True)
    return out[out["t"] < n_epochs].reset_index(drop=True)


def tiled_scenario(base: Scenario, n_epochs: int) -> Scenario:
    """The template scenario repeated in time to ``n_epochs`` epochs (labels stay row-aligned)."""
    obs = base.observations.assign(_row=np.arange(len(base.observations)))
    obs = tiled(obs, n_epochs)
    labels = None
    if base.labels is not None:
        labels = base.labels.iloc[obs["_row"].to_numpy()].reset_index(drop=True).assign(epoch=obs["epoch"].to_numpy())
    return replace(
        base,
        observations=obs.drop(columns="_row"),
        imu=tiled(base.imu, n_epochs, has_epoch=False),
        truth=tiled(base.truth, n_epochs),
        labels=labels,
        odometry=tiled(base.odometry, n_epochs, has_epoch=False),
    )


def sweep_values(args: list[str]) -> tuple[list[str], list[tuple[str, list[str]]]]:
    """A study's fixed overrides and its swept keys with their values: the sweep file's params,
    then the command line's (which win), as Hydra's basic sweeper expands them."""
    parser = OverridesParser.create()
    fixed = [a for a, o in zip(args, parser.parse_overrides(args)) if not o.is_sweep_override()]
    params = OmegaConf.select(compose_config(fixed, with_hydra=True), "hydra.sweeper.params", default=None) or {}
    swept: dict[str, list[str]] = {}
    for item in [*(f"{k}={v}" for k, v in params.items()), *args]:
        override = parser.parse_overrides([item])[0]
        if override.is_sweep_override():
            swept[override.get_key_element()] = list(override.sweep_string_iterator())
    return fixed, list(swept.items())


def job_configs(fixed: list[str], swept: list[tuple[str, list[str]]]) -> list[DictConfig]:
    """One composed config per job; a config group (receiver) is composed, a value is set in place."""
    groups = set(config_groups())
    by_group = [(k, v) for k, v in swept if k in groups]
    by_value = [(k, v) for k, v in swept if k not in groups]
    configs = []
    for group_values in itertools.product(*(v for _, v in by_group)):
        base = compose_config([*fixed, *(f"{k}={v}" for (k, _), v in zip(by_group, group_values))])
        for values in itertools.product(*(v for _, v in by_value)):
            cfg = base.copy()
            for (key, _), value in zip(by_value, values):
                OmegaConf.update(cfg, key, yaml.safe_load(value))
            configs.append(cfg)
    return configs


def write_store(root: Path, seeds: int, tmpl: Path) -> dict[str, int]:
    """The thesis-shaped store under ``root``; returns its counts."""
    jobs, base = load_template(tmpl)
    cfg = StudiesConfig.from_config(compose_config(["+sweep=thesis"]))
    runs = plan(cfg, root, [f"seed=range(0,{seeds})"])
    scenarios: dict[int, Scenario] = {}
    codes = {name: code_identity(estimators.get(name).__module__) for name in THESIS_ESTIMATORS}
    rng = np.random.default_rng(0)
    counts = {"studies x worlds": len(runs), "jobs": 0, "results": 0, "epoch rows": 0, "scenarios": 0}
    times = []
    for run in runs:
        fixed, swept = sweep_values(run.args)
        for job in job_configs(fixed, swept):
            counts["jobs"] += 1
            sim = scenario_settings(job)
            key = scenario_key(sim)
            n_epochs = int(round(sim.scenario.duration_s * sim.scenario.rate_hz))
            label = sources.get(sim.scenario.source)().label(sim)
            cache = run.results_dir / "cache" / key
            if not cache.is_dir():
                scenario = scenarios.setdefault(n_epochs, tiled_scenario(base, n_epochs))
                replace(scenario, meta={**scenario.meta, "name": label, "seed": sim.seed}).save(cache)
                counts["scenarios"] += 1
            config = cast(dict[str, Any], OmegaConf.to_container(job, resolve=True, enum_to_str=True))
            meta = provenance(config)
            gnss_model = str(job.gnss_model.name)
            for name, est_cfg in config["estimator"].items():
                stem = result_stem(run.results_dir, key, name, est_cfg, codes[name])
                if stem.with_suffix(".summary.parquet").is_file():  # the same result of another swept value
                    continue
                overrides = estimator_overrides(name, est_cfg, gnss_model)
                summary, epochs, diagnostics = jobs[name]
                factor = float(rng.lognormal(0.0, 0.25))
                epochs = tiled(epochs, n_epochs)
                epochs[ERRORS] *= factor
                tags = {
                    "sweep": str(job.sweep_name),
                    "scenario": label,
                    "source": sim.scenario.source,
                    "receiver": sim.receiver.name,
                    "seed": sim.seed,
                    "scenario_key": key,
                    "gnss_model": gnss_model,
                    "variant": variant_label(overrides),
                    "overrides": overrides_json(overrides),
                }
                summary = summary.assign(**tags)
                summary[LINEAR] *= factor
                summary[SQUARED] *= factor**2
                ratio = n_epochs / TEMPLATE_S
                summary = summary.assign(
                    n_epochs=n_epochs,
                    n_solved=len(epochs),
                    availability=len(epochs) / n_epochs,
                    n_obs=int(summary["n_obs"].iloc[0] * ratio),
                    total_s=summary["total_s"] * ratio,
                )
                write_result(
                    stem,
                    summary[list(SUMMARY_COLUMNS)],
                    epochs.assign(**tags)[list(EPOCH_COLUMNS)],
                    json.loads(diagnostics),
                    {**meta, "simbench.code": {"estimator": codes[name], "source": source_code(sim.scenario.source)}},
                )
                counts["results"] += 1
                counts["epoch rows"] += len(epochs)
        times.append(
            {
                "study": run.study,
                "world": run.world,
                "started": "",
                "wall_s": 0.0,
                "exit_code": 0,
                "results_dir": str(run.results_dir),
            }
        )
    pd.DataFrame(times).to_csv(root / STUDY_TIMES, index=False)
    return counts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3, help="seeds per study (the recorded thesis run: 3)")
    ap.add_argument("--out", type=Path, default=None, help="store folder (default: a temporary one, removed)")
    ap.add_argument("--template", type=Path, default=Path(tempfile.gettempdir()) / "simbench-report-template")
    ap.add_argument("--formats", default="png", help="figure formats, comma-separated, e.g. png,pdf")
    ap.add_argument("--no-profile", action="store_true", help="time the build only")
    a = ap.parse_args()
    root = a.out or Path(tempfile.mkdtemp(prefix="simbench-report-"))
    formats = [f for f in a.formats.split(",") if f]
    try:
        start = time.perf_counter()
        tmpl = template(a.template)
        if not (root / STUDY_TIMES).is_file():
            counts = write_store(root, a.seeds, tmpl)
            print(f"store {root}: {counts} in {time.perf_counter() - start:.0f} s")
        start, cpu = time.perf_counter(), time.process_time()
        finalize(root, None, formats=formats)
        elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu
        figures = len(list((root / "report").glob("*.png")))
        # CPU time beside the wall time: on a shared machine the wall time includes other processes' turns
        print(f"report build: {elapsed:.1f} s wall, {cpu:.1f} s CPU ({figures} figures; target {TARGET_S:.0f} s)")
        if not a.no_profile:
            profile = cProfile.Profile()
            profile.runcall(finalize, root, None, formats=formats)
            pstats.Stats(profile).sort_stats("cumulative").print_stats(10)
            pstats.Stats(profile).sort_stats("tottime").print_stats(10)
    finally:
        if a.out is None:
            shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
