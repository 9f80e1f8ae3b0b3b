"""The schemas of every estimator and source, recorded so the command line's door imports none of them.

Composing a run needs each estimator's and source's ``Config`` dataclass in Hydra's ConfigStore
(:func:`simbench.runs.compose.register_schemas`), and importing them all (gtsam, scipy.stats, sklearn,
the simulator) takes longer than the rest of a refused command line. So the process that registers
the real classes also writes their description here (:func:`write_record`): field names, types,
choices and defaults, and where each class and each source's check live. While no code file changed
(:func:`code_stamp`: the size and time of every ``.py`` and ``.yaml`` file of ``simbench``, ``estimators``
and the installed plug-ins, and the plug-ins' entry points), :func:`read_record` gives it back and
:func:`rebuild` turns a description into a dataclass OmegaConf types exactly as the original (same
name, fields, types, choices, defaults), so composing refuses the same values with the same words.

Range checks are code (``Config.validate``): the record keeps the estimator nodes that passed them
under this code (:func:`remember_valid`, :func:`known_valid`); any other node is checked by its real
class, imported then from the module it was defined in (recorded): the built-in families keep their
``Config`` classes in light modules (``estimators/<family>/configs.py``, no gtsam, scipy or sklearn), so
that import costs milliseconds, not the estimator's solvers. A source's check is called without its
source when it is a function of a light module (the simulator's :func:`simbench.sim.config.check_simulation`).
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import importlib.util
import inspect
import json
import os
import sys
import tempfile
import typing
from collections.abc import Callable, Iterable, Mapping
from enum import Enum
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

from simbench.entry_points import ESTIMATOR_GROUP, SOURCE_GROUP
from simbench.runs.groups import estimators_folder
from simbench.typed import Choice

__all__ = [
    "RECORD",
    "NotRecorded",
    "Record",
    "package_folders",
    "record_path",
    "code_stamp",
    "describe",
    "rebuild",
    "write_record",
    "read_record",
    "known_valid",
    "remember_valid",
    "node_text",
    "real_class",
]

#: The record's file, beside the built-in estimator names (:data:`simbench.runs.groups.BUILT_IN_NAMES`).
RECORD = "simbench-schemas.json"
#: Validated nodes kept per estimator (the newest): the presets' defaults and the last variants run.
VALID_KEPT = 64


class NotRecorded(Exception):
    """The record cannot answer (a source or class it lacks): import the real classes and ask them."""


@dataclasses.dataclass
class Record:
    """A current record: per estimator and source its ``Config`` description (:func:`describe`)."""

    estimators: dict[str, dict[str, Any]]  #: name -> {"config": description, "node": plug-in node or None}
    sources: dict[str, dict[str, Any]]  #: name -> {"config": description, "check": "module:name" or None}
    valid: dict[str, list[str]]  #: estimator name -> :func:`node_text` of nodes that passed its checks


def package_folders() -> list[Path]:
    """The folders whose ``.py`` files the schemas come from: simbench, estimators, and each plug-in's package
    (found, not imported: a plug-in's package may import every estimator)."""
    names = {"simbench", "estimators"}
    for group in (ESTIMATOR_GROUP, SOURCE_GROUP):
        names |= {entry.module.split(".")[0] for entry in entry_points(group=group)}
    folders = []
    for name in sorted(names):
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.origin:
            folders.append(Path(spec.origin).parent)
    return folders


def code_stamp() -> list[Any]:
    """What the record is valid for: every entry point of both groups and the size and modification time of
    each ``.py`` and ``.yaml`` file of the :func:`package_folders` (a few hundred stat calls)."""
    points = sorted(
        f"{e.group}:{e.name}={e.value}" for g in (ESTIMATOR_GROUP, SOURCE_GROUP) for e in entry_points(group=g)
    )
    files = []
    for folder in package_folders():
        # the YAML a plug-in ships beside its module too (plugin_config_node reads it)
        for path in sorted([*folder.rglob("*.py"), *folder.rglob("*.yaml")]):
            stat = path.stat()
            files.append([str(path), stat.st_size, stat.st_mtime_ns])
    return [points, files]


def _type_text(kind: Any) -> Any:
    """A field type as JSON: a builtin's name, ``{"enum": ...}``, ``{"tuple": [...]}``, ``{"dataclass": ...}``."""
    origin = typing.get_origin(kind)
    if origin is tuple:
        return {"tuple": [_type_text(arg) if arg is not Ellipsis else "..." for arg in typing.get_args(kind)]}
    if kind is Any:
        return "any"
    if isinstance(kind, type) and issubclass(kind, Enum):
        return {"enum": kind.__name__, "choices": [m.value for m in kind]}
    if isinstance(kind, type) and dataclasses.is_dataclass(kind):
        return {"dataclass": describe(kind)}
    if kind in (bool, int, float, str):
        return kind.__name__
    raise TypeError(f"no record of the field type {kind!r}")


def _json_value(value: Any) -> Any:
    if isinstance(value, Enum):
        return value.value
    if isinstance(value, tuple):
        return [_json_value(v) for v in value]
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _json_value(getattr(value, f.name)) for f in dataclasses.fields(value)}
    return value


