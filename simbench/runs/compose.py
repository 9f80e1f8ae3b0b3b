"""Compose configurations from ``conf/`` outside a Hydra app (notebooks, tests)."""

from __future__ import annotations

import dataclasses
import difflib
import functools
import inspect
from collections.abc import Iterable
from pathlib import Path
from typing import Any, cast

import yaml
from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from hydra.core.global_hydra import GlobalHydra
from hydra.errors import HydraException
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

import estimators
from estimators.base import validate_config
from estimators.model.ppp_config import GnssModelConfig
from simbench import source_registry as sources
from simbench.errors import SimbenchError
from simbench.paths import data_path
from simbench.runs.groups import CONF_DIR, available, check_group_choices, config_groups, record_built_in_estimators
from simbench.runs.provenance import module_file
from simbench.runs.schema_record import (
    NotRecorded,
    Record,
    class_or_rebuilt,
    rebuild,
    remember_valid,
    source_check,
    write_record,
)
from simbench.sim.config import ImuConfig, ReceiverConfig, ScenarioConfig
from simbench.typed import to_typed


@dataclasses.dataclass(eq=False)  # one set of schemas is stored once (store_schemas), by identity
class Schemas:
    """The ``Config`` classes a composition types its nodes with: the real ones (:func:`real_schemas`), or
    those rebuilt from the record of the last registration (:func:`recorded_schemas`), which the command
    line's door composes with before any estimator or source is imported."""

    estimators: dict[str, type]  #: estimator name -> its ``Config`` dataclass, built-in and plug-in
    plugin_nodes: dict[str, dict[str, Any]]  #: plug-in estimator name -> its ``estimator/<name>`` node
    sources: dict[str, type]  #: source name -> its ``Config`` dataclass
    record: Record | None = None  #: the record the classes were rebuilt from; None: the real classes


def real_schemas() -> Schemas:
    """The registered estimators' and sources' real ``Config`` classes (importing every one of them).

    Raises
    ------
    SimbenchError
        For a broken plug-in, naming its package (:func:`estimators.discover`,
        :func:`simbench.source_registry.discover`).
    """
    return Schemas(
        estimators={name: cls.Config for name, cls in estimators.registered().items()},
        plugin_nodes={name: plugin_config_node(plugin) for name, plugin in estimators.plugins().items()},
        sources={name: source.Config for name, source in sources.registered().items()},
    )


def recorded_schemas(record: Record) -> Schemas:
    """The schemas of ``record`` (:func:`simbench.runs.schema_record.read_record`): each ``Config`` rebuilt,
    but for those whose module is imported already (:func:`class_or_rebuilt`): the simulator's, and a source's
    whose recorded check is a function beside it (the log sources': importing them takes 0.15 s, and a
    composed scenario node then has the type the source's check asks for)."""
    for name in record.sources:
        source_check(record, name)
    return Schemas(
        estimators={name: rebuild(entry["config"]) for name, entry in record.estimators.items()},
        plugin_nodes={name: entry["node"] for name, entry in record.estimators.items() if entry["node"] is not None},
        sources={name: class_or_rebuilt(entry["config"]) for name, entry in record.sources.items()},
        record=record,
    )


@functools.cache
def register_schemas() -> None:
    """Put the real typed schemas and the plug-in estimators into Hydra's ConfigStore (once per process,
    :func:`store_schemas` of :func:`real_schemas`), and record them for the next command line
    (:func:`simbench.runs.schema_record.write_record`).

    Raises
    ------
    SimbenchError
        For a broken plug-in, naming its package (:func:`estimators.discover`,
        :func:`simbench.source_registry.discover`).
    """
    schemas = real_schemas()
    store_schemas(schemas)
    record_estimator_names()
    if write_record(schemas.estimators, schemas.plugin_nodes, sources.registered()):
        remember_default_nodes()


def remember_default_nodes() -> None:
    """Record the default run's estimator nodes that pass their checks (:func:`simbench.runs.schema_record.
    remember_valid`), so the next command line's door checks none of them again (once per code change)."""
    cfg = hydra_compose([])
    passed = []
    for name in cfg.estimator:
        where, node = f"estimator.{name}", estimator_node(cfg, str(name))
        try:
            validate_config(to_typed(node, estimators.get(str(name)).Config, where), where)
        except SimbenchError:
            continue
        passed.append((str(name), node))
    remember_valid(passed)


