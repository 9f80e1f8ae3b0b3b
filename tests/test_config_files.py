"""``conf/`` against the typed schemas: minimal estimator YAML, documented overrides, choice fields.

An estimator file ``conf/estimator/<name>.yaml`` starts from its ``Config``
dataclass (``defaults: [<name>_schema, _self_]``) and holds under ``<name>:``
only values that differ from the dataclass defaults, each documented by a
trailing ``# override: <reason>`` comment. Restating a default is an error
too: the dataclass is the one place a default lives. A plug-in estimator's
shipped ``<name>.yaml`` follows the same rule. Scenario, receiver and
IMU presets are overrides by nature (a preset *is* its values), so they need
no comment; for them every key must be a schema field and every value must
type-check, which composing them checks.
"""

from __future__ import annotations

import dataclasses
import json
import re
from typing import Any

import pytest
import yaml
from omegaconf import OmegaConf

import estimators
from estimators.model.ppp_config import (
    GnssModelConfig,
    IonosphereMode,
    MotionModel,
    NlosModel,
    SigmaModel,
    VarianceComponents,
    WetDelayMode,
)
from simbench.data.log_sources import RinexConfig
from simbench.errors import SimbenchError
from simbench.runs.compose import CONF_DIR, available, compose_config, estimator_yaml, overrides_from_kwargs
from simbench.runs.scenarios import ScenarioSettings, check_scenario, scenario_settings
from simbench.runs.store import config_key
from simbench.sim.config import SimConfig, TrajectoryKind, validate_sim
from simbench.typed import check_choices, to_typed

NAMES = sorted(estimators.registered())
#: Estimators with a YAML file: every built-in's conf/estimator/<name>.yaml, a plug-in's shipped one.
WITH_YAML = [name for name in NAMES if estimator_yaml(name) is not None]
OVERRIDE_COMMENT = re.compile(r"#\s*override:\s*\S")


def estimator_yaml_problems(text: str, name: str, config: type) -> list[str]:
    """Every way an estimator YAML text breaks the minimal-file rule (empty when it follows it).

    Parameters
    ----------
    text : str
        Contents of ``conf/estimator/<name>.yaml``.
    name : str
        Estimator name: the one node besides ``defaults``.
    config : type
        The estimator's ``Config`` dataclass.
    """
    problems = []
    top = yaml.safe_load(text) or {}
    if set(top) != {"defaults", name}:
        problems.append(f"top-level keys {sorted(top)}, expected ['defaults', '{name}']")
    if top.get("defaults") != [f"{name}_schema", "_self_"]:
        problems.append(f"defaults {top.get('defaults')}, expected ['{name}_schema', '_self_']")
    root = yaml.compose(text)
    node = next((v for k, v in (root.value if root else []) if k.value == name), None)
    if node is None:
        return problems
    if not isinstance(node, yaml.MappingNode):
        return problems + [f"{name}: must be a mapping (possibly {{}})"]
    fields = {f.name for f in dataclasses.fields(config)}
    defaults = config()
    lines = text.splitlines()
    for key_node, value_node in node.value:
        key = key_node.value
        if key not in fields:
            problems.append(f"{key}: not a field of {config.__name__}")
            continue
        try:
            value = getattr(to_typed({key: yaml.safe_load(yaml.serialize(value_node))}, config, name), key)
        except SimbenchError as exc:
            problems.append(f"{key}: {exc}")
            continue
        documented = bool(OVERRIDE_COMMENT.search(lines[key_node.start_mark.line]))
        if value == getattr(defaults, key):
            problems.append(f"{key}: restates the dataclass default {getattr(defaults, key)!r}; delete it")
        elif not documented:
            problems.append(
                f"{key}: {value!r} differs from the default {getattr(defaults, key)!r} without a "
                "'# override: <reason>' comment"
            )
    return problems


@pytest.mark.parametrize("name", WITH_YAML)
def test_estimator_yaml_holds_only_documented_overrides(name: str) -> None:
    text = estimator_yaml(name).read_text()
    assert estimator_yaml_problems(text, name, estimators.get(name).Config) == []


def test_every_built_in_estimator_has_one_yaml_and_every_yaml_an_estimator() -> None:
    assert sorted(p.stem for p in (CONF_DIR / "estimator").glob("*.yaml")) == sorted(estimators.built_in())


