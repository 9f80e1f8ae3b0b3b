"""Estimator registry.

Every estimator module registers its class with :func:`register`; the runner,
the CLI and the contract test look estimators up here by name. The modules of
this package are discovered, not listed: a new estimator family is a new
module that registers its class.
"""
from __future__ import annotations

import importlib
import pkgutil
from typing import TypeVar

from estimators.base import Estimator, Solution
from simbench.errors import SimbenchError

_REGISTRY: dict[str, type[Estimator]] = {}

E = TypeVar("E", bound=type[Estimator])


def register(cls: E) -> E:
    """Class decorator adding an estimator to the registry under ``cls.name``."""
    if cls.name in _REGISTRY and _REGISTRY[cls.name] is not cls:
        raise ValueError(f"estimator name '{cls.name}' registered twice")
    _REGISTRY[cls.name] = cls
    return cls


def _load_all() -> None:
    for module in pkgutil.iter_modules(__path__, prefix=f"{__name__}."):
        importlib.import_module(module.name)


def registered() -> dict[str, type[Estimator]]:
    """All registered estimators by name."""
    _load_all()
    return dict(sorted(_REGISTRY.items()))


def get(name: str) -> type[Estimator]:
    """Look an estimator class up by name, with a one-line error for unknown names."""
    known = registered()
    if name not in known:
        raise SimbenchError("estimator", f"unknown estimator '{name}'",
                            f"choose from {', '.join(known)} (python -m simbench --help lists them)")
    return known[name]


__all__ = ["Estimator", "Solution", "register", "registered", "get"]