def estimator_node(cfg: DictConfig, name: str) -> dict[str, Any]:
    """Estimator ``name``'s node of a composed config as plain values, resolved: its gnss_model fields are
    interpolations into the root config."""
    return cast(dict[str, Any], OmegaConf.to_container(cfg.estimator[name], resolve=True) or {})


@functools.cache
def store_schemas(schemas: Schemas) -> None:
    """Put typed schemas into Hydra's ConfigStore (once per set of schemas).

    Each preset file in ``conf/<group>/`` starts from its schema (``defaults:
    [schema, _self_]``), and each ``conf/estimator/<name>.yaml`` from its
    estimator's ``Config`` dataclass (``defaults: [<name>_schema, _self_]``), so
    every field exists in the composed config, can be overridden without ``+``
    and is type-checked by Hydra; the estimator files hold only what differs
    from the dataclass defaults. A plug-in estimator gets the same node from
    :func:`plugin_config_node`, a built-in estimator without ``conf/estimator/<name>.yaml``
    its ``Config`` defaults (its module is all it takes), and ``estimator/all`` lists every
    registered estimator, built-in and plug-in, so the default run and the sweeps include
    them without an edit to ``conf/``. Each scenario source (:mod:`simbench.source_registry`)
    gets its typed node ``scenario/<name>_schema`` from its ``Config`` (the simulator's presets
    use ``scenario/schema``, ``rinex.yaml`` uses ``rinex_schema``), and a source without a
    ``conf/scenario/<name>.yaml`` a preset of its ``Config`` defaults, so ``scenario=<name>`` runs it.
    """
    cs = ConfigStore.instance()
    for group, node in (
        ("scenario", ScenarioConfig),  # the simulator's presets in conf/scenario/ (= simulated_schema)
        ("receiver", ReceiverConfig),
        ("imu", ImuConfig),
        ("gnss_model", GnssModelConfig),
    ):
        cs.store(group=group, name="schema", node=node)
    for name, config in schemas.sources.items():
        cs.store(group="scenario", name=f"{name}_schema", node=config)
        if not (CONF_DIR / "scenario" / f"{name}.yaml").is_file():  # a plug-in's preset: its Config defaults
            cs.store(group="scenario", name=name, node={"defaults": [f"{name}_schema", "_self_"]})
    for name, config in schemas.estimators.items():
        cs.store(group="estimator", name=f"{name}_schema", node={name: estimator_schema(name, config)})
    for name, plugin_node in schemas.plugin_nodes.items():
        cs.store(group="estimator", name=name, node=plugin_node)
    for name in schemas.estimators:
        # a built-in module without conf/estimator/<name>.yaml runs on its Config defaults, as a plug-in
        # does (before, 'Could not load estimator/<name>' broke the default run for everyone)
        if name not in schemas.plugin_nodes and not (CONF_DIR / "estimator" / f"{name}.yaml").is_file():
            cs.store(group="estimator", name=name, node={"defaults": [f"{name}_schema", "_self_"], name: {}})
    cs.store(group="estimator", name=estimators.ALL, node={"defaults": list(schemas.estimators)})


def record_estimator_names() -> None:
    """Record the built-in estimators' names, which ``--help`` and a name check read without importing an
    estimator (:func:`simbench.runs.groups.recorded_built_in_estimators`); a built-in is a module file."""
    record_built_in_estimators(n for n, cls in estimators.built_in().items() if module_file(cls.__module__))


def estimator_schema(name: str, config: type) -> DictConfig:
    """The typed node of estimator ``name``'s ``Config`` dataclass, its :class:`GnssModelConfig`
    fields defaulting to the ``gnss_model`` group's choice: the preset's ``per_estimator.<name>``
    value where it has one, else its ``<field>``.

    This is the one place where a ``gnss_model`` preset reaches the estimators: a composed
    run gets its values through it, and :func:`preset_estimator_config` (the baseline of a
    result's ``overrides``) too.
    """
    node = OmegaConf.structured(config)
    for field in GnssModelConfig.model_fields():
        if field in node:
            node[field] = f"${{oc.select:gnss_model.per_estimator.{name}.{field},${{gnss_model.{field}}}}}"
    return node


