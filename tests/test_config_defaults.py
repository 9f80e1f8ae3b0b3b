"""No dataclass default differs silently from the presets in ``conf/``.

Each config group's shipped default preset (``conf/config.yaml``: receiver=low,
imu=consumer, gnss_model=urban) *is* its dataclass's defaults: its file sets no
value, so a default lives in one place. Every other preset composes to the
dataclass defaults with exactly the values its file sets. Each estimator composes,
under every ``gnss_model`` preset, to its ``Config`` defaults under that preset
(:func:`~simbench.runs.compose.preset_estimator_config`, the baseline of a
result's ``overrides``) with exactly the values its YAML sets; under the shipped
default that baseline is the ``Config`` defaults, and another preset changes only
the ``gnss_model`` fields. A job checks its data config once, where its source
checks it, and the receiver and IMU values are checked there.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
import yaml
from omegaconf import OmegaConf

import estimators
import simbench.sim.config
import simbench.sim.generator
from estimators.model.ppp_config import GnssModelConfig
from simbench.analysis.tables import seed_statistics
from simbench.analysis.variants import overrides_of
from simbench.errors import SimbenchError
from simbench.runs.compose import (
    CONF_DIR,
    available,
    compose_config,
    estimator_yaml,
    gnss_model_preset,
    preset_estimator_config,
)
from simbench.runs.jobs import run_job
from simbench.runs.runner import SUMMARY_COLUMNS
from simbench.runs.scenarios import sim_config
from simbench.sim.config import ImuConfig, ReceiverConfig, SimConfig, validate_sim
from simbench.typed import to_typed

#: Config group -> its typed schema.
GROUPS: dict[str, type] = {"receiver": ReceiverConfig, "imu": ImuConfig, "gnss_model": GnssModelConfig}
SHIPPED: dict[str, str] = {
    group: choice
    for entry in yaml.safe_load((CONF_DIR / "config.yaml").read_text())["defaults"]
    if isinstance(entry, dict)
    for group, choice in entry.items()
}


def preset_values(group: str, preset: str) -> dict[str, Any]:
    """The values ``conf/<group>/<preset>.yaml`` sets (everything but its defaults list)."""
    # OmegaConf reads YAML as Hydra does (PyYAML alone reads 1.0e6 as a string)
    node = OmegaConf.to_container(OmegaConf.load(CONF_DIR / group / f"{preset}.yaml"))
    return {k: v for k, v in node.items() if k != "defaults"}


def composed(group: str, preset: str) -> Any:
    """The typed ``group`` node of ``conf/config.yaml`` composed with ``group=preset``."""
    node = compose_config([f"{group}={preset}"])[group]
    return to_typed(OmegaConf.to_container(node, resolve=True), GROUPS[group], group)


@pytest.mark.parametrize("group", sorted(GROUPS))
def test_the_shipped_default_preset_is_the_dataclass_default_and_sets_nothing(group: str) -> None:
    preset = SHIPPED[group]
    assert preset_values(group, preset) == {}, f"conf/{group}/{preset}.yaml restates the dataclass defaults"
    assert composed(group, preset) == GROUPS[group]()


@pytest.mark.parametrize("group", sorted(GROUPS))
def test_every_preset_is_the_dataclass_defaults_plus_what_its_file_sets(group: str) -> None:
    schema = GROUPS[group]
    for preset in available(group):
        values = preset_values(group, preset)
        got = composed(group, preset)
        assert got == to_typed(values, schema, group), preset
        default = schema()
        for f in dataclasses.fields(schema):
            assert getattr(got, f.name) == getattr(default, f.name) or f.name in values, (group, preset, f.name)


def test_gnss_model_presets_name_themselves_and_only_model_fields_of_known_estimators() -> None:
    for preset in available("gnss_model"):
        model = gnss_model_preset(preset)
        assert model.name == preset
        for name, values in model.per_estimator.items():
            fields = {f.name for f in dataclasses.fields(estimators.get(name).Config)}
            assert set(values) <= fields & set(GnssModelConfig.model_fields()), (preset, name)


@pytest.mark.parametrize("preset", available("gnss_model"))
def test_each_estimator_composes_to_its_preset_defaults_plus_its_yaml(preset: str) -> None:
    cfg = compose_config([f"gnss_model={preset}"])
    model_fields = set(GnssModelConfig.model_fields())
    for name in sorted(estimators.registered()):
        config = estimators.get(name).Config
        path = estimator_yaml(name)
        explicit = ((yaml.safe_load(path.read_text()) if path else None) or {}).get(name) or {}
        got = to_typed(OmegaConf.to_container(cfg.estimator[name], resolve=True), config, name)
        baseline = preset_estimator_config(name, preset)
        typed = to_typed(explicit, config, name)
        assert got == dataclasses.replace(baseline, **{k: getattr(typed, k) for k in explicit}), name
        if preset == SHIPPED["gnss_model"]:  # the shipped default preset is the dataclass defaults
            assert baseline == config(), name
        else:  # another preset changes only model fields
            assert set(overrides_of(baseline)) <= model_fields, (name, preset)


def test_an_unmodified_run_under_either_preset_has_no_overrides() -> None:
    for preset in available("gnss_model"):
        cfg = compose_config([f"gnss_model={preset}", "estimator=[l2,mm,isam2_mm,ice]"])
        for name in cfg.estimator:
            config = estimators.get(name).Config
            got = to_typed(OmegaConf.to_container(cfg.estimator[name], resolve=True), config, name)
            assert overrides_of(got, preset_estimator_config(name, preset)) == {}, (preset, name)
    changed = compose_config(["gnss_model=dissertation", "gnss_model.sigma_model=cn0", "estimator=[l2]"])
    got = to_typed(OmegaConf.to_container(changed.estimator.l2, resolve=True), estimators.get("l2").Config, "l2")
    assert overrides_of(got, preset_estimator_config("l2", "dissertation")) == {"sigma_model": "cn0"}


def test_a_job_checks_its_scenario_config_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls = []

    def counting(cfg: SimConfig) -> SimConfig:
        calls.append(cfg)
        return validate_sim(cfg)

    monkeypatch.setattr(simbench.sim.config, "validate_sim", counting)  # the simulator's check calls it there
    cfg = compose_config(
        ["scenario=open_sky", "scenario.duration_s=20", "estimator=[l2]", f"results_dir={tmp_path}", "progress=false"]
    )
    assert run_job(cfg)["status"].tolist() == ["ok"]
    assert len(calls) == 1
    assert not hasattr(simbench.sim.generator, "validate_sim")  # the generator trusts the checked config


@pytest.mark.parametrize(
    "override, field",
    [
        ("receiver.dll_bw_hz=0", "receiver.dll_bw_hz"),
        ("receiver.correlator_spacing_chips=2.5", "receiver.correlator_spacing_chips"),
        ("receiver.lock_threshold_dbhz=40", "receiver.acquisition_threshold_dbhz"),
        ("imu.bias_tau_s=0", "imu.bias_tau_s"),
    ],
)
def test_receiver_and_imu_values_are_checked_at_the_door(override: str, field: str) -> None:
    with pytest.raises(SimbenchError, match=f"^{field}:"):
        validate_sim(sim_config(compose_config([override])))


def test_statistics_keep_the_default_rows_of_each_gnss_model_apart() -> None:
    """A sweep over presets has a default (``{}``) row under each; the tables do not pool them."""
    rows = [
        {"sweep": "tune", "scenario": "urban", "receiver": "low", "seed": seed, "estimator": "l2", "status": "ok"}
        | {"gnss_model": preset, "overrides": "{}", "variant": "", "availability": 1.0, "horizontal_median_ref": m}
        for preset, m in (("urban", 3.0), ("dissertation", 7.0))
        for seed in (0, 1)
    ]
    stats = seed_statistics(pd.DataFrame(rows).reindex(columns=list(SUMMARY_COLUMNS)))
    assert stats.set_index("gnss_model")["horizontal_median_ref"].to_dict() == {"dissertation": 7.0, "urban": 3.0}
    # results from before the column: one unnamed preset
    old = pd.DataFrame(rows).reindex(columns=list(SUMMARY_COLUMNS)).drop(columns="gnss_model")
    assert seed_statistics(old)["gnss_model"].tolist() == [""]
