"""Compose configurations from ``conf/`` outside a Hydra app (notebooks, tests)."""
from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from hydra.core.global_hydra import GlobalHydra
from hydra.errors import HydraException
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException
import yaml

import estimators
from simbench.config import ImuConfig, ReceiverConfig, ScenarioConfig
from simbench.errors import SimbenchError

#: The repository's top-level ``conf/`` directory.
CONF_DIR = Path(__file__).resolve().parent.parent / "conf"


def register_schemas() -> None:
    """Put the typed schemas into Hydra's ConfigStore.

    Each preset file in ``conf/<group>/`` starts from its schema (``defaults:
    [schema, _self_]``), and each ``conf/estimator/<name>.yaml`` from its
    estimator's ``Config`` dataclass (``defaults: [<name>_schema, _self_]``), so
    every field exists in the composed config, can be overridden without ``+``
    and is type-checked by Hydra; the estimator files hold only what differs
    from the dataclass defaults.
    """
    cs = ConfigStore.instance()
    for group, node in (("scenario", ScenarioConfig), ("receiver", ReceiverConfig), ("imu", ImuConfig)):
        cs.store(group=group, name="schema", node=node)
    for name, cls in estimators.registered().items():
        cs.store(group="estimator", name=f"{name}_schema", node={name: cls.Config})


register_schemas()


def available(group: str) -> list[str]:
    """Names of the options of a config group (``scenario``, ``receiver``, ...)."""
    return sorted(p.stem for p in (CONF_DIR / group).glob("*.yaml"))


def config_groups() -> list[str]:
    """The config groups a user chooses from: the folders of ``conf/`` (not the ConfigStore schemas)."""
    return sorted(d.name for d in CONF_DIR.iterdir() if d.is_dir() and any(d.glob("*.yaml")))


def group_choices(value: str) -> list[str] | None:
    """Option names in the value of a group override.

    Understands ``a``, a list ``[a,b]``, sweep lists ``a,b`` or ``[a],[a,b]`` and
    ``choice(a,b)``; None for the other sweep functions (``range``, ``glob``),
    which Hydra expands itself.
    """
    text = value.strip()
    if text.startswith("choice(") and text.endswith(")"):
        text = text[len("choice("):-1]
    elif "(" in text:
        return None
    names = (name.strip().strip("'\"") for name in re.split(r"[\[\],]", text))
    return [name for name in names if name]


def check_group_choices(overrides: Iterable[str]) -> None:
    """Reject an unknown option of a config group (``estimator=[nosuch]``) in one line.

    Raises
    ------
    SimbenchError
        Naming the group, the unknown option and the known ones.
    """
    groups = config_groups()
    for item in overrides:
        key, sep, value = item.partition("=")
        group = key.lstrip("+~")
        if not sep or group not in groups:
            continue
        known = available(group)
        for name in group_choices(value) or []:
            if name not in known:
                raise SimbenchError(group, f"unknown {group} '{name}'", f"choose from {', '.join(known)}")


def config_groups_help() -> str:
    """One line per config group, as typed on the command line, with its options and default.

    ``--help`` shows it (``conf/config.yaml`` hydra.help.template); Hydra's own
    group list would also show the ConfigStore schemas, which are not choices.
    """
    defaults: dict[str, Any] = {}
    for entry in (yaml.safe_load((CONF_DIR / "config.yaml").read_text()) or {}).get("defaults", []):
        if isinstance(entry, dict):
            defaults.update(entry)
    lines = []
    for group in config_groups():
        options = available(group)
        default = defaults.get(group)
        if isinstance(default, list):
            note = "a list, e.g. [ekf_ppp,l2]; default: " + ("all" if sorted(default) == options else ",".join(default))
        elif default is not None:
            note = f"default: {default}"
        else:
            note = "optional"
        key = group if group in defaults else f"+{group}"
        lines.append(f"  {key}: {', '.join(options)}  ({note})")
    return "\n".join(lines)


# conf/config.yaml's help template lists the groups with ${simbench_config_groups:}
OmegaConf.register_new_resolver("simbench_config_groups", config_groups_help, replace=True)


def compose_config(overrides: list[str] | None = None) -> DictConfig:
    """Compose ``conf/config.yaml`` with Hydra command-line style overrides.

    Raises
    ------
    SimbenchError
        For an unknown group option or a malformed override, in one line.
    """
    if not CONF_DIR.is_dir():
        raise SimbenchError("conf", f"config directory {CONF_DIR} not found",
                            "install simbench from its repository with 'pip install -e .'")
    overrides = list(overrides or [])
    check_group_choices(overrides)
    if GlobalHydra.instance().is_initialized():
        GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            return compose(config_name="config", overrides=overrides)
    except (HydraException, OmegaConfBaseException) as exc:
        key = getattr(exc.__cause__, "full_key", None)
        if key:  # a bad value of a known key: OmegaConf's first line names the value and what is allowed
            raise SimbenchError(str(key), str(exc.__cause__).splitlines()[0],
                                f"fix {key} on the command line or in conf/") from None
        text = f"{exc}\n{exc.__cause__}" if exc.__cause__ else str(exc)
        lines = [ln.strip() for ln in text.splitlines() if ln.strip()][:2]
        raise SimbenchError("overrides", ": ".join(lines),
                            "write overrides as key=value with keys and types from conf/") from None


def overrides_from_kwargs(kwargs: dict[str, Any]) -> list[str]:
    """Turn ``{"scenario.duration_s": 60, "scenario__rate_hz": 10}`` into Hydra overrides."""
    out = []
    for key, value in kwargs.items():
        value = OmegaConf.to_yaml(value).strip() if isinstance(value, (list, dict)) else value
        if isinstance(value, bool):
            value = str(value).lower()
        out.append(f"{key.replace('__', '.')}={value}")
    return out
