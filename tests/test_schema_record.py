"""The command line's door composes with recorded schemas: the same refusals, in the same words, without
importing an estimator or the simulation (issue 46: a refused command line in <= 2 s)."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from omegaconf import OmegaConf

import estimators
from simbench import source_registry as sources
from simbench.errors import SimbenchError
from simbench.runs import schema_record
from simbench.runs.schema_record import class_or_rebuilt, describe, read_record, rebuild, write_record
from simbench.typed import to_typed

ROOT = Path(__file__).resolve().parent.parent


def _configs() -> dict[str, type]:
    found = {f"estimator {n}": cls.Config for n, cls in estimators.registered().items()}
    return {**found, **{f"source {n}": cls.Config for n, cls in sources.registered().items()}}


def _bad_values(config: type) -> list[tuple[str, Any]]:
    """One value of the wrong type per field kind: a word for a number, a number for a choice."""
    bad = []
    for f in dataclasses.fields(config):
        default = getattr(config(), f.name)
        if isinstance(default, bool):
            bad.append((f.name, "maybe"))
        elif isinstance(default, (int, float)):
            bad.append((f.name, "abc"))
        elif isinstance(default, str) and hasattr(type(default), "__members__"):
            bad.append((f.name, "no_such_choice"))
    return bad


def _error(node: dict[str, Any], config: type) -> str:
    try:
        to_typed(node, config, "x")
    except SimbenchError as exc:
        return str(exc)
    return ""


@pytest.mark.parametrize("label", sorted(_configs()))
def test_a_rebuilt_config_types_as_its_original(label: str) -> None:
    config = _configs()[label]
    rebuilt = rebuild(json.loads(json.dumps(describe(config))))  # through JSON, as the record keeps it
    assert rebuilt.__name__ == config.__name__ and rebuilt is not config
    original = OmegaConf.to_container(OmegaConf.structured(config), enum_to_str=True)
    assert OmegaConf.to_container(OmegaConf.structured(rebuilt), enum_to_str=True) == original
    bad = _bad_values(config)
    assert bad, f"{label}: no field to check"
    for field, value in bad:
        message = _error({field: value}, config)
        assert message and _error({field: value}, rebuilt) == message, field
    assert _error({"no_such_field": 1}, rebuilt) == _error({"no_such_field": 1}, config)


def test_the_record_is_read_only_for_the_code_it_was_written_for(tmp_path: Path, monkeypatch) -> None:
    code = tmp_path / "code"
    code.mkdir()
    (code / "a.py").write_text("x = 1\n")
    monkeypatch.setattr(schema_record, "package_folders", lambda: [code])
    monkeypatch.setattr(schema_record, "record_path", lambda: tmp_path / "record.json")
    simulated = sources.get("simulated")
    assert write_record({"l2": estimators.get("l2").Config}, {}, {"simulated": simulated})
    record = read_record()
    assert record is not None and set(record.estimators) == {"l2"}
    assert record.sources["simulated"]["check"] == "simbench.sim.config:check_simulation"
    assert class_or_rebuilt(record.sources["simulated"]["config"]) is simulated.Config  # imported: the real one
    assert not write_record({"l2": estimators.get("l2").Config}, {}, {})  # current: kept
    (code / "b.py").write_text("y = 2\n")  # a new module
    assert read_record() is None


#: A refused value through the command line, then which heavy modules the process imported.
REFUSE = """
import sys
from simbench.cli.main import main
sys.argv = ["simbench", *sys.argv[1:]]
try:
    main()
except SystemExit as exc:
    print(exc.code)
heavy = ("gtsam", "sklearn", "scipy", "simbench.sim.generator", "estimators.batch.robust", "estimators.batch.bce",
         "estimators.gnss_ins.driver", "estimators.model.measurement")
print(",".join(sorted(m for m in heavy if m in sys.modules)))
"""


def _refuse(*args: str) -> tuple[str, str, str]:
    proc = subprocess.run([sys.executable, "-c", REFUSE, *args], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    code, imported = proc.stdout.splitlines()[-2:]  # the exit code, the heavy modules imported ('' for none)
    return code, imported, proc.stderr.strip()


#: (overrides, the one-line error after ``error: ``) of values refused before any estimator or the simulation
#: is imported; an error given with its fix (`` -- ``) is the whole line, else its start.
REFUSED_LIGHT: list[tuple[tuple[str, ...], str]] = [
    (
        ("scenario.duration_s=-5",),
        "scenario.duration_s: must be positive, got -5.0 -- give the scenario length in seconds, "
        "e.g. scenario.duration_s=600",
    ),
    (("estimator.dcs.kernel_width=nan",), "estimator.dcs.kernel_width: must be finite, got nan"),
    # a range only the estimator's code knows: its ``Config`` is imported from the family's light config
    # module (no solver), and says it in the same words
    (("estimator.dcs.kernel_width=-1",), "estimator.dcs.kernel_width: must be positive, got -1.0"),
    (
        ("estimator.bce.truncation=0",),
        "estimator.bce.truncation: must be at least 1, got 0 -- the defaults are in BceConfig "
        "(estimators/batch/configs.py)",
    ),
    (("estimator.crt_lss.window=0",), "estimator.crt_lss.window: must be at least 1, got 0"),
    # a log source's check is a function beside its Config (simbench.data.log_sources): no estimator either
    (
        ("scenario=librsf", "scenario.truth_max_gap_s=-1"),
        "scenario.truth_max_gap_s: must be positive and finite, got -1.0",
    ),
]


def test_a_refused_value_imports_no_estimator_and_no_simulation() -> None:
    _refuse("scenario.duration_s=-5")  # the first after an edit writes the record (every class imported)
    for args, message in REFUSED_LIGHT:
        code, imported, err = _refuse(*args)
        assert (code, imported) == ("2", ""), (args, imported)
        expected = f"error: {message}"
        assert (err == expected) if " -- " in message else err.startswith(expected), err
