"""Several studies over several worlds, one aggregate: ``python -m simbench +sweep=thesis worlds=[...]``.

A *study* is a sweep of ``conf/sweep/``; a *world* is a scenario preset of
``conf/scenario/`` (``urban``, ``urban_deep``, ``morgantown1``, ...). Each study
runs on each world into ``results_dir/<world>/<study>`` (the world replaces
the study's scenario; the study's own scenario settings, e.g. ``ch7_ice``'s
``scenario.duration_s``, still apply on top). A study listed in
``own_scenario`` runs once on the scenario of its sweep file, into
``results_dir/<study>``: Ch.4's Monte-Carlo flights are part of its claim, not
a drive through a world. A world listed in ``world_studies`` runs only the
studies listed for it. Then one aggregate, ``claims.csv`` (one verdict per
claim and world, :func:`simbench.claims.claims_table`) and report over all of
them. The wall time of every study x world is appended to ``results_dir/study_times.csv``.
"""
from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from datetime import datetime, timezone
from pathlib import Path

import pandas as pd
from omegaconf import DictConfig

from simbench.compose import available
from simbench.config import to_typed
from simbench.errors import SimbenchError

__all__ = ["STUDY_TIMES", "StudiesConfig", "StudyRun", "plan", "run_studies", "time_budget"]

#: File of ``results_dir`` with one row per study x world: wall time and exit code.
STUDY_TIMES = "study_times.csv"


@dataclass
class StudiesConfig:
    """Top-level keys of a sweep file that runs other sweeps (``conf/sweep/thesis.yaml``)."""

    studies: list[str] = field(default_factory=list)  #: sweeps of conf/sweep/, run one after another
    #: scenario presets every study runs on; empty: each study on the scenario of its sweep file
    worlds: list[str] = field(default_factory=list)
    #: studies that run once on the scenario of their sweep file whatever the worlds
    own_scenario: list[str] = field(default_factory=list)
    #: extra command-line overrides of one study, e.g. {ch5_bce: ["estimator=[l2,dcs,mm,bce,oracle]"]}
    study_args: dict[str, list[str]] = field(default_factory=dict)
    #: the studies of one world when not all of them, e.g. {morgantown1: [ch5_bce, ch7_ice]}
    world_studies: dict[str, list[str]] = field(default_factory=dict)

    @classmethod
    def from_config(cls, cfg: DictConfig) -> StudiesConfig:
        """The studies keys of a composed config (those it sets), typed and checked."""
        return to_typed({f.name: cfg[f.name] for f in fields(cls) if f.name in cfg}, cls, "config")

    def validate(self) -> None:
        """One-line :class:`SimbenchError` for an unknown study or world."""
        sweeps, scenarios = available("sweep"), available("scenario")
        for key, names, known in (("studies", self.studies, sweeps), ("worlds", self.worlds, scenarios),
                                  ("own_scenario", self.own_scenario, self.studies),
                                  ("study_args", list(self.study_args), self.studies),
                                  ("world_studies", list(self.world_studies), scenarios),
                                  *((f"world_studies.{w}", s, self.studies) for w, s in self.world_studies.items())):
            unknown = [n for n in names if n not in known]
            if unknown:
                raise SimbenchError(key, f"unknown {', '.join(unknown)}", f"choose from {', '.join(known)}")
        if not self.studies:
            raise SimbenchError("studies", "is empty", "list sweeps of conf/sweep/, e.g. studies=[ch5_bce]")


@dataclass(frozen=True)
class StudyRun:
    """One study on one world: the sweep, where it writes and the command-line arguments it gets."""

    study: str
    world: str  #: scenario preset, '' for a study on its own scenario
    results_dir: Path
    args: list[str]


#: Keys of the studies config itself and of what each study sets: never passed down to a study.
_OWN_KEYS = ("sweep", "sweep_name", "results_dir", *(f.name for f in fields(StudiesConfig)))


def _key(arg: str) -> str:
    """The config key an override sets, without Hydra's ``+``/``++``/``~`` prefix."""
    return arg.partition("=")[0].lstrip("+~")


