"""Plug-in estimators: entry-point discovery, their config, one-line errors, and a run through the CLI.

The installed example (``examples/simbench-example-estimator``, estimator
``cauchy_spp``; ``.ci/run`` installs it) is the real plug-in; broken packages are
simulated with entry points handed to :func:`estimators.discover` or patched in
for the CLI, so nothing else is installed.
"""

from __future__ import annotations

import dataclasses
import importlib
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
from conftest import EXAMPLE_MISSING, EXAMPLE_PACKAGE, FakeEntryPoint, cli_error_line, one_line_error, simbench_summary
from omegaconf import OmegaConf

import estimators
import simbench.cli.main as cli
from simbench.runs.compose import compose_config, plugin_config_node
from simbench.typed import to_typed

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = "cauchy_spp"


def fake_estimator(name: str, config: Any = "dataclass") -> type[estimators.Estimator]:
    """An Estimator subclass called ``name``; ``config`` None leaves out ``Config``."""
    body: dict[str, Any] = {"name": name, "_estimate": lambda self, data: (pd.DataFrame(), {})}
    if config == "dataclass":
        body["Config"] = dataclasses.make_dataclass(f"{name}_config", [("k", float, 1.0)])
    elif config is not None:
        body["Config"] = config
    return type(f"Fake_{name}", (estimators.Estimator,), body)


def test_installed_example_is_listed_and_configured_from_its_dataclass() -> None:
    assert EXAMPLE in estimators.plugins(), EXAMPLE_MISSING
    assert estimators.source(EXAMPLE) == EXAMPLE_PACKAGE and estimators.source("l2") == estimators.BUILT_IN
    table = cli.estimator_table().set_index("name")
    assert table.loc[EXAMPLE, "source"] == EXAMPLE_PACKAGE
    assert table.loc[EXAMPLE, "family"] == "simbench_example_estimator"
    assert (table.drop(EXAMPLE)["source"] == estimators.BUILT_IN).all()
    config = estimators.get(EXAMPLE).Config
    # in the default run and the smoke sweep, with the dataclass defaults (its shipped YAML overrides none;
    # the shared sigma-model fields follow gnss_model, whose default preset has the same values)
    for overrides in ([], ["+sweep=smoke"]):
        composed = compose_config(overrides).estimator
        assert set(composed) == set(estimators.registered())
        typed = to_typed(OmegaConf.to_container(composed[EXAMPLE], resolve=True), config, EXAMPLE)
        assert typed == config() and typed.cauchy_c == 2.385
    chosen = compose_config([f"estimator=[l2,{EXAMPLE}]", f"estimator.{EXAMPLE}.cauchy_c=3"]).estimator
    assert list(chosen) == ["l2", EXAMPLE] and chosen[EXAMPLE].cauchy_c == 3.0


@pytest.mark.parametrize(
    "entries, fragments",
    [
        ([FakeEntryPoint("l2", fake_estimator("l2"))], ["name 'l2' of a built-in estimator"]),
        (
            [
                FakeEntryPoint("twin", fake_estimator("twin"), "first-pkg"),
                FakeEntryPoint("twin", fake_estimator("twin")),
            ],
            ["name 'twin' of package 'first-pkg'"],
        ),
        ([FakeEntryPoint("bare", fake_estimator("bare", config=None))], ["Fake_bare has no Config dataclass"]),
        ([FakeEntryPoint("plain", fake_estimator("plain", config=dict))], ["Fake_plain has no Config dataclass"]),
        ([FakeEntryPoint("alias", fake_estimator("other"))], ["Fake_other.name is 'other'"]),
        ([FakeEntryPoint("all", fake_estimator("all"))], ["reserved name 'all'"]),
        ([FakeEntryPoint("gone", ImportError("No module named 'fake_plugins'"))], ["cannot load", "ImportError"]),
        ([FakeEntryPoint("func", len)], ["not an Estimator subclass"]),
    ],
)
def test_a_broken_plugin_is_one_line_naming_its_package(entries: list[FakeEntryPoint], fragments: list[str]) -> None:
    message = one_line_error(estimators.discover, entries, estimators.built_in())
    assert message.startswith(f"estimator plug-in '{entries[-1].name}': package 'fake-plugins'")
    for fragment in fragments:
        assert fragment in message


def test_the_same_class_from_two_entry_points_is_no_clash() -> None:
    cls = fake_estimator("once")
    found = estimators.discover([FakeEntryPoint("once", cls), FakeEntryPoint("once", cls)], estimators.built_in())
    assert found == {"once": estimators.Plugin(cls=cls, package="fake-plugins")}


def test_cli_stops_on_a_clashing_plugin_in_one_line(fresh_discovery, monkeypatch, capsys) -> None:
    monkeypatch.setattr(estimators, "entry_points", lambda group: [FakeEntryPoint("dcs", fake_estimator("dcs"))])
    line = cli_error_line(monkeypatch, capsys, "--estimators")
    assert line.startswith("error: estimator plug-in 'dcs': package 'fake-plugins'")


def _plugin_module(tmp_path: Path, monkeypatch, yaml_text: str | None) -> estimators.Plugin:
    """A plug-in class in a module file of its own, with ``yaml_est.yaml`` beside it when given."""
    module = f"plugin_{tmp_path.name}"  # one module per test: imports are cached by name
    (tmp_path / f"{module}.py").write_text(
        "import dataclasses\nfrom estimators.base import Estimator\n\n"
        "@dataclasses.dataclass\nclass YamlConfig:\n    k: float = 1.0\n    mode: str = 'fast'\n\n"
        "class YamlEst(Estimator):\n    name = 'yaml_est'\n    Config = YamlConfig\n\n"
        "    def _estimate(self, data):\n        raise NotImplementedError\n"
    )
    if yaml_text is not None:
        (tmp_path / "yaml_est.yaml").write_text(yaml_text)
    monkeypatch.syspath_prepend(str(tmp_path))
    return estimators.Plugin(cls=importlib.import_module(module).YamlEst, package="yaml-pkg")