@functools.cache
def gnss_model_preset(preset: str) -> GnssModelConfig:
    """The ``gnss_model`` preset ``conf/gnss_model/<preset>.yaml`` as shipped (no command-line overrides).

    Raises
    ------
    SimbenchError
        When ``conf/gnss_model/`` has no such preset.
    """
    path = CONF_DIR / "gnss_model" / f"{preset}.yaml"
    if not path.is_file():
        raise SimbenchError(
            "gnss_model.name", f"no preset '{preset}'", f"choose from {', '.join(available('gnss_model'))}"
        )
    # OmegaConf's YAML reading, as Hydra's: PyYAML alone reads 1.0e6 as a string
    node = OmegaConf.load(path)
    if not isinstance(node, DictConfig):
        raise SimbenchError("gnss_model", f"{path} is not a mapping", "write the preset as field: value lines")
    node.pop("defaults", None)
    return to_typed(node, GnssModelConfig, "gnss_model")


def preset_estimator_config(name: str, preset: str) -> Any:
    """Estimator ``name``'s ``Config`` dataclass defaults under ``gnss_model`` preset ``preset``.

    The baseline of a result's ``overrides`` (:func:`simbench.analysis.variants.overrides_of`):
    an unmodified run under either preset has none.

    Raises
    ------
    SimbenchError
        For an unknown estimator or preset.
    """
    config = estimators.get(name).Config
    model = OmegaConf.structured(gnss_model_preset(preset))
    root = OmegaConf.create({"gnss_model": model, "estimator": {name: estimator_schema(name, config)}})
    node = cast(dict[str, Any], OmegaConf.to_container(root.estimator[name], resolve=True))
    return to_typed(node, config, f"estimator.{name}")


def plugin_config_node(plugin: estimators.Plugin) -> dict[str, Any]:
    """The ``estimator/<name>`` config of a plug-in estimator.

    Its ``Config`` dataclass defaults, overridden by ``<name>.yaml`` beside the
    module that defines the class when the package ships one, in the form of
    ``conf/estimator/<name>.yaml`` (``defaults: [<name>_schema, _self_]`` and
    ``<name>:`` with the values that differ from the dataclass).

    Raises
    ------
    SimbenchError
        Naming the package, for a shipped YAML of another form or with values
        that do not type-check against ``Config``.
    """
    name = plugin.cls.name
    node: dict[str, Any] = {"defaults": [f"{name}_schema", "_self_"], name: {}}
    path = shipped_yaml(plugin.cls)
    if path is None:
        return node
    field = f"estimator plug-in '{name}'"
    fix = f"fix {path.name} in package '{plugin.package}' (README, Add your estimator)"
    try:
        shipped = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as exc:
        detail = " ".join(str(exc).split())  # PyYAML's message spans lines
        raise SimbenchError(field, f"package '{plugin.package}': {path.name} is not YAML: {detail}", fix) from None
    if (
        not isinstance(shipped, dict)
        or set(shipped) - set(node)
        or shipped.get("defaults", node["defaults"]) != node["defaults"]
    ):
        raise SimbenchError(
            field,
            f"package '{plugin.package}': {path.name} must hold only 'defaults: [{name}_schema, _self_]' and '{name}:'",
            fix,
        )
    node[name] = shipped.get(name) or {}
    try:
        to_typed(node[name], plugin.cls.Config, f"estimator.{name}")
    except SimbenchError as exc:
        raise SimbenchError(field, f"package '{plugin.package}': {path.name}: {exc}", fix) from None
    return node


def shipped_yaml(cls: type[estimators.Estimator]) -> Path | None:
    """``<cls.name>.yaml`` beside the module that defines a plug-in estimator class, if its package ships one."""
    path = Path(inspect.getfile(cls)).with_name(f"{cls.name}.yaml")
    return path if path.is_file() else None


def estimator_yaml(name: str) -> Path | None:
    """The YAML file of estimator ``name``: ``conf/estimator/<name>.yaml`` for a built-in,
    :func:`shipped_yaml` for a plug-in (None when its package ships none)."""
    if estimators.source(name) == estimators.BUILT_IN:
        return CONF_DIR / "estimator" / f"{name}.yaml"
    return shipped_yaml(estimators.get(name))


# the named presets' files: ${simbench_data:hk_tst_2019/x.obs} is x.obs in the data home ($SIMBENCH_DATA or
# <repository>/../shared/data, simbench.paths), so a preset reads the same files from any working directory
OmegaConf.register_new_resolver("simbench_data", data_path, replace=True)