def describe(config: type) -> dict[str, Any]:
    """A ``Config`` dataclass as JSON: its name, module and fields (name, type, default).

    Raises
    ------
    TypeError
        For a field type the record cannot hold (then the class is imported, not rebuilt).
    """
    hints = typing.get_type_hints(config)
    defaults = config()
    fields = [
        [f.name, _type_text(hints[f.name]), _json_value(getattr(defaults, f.name))]
        for f in dataclasses.fields(config)
        if f.init
    ]
    return {"name": config.__name__, "module": config.__module__, "qualname": config.__qualname__, "fields": fields}


@functools.cache
def _choice(name: str, choices: tuple[str, ...]) -> type[Choice]:
    return Enum(name, [(value, value) for value in choices], type=Choice)  # type: ignore[return-value]


def _python_type(text: Any) -> Any:
    if isinstance(text, str):
        return Any if text == "any" else {"bool": bool, "int": int, "float": float, "str": str}[text]
    if "enum" in text:
        return _choice(text["enum"], tuple(text["choices"]))
    if "dataclass" in text:
        return rebuild(text["dataclass"])
    args = tuple(Ellipsis if a == "..." else _python_type(a) for a in text["tuple"])
    return tuple[args]  # type: ignore[valid-type]


def _python_value(text: Any, value: Any) -> Any:
    kind = _python_type(text)
    if isinstance(text, dict) and "tuple" in text:
        parts = text["tuple"]
        items = [_python_value(parts[0] if parts[-1] == "..." else parts[i], v) for i, v in enumerate(value)]
        return tuple(items)
    if isinstance(kind, type) and issubclass(kind, Enum):
        return kind(value)
    if isinstance(kind, type) and dataclasses.is_dataclass(kind):
        return kind(
            **{
                f.name: _python_value(t, value[f.name])
                for f, (_, t, _d) in zip(dataclasses.fields(kind), text["dataclass"]["fields"])
            }
        )
    return value


def rebuild(description: Mapping[str, Any]) -> type:
    """The dataclass a :func:`describe` output describes: same name, fields, types, choices and defaults
    (no methods), which OmegaConf types as it types the original. One class per description and process,
    so a nested field's type and its default's class are one."""
    return _rebuilt(json.dumps(description, sort_keys=True))


@functools.cache
def _rebuilt(text: str) -> type:
    description = json.loads(text)
    fields = []
    for name, text, default in description["fields"]:
        value = _python_value(text, default)
        if isinstance(value, (list, dict)) or dataclasses.is_dataclass(value):
            fields.append(
                (
                    name,
                    _python_type(text),
                    dataclasses.field(default_factory=functools.partial(_python_value, text, default)),
                )
            )
        else:
            fields.append((name, _python_type(text), dataclasses.field(default=value)))
    cls = dataclasses.make_dataclass(description["name"], fields)
    cls.__qualname__ = description["qualname"]
    return cls


def real_class(description: Mapping[str, Any]) -> type:
    """The class a description was made from, imported (its module, then the dotted name within)."""
    found: Any = importlib.import_module(description["module"])  # dynamic: a registered class, recorded
    for part in description["qualname"].split("."):
        found = getattr(found, part)
    return typing.cast(type, found)


def class_or_rebuilt(description: Mapping[str, Any]) -> type:
    """The real class when its module is imported already (the simulator's schemas), else :func:`rebuild`'s."""
    module = sys.modules.get(description["module"])
    return real_class(description) if module is not None else rebuild(description)


