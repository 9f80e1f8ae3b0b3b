"""The config groups of ``conf/`` and their options, by name only.

What ``--help`` and the first checks of a command line need (a misspelt ``scenario=urbn``),
without importing an estimator, a source or pandas, so they answer in well under a second;
:mod:`simbench.runs.compose` composes and types the configs.
"""

from __future__ import annotations

import importlib.util
import json
import re
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import yaml
from omegaconf import OmegaConf

from simbench.entry_points import ALL_ESTIMATORS, ESTIMATOR_GROUP, SOURCE_GROUP, entry_point_names
from simbench.errors import SimbenchError, did_you_mean

#: The repository's top-level ``conf/`` directory.
CONF_DIR = Path(__file__).resolve().parents[2] / "conf"


#: Where :func:`record_built_in_estimators` keeps the built-in estimators' names: beside the bytecode of the
#: ``estimators`` package, with the size and time of each of its module files, so an edit makes it stale.
BUILT_IN_NAMES = "simbench-estimator-names.json"


def estimators_folder() -> Path | None:
    """The folder of the ``estimators`` package, found without importing it (None when it is not installed)."""
    spec = importlib.util.find_spec("estimators")  # located, not imported
    return Path(spec.origin).parent if spec is not None and spec.origin else None


def _estimators_stamp(folder: Path) -> list[list[object]]:
    files = sorted(folder.rglob("*.py"))
    return [[p.relative_to(folder).as_posix(), p.stat().st_size, p.stat().st_mtime_ns] for p in files]


def recorded_built_in_estimators() -> list[str] | None:
    """The built-in estimators' names as :mod:`simbench.runs.compose` last registered them; None when the
    package's files changed since (or it never did): then only importing every estimator tells."""
    folder = estimators_folder()
    if folder is None:
        return None
    try:
        record = json.loads((folder / "__pycache__" / BUILT_IN_NAMES).read_text())
        current = record["stamp"] == _estimators_stamp(folder)
        return [str(name) for name in record["names"]] if current else None
    except (OSError, ValueError, KeyError, TypeError):  # none yet, or half written by another process
        return None


def record_built_in_estimators(names: Iterable[str]) -> None:
    """Keep the built-in estimators' names for :func:`available` (nothing when the folder is read-only)."""
    folder = estimators_folder()
    if folder is None:
        return
    record = {"stamp": _estimators_stamp(folder), "names": sorted(names)}
    if recorded_built_in_estimators() == record["names"]:
        return  # current already: every run and every job process registers, few need to write
    try:  # plainly: a half-written record reads as none (simbench.contract's atomic write imports pandas)
        (folder / "__pycache__").mkdir(exist_ok=True)
        (folder / "__pycache__" / BUILT_IN_NAMES).write_text(json.dumps(record))
    except OSError:
        pass


def available(group: str, registered: Iterable[str] = ()) -> list[str]:
    """Names of the options of a config group (``scenario``, ``receiver``, ...).

    The files of ``conf/<group>/``; for ``estimator`` also the plug-in estimators, the built-in ones
    (a module without its YAML too) and ``all``; for ``scenario`` also every source by name.
    Plug-ins are named by their entry points, not loaded (:func:`simbench.entry_points.entry_point_names`),
    built-ins by the names recorded when they were last registered (:func:`recorded_built_in_estimators`);
    ``registered`` adds the estimators a caller that imported them has (``estimators.registered()``).
    """
    names = {p.stem for p in (CONF_DIR / group).glob("*.yaml")}
    if group == "estimator":
        recorded = recorded_built_in_estimators() or []
        names |= {*entry_point_names(ESTIMATOR_GROUP), *recorded, *registered, ALL_ESTIMATORS}
    if group == "scenario":
        names |= set(entry_point_names(SOURCE_GROUP))
    return sorted(names)


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
        text = text[len("choice(") : -1]
    elif "(" in text:
        return None
    names = (name.strip().strip("'\"") for name in re.split(r"[\[\],]", text))
    return [name for name in names if name]


def check_group_choices(
    overrides: Iterable[str],
    registered: Iterable[str] = (),
    every_estimator: Callable[[], list[str]] | None = None,
) -> None:
    """Reject an unknown option of a config group (``estimator=[nosuch]``) in one line, with the closest
    known one (``did you mean 'dcs'?``).

    ``registered``: the estimators a caller that imported them has (:func:`available`);
    ``every_estimator``: asked for the certain list before an estimator name is refused (the command
    line's names come from a record that may be stale).

    Raises
    ------
    SimbenchError
        Naming the group, the unknown option, the suggestion and the known ones.
    """
    groups = config_groups()
    for item in overrides:
        key, sep, value = item.partition("=")
        group = key.lstrip("+~")
        if not sep or group not in groups:
            continue
        known = available(group, registered)
        for name in group_choices(value) or []:
            if name not in known and group == "estimator" and every_estimator is not None:
                known = every_estimator()
            if name not in known:
                raise SimbenchError(
                    group, f"unknown {group} '{name}'{did_you_mean(name, known)}", f"choose from {', '.join(known)}"
                )


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
        if default == ALL_ESTIMATORS:
            note = "a list, e.g. [ekf_ppp,l2]; default: all, every registered estimator"
        elif isinstance(default, list):
            note = "a list, e.g. [ekf_ppp,l2]; default: " + ",".join(default)
        elif default is not None:
            note = f"default: {default}"
        else:
            note = "optional"
        key = group if group in defaults else f"+{group}"
        lines.append(f"  {key}: {', '.join(options)}  ({note})")
    return "\n".join(lines)


# conf/config.yaml's help template lists the groups with ${simbench_config_groups:}
OmegaConf.register_new_resolver("simbench_config_groups", config_groups_help, replace=True)
