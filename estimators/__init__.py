"""Estimator registry.

Built-in estimators live in family packages (``model/`` holds the shared GNSS
model and registers nothing; ``batch/``, ``incremental/``, ``filters/``,
``gnss_ins/``, ``baselines/`` hold the estimators; a family imports ``model/``,
never another family). Every module registers its class with :func:`register`;
the modules are discovered, not listed, so a new estimator is a new module in
its family that registers its class.

Plug-in estimators: an installed package names an :class:`Estimator` subclass
in the entry-point group ``simbench.estimators`` (:data:`ENTRY_POINT_GROUP`),
the entry point's name being the estimator's ``name``::

    [project.entry-points."simbench.estimators"]
    huber_spp = "simbench_example_estimator:HuberSpp"

Its parameters are its ``Config`` dataclass; :mod:`simbench.runs.compose` puts it
into the Hydra ``estimator`` group beside ``conf/estimator/``. The runner, the
CLI and the contract test look built-ins and plug-ins up alike by name.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import pkgutil
from collections.abc import Iterable
from dataclasses import dataclass
from importlib.metadata import EntryPoint, entry_points
from typing import TypeVar

from estimators.base import Estimator, Solution
from simbench.entry_points import ALL_ESTIMATORS, ESTIMATOR_GROUP, load_plugin
from simbench.errors import SimbenchError

#: Entry-point group in which installed packages name their estimator classes.
ENTRY_POINT_GROUP = ESTIMATOR_GROUP
#: :func:`source` of the estimators in this package.
BUILT_IN = "built-in"
#: The ``estimator`` option that selects every registered estimator (the default run); no
#: estimator may take this name.
ALL = ALL_ESTIMATORS

_REGISTRY: dict[str, type[Estimator]] = {}

E = TypeVar("E", bound=type[Estimator])


@dataclass(frozen=True)
class Plugin:
    """An estimator class an installed package registered through :data:`ENTRY_POINT_GROUP`."""

    cls: type[Estimator]
    package: str  #: the distribution that declares the entry point (``pip install`` name)


def register(cls: E) -> E:
    """Class decorator adding a built-in estimator to the registry under ``cls.name``."""
    if cls.name in _REGISTRY and _REGISTRY[cls.name] is not cls:
        raise ValueError(f"estimator name '{cls.name}' registered twice")
    _REGISTRY[cls.name] = cls
    return cls


def _load_all() -> None:
    # every module of every family package: an estimator registers itself on import
    for module in pkgutil.walk_packages(__path__, prefix=f"{__name__}."):
        importlib.import_module(module.name)  # dynamic: discovered, not listed


def built_in() -> dict[str, type[Estimator]]:
    """The estimators of this package by name."""
    _load_all()
    return {name: cls for name, cls in sorted(_REGISTRY.items()) if cls.__module__.startswith(f"{__name__}.")}


def discover(entries: Iterable[EntryPoint], taken: dict[str, type[Estimator]]) -> dict[str, Plugin]:
    """Load the estimator classes the entry points name and check each one.

    Parameters
    ----------
    entries : iterable of importlib.metadata.EntryPoint
        Entry points of :data:`ENTRY_POINT_GROUP`.
    taken : dict
        Estimators already registered (the built-ins) by name.

    Raises
    ------
    SimbenchError
        In one line naming the package: an entry point that cannot be loaded or
        names no :class:`Estimator` subclass, a class without a ``Config``
        dataclass or whose ``name`` differs from the entry point's, or a name
        that a built-in estimator or another package has, or :data:`ALL`.
    """
    found: dict[str, Plugin] = {}
    for entry in entries:
        loaded = load_plugin(entry, Estimator, "estimator", "Add your estimator")
        cls, package, field, fix = loaded.cls, loaded.package, loaded.field, loaded.fix
        config = getattr(cls, "Config", None)
        if not (isinstance(config, type) and dataclasses.is_dataclass(config)):
            raise SimbenchError(
                field,
                f"package '{package}': {cls.__name__} has no Config dataclass",
                f"give {cls.__name__} a Config dataclass of its parameters, or pip uninstall {package}",
            )
        if getattr(cls, "name", None) != entry.name:
            raise SimbenchError(
                field,
                f"package '{package}': {cls.__name__}.name is "
                f"{getattr(cls, 'name', None)!r}, not the entry point's name",
                fix,
            )
        if entry.name == ALL:
            raise SimbenchError(field, f"package '{package}' uses the reserved name '{entry.name}'", fix)
        if entry.name in taken and taken[entry.name] is not cls:
            owner = "a built-in estimator"
        elif entry.name in found and found[entry.name].cls is not cls:
            owner = f"package '{found[entry.name].package}'"
        else:
            owner = ""
        if owner:
            raise SimbenchError(
                field,
                f"package '{package}' registers the name '{entry.name}' of {owner}",
                f"rename the estimator in package '{package}' or pip uninstall one of them",
            )
        found[entry.name] = Plugin(cls=cls, package=package)
    return found


@functools.cache
def plugins() -> dict[str, Plugin]:
    """The installed plug-in estimators by name (discovered once per process; see :func:`discover`)."""
    return dict(sorted(discover(entry_points(group=ENTRY_POINT_GROUP), built_in()).items()))


def registered() -> dict[str, type[Estimator]]:
    """All registered estimators, built-in and plug-in, by name."""
    return dict(sorted({**built_in(), **{name: p.cls for name, p in plugins().items()}}.items()))


def source(name: str) -> str:
    """Where estimator ``name`` comes from: :data:`BUILT_IN` or the plug-in's package name."""
    found = plugins().get(name)
    if found is not None:
        return found.package
    get(name)  # an unknown name: the one-line error
    return BUILT_IN


def get(name: str) -> type[Estimator]:
    """Look an estimator class up by name, with a one-line error for unknown names."""
    known = registered()
    if name not in known:
        raise SimbenchError(
            "estimator",
            f"unknown estimator '{name}'",
            f"choose from {', '.join(known)} (python -m simbench --estimators lists them)",
        )
    return known[name]


__all__ = [
    "Estimator",
    "Solution",
    "Plugin",
    "ENTRY_POINT_GROUP",
    "BUILT_IN",
    "ALL",
    "register",
    "built_in",
    "discover",
    "plugins",
    "registered",
    "source",
    "get",
]
