"""Typed configuration: Hydra/OmegaConf nodes merged into dataclasses, choices as Enums.

Hydra composes YAML from ``conf/``; :func:`to_typed` merges the result into a
dataclass schema, so code reads attributes with known types and units, and a
malformed value fails early with a one-line :class:`~simbench.errors.SimbenchError`.
Choice fields are :class:`Choice` Enums whose member names are the YAML words,
so OmegaConf rejects any other value at composition, naming the key and the
allowed values. Every layer's config (simulation, sources, estimators, runs)
builds on these three pieces.
"""

from __future__ import annotations

import dataclasses
import difflib
from enum import Enum
from typing import Any, TypeVar, get_type_hints

from omegaconf import DictConfig, ListConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from simbench.errors import SimbenchError

__all__ = ["Choice", "to_typed", "check_known_keys", "check_choices"]


class Choice(str, Enum):
    """Base of the config choice Enums: a member prints, formats and JSON-encodes as its YAML word.

    (``enum.StrEnum`` does this from Python 3.11; the package supports 3.10.)
    """

    def __str__(self) -> str:
        return str(self.value)

    def __format__(self, spec: str) -> str:
        return format(str(self.value), spec)


T = TypeVar("T")


def to_typed(cfg: DictConfig | dict[str, Any], schema: type[T], where: str = "config") -> T:
    """Merge a (Hydra) config into a dataclass schema and return the typed object.

    Parameters
    ----------
    cfg : DictConfig or dict
        Composed configuration; unknown keys are rejected.
    schema : type
        Dataclass to validate against.
    where : str
        Name of the config node, used in error messages.

    Raises
    ------
    SimbenchError
        With the full key of the first malformed value, or of a key the schema lacks
        (:func:`check_known_keys`).
    """
    try:
        merged = OmegaConf.merge(OmegaConf.structured(schema), cfg)
        check_known_keys(merged, where)
        return OmegaConf.to_object(merged)  # type: ignore[return-value]
    except OmegaConfBaseException as exc:
        key = getattr(exc, "full_key", None) or where
        msg = str(exc).splitlines()[0]
        raise SimbenchError(
            f"{where}.{key}" if where not in str(key) else str(key),
            msg,
            "check the value and its type in conf/ or on the command line",
        ) from None


def check_known_keys(node: DictConfig | ListConfig, where: str) -> None:
    """Raise a one-line :class:`SimbenchError` for a key of ``node`` that its dataclass type lacks, recursively.

    A ``+key=value`` override adds a key to a typed node, and merging it into the
    schema keeps it (the node's struct flag is off); :func:`OmegaConf.to_object`
    would then drop it without a word, so a typo such as ``+scenario.duraton_s=10``
    would run the default duration.

    Parameters
    ----------
    node : DictConfig or ListConfig
        A typed node (or a plain one holding typed nodes); a list has no keys to check.
    where : str
        Config node name prefixed to the key in the message, e.g. ``scenario``; ``""`` for the root.
    """
    if not isinstance(node, DictConfig):
        return
    prefix = f"{where}." if where else ""
    kind = OmegaConf.get_type(node)
    if isinstance(kind, type) and dataclasses.is_dataclass(kind):
        known = [f.name for f in dataclasses.fields(kind)]
        for key in map(str, node):
            if key not in known:
                close = difflib.get_close_matches(key, known, n=1)
                hint = f"did you mean {prefix}{close[0]}? " if close else ""
                raise SimbenchError(
                    f"{prefix}{key}",
                    f"unknown key: {kind.__name__} has no such field",
                    f"{hint}set a known field without '+' (the fields are in conf/ or --cfg job)",
                )
    for name, value in node.items_ex(resolve=False):
        if isinstance(value, DictConfig):
            check_known_keys(value, f"{prefix}{name!s}")


def check_choices(cfg: Any, where: str = "") -> None:
    """Raise a one-line :class:`SimbenchError` for a choice field holding a value its Enum lacks.

    OmegaConf checks every config composed from YAML or the command line; this
    catches dataclasses built or changed in Python, recursively.

    Parameters
    ----------
    cfg : dataclass instance
    where : str
        Config node name prefixed to the field in the message, e.g. ``estimator.l2``.
    """
    hints = get_type_hints(type(cfg))
    for f in dataclasses.fields(cfg):
        value, kind, key = getattr(cfg, f.name), hints[f.name], f"{where}.{f.name}" if where else f.name
        if isinstance(kind, type) and issubclass(kind, Choice):
            if value not in list(kind):
                raise SimbenchError(key, f"unknown value '{value}'", f"use one of {', '.join(map(str, kind))}")
        elif dataclasses.is_dataclass(value):
            check_choices(value, key)
