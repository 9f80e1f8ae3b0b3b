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
claim and world, :func:`simbench.analysis.claims.claims_table`) and report over all of
them. The wall time and peak memory of every study x world are appended to ``results_dir/study_times.csv``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, NamedTuple

import pandas as pd
from omegaconf import DictConfig

from simbench.errors import SimbenchError
from simbench.runs.compose import available, overrides_from_kwargs
from simbench.runs.files import read_csv_table
from simbench.typed import to_typed

__all__ = [
    "STUDY_TIMES",
    "StudiesConfig",
    "StudyProcess",
    "StudyRun",
    "plan",
    "run_all",
    "run_study_process",
    "read_study_times",
    "study_dir",
    "study_dirs",
    "time_budget",
]

#: File of ``results_dir`` with one row per study x world: wall time, peak memory of the study's largest
#: process [MB] (``peak_rss_mb``; a worker when the launcher has them) and exit code.
STUDY_TIMES = "study_times.csv"
#: Columns every reader of :data:`STUDY_TIMES` uses (``peak_rss_mb`` and ``exit_code`` came later).
STUDY_TIMES_COLUMNS = ("study", "world", "wall_s")


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
        for key, names, known in (
            ("studies", self.studies, sweeps),
            ("worlds", self.worlds, scenarios),
            ("own_scenario", self.own_scenario, self.studies),
            ("study_args", list(self.study_args), self.studies),
            ("world_studies", list(self.world_studies), scenarios),
            *((f"world_studies.{w}", s, self.studies) for w, s in self.world_studies.items()),
        ):
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
        For a ``scenario=`` override together with ``worlds``, and for ``world_studies={}`` or
        ``study_args={}``, which Hydra merges into the sweep file's dict (changing nothing).
    """
    cfg.validate()
    for arg in args:
        key = _key(arg)
        if key in ("study_args", "world_studies") and not arg.startswith("~") and arg.partition("=")[2].strip() == "{}":
            raise SimbenchError(
                key,
                "an empty dict merges into the sweep file's and changes nothing",
                f"delete the key instead: '~{key}'",
            )
    passed = [a for a in args if _key(a) not in _OWN_KEYS]
    if cfg.worlds and any(_key(a) == "scenario" for a in passed):
        raise SimbenchError(
            "scenario",
            "is set on the command line together with worlds",
            "list the scenario presets in worlds=[...] instead",
        )
    runs = []
    for study in cfg.studies:
        extra = [*cfg.study_args.get(study, []), *passed]  # the command line last: it has the final word
        if not cfg.worlds or study in cfg.own_scenario:
            out = study_dir(root, study, "")
            runs.append(StudyRun(study, "", out, [f"+sweep={study}", f"results_dir={out}", *extra]))
            continue
        for world in cfg.worlds:
            if study not in cfg.world_studies.get(world, [study]):
                continue
            out = study_dir(root, study, world)
            # identical rows of the world's studies are computed once (simbench.runs.plan.RunOptions)
            siblings = [
                str(study_dir(root, other, world))
                for other in cfg.studies
                if other != study and other not in cfg.own_scenario and other in cfg.world_studies.get(world, [other])
            ]
            args = [f"+sweep={study}", f"scenario={world}", f"results_dir={out}"]
            args += overrides_from_kwargs({"shared_results": siblings})
            runs.append(StudyRun(study, world, out, [*args, *extra]))
    return runs


def study_dir(root: Path, study: str, world: str) -> Path:
    """Where a study writes: ``root/<world>/<study>``, or ``root/<study>`` on its own scenario (world ``''``)."""
    return root / world / study if world else root / study


def study_dirs(root: Path) -> list[Path]:
    """The results_dir of every study ``root/study_times.csv`` records (:data:`STUDY_TIMES`), in its order;
    none when ``root`` is no study collection. Found from ``root``, not from the recorded paths,
    which are relative to the folder the collection ran from."""
    times = read_study_times(Path(root), dtype=str)
    if times is None:
        return []
    return list(dict.fromkeys(study_dir(Path(root), s, w) for s, w in zip(times["study"], times["world"])))


def read_study_times(root: Path, **read_csv: Any) -> pd.DataFrame | None:
    """``root/study_times.csv`` (:data:`STUDY_TIMES`), None when ``root`` has none.

    Raises
    ------
    SimbenchError
        Naming the file when it cannot be read, lacks a column of :data:`STUDY_TIMES_COLUMNS` or
        has a wall time that is not a number.
    """
    path = Path(root) / STUDY_TIMES
    if not path.is_file():
        return None
    fix = "restore it, or delete it if the folder is no collection of studies (+sweep=thesis)"
    return read_csv_table(path, STUDY_TIMES_COLUMNS, fix, numbers=("wall_s",), keep_default_na=False, **read_csv)


def time_budget(summary: pd.DataFrame) -> pd.DataFrame:
    """Where the estimators' time went: summed wall time per sweep, world and estimator.

    Parameters
    ----------
    summary : pandas.DataFrame
        ``summary.parquet`` rows (:data:`~simbench.runs.runner.SUMMARY_COLUMNS`).

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
    table = (
        timed.groupby(["sweep", "scenario", "estimator"])["total_s"]
        .agg(jobs="count", total_s="sum", job_mean_s="mean")
        .reset_index()
        .sort_values("total_s", ascending=False, ignore_index=True)
    )
    return table.assign(share=table["total_s"] / table["total_s"].sum())


