"""Scenario sources as plug-ins: entry-point discovery, one-line errors, and the example source end to end.

The built-ins (simulated, rinex, librsf) come through simbench's own entry points; the
example package (``examples/simbench-example-estimator``, source ``static_receiver``;
``.ci/run`` installs it) is the real plug-in. Broken packages are simulated with entry
points handed to :func:`simbench.source_registry.discover` or patched in for the CLI.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from conftest import EXAMPLE_MISSING, EXAMPLE_PACKAGE, FakeEntryPoint, cli_error_line, one_line_error, simbench_summary

from simbench import source_registry as sources
from simbench.contract import Scenario
from simbench.runs.compose import available, compose_config
from simbench.runs.scenarios import build_scenario, scenario_settings

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = "static_receiver"


def fake_source(name: str, source: str | None = None) -> type[sources.Source]:
    """A Source subclass called ``name`` whose ``Config`` declares ``source`` (default ``name``)."""
    config = dataclasses.make_dataclass(
        f"{name}_config", [("source", str, source if source is not None else name)], bases=(sources.SourceConfig,)
    )
    body = {"name": name, "Config": config, "load": lambda self, cfg: None}
    return type(f"Fake_{name}", (sources.Source,), body)


def test_built_ins_and_the_example_are_registered_by_entry_point() -> None:
    found = sources.plugins()
    assert EXAMPLE in found, EXAMPLE_MISSING
    assert found[EXAMPLE].package == EXAMPLE_PACKAGE
    built_ins = ("simulated", "rinex", "gnsslogger", "librsf")
    assert {name: found[name].package for name in built_ins} == dict.fromkeys(built_ins, "simbench")
    assert {*built_ins, EXAMPLE} <= set(available("scenario"))


def test_the_example_source_builds_from_its_config_defaults() -> None:
    settings = scenario_settings(compose_config([f"scenario={EXAMPLE}", "scenario.duration_s=10", "seed=1"]))
    assert type(settings.scenario).__name__ == "StaticReceiverConfig" and settings.scenario.duration_s == 10.0
    scenario = build_scenario(settings)
    assert isinstance(scenario, Scenario) and scenario.meta["source"] == EXAMPLE
    assert scenario.n_epochs == 10 and len(scenario.truth) == 10
    assert scenario.observations.groupby("epoch").size().min() >= 4


def test_the_example_source_runs_through_the_cli(tmp_path: Path) -> None:
    out = tmp_path / "run"
    summary = simbench_summary(out, f"scenario={EXAMPLE}", "scenario.duration_s=20", "estimator=[cauchy_spp]")
    assert list(summary["source"]) == [EXAMPLE] and (summary["status"] == "ok").all()
    # 1 m white code noise on six or more satellites: metre-level single-point fixes
    assert (summary["horizontal_median"] < 3.0).all()


def test_an_unknown_source_is_one_line_listing_the_known_ones() -> None:
    message = one_line_error(sources.get, "sp3")
    assert message.startswith("scenario.source: unknown source 'sp3' -- choose from ")
    assert all(name in message for name in ("librsf", "rinex", "simulated", EXAMPLE))
    assert one_line_error(compose_config, ["scenario.source=sp3"]) == message
    # a source whose Config cannot read the preset's keys: pick the source with its own preset
    message = one_line_error(scenario_settings, compose_config(["scenario=urban", "scenario.source=rinex"]))
    assert message.startswith("scenario.source: source 'rinex' cannot read") and "scenario=rinex" in message


@pytest.mark.parametrize(
    "entries, fragments",
    [
        ([FakeEntryPoint("gone", ImportError("No module named 'fake_plugins'"))], ["cannot load", "ImportError"]),
        ([FakeEntryPoint("func", len)], ["not a Source subclass"]),
        ([FakeEntryPoint("mislabelled", fake_source("mislabelled", "simulated"))], ["source: str = 'mislabelled'"]),
        ([FakeEntryPoint("alias", fake_source("other", "alias"))], ["Fake_other.name is 'other'"]),
        (
            [FakeEntryPoint("twin", fake_source("twin"), "first-pkg"), FakeEntryPoint("twin", fake_source("twin"))],
            ["name 'twin' of package 'first-pkg'"],
        ),
    ],
)
def test_a_broken_source_plugin_is_one_line_naming_its_package(
    entries: list[FakeEntryPoint], fragments: list[str]
) -> None:
    message = one_line_error(sources.discover, entries)
    assert message.startswith(f"source plug-in '{entries[-1].name}': package 'fake-plugins'")
    assert all(fragment in message for fragment in fragments)


def test_cli_stops_on_a_broken_source_plugin_in_one_line(fresh_discovery, monkeypatch, capsys) -> None:
    broken = [FakeEntryPoint("gone", ImportError("No module named 'fake_plugins'"))]
    monkeypatch.setattr(sources, "entry_points", lambda group: broken)
    line = cli_error_line(monkeypatch, capsys, "scenario=urban")
    assert line.startswith("error: source plug-in 'gone': package 'fake-plugins'")
