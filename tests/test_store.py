"""The results store: code-aware keys, self-checking files, unique temporary names, a run's own jobs only.

One tiny run (30 s urban, the L2 estimator) is made once; each store fault is
applied to a copy of it, and the report (``finalize``) and a rerun
(``run_job``) must then recover: a one-line warning naming the damaged file,
and the very result of the intact run.
"""

from __future__ import annotations

import importlib
import json
import os
import shutil
import subprocess
import sys
import warnings
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pytest
from conftest import REPO_ROOT, empty, garble, truncate
from omegaconf import OmegaConf, open_dict

import estimators
from simbench.cli.report import main as report_main
from simbench.contract import read_parquet_metadata
from simbench.errors import SimbenchWarning
from simbench.report.build import finalize
from simbench.runs.compose import compose_config
from simbench.runs.jobs import run_job
from simbench.runs.provenance import code_identity
from simbench.runs.store import MANIFEST, aggregate
from simbench.runs.studies import STUDY_TIMES

ARGS = ["estimator=[l2]", "scenario.duration_s=30", "progress=false"]


def _run(run_dir: Path) -> pd.DataFrame:
    """Run (or resume) the tiny job into ``run_dir`` and finalize it; the aggregate summary.

    Without figures: these tests check the store, and drawing was most of a finalize's time.
    """
    run_job(compose_config([*ARGS, f"results_dir={run_dir}"]))
    finalize(run_dir, None, figures=False)
    return pd.read_parquet(run_dir / "summary.parquet")


