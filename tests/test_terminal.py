"""What the terminal shows: one progress bar for a whole sweep under any launcher, steps and warnings
above it, skipped estimators as skipped, help text without Sphinx markup, and the names the fast
paths (--help, a misspelt name) read without importing an estimator."""

from __future__ import annotations

import dataclasses
import importlib.util
import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import run_simbench

import estimators
import simbench.cli.main as cli
from simbench.cli.progress import JobStatus, LiveBar, single_run, status_dir, sweep_files
from simbench.cli.terminal import compact_summary
from simbench.cli.text import plain_text
from simbench.runs.compose import register_schemas
from simbench.runs.groups import BUILT_IN_NAMES, available, recorded_built_in_estimators

ROOT = Path(__file__).resolve().parent.parent
#: What reStructuredText leaves in a terminal: inline literals and cross-reference roles.
SPHINX = re.compile(r"``|:(mod|func|class|data|meth|attr):`")
#: A tqdm bar as it is drawn, e.g. ``sweep: 100%|██████████| 2/2 [00:12<00:00, ...]``.
BAR = re.compile(r"(?P<desc>[a-z ]+): +\d+%\|[^|]*\| (?P<n>\d+)/(?P<total>\d+) ")


@pytest.mark.slow
def test_a_joblib_sweep_draws_one_bar_in_the_parent_that_ends_at_n_of_n(tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    sweep = ("-m", "seed=0,1", "scenario.duration_s=10", "estimator=[wls_spp]")
    proc = run_simbench(*sweep, "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", f"results_dir={out}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    draws = [m for m in BAR.finditer(proc.stderr)]
    # one bar: the parent's over the jobs; before, each worker drew its own over its estimators (0/1 ... 1/1)
    assert {m["desc"] for m in draws} == {"sweep"} and {m["total"] for m in draws} == {"2"}
    assert draws[-1]["n"] == "2" and [int(m["n"]) for m in draws] == sorted(int(m["n"]) for m in draws)
    # the bar ends before the summary: nothing of it is drawn after the results line
    assert not BAR.search(proc.stderr.split("results: ")[-1])
    assert "wls_spp" in proc.stdout and not (status_dir(out)).exists()  # the status files are removed


def test_the_bar_reads_the_jobs_status_files_with_their_steps_and_warnings(tmp_path: Path, capsys) -> None:
    directory = tmp_path / "progress"
    first = JobStatus(3, directory / "job0.json", "job0")
    second = JobStatus(3, directory / "job1.json", "job1")
    first.update(3)
    first.close()
    second.update(1)
    second.set_postfix_str("urban seed 1: reading or building the scenario")
    second.message("warning: a thing")
    snap = sweep_files(directory)()
    assert (snap.done, snap.estimators_done, snap.estimators) == (1, 4, 6)
    assert len(snap.steps) == 1 and snap.steps[0].startswith("job1 urban seed 1: reading or building the scenario ")
    bar = LiveBar(sweep_files(directory), 2, "job")
    second.update(2)
    second.close()
    bar.close()
    err = capsys.readouterr().err
    assert err.count("warning: a thing") == 1  # printed above the bar, once
    assert BAR.findall(err)[-1] == ("sweep", "2", "2") and "6/6 est" in err.splitlines()[-1]


def test_a_single_run_bar_counts_estimators_and_shows_the_step() -> None:
    status = JobStatus(4)
    status.update(2)
    status.set_postfix_str("urban seed 0: ekf_ppp")
    snap = single_run(status)()
    assert (snap.done, snap.estimators) == (2, 4) and snap.steps[0].startswith("urban seed 0: ekf_ppp ")
    status.close()
    assert single_run(status)().steps == []


def test_a_skipped_estimator_reads_skipped_not_zero_of_one() -> None:
    rows = pd.DataFrame(
        {
            "estimator": ["ekf_ins", "l2", "l2", "dcs", "dcs"],
            "status": ["skipped", "ok", "skipped", "ok", "failed"],
            "message": ["no IMU", "", "no IMU", "", "boom"],
            "availability": [0.0, 1.0, 0.0, 1.0, 0.0],
            "horizontal_median_ref": [np.nan, 2.0, np.nan, 3.0, np.nan],
            "horizontal_p95_ref": [np.nan, 4.0, np.nan, 5.0, np.nan],
            "error_3d_median_ref": [np.nan, 3.0, np.nan, 4.0, np.nan],
            "total_s": [np.nan, 1.0, np.nan, 1.0, np.nan],
            "n_epochs": 10,
        }
    )
    ok = {line.split()[0]: line.split()[1:4] for line in compact_summary(rows).splitlines()[2:5]}
    assert ok["ekf_ins"][0] == "skipped"
    assert ok["l2"][:3] == ["1/1", "+1", "skipped"]  # the skipped row is not counted against l2
    assert ok["dcs"][0] == "1/2"  # a failure is


@pytest.mark.parametrize("name", sorted(cli.SUBCOMMANDS))
def test_subcommand_help_has_no_sphinx_markup(name: str, capsys, monkeypatch) -> None:
    monkeypatch.setattr(sys, "argv", ["simbench", name, "--help"])
    with pytest.raises(SystemExit) as info:
        cli.main()
    assert info.value.code == 0
    text = capsys.readouterr().out
    assert len(text.splitlines()) >= 2 and not SPHINX.search(text), text


def test_main_help_has_no_sphinx_markup(capsys, monkeypatch) -> None:
    monkeypatch.setattr(sys, "argv", ["simbench", "--help"])
    cli.main()
    text = capsys.readouterr().out
    assert text.startswith("simbench -- ") and not SPHINX.search(text)


def test_plain_text_keeps_the_words_of_markup() -> None:
    doc = "``simbench score RUN``: a row (:mod:`simbench.runs.foreign`, :func:`~simbench.runs.x.score`)::\n"
    assert plain_text(doc) == "simbench score RUN: a row (simbench.runs.foreign, score):\n"


def test_the_name_checks_read_the_built_in_names_recorded_at_registration(monkeypatch) -> None:
    register_schemas.cache_clear()
    register_schemas()
    assert recorded_built_in_estimators() == sorted(estimators.built_in())
    assert set(estimators.built_in()) <= set(available("estimator"))  # without importing, in a new process
    record = Path(importlib.util.find_spec("estimators").origin).parent / "__pycache__" / BUILT_IN_NAMES
    record.write_text(record.read_text().replace('"stamp": [[', '"stamp": [["edited.py", 1, 1], ['))
    assert recorded_built_in_estimators() is None  # an estimator file changed: the record tells nothing
    # a name it lacks is then checked against the imported estimators, which records them again
    assert "l2" in cli.all_estimator_options() and recorded_built_in_estimators() == sorted(estimators.built_in())
    # a class without a module file of the package (a test's) is registered in that process, not recorded
    config = dataclasses.make_dataclass("BrandNewConfig", [("k", float, 1.0)])
    fake = type("Fake", (estimators.Estimator,), {"name": "brand_new", "Config": config})
    fake.__module__ = "estimators.brand_new"
    built_in = estimators.built_in()
    monkeypatch.setattr(estimators, "built_in", lambda: {**built_in, "brand_new": fake})
    register_schemas.cache_clear()
    register_schemas()
    assert "brand_new" not in (recorded_built_in_estimators() or [])
    register_schemas.cache_clear()