class StudyProcess(NamedTuple):
    """How a study's process ended."""

    exit_code: int
    #: peak resident memory of the largest process of the study's tree (the study process or one of its
    #: launcher's workers) [MB]; NaN where the platform cannot say (no ``os.wait4``)
    peak_rss_mb: float


#: Starts the study from a small process and reports, on the file descriptor in ``argv[1]``, its exit
#: code and the ``ru_maxrss`` of its tree. A child started straight from a large process (a notebook,
#: a pytest worker) inherits that process's high-water mark: ``vfork`` shares its address space until
#: ``exec``, and Linux then records the parent's peak as the child's (a 300 MB study read 1,176 MB).
_PEAK_SHIM = (
    "import os, sys\n"
    "try:\n"
    "    pid = os.posix_spawnp(sys.argv[2], sys.argv[2:], os.environ)\n"
    "except OSError as e:\n"
    "    sys.exit(f'cannot start {sys.argv[2]}: {e.strerror}')\n"
    "_, status, usage = os.wait4(pid, 0)\n"
    "code = os.waitstatus_to_exitcode(status)\n"
    "os.write(int(sys.argv[1]), f'{code} {usage.ru_maxrss}'.encode())\n"
)


def run_study_process(cmd: Sequence[str]) -> StudyProcess:
    """Run ``cmd`` and wait for it; its exit code and the peak memory of its process tree.

    ``os.wait4`` returns the child's resource usage with that of every descendant it
    waited for, and ``ru_maxrss`` is then the largest peak among them (Linux reports
    kibibytes, macOS bytes): a joblib or submitit-local worker counts, which is the
    per-worker peak a sweep has to fit into. The command is started from a small
    Python process (:data:`_PEAK_SHIM`), so the caller's own size does not count.
    """
    if not hasattr(os, "wait4"):  # Windows
        return StudyProcess(subprocess.Popen(list(cmd)).wait(), float("nan"))
    read, write = os.pipe()
    try:
        shim = subprocess.Popen([sys.executable, "-c", _PEAK_SHIM, str(write), *cmd], pass_fds=(write,))
    finally:
        os.close(write)
    with os.fdopen(read) as report:
        text = report.read().split()
    shim.wait()
    if len(text) != 2:  # the shim itself failed (the command could not be started)
        return StudyProcess(shim.returncode or 1, float("nan"))
    unit = 1.0 if sys.platform == "darwin" else 1024.0
    return StudyProcess(int(text[0]), float(text[1]) * unit / 2**20)


def run_all(cfg: StudiesConfig, root: Path, args: Sequence[str]) -> list[dict[str, Any]]:
    """Run every study of :func:`plan` in its own process (:func:`run_study_process`), one after another.

    A study that exits with an error does not stop the others (its finished jobs are in the
    store). Each study's row (study, world, started, wall_s, peak_rss_mb, exit_code,
    results_dir) is appended to :data:`STUDY_TIMES` as soon as it ends, after the rows of
    earlier invocations into the same ``root``.

    Returns
    -------
    list of dict
        This invocation's rows, in the order the studies ran.
    """
    runs = plan(cfg, root, args)
    root.mkdir(parents=True, exist_ok=True)
    path = root / STUDY_TIMES
    # appended to: a second invocation into the same results_dir (another world, other seeds) keeps the first's
    earlier = read_study_times(root)  # a damaged one is one line naming it, before the first study
    earlier = pd.DataFrame() if earlier is None else earlier
    times = []
    for i, run in enumerate(runs, 1):
        print(
            f"=== study {run.study}" + (f" on {run.world}" if run.world else "") + f" ({i}/{len(runs)})",
            file=sys.stderr,
        )
        started, start = datetime.now(timezone.utc).isoformat(timespec="seconds"), time.perf_counter()
        ended = run_study_process([sys.executable, "-m", "simbench", *run.args])
        times.append(
            {
                "study": run.study,
                "world": run.world,
                "started": started,
                "wall_s": time.perf_counter() - start,
                "peak_rss_mb": ended.peak_rss_mb,
                "exit_code": ended.exit_code,
                "results_dir": str(run.results_dir),
            }
        )
        # written after every study: a killed run still says where its time went
        pd.concat([earlier, pd.DataFrame(times)], ignore_index=True).to_csv(path, index=False)
    return times