def test_the_yaml_rule_catches_each_kind_of_violation() -> None:
    config = estimators.get("l2").Config
    head = "defaults:\n  - l2_schema\n  - _self_\n\n"
    assert config().prior_scale == 1.0 and config().max_iterations == 100  # the cases below rely on these
    assert estimator_yaml_problems(head + "l2: {}\n", "l2", config) == []
    assert estimator_yaml_problems(head + "l2:\n  prior_scale: 3.0  # override: Fig. 5.3.7 point\n", "l2", config) == []
    undocumented = estimator_yaml_problems(head + "l2:\n  prior_scale: 3.0  # larger\n", "l2", config)
    assert len(undocumented) == 1 and "prior_scale: 3.0 differs" in undocumented[0]
    restated = estimator_yaml_problems(head + "l2:\n  max_iterations: 100  # override: same\n", "l2", config)
    assert len(restated) == 1 and "restates the dataclass default 100" in restated[0]
    # an int written for a float field is the same value, not an override
    assert "restates" in estimator_yaml_problems(head + "l2:\n  prior_scale: 1\n", "l2", config)[0]
    unknown = estimator_yaml_problems(head + "l2:\n  window: 5  # override: no such field\n", "l2", config)
    assert unknown == ["window: not a field of L2Config"]
    wrong_type = estimator_yaml_problems(head + "l2:\n  clock_model: pink  # override: bad\n", "l2", config)
    assert len(wrong_type) == 1 and "clock_model" in wrong_type[0] and "random_walk" in wrong_type[0]
    no_schema = estimator_yaml_problems("l2: {}\n", "l2", config)
    assert len(no_schema) == 2 and "defaults" in no_schema[1]


def test_composed_estimator_configs_are_the_dataclass_defaults_but_for_the_gnss_model() -> None:
    """The default ``urban`` gives the dataclass defaults; ``gnss_model=dissertation`` differs from them
    exactly in the :class:`GnssModelConfig` fields, and an estimator's own setting still wins."""
    dissertation = compose_config(["gnss_model=dissertation"])
    urban = compose_config([])
    model = to_typed(OmegaConf.to_container(urban.gnss_model), GnssModelConfig, "gnss_model")
    assert model == GnssModelConfig() and model.name == "urban"  # the shipped default is the dataclass default
    profile = {field: getattr(model, field) for field in GnssModelConfig.model_fields()}
    assert profile == {
        "motion_model": MotionModel.constant_velocity,
        "sigma_model": SigmaModel.cn0,
        "doppler_slip_m": 1.0,
        "min_satellites": 1,
        "scaled_mixture": True,
        "nlos_model": NlosModel.conditioned,
        "outlier_scale": 10.0,
        "ionosphere": IonosphereMode.auto,
        "variance_components": VarianceComponents.system,
        "iono_sigma_m": 1.0,
        "wet_delay": WetDelayMode.auto,
    }
    table = {
        "motion_model": MotionModel.random_walk,
        "sigma_model": SigmaModel.elevation,
        "doppler_slip_m": 0.0,
        "min_satellites": 4,
        "scaled_mixture": False,
        "nlos_model": NlosModel.none,
        "outlier_scale": 10.0,
        "ionosphere": IonosphereMode.broadcast,
        "variance_components": VarianceComponents.none,
        "iono_sigma_m": 2.0,
        "wet_delay": WetDelayMode.estimate,
    }
    shared = 0
    for name in NAMES:
        cls = estimators.get(name).Config
        assert to_typed(OmegaConf.to_container(urban.estimator[name], resolve=True), cls, name) == cls(), name
        mine = {k: v for k, v in table.items() if k in {f.name for f in dataclasses.fields(cls)}}
        shared += bool(mine)
        if name == "mm":  # the batch code's published outlier scale (the preset's per_estimator entry)
            mine["outlier_scale"] = 1e6
        got = to_typed(OmegaConf.to_container(dissertation.estimator[name], resolve=True), cls, name)
        assert got == dataclasses.replace(cls(), **mine), name
    assert shared >= 11  # every GNSS estimator
    one = compose_config(["estimator.dcs.sigma_model=elevation"]).estimator
    assert one.dcs.sigma_model == "elevation" and one.l2.sigma_model == "cn0"
    assert urban.estimator.ice.scaled_mixture and "scaled_mixture" not in urban.estimator.l2


