"""Compose configurations from ``conf/`` outside a Hydra app (notebooks, tests)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from hydra.core.global_hydra import GlobalHydra
from hydra.errors import HydraException
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from simbench.config import ImuConfig, ReceiverConfig, ScenarioConfig
from simbench.errors import SimbenchError

#: The repository's top-level ``conf/`` directory.
CONF_DIR = Path(__file__).resolve().parent.parent / "conf"


def register_schemas() -> None:
    """Put the typed schemas into Hydra's ConfigStore as ``<group>/schema``.

    Each preset file in ``conf/<group>/`` starts from its schema (``defaults:
    [schema, _self_]``), so every field exists in the composed config, can be
    overridden without ``+`` and is type-checked by Hydra.
    """
    cs = ConfigStore.instance()
    for group, node in (("scenario", ScenarioConfig), ("receiver", ReceiverConfig), ("imu", ImuConfig)):
        cs.store(group=group, name="schema", node=node)


register_schemas()


def available(group: str) -> list[str]:
    """Names of the options of a config group (``scenario``, ``receiver``, ...)."""
    return sorted(p.stem for p in (CONF_DIR / group).glob("*.yaml"))


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
    for item in overrides:
        group, _, choice = item.partition("=")
        if group in ("scenario", "receiver", "imu") and choice not in available(group):
            raise SimbenchError(group, f"unknown {group} '{choice}'", f"choose from {', '.join(available(group))}")
    if GlobalHydra.instance().is_initialized():
        GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            return compose(config_name="config", overrides=overrides)
    except (HydraException, OmegaConfBaseException) as exc:
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