@pytest.fixture(scope="module")
def intact(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run_dir = tmp_path_factory.mktemp("store") / "run"
    _run(run_dir)
    return run_dir


def _job(run_dir: Path, suffix: str) -> Path:
    return next(run_dir.glob(f"jobs/*/l2-*{suffix}"))


def _cache(run_dir: Path, name: str) -> Path:
    return next(run_dir.glob(f"cache/*/{name}"))


def delete(path: Path) -> None:
    path.unlink()


def swap_epochs(path: Path) -> None:
    """Replace the job's epochs with a valid Parquet file of other rows."""
    pd.read_parquet(path).iloc[:3].to_parquet(path)


#: (case id, file to damage, damage, whether a warning must name the file): every case must end in the
#: intact run's result after a rerun. A run-level file is rebuilt by every finalize and needs no warning.
FAULTS: list[tuple[str, Callable[[Path], Path], Callable[[Path], None], bool]] = [
    *(
        (f"job summary {d.__name__}", lambda r: _job(r, ".summary.parquet"), d, True)
        for d in (truncate, empty, garble, delete)
    ),
    *(
        (f"job epochs {d.__name__}", lambda r: _job(r, ".epochs.parquet"), d, True)
        for d in (truncate, empty, garble, delete, swap_epochs)
    ),
    *((f"job diagnostics {d.__name__}", lambda r: _job(r, ".diagnostics.json"), d, True) for d in (garble, delete)),
    *(
        (f"cache observations {d.__name__}", lambda r: _cache(r, "observations.parquet"), d, True)
        for d in (truncate, empty, garble, delete)
    ),
    *(
        (f"cache {n} truncate", lambda r, n=n: _cache(r, f"{n}.parquet"), truncate, True)
        for n in ("imu", "truth", "labels", "odometry")
    ),
    ("cache manifest truncate", lambda r: _cache(r, MANIFEST), truncate, True),
    ("cache manifest delete", lambda r: _cache(r, MANIFEST), delete, True),
    ("run summary truncate", lambda r: r / "summary.parquet", truncate, False),
    ("run epochs truncate", lambda r: r / "epochs.parquet", truncate, False),
    ("run epochs delete", lambda r: r / "epochs.parquet", delete, False),
    ("claims truncate", lambda r: r / "claims.csv", truncate, False),
]


@pytest.mark.parametrize("target,damage,warned", [f[1:] for f in FAULTS], ids=[f[0] for f in FAULTS])
def test_a_damaged_store_file_is_named_and_recomputed(
    intact: Path,
    tmp_path: Path,
    target: Callable[[Path], Path],
    damage: Callable[[Path], None],
    warned: bool,
) -> None:
    run_dir = tmp_path / "run"
    shutil.copytree(intact, run_dir)
    path = target(run_dir)
    damage(path)
    relative = str(path.relative_to(run_dir))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        # the report of the damaged run: a damaged job is left out, never a crash; figures are drawn where
        # they read the damaged file (the time views and the sim-vs-real figure read the scenario cache)
        finalize(run_dir, None, figures=relative.startswith("cache"))
        summary = _run(run_dir)  # the rerun recomputes what is damaged
    messages = [str(w.message) for w in caught if issubclass(w.category, SimbenchWarning)]
    if warned:
        assert any(relative in m for m in messages), messages
        assert all("\n" not in m for m in messages)
    else:
        assert not messages
    expected = pd.read_parquet(intact / "summary.parquet")
    assert len(summary) == 1 and summary["status"].tolist() == ["ok"]
    assert summary["horizontal_median"].iloc[0] == pytest.approx(expected["horizontal_median"].iloc[0])
    assert len(pd.read_parquet(run_dir / "epochs.parquet")) == len(pd.read_parquet(intact / "epochs.parquet"))
    assert (run_dir / "report" / "index.html").is_file() and len(pd.read_csv(run_dir / "claims.csv"))
    with warnings.catch_warnings(record=True) as again:
        warnings.simplefilter("always")
        finalize(run_dir, None, figures=False)
    assert not [w for w in again if issubclass(w.category, SimbenchWarning)]  # the store is whole again


def test_a_report_without_figures_has_its_tables_and_draws_nothing(intact: Path) -> None:
    report = intact / "report"  # the fixture's finalize: figures=False
    assert json.loads((report / "figures.json").read_text()) == []
    assert not list(report.glob("*.png")) and not list(report.glob("*.pdf"))
    page = (report / "index.html").read_text()
    assert "Built without figures" in page and "<figure>" not in page
    assert page.index("id='leaderboard-table'") < page.index("Statistics over seeds")


def test_a_report_leaves_a_damaged_job_out_with_one_warning_line(intact: Path, tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    shutil.copytree(intact, run_dir)
    truncate(_job(run_dir, ".epochs.parquet"))
    with pytest.warns(SimbenchWarning, match=r"epochs\.parquet: differs from the sha256 .* -- left out"):
        summary, _ = aggregate(run_dir, {})
    assert summary.empty


def test_only_the_runs_own_jobs_and_its_studies_are_aggregated(intact: Path, tmp_path: Path) -> None:
    root = tmp_path / "results"
    shutil.copytree(intact, root)
    shutil.copytree(intact, root / "earlier-run")  # an earlier run kept inside results_dir: not part of it
    summary, _ = aggregate(root, {})
    assert len(summary) == 1
    # a study collection (+sweep=thesis): each study's results_dir, as study_times.csv records them
    collection = tmp_path / "thesis"
    for world, study in (("urban", "ch5_bce"), ("", "ch4_convergence")):
        shutil.copytree(intact, collection / world / study)
    shutil.copytree(intact, collection / "old")
    pd.DataFrame(
        [
            {"study": s, "world": w, "wall_s": 1.0, "exit_code": 0, "results_dir": "elsewhere"}
            for w, s in (("urban", "ch5_bce"), ("", "ch4_convergence"))
        ]
    ).to_csv(collection / STUDY_TIMES, index=False)
    summary, _ = aggregate(collection, {})
    assert len(summary) == 2
    assert report_main([str(collection)]) == 0  # the report command finds the studies two levels down
    assert len(pd.read_parquet(collection / "summary.parquet")) == 2


PLUGIN = '''
from dataclasses import dataclass

from estimators.batch.robust import L2Batch
from estimators.batch.configs import L2Config

OFFSET_M = {offset}


@dataclass
class ShiftedConfig(L2Config):
    """L2's settings."""


class Shifted(L2Batch):
    """L2 with every position moved OFFSET_M along ECEF x."""

    name = "shifted"
    Config = ShiftedConfig

    def _estimate(self, data):
        epochs, diagnostics = super()._estimate(data)
        return epochs.assign(x=epochs["x"] + OFFSET_M), diagnostics
'''


def test_an_edited_estimator_is_recomputed_and_an_untouched_one_reused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    package = f"sbplug_{tmp_path.name.replace('-', '_')}"
    (tmp_path / package).mkdir()
    (tmp_path / package / "__init__.py").write_text("")
    module_path = tmp_path / package / "shifted.py"
    module_path.write_text(PLUGIN.format(offset=0.0))
    monkeypatch.syspath_prepend(str(tmp_path))
    module = importlib.import_module(f"{package}.shifted")

    def run(run_dir: Path) -> pd.DataFrame:
        monkeypatch.setattr(estimators, "plugins", lambda: {"shifted": estimators.Plugin(module.Shifted, package)})
        cfg = compose_config([*ARGS, f"results_dir={run_dir}"])
        with open_dict(cfg):
            cfg.estimator.shifted = OmegaConf.to_container(cfg.estimator.l2)
        return run_job(cfg).set_index("estimator")

    run_dir = tmp_path / "run"
    first = run(run_dir)
    stamps = {p.name: p.stat().st_mtime_ns for p in run_dir.glob("jobs/*/*.summary.parquet")}
    identity = code_identity(module.__name__)
    again = run(run_dir)  # nothing changed: nothing recomputed
    assert {p.name: p.stat().st_mtime_ns for p in run_dir.glob("jobs/*/*.summary.parquet")} == stamps
    assert again.loc["shifted", "horizontal_median"] == first.loc["shifted", "horizontal_median"]

    module_path.write_text(PLUGIN.format(offset=100.0))  # the estimator's code changes, its config does not
    os.utime(module_path, ns=(module_path.stat().st_atime_ns, module_path.stat().st_mtime_ns + 1))
    module = importlib.reload(module)
    assert code_identity(module.__name__) != identity
    edited = run(run_dir)
    now = {p.name: p.stat().st_mtime_ns for p in run_dir.glob("jobs/*/*.summary.parquet")}
    l2 = next(n for n in stamps if n.startswith("l2-"))
    assert now[l2] == stamps[l2]  # the untouched estimator's result is reused
    assert len(now) == 2 and set(now) - set(stamps)  # the edited one's is new and replaced the old one
    assert edited.loc["shifted", "horizontal_median"] > first.loc["shifted", "horizontal_median"] + 50.0
    new = next(run_dir.glob("jobs/*/shifted-*.summary.parquet"))
    assert read_parquet_metadata(new)["simbench.code"]["estimator"] == code_identity(module.__name__)
    assert new.name.endswith(f"-{code_identity(module.__name__)}.summary.parquet")


@pytest.mark.slow
def test_ten_concurrent_reports_of_one_run_all_succeed(intact: Path, tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    shutil.copytree(intact, run_dir)
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "simbench", "report", str(run_dir)],
            cwd=REPO_ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(10)
    ]
    results = [(p.wait(timeout=600), p.stderr.read() if p.stderr else "") for p in procs]
    assert [code for code, _ in results] == [0] * 10, [err for code, err in results if code]
    assert len(pd.read_parquet(run_dir / "summary.parquet")) == 1
    assert not list(run_dir.rglob("*.tmp"))  # no temporary file left behind