@pytest.mark.parametrize("sweep", available("sweep"))
def test_sweeps_compose_and_their_estimator_overrides_apply(sweep: str) -> None:
    cfg = compose_config([f"+sweep={sweep}"])
    for name in cfg.estimator:
        to_typed(OmegaConf.to_container(cfg.estimator[name], resolve=True), estimators.get(name).Config, name)
    params = (
        (yaml.safe_load((CONF_DIR / "sweep" / f"{sweep}.yaml").read_text()).get("hydra") or {})
        .get("sweeper", {})
        .get("params", {})
    )
    for key, values in params.items():
        if not key.startswith("estimator."):
            continue
        _, name, field = key.split(".")
        for value in str(values).split(","):
            node = compose_config([f"+sweep={sweep}", f"{key}={value}"]).estimator[name]
            typed = to_typed(OmegaConf.to_container(node, resolve=True), estimators.get(name).Config, name)
            assert getattr(typed, field) == yaml.safe_load(value), (key, value)


@pytest.mark.parametrize("group", ["scenario", "receiver", "imu"])
def test_presets_compose_into_the_typed_schema(group: str) -> None:
    for preset in available(group):
        cfg = compose_config([f"{group}={preset}"])
        sim = scenario_settings(cfg)
        check_choices(sim)


def test_a_bad_choice_on_the_command_line_is_one_line_with_the_allowed_values() -> None:
    for override, key, allowed in (
        ("scenario.trajectory.kind=boat", "scenario.trajectory.kind", "urban_drive"),
        ("scenario.source=sp3", "scenario.source", "librsf"),
        ("estimator.l2.clock_model=pink", "estimator.l2.clock_model", "random_walk"),
    ):
        with pytest.raises(SimbenchError) as info:
            compose_config([override])
        message = str(info.value)
        assert message.startswith(f"{key}:") and allowed in message and "\n" not in message


def test_a_bad_choice_set_in_python_is_one_line_with_the_allowed_values() -> None:
    cfg = SimConfig()
    cfg.scenario.trajectory.kind = "boat"  # type: ignore[assignment]
    with pytest.raises(
        SimbenchError,
        match=r"^scenario.trajectory.kind: unknown value 'boat' -- use one of "
        r"urban_drive, flight, replay$",
    ):
        validate_sim(cfg)
    cfg = ScenarioSettings(scenario=RinexConfig())  # a source's own Config, built in Python
    with pytest.raises(SimbenchError, match="^scenario.obs"):
        check_scenario(cfg)


def test_choice_fields_serialise_as_their_yaml_words() -> None:
    # scenario keys hash dataclasses.asdict(sim): an Enum member must encode as the old string did
    sim = SimConfig()
    text = json.dumps(dataclasses.asdict(sim))
    assert '"kind": "urban_drive"' in text and '"source": "simulated"' in text and '"kind": "nominal"' in text
    as_strings: dict[str, Any] = json.loads(text)
    assert config_key(dataclasses.asdict(sim)) == config_key(as_strings)
    assert sim.scenario.trajectory.kind is TrajectoryKind.urban_drive and sim.scenario.source == "simulated"
    assert f"{TrajectoryKind.flight}" == "flight"


def test_estimator_yaml_keeps_its_file_header() -> None:
    for name in WITH_YAML:
        first = estimator_yaml(name).read_text().splitlines()[0]
        assert first.startswith("# ") and len(first) > 20, f"{name}.yaml lost its description"


def test_keyword_overrides_become_hydra_overrides_lists_included() -> None:
    """``simbench.run(overrides=...)`` and ``simbench.scenario(**kw)``: lists of paths reach the config as lists."""
    nav = ["/logs/a b.20n", "/logs/it's.20n"]
    cfg = compose_config(
        ["scenario=rinex", *overrides_from_kwargs({"scenario.nav": nav, "scenario__systems": "GE", "seed": 3})]
    )
    assert list(cfg.scenario.nav) == nav and cfg.scenario.systems == "GE" and cfg.seed == 3
    assert overrides_from_kwargs({"a.b": True, "a.c": None, "a.d": {"k": 1}}) == ["a.b=true", "a.c=null", "a.d={k:1}"]