def plan(cfg: StudiesConfig, root: Path, args: Sequence[str]) -> list[StudyRun]:
    """The study runs of ``cfg`` in order: per study, each world (or the study's own scenario).

    Parameters
    ----------
    cfg : StudiesConfig
    root : Path
        ``results_dir`` of the whole run.
    args : sequence of str
        The command line; every override but those of the keys of
        :class:`StudiesConfig`, ``sweep``, ``sweep_name`` and ``results_dir`` (with
        or without Hydra's ``+``/``++``/``~``) goes to every study (e.g.
        ``hydra/launcher=joblib``, ``seed=range(0,5)``).

    Raises
    ------
    SimbenchError
        For a ``scenario=`` override together with ``worlds``.
    """
    cfg.validate()
    passed = [a for a in args if _key(a) not in _OWN_KEYS]
    if cfg.worlds and any(_key(a) == "scenario" for a in passed):
        raise SimbenchError("scenario", "is set on the command line together with worlds",
                            "list the scenario presets in worlds=[...] instead")
    runs = []
    for study in cfg.studies:
        extra = [*cfg.study_args.get(study, []), *passed]  # the command line last: it has the final word
        if not cfg.worlds or study in cfg.own_scenario:
            runs.append(StudyRun(study, "", root / study, [f"+sweep={study}", f"results_dir={root / study}",
                                                          *extra]))
            continue
        for world in cfg.worlds:
            if study not in cfg.world_studies.get(world, [study]):
                continue
            out = root / world / study
            runs.append(StudyRun(study, world, out, [f"+sweep={study}", f"scenario={world}", f"results_dir={out}",
                                                     *extra]))
    return runs


def run_studies(cfg: StudiesConfig, root: Path, args: Sequence[str]) -> int:
    """Run every study of :func:`plan` in its own process, then one aggregate over all of them.

    A study that exits with an error does not stop the others (its finished jobs
    are in the store); the return code is then 1.

    Returns
    -------
    int
        0 when every study exited cleanly, else 1.
    """
    from simbench.report.build import finalize

    runs = plan(cfg, root, args)
    root.mkdir(parents=True, exist_ok=True)
    path = root / STUDY_TIMES
    # appended to: a second invocation into the same results_dir (another world, other seeds) keeps the first's
    earlier = pd.read_csv(path, keep_default_na=False) if path.is_file() else pd.DataFrame()
    times = []
    for i, run in enumerate(runs, 1):
        print(f"=== study {run.study}" + (f" on {run.world}" if run.world else "") + f" ({i}/{len(runs)})",
              file=sys.stderr)
        started, start = datetime.now(timezone.utc).isoformat(timespec="seconds"), time.perf_counter()
        code = subprocess.call([sys.executable, "-m", "simbench", *run.args])
        times.append({"study": run.study, "world": run.world, "started": started,
                      "wall_s": time.perf_counter() - start, "exit_code": code, "results_dir": str(run.results_dir)})
        # written after every study: a killed run still says where its time went
        pd.concat([earlier, pd.DataFrame(times)], ignore_index=True).to_csv(path, index=False)
    report = finalize(root, {"studies": cfg.studies, "worlds": cfg.worlds, "args": list(args)})
    print(f"results: {root.resolve()}  report: {report.resolve() / 'index.html'}", file=sys.stderr)
    failed = [f"{t['study']}" + (f" on {t['world']}" if t["world"] else "") for t in times if t["exit_code"]]
    if failed:
        print(f"error: studies {', '.join(failed)} exited with errors -- see their logs in {root}", file=sys.stderr)
    return 1 if failed else 0


def time_budget(summary: pd.DataFrame) -> pd.DataFrame:
    """Where the estimators' time went: summed wall time per sweep, world and estimator.

    Parameters
    ----------
    summary : pandas.DataFrame
        ``summary.parquet`` rows (:data:`~simbench.runner.SUMMARY_COLUMNS`).

    Returns
    -------
    pandas.DataFrame
        Columns ``sweep``, ``scenario``, ``estimator``, ``jobs``, ``total_s`` (sum over
        jobs [s]), ``job_mean_s`` [s] and ``share`` (of the whole run's estimator time),
        largest first.
    """
    timed = summary[summary["total_s"].notna()]
    if timed.empty:
        return pd.DataFrame(columns=["sweep", "scenario", "estimator", "jobs", "total_s", "job_mean_s", "share"])
    table = (timed.groupby(["sweep", "scenario", "estimator"])["total_s"].agg(jobs="count", total_s="sum",
                                                                             job_mean_s="mean")
             .reset_index().sort_values("total_s", ascending=False, ignore_index=True))
    return table.assign(share=table["total_s"] / table["total_s"].sum())