def record_path() -> Path | None:
    """Where the record is kept: beside the ``estimators`` package's bytecode (None without the package)."""
    folder = estimators_folder()
    return None if folder is None else folder / "__pycache__" / RECORD


def _read() -> dict[str, Any] | None:
    path = record_path()
    try:
        record = json.loads(path.read_text()) if path is not None else None
    except (OSError, ValueError):  # none yet, or unreadable
        return None
    return record if isinstance(record, dict) else None


def _write(record: dict[str, Any]) -> bool:
    """Replace the record atomically (a parallel process reads the old one or the new, never half); False
    when the folder is read-only."""
    path = record_path()
    if path is None:
        return False
    try:
        path.parent.mkdir(exist_ok=True)
        with tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False, suffix=".tmp") as out:
            json.dump(record, out)
        os.replace(out.name, path)
    except OSError:
        return False
    return True


def read_record() -> Record | None:
    """The record when it was written for the code as it is now (:func:`code_stamp`); None otherwise."""
    record = _read()
    try:
        if record is None or record["stamp"] != json.loads(json.dumps(code_stamp())):
            return None
        return Record(estimators=record["estimators"], sources=record["sources"], valid=record.get("valid", {}))
    except (KeyError, TypeError):
        return None


def write_record(
    estimator_configs: Mapping[str, type],
    plugin_nodes: Mapping[str, Any],
    sources: Mapping[str, Any],
) -> bool:
    """Record every estimator's ``Config`` (a plug-in's node too) and every source's ``Config`` and check;
    True when written, False when the record is current already (kept, with the validated nodes gathered
    so far) or cannot be written.

    Parameters
    ----------
    estimator_configs : mapping of name to ``Config`` dataclass
    plugin_nodes : mapping of plug-in name to its ``estimator/<name>`` node
    sources : mapping of name to :class:`simbench.source_registry.Source` subclass
    """
    stamp = code_stamp()
    old = _read()
    if old is not None and old.get("stamp") == json.loads(json.dumps(stamp)):
        return False
    try:
        record = {
            "stamp": stamp,
            "estimators": {
                name: {"config": describe(config), "node": plugin_nodes.get(name)}
                for name, config in estimator_configs.items()
            },
            "sources": {
                name: {"config": describe(cls.Config), "check": _check_name(cls)} for name, cls in sources.items()
            },
            "valid": {},
        }
    except TypeError:  # a field type the record cannot hold: every command line imports the classes
        return False
    return _write(record)


def _check_name(source: type) -> str | None:
    """``module:name`` of a source's check when it is a plain function (a ``staticmethod``, its own or
    inherited), else None."""
    check = inspect.getattr_static(source, "check", None)
    if not isinstance(check, staticmethod):
        return None
    return f"{check.__func__.__module__}:{check.__func__.__qualname__}"


def source_check(record: Record, name: str) -> Callable[[Any], None] | None:
    """The recorded check of source ``name`` (:func:`_check_name`), imported; None without one."""
    text = record.sources.get(name, {}).get("check")
    if not text:
        return None
    module, _, qualname = text.partition(":")
    return typing.cast(Callable[[Any], None], real_class({"module": module, "qualname": qualname}))


def node_text(node: Any) -> str:
    """A resolved estimator node as canonical JSON (sorted keys), how :func:`known_valid` compares nodes."""
    return json.dumps(node, sort_keys=True, separators=(",", ":"), default=str)


def known_valid(record: Record, name: str, node: Any) -> bool:
    """True when estimator ``name``'s resolved ``node`` passed its checks under this code before."""
    return node_text(node) in record.valid.get(name, ())


def remember_valid(checked: Iterable[tuple[str, Any]]) -> None:
    """Add estimator nodes that passed their checks (name, resolved node) to a current record."""
    checked = list(checked)
    if not checked:
        return
    record = _read()
    if record is None or record.get("stamp") != json.loads(json.dumps(code_stamp())):
        return  # none, or of other code: what this process checked says nothing about it
    valid: dict[str, list[str]] = record.setdefault("valid", {})
    changed = False
    for name, node in checked:
        text = node_text(node)
        kept = valid.setdefault(name, [])
        if text not in kept:
            kept.append(text)
            del kept[:-VALID_KEPT]
            changed = True
    if changed:
        _write(record)