HEAD = "defaults:\n  - yaml_est_schema\n  - _self_\n"


@pytest.mark.parametrize(
    "yaml_text, node",
    [
        (None, {}),
        (HEAD + "yaml_est:\n  k: 2.5  # override: shipped\n", {"k": 2.5}),
        ("yaml_est:\n  mode: slow  # override: shipped\n", {"mode": "slow"}),
    ],
)
def test_shipped_yaml_overrides_the_dataclass(
    tmp_path: Path, monkeypatch, yaml_text: str | None, node: dict[str, Any]
) -> None:
    plugin = _plugin_module(tmp_path, monkeypatch, yaml_text)
    assert plugin_config_node(plugin) == {"defaults": ["yaml_est_schema", "_self_"], "yaml_est": node}


@pytest.mark.parametrize(
    "yaml_text, fragment",
    [
        ("yaml_est:\n  k: soft\n", "estimator.yaml_est.k"),
        ("yaml_est: {}\nother: 1\n", "must hold only"),
        ("defaults: [l2_schema, _self_]\nyaml_est: {}\n", "must hold only"),
        ("yaml_est: [unclosed\n", "is not YAML"),
    ],
)
def test_a_bad_shipped_yaml_is_one_line_naming_the_package(
    tmp_path: Path, monkeypatch, yaml_text: str, fragment: str
) -> None:
    plugin = _plugin_module(tmp_path, monkeypatch, yaml_text)
    message = one_line_error(plugin_config_node, plugin)
    assert message.startswith("estimator plug-in 'yaml_est': package 'yaml-pkg'") and fragment in message


def test_the_example_runs_in_a_sweep_through_the_cli(tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    sweep = ("-m", "scenario=open_sky", "receiver=high", "scenario.duration_s=30", "seed=0", f"estimator=[{EXAMPLE}]")
    summary = simbench_summary(out, *sweep)
    assert list(summary["estimator"]) == [EXAMPLE] and (summary["status"] == "ok").all()
    assert (summary["availability"] == 1.0).all()
    # open sky, single-point code with Klobuchar: about a metre horizontally (1.0 m when written with
    # the low receiver; its 4.092 MHz sample grid now costs a single-point fix metres, hence high)
    assert (summary["horizontal_median"] < 3.0).all()
    assert EXAMPLE in (out / "report" / "README.md").read_text()


def test_a_built_in_module_without_its_yaml_runs_on_its_defaults(fresh_discovery, monkeypatch) -> None:
    """README: a new estimator module is all it takes. Before, a built-in without conf/estimator/<name>.yaml
    broke every default run ("Could not load 'estimator/<name>'")."""
    new = fake_estimator("brand_new")
    new.__module__ = "estimators.brand_new"
    built_in = estimators.built_in()
    monkeypatch.setattr(estimators, "built_in", lambda: {**built_in, "brand_new": new})
    assert not (ROOT / "conf" / "estimator" / "brand_new.yaml").exists()
    assert "brand_new" in compose_config([]).estimator  # the default run, estimator=all
    chosen = compose_config(["estimator=[brand_new]", "estimator.brand_new.k=3"]).estimator
    assert list(chosen) == ["brand_new"] and chosen.brand_new.k == 3.0


#: A new built-in estimator module without a YAML: ``wls_spp`` under another name, with one more parameter.
NEW_MODULE = '''
from dataclasses import dataclass

from estimators import register
from estimators.baselines.spp import WlsSpp
from estimators.baselines.configs import WlsSppConfig


@dataclass
class BrandNewConfig(WlsSppConfig):
    """wls_spp's parameters and one the estimator adds."""

    extra_weight: float = 1.0


@register
class BrandNew(WlsSpp):
    """wls_spp as a new module."""

    name = "brand_new"
    Config = BrandNewConfig
'''

#: Runs the module above as a module of the ``estimators.baselines`` family (its folder joins the package's
#: path, as a file in estimators/baselines/ would be found) through simbench.run, in a process of its own: the
#: registry keeps it.
RUN_NEW_MODULE = """
import sys
import estimators.baselines
import simbench

estimators.baselines.__path__.append(sys.argv[1])
result = simbench.run("open_sky", "high", estimators=["wls_spp", "brand_new"], results_dir=sys.argv[2],
                      overrides={"scenario.duration_s": 20, "estimator.brand_new.extra_weight": 2.0}, progress=False)
print(result.summary[["estimator", "status", "overrides", "horizontal_median"]].to_json(orient="records"))
"""


def test_a_new_estimator_module_without_yaml_runs_by_its_name(tmp_path: Path) -> None:
    """README and docs/extending.md: a built-in estimator is its module; its node comes from its Config."""
    folder = tmp_path / "new_estimators"
    folder.mkdir()
    (folder / "brand_new.py").write_text(NEW_MODULE)
    assert not (ROOT / "conf" / "estimator" / "brand_new.yaml").exists()
    proc = subprocess.run(
        [sys.executable, "-c", RUN_NEW_MODULE, str(folder), str(tmp_path / "run")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = {row["estimator"]: row for row in json.loads(proc.stdout.strip().splitlines()[-1])}
    assert rows["brand_new"]["status"] == rows["wls_spp"]["status"] == "ok"
    assert rows["brand_new"]["overrides"] == '{"extra_weight":2.0}'  # typed by its Config, relative to its defaults
    # the same solver on the same data: the same positions
    assert rows["brand_new"]["horizontal_median"] == rows["wls_spp"]["horizontal_median"]
