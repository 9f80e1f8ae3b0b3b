"""Fixtures shared by the test files: the real data in ``shared/`` beside the repository.

A test that needs ``shared/`` takes the ``shared_dir`` or ``shared_data``
fixture. When the directory is missing such a test fails with one line (CI must
not pass by skipping it), unless ``SIMBENCH_ALLOW_MISSING_SHARED`` is set, for
machines that knowingly run without the data; then it is skipped.
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pandas as pd
import pytest
from threadpoolctl import threadpool_limits

import estimators
import simbench.cli.main as cli
from estimators.model.measurement import PppObservations, prepare_ppp
from estimators.model.ppp_config import MeasurementMode
from simbench import source_registry
from simbench.contract import ReceiverData
from simbench.errors import SimbenchError
from simbench.gnss.spp import SppSolution, solve_epochs
from simbench.paths import data_home
from simbench.runs.compose import preset_estimator_config, register_schemas

# One BLAS thread per test process, here and in the CLI runs the tests start: with
# ``pytest -n 2`` on 2 cores, OpenBLAS's spinning threads made the suite several times slower.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
threadpool_limits(limits=1)

#: Environment switch that turns a missing ``shared/`` from a failure into a skip.
ALLOW_MISSING_SHARED = "SIMBENCH_ALLOW_MISSING_SHARED"

#: The repository root (the parent of ``tests/``).
REPO_ROOT = Path(__file__).resolve().parent.parent


def shared_path(repo_root: Path = REPO_ROOT) -> Path:
    """Where the shared reference material lives: ``shared/`` next to the repository root."""
    return repo_root.parent / "shared"


def require_shared(path: Path, environ: Mapping[str, str] = os.environ) -> Path:
    """Return ``path`` if it is a directory; otherwise fail the test, or skip it when the switch is set.

    The switch counts as set for any value but empty and ``0``.
    """
    if path.is_dir():
        return path
    message = (
        f"shared data directory {path} not found -- put shared/ beside the repository, "
        f"or set {ALLOW_MISSING_SHARED}=1 to skip the tests that need it"
    )
    if environ.get(ALLOW_MISSING_SHARED, "") not in ("", "0"):
        pytest.skip(message)
    pytest.fail(message, pytrace=False)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Slow tests first (a stable sort): started last, one would keep a worker busy while the other idles."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """``<repository root>/../shared`` (REFERENCE.md, data/, seeds/)."""
    return require_shared(shared_path())


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The data home the named presets read (:func:`simbench.paths.data_home`): ``shared/data`` beside the
    repository, or the folder ``SIMBENCH_DATA`` names; the WVU drives, the Hong Kong and Nagoya logs."""
    return require_shared(data_home())


def truncate(path: Path) -> None:
    """Damage: cut the file to half its bytes."""
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def empty(path: Path) -> None:
    """Damage: the file holds no bytes."""
    path.write_bytes(b"")


def garble(path: Path) -> None:
    """Damage: flip 16 bytes in the middle; the file keeps its size, a Parquet file its footer and magic bytes."""
    data = bytearray(path.read_bytes())
    mid = len(data) // 2
    data[mid - 8 : mid + 8] = bytes(b ^ 0xFF for b in data[mid - 8 : mid + 8])
    path.write_bytes(bytes(data))


def one_line_error(fn, *args, **kwargs) -> str:
    """Call ``fn``; assert it raises a :class:`SimbenchError` whose message is one line of the
    form ``field: problem -- fix``; return the message."""
    with pytest.raises(SimbenchError) as info:
        fn(*args, **kwargs)
    msg = str(info.value)
    assert "\n" not in msg and " -- " in msg
    return msg


def dissertation(name: str, **changes: Any) -> Any:
    """Estimator ``name``'s ``Config`` under ``gnss_model=dissertation`` (Table 4.4.2's model) with ``changes``.

    For the tests of the published model: the dataclass defaults are the shipped ``urban`` preset's.
    """
    return dataclasses.replace(preset_estimator_config(name, "dissertation"), **changes)


@dataclasses.dataclass
class FakeEntryPoint:
    """What a plug-in group's ``discover`` reads of an ``importlib.metadata.EntryPoint``."""

    name: str
    target: Any  #: what ``load()`` returns, or the exception it raises
    package: str = "fake-plugins"

    @property
    def value(self) -> str:
        return f"fake_plugins:{getattr(self.target, '__name__', 'Broken')}"

    @property
    def dist(self) -> SimpleNamespace:
        return SimpleNamespace(name=self.package)

    def load(self) -> Any:
        if isinstance(self.target, Exception):
            raise self.target
        return self.target


# --- plug-ins and the command line ---------------------------------------------------------------

#: The example plug-in package (``examples/simbench-example-estimator``: estimator ``cauchy_spp``,
#: source ``static_receiver``); ``.ci/run`` installs it.
EXAMPLE_PACKAGE = "simbench-example-estimator"
#: What a test of the example says when it is not installed.
EXAMPLE_MISSING = (
    "the example plug-in is not installed: pip install -e examples/simbench-example-estimator (.ci/run does)"
)


@pytest.fixture
def fresh_discovery():
    """Plug-in discovery (estimators and sources) and the ConfigStore registration run again in the
    test, and again after it."""

    def clear() -> None:
        estimators.plugins.cache_clear()
        source_registry.plugins.cache_clear()
        register_schemas.cache_clear()

    clear()
    yield
    clear()


def run_simbench(*args: str, **kwargs: Any) -> subprocess.CompletedProcess:
    """``python -m simbench ARGS`` in a process of its own from the repository root, its output captured
    as text (at most 10 minutes; ``kwargs`` go to :func:`subprocess.run`)."""
    return subprocess.run(
        [sys.executable, "-m", "simbench", *args], cwd=REPO_ROOT, capture_output=True, text=True, timeout=600, **kwargs
    )


def simbench_summary(out: Path, *args: str) -> pd.DataFrame:
    """``python -m simbench ARGS results_dir=OUT progress=false`` (:func:`run_simbench`); assert it
    exits 0; its ``summary.parquet``."""
    proc = run_simbench(*args, f"results_dir={out}", "progress=false")
    assert proc.returncode == 0, proc.stderr[-2000:]
    return pd.read_parquet(out / "summary.parquet")


def cli_error_line(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    """Run ``python -m simbench ARGV`` in this process; assert it exits with code 2 and one line on
    stderr; return that line."""
    monkeypatch.setattr(sys, "argv", ["simbench", *argv])
    with pytest.raises(SystemExit) as info:
        cli.main()
    assert info.value.code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def single_point_fixes(
    view: ReceiverData, code_sigma_m: float, phase_sigma_m: float, elevation_mask_deg: float
) -> tuple[PppObservations, SppSolution]:
    """The shared model's rows of a receiver view (broadcast ionosphere, measurements ``auto``) and the
    single-point fix of each of its epochs (one clock per system)."""
    obs = prepare_ppp(
        view,
        ionosphere="broadcast",
        code_sigma_m=code_sigma_m,
        phase_sigma_m=phase_sigma_m,
        elevation_mask_deg=elevation_mask_deg,
        measurements=MeasurementMode.auto,
    )
    row_k = np.repeat(np.arange(obs.n_epochs), obs.epoch_stop - obs.epoch_start)
    fixes = solve_epochs(
        row_k, obs.sat_pos, obs.code, sigma=obs.sigma_code, el=obs.el, doy=obs.doy, system_index=obs.system_index
    )
    return obs, fixes