def compose_config(
    overrides: list[str] | None = None, *, with_hydra: bool = False, schemas: Schemas | None = None
) -> DictConfig:
    """Compose ``conf/config.yaml`` with Hydra command-line style overrides.

    ``with_hydra`` keeps Hydra's own node (``hydra.sweeper.params`` of a sweep file, unresolved);
    ``schemas`` types the nodes with other classes than the real ones (:func:`recorded_schemas`).

    Raises
    ------
    SimbenchError
        For an unknown group option, source (``scenario.source``) or a malformed override, in one line.
    NotRecorded
        With recorded ``schemas``, for a source the record lacks (the real classes tell what is wrong).
    """
    if not CONF_DIR.is_dir():
        raise SimbenchError(
            "conf",
            f"config directory {CONF_DIR} not found",
            "install simbench from its repository with 'pip install -e .'",
        )
    overrides = list(overrides or [])
    if schemas is None:
        register_schemas()
    else:
        store_schemas(schemas)
    check_group_choices(overrides, estimators.registered() if schemas is None else schemas.estimators)
    cfg = hydra_compose(overrides, with_hydra=with_hydra)
    if schemas is None:
        sources.get(str(cfg.scenario.source))  # an unknown source fails here, in one line
    elif str(cfg.scenario.source) not in schemas.sources:
        raise NotRecorded(f"source '{cfg.scenario.source}'")
    check_added_root_keys(overrides, cfg)
    return cfg


def hydra_compose(overrides: list[str], *, with_hydra: bool = False) -> DictConfig:
    """Hydra's composition of ``conf/config.yaml`` with ``overrides``, with the schemas stored so far.

    Raises
    ------
    SimbenchError
        For a bad value of a known key or a malformed override, in one line.
    """
    if GlobalHydra.instance().is_initialized():
        GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            cfg = compose(config_name="config", overrides=overrides, return_hydra_config=with_hydra)
    except (HydraException, OmegaConfBaseException) as exc:
        key = getattr(exc.__cause__, "full_key", None)
        if key:  # a bad value of a known key: OmegaConf's first line names the value and what is allowed
            raise SimbenchError(
                str(key), str(exc.__cause__).splitlines()[0], f"fix {key} on the command line or in conf/"
            ) from None
        text = f"{exc}\n{exc.__cause__}" if exc.__cause__ else str(exc)
        lines = [ln.strip() for ln in text.splitlines() if ln.strip()][:2]
        raise SimbenchError(
            "overrides", ": ".join(lines), "write overrides as key=value with keys and types from conf/"
        ) from None
    return cfg


def check_added_root_keys(overrides: Iterable[str], cfg: DictConfig) -> None:
    """Reject a ``+key=value`` that adds a top-level key which is not a config group (``+seeed=3``).

    Hydra adds it without a word and nothing reads it. (A ``+`` key inside a typed node,
    ``+scenario.duraton_s=10``, is refused where the node is typed:
    :func:`simbench.typed.check_known_keys`.)

    Raises
    ------
    SimbenchError
        Naming the key and the closest key the config has.
    """
    groups = config_groups()
    for item in overrides:
        key = item.partition("=")[0]
        if not key.startswith("+") or key.startswith("++"):
            continue
        name = key[1:]
        if "." in name or "/" in name or name in groups:
            continue
        known = [str(k) for k in cfg if k != name]
        close = difflib.get_close_matches(name, known, n=1)
        raise SimbenchError(
            name,
            "unknown key: '+' added it to the config, but nothing reads it",
            f"{f'did you mean {close[0]}? ' if close else ''}set a known key without '+' (see --cfg job)",
        )


def overrides_from_kwargs(kwargs: dict[str, Any]) -> list[str]:
    """Turn ``{"scenario.duration_s": 60, "scenario__rate_hz": 10, "scenario.nav": ["a.20n", "b.20n"]}``
    into Hydra overrides (lists and dicts in Hydra's own syntax, their strings quoted)."""
    return [f"{key.replace('__', '.')}={_override_value(value, top=True)}" for key, value in kwargs.items()]


def _override_value(value: Any, top: bool = False) -> str:
    """One value in Hydra's override grammar; a top-level string stays as given (it may be an interpolation)."""
    if isinstance(value, bool):
        return str(value).lower()
    if value is None:
        return "null"
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(_override_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ",".join(f"{k}:{_override_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, str) and not top:
        return "'" + value.replace("\\", "\\\\").replace("'", "\\'") + "'"
    return str(value)
