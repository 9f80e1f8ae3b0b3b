"""A run of several studies over several worlds (``+sweep=thesis worlds=[...]``): plan, command line, report."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import simbench.cli.studies
import simbench.runs.studies
from simbench.analysis.claims import claims_table
from simbench.cli.main import config_overrides
from simbench.errors import SimbenchError
from simbench.report.build import build_report
from simbench.runs.compose import compose_config
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS
from simbench.runs.studies import STUDY_TIMES, StudiesConfig, StudyProcess, plan, run_study_process, time_budget

ROOT = Path("results/thesis")


def _studies(args: list[str]) -> StudiesConfig:
    cfg = compose_config(config_overrides(args))
    return StudiesConfig.from_config(cfg)


def test_thesis_over_worlds_puts_each_study_and_world_in_its_own_folder() -> None:
    args = ["+sweep=thesis", "worlds=[urban,morgantown1]", "hydra/launcher=joblib", "seed=range(0,5)"]
    cfg = _studies(args)  # the seed range (a sweep) is left to the studies, not composed here
    assert cfg.worlds == ["urban", "morgantown1"] and cfg.own_scenario == ["ch4_convergence"]
    runs = plan(cfg, ROOT, args)
    assert [(r.study, r.world) for r in runs[:3]] == [
        ("ch4_convergence", ""),
        ("ch5_bce", "urban"),
        ("ch5_bce", "morgantown1"),
    ]
    # the drive runs the studies the dissertation measured on collect 1
    assert len(runs) == 1 + (len(cfg.studies) - 1) + 4
    assert {r.study for r in runs if r.world == "morgantown1"} == {
        "ch5_bce",
        "ch5_sensitivity",
        "ch6_bce_ad",
        "ch7_ice",
    }
    ch4, ch5_mt = runs[0], runs[2]
    assert ch4.results_dir == ROOT / "ch4_convergence" and not any(a.startswith("scenario=") for a in ch4.args)
    assert ch5_mt.results_dir == ROOT / "morgantown1" / "ch5_bce"
    # the thesis's own override of the study, then the command line's
    # the world's other studies share their identical rows with this one
    siblings = ",".join(f"'{ROOT / 'morgantown1' / s}'" for s in ("ch5_sensitivity", "ch6_bce_ad", "ch7_ice"))
    assert ch5_mt.args == [
        "+sweep=ch5_bce",
        "scenario=morgantown1",
        f"results_dir={ROOT / 'morgantown1/ch5_bce'}",
        f"shared_results=[{siblings}]",
        "estimator=[l2,dcs,mm,bce,oracle]",
        "hydra/launcher=joblib",
        "seed=range(0,5)",
    ]
    assert "estimator=[l2,dcs,mm,bce,oracle]" not in runs[-1].args  # crt_window keeps its estimators
    # the world replaces the sweep file's scenario; the study's own scenario settings stay
    # Hydra's deletion of an own key is not passed down either (a study has no world_studies)
    trimmed = _studies([*args, "~world_studies"])
    assert trimmed.world_studies == {}
    assert not any("world_studies" in a for run in plan(trimmed, ROOT, [*args, "~world_studies"]) for a in run.args)
    study = compose_config(["+sweep=ch7_ice", "scenario=morgantown1"])
    assert study.scenario.name == "morgantown1" and study.scenario.duration_s == 1200.0


def test_bad_worlds_are_one_line_errors() -> None:
    with pytest.raises(SimbenchError, match=r"^worlds: unknown nosuch -- choose from .*urban"):
        plan(StudiesConfig(studies=["ch5_bce"], worlds=["nosuch"]), ROOT, [])
    with pytest.raises(SimbenchError, match=r"^scenario: .* together with worlds -- list the scenario presets"):
        plan(StudiesConfig(studies=["ch5_bce"], worlds=["urban"]), ROOT, ["scenario=flight"])
    with pytest.raises(SimbenchError, match=r"^own_scenario: unknown ch4_convergence"):
        plan(StudiesConfig(studies=["ch5_bce"], own_scenario=["ch4_convergence"]), ROOT, [])
    with pytest.raises(SimbenchError, match=r"^study_args: unknown ch7_ice -- choose from ch5_bce"):
        plan(StudiesConfig(studies=["ch5_bce"], study_args={"ch7_ice": ["seed=1"]}), ROOT, [])
    with pytest.raises(SimbenchError, match=r"^world_studies.urban: unknown ch7_ice -- choose from ch5_bce"):
        plan(StudiesConfig(studies=["ch5_bce"], worlds=["urban"], world_studies={"urban": ["ch7_ice"]}), ROOT, [])
    with pytest.raises(SimbenchError, match=r"^world_studies: unknown nosuch -- choose from .*urban"):
        plan(StudiesConfig(studies=["ch5_bce"], worlds=["urban"], world_studies={"nosuch": ["ch5_bce"]}), ROOT, [])
    # Hydra merges an empty dict into the sweep file's: the thesis would still skip studies on the drives
    with pytest.raises(
        SimbenchError, match=r"^world_studies: an empty dict merges .* -- delete the key instead: '~world_studies'$"
    ):
        plan(StudiesConfig(studies=["ch5_bce"], worlds=["urban"]), ROOT, ["world_studies={}"])


def test_config_overrides_drops_sweeps_only() -> None:
    assert config_overrides(
        [
            "+sweep=smoke",
            "seed=0,1",
            "estimator=[l2,dcs]",
            "worlds=[a,b]",
            "hydra.sweeper.params.seed=0",
            "hydra/launcher=joblib",
        ]
    ) == ["+sweep=smoke", "estimator=[l2,dcs]", "worlds=[a,b]", "hydra/launcher=joblib"]
    assert config_overrides(["-m", "seed=0,1"]) is None


def _summary() -> pd.DataFrame:
    """ch5_bce rows on two worlds: BCE clearly lower on urban, not on urban_deep; timed."""
    base = 5.0 + np.random.default_rng(1).normal(0, 0.3, 6)
    rows = [
        {
            "sweep": "ch5_bce",
            "scenario": world,
            "receiver": "low",
            "seed": seed,
            "estimator": name,
            "overrides": "{}",
            "variant": "",
            "status": "ok",
            "source": "simulated",
            "uses_labels": False,
            "horizontal_median": base[seed] * factor,
            "total_s": seconds,
            "n_epochs": 600,
            "n_solved": 600,
            "availability": 1.0,
        }
        for world, bce in (("urban", 0.7), ("urban_deep", 1.2))
        for name, factor, seconds in (("bce", bce, 10.0), ("l2", 1.0, 1.0), ("dcs", 1.0, 2.0), ("mm", 1.1, 2.0))
        for seed in range(6)
    ]
    return pd.DataFrame(rows).reindex(columns=list(SUMMARY_COLUMNS))


def test_time_budget_sums_the_estimators_time_per_sweep_world_and_estimator() -> None:
    table = time_budget(_summary())
    top = table.iloc[0]
    assert top["estimator"] == "bce" and top["jobs"] == 6 and top["total_s"] == pytest.approx(60.0)
    assert table["share"].sum() == pytest.approx(1.0) and top["share"] == pytest.approx(60.0 / 180.0)


def test_report_shows_one_claims_column_per_world_and_the_study_times(tmp_path: Path) -> None:
    summary = _summary()
    claims = claims_table(summary, pd.DataFrame(columns=list(EPOCH_COLUMNS)), {})
    pd.DataFrame(
        [
            {"study": "ch5_bce", "world": w, "wall_s": 90.0, "exit_code": 0, "results_dir": "x"}
            for w in ("urban", "urban_deep")
        ]
    ).to_csv(tmp_path / STUDY_TIMES, index=False)
    page = (
        build_report(tmp_path, summary, pd.DataFrame(columns=list(EPOCH_COLUMNS)), claims, {}) / "README.md"
    ).read_text()
    header = next(
        ln for ln in page.splitlines() if ln.startswith("| claim_id") and "published" in ln and "urban_deep" in ln
    )
    assert [c.strip() for c in header.strip("|").split("|")][-2:] == ["urban", "urban_deep"]
    row = next(ln for ln in page.splitlines() if ln.startswith("| ch5_bce_low ") and "does not hold" in ln)
    assert " holds " in row.replace("does not hold", "")  # urban holds, urban_deep does not, one row
    assert "Where the time went" in page and "total 3.0 min" in page
    assert "11 of 12 published claims not measured" in page


def test_run_studies_records_every_study_and_keeps_earlier_invocations(tmp_path: Path, monkeypatch) -> None:
    calls: list[list[str]] = []

    def fake_process(cmd: list[str]) -> StudyProcess:  # a study process: fails on urban_deep
        calls.append(cmd)
        return StudyProcess(1 if "scenario=urban_deep" in cmd else 0, 100.0 + len(calls))

    monkeypatch.setattr(simbench.runs.studies, "run_study_process", fake_process)
    reported: list[list[str]] = []

    def fake_finalize(root: Path, config: dict, formats: list[str]) -> Path:
        reported.append(list(formats))
        return root / "report"

    monkeypatch.setattr(simbench.cli.studies, "finalize", fake_finalize)
    cfg = StudiesConfig(studies=["ch5_bce", "ch6_bce_ad"], worlds=["urban"])
    assert simbench.cli.studies.run_studies(cfg, tmp_path, ["hydra/launcher=joblib"], ["png", "pdf"]) == 0
    assert reported == [["png", "pdf"]]  # the aggregate report gets the command line's formats
    assert [c[3:6] for c in calls] == [
        ["+sweep=ch5_bce", "scenario=urban", f"results_dir={tmp_path / 'urban/ch5_bce'}"],
        ["+sweep=ch6_bce_ad", "scenario=urban", f"results_dir={tmp_path / 'urban/ch6_bce_ad'}"],
    ]
    cfg.worlds = ["urban_deep"]
    assert simbench.cli.studies.run_studies(cfg, tmp_path, []) == 1  # a failed study: exit code 1, the others ran
    times = pd.read_csv(tmp_path / STUDY_TIMES, keep_default_na=False)
    assert list(zip(times["study"], times["world"], times["exit_code"])) == [
        ("ch5_bce", "urban", 0),
        ("ch6_bce_ad", "urban", 0),
        ("ch5_bce", "urban_deep", 1),
        ("ch6_bce_ad", "urban_deep", 1),
    ]
    assert (times["wall_s"] >= 0).all()
    assert times["peak_rss_mb"].tolist() == [101.0, 102.0, 103.0, 104.0]


def test_a_study_process_reports_the_peak_memory_of_its_workers(tmp_path: Path) -> None:
    """The peak of a worker process the study started counts, not only the study process's own."""
    script = tmp_path / "study.py"
    script.write_text(
        "import multiprocessing as mp, sys\n"
        "def work():\n"
        "    block = bytearray(300 * 2**20)\n"
        "    block[::4096] = b'x' * len(block[::4096])\n"  # touch every page: resident, not just reserved
        "if __name__ == '__main__':\n"
        "    p = mp.get_context('spawn').Process(target=work)\n"
        "    p.start(); p.join()\n"
        "    sys.exit(3)\n"
    )
    ended = run_study_process([sys.executable, str(script)])
    assert ended.exit_code == 3
    assert 300 < ended.peak_rss_mb < 1000
