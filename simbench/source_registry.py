"""Scenario sources: where a scenario's data come from, found by name like the estimators.

A source is a :class:`Source` subclass with a ``name`` (the ``scenario.source``
value), a ``Config`` dataclass (the typed ``scenario`` node, a
:class:`SourceConfig`) and :meth:`Source.load`, which turns a typed config into a
:class:`~simbench.contract.Scenario`. Every source, built-in or not, is
registered in the entry-point group ``simbench.sources``
(:data:`ENTRY_POINT_GROUP`), the entry point's name being the source's ``name``::

    [project.entry-points."simbench.sources"]
    static_receiver = "simbench_example_estimator.static_source:StaticReceiver"

The built-ins (``simulated``, ``rinex``, ``gnsslogger``, ``librsf``) are declared the same way
in simbench's own ``pyproject.toml``. :mod:`simbench.runs.compose` gives each
source its typed Hydra node (``scenario/<name>_schema``) and, unless
``conf/scenario/<name>.yaml`` exists, a preset of its ``Config`` defaults, so
``python -m simbench scenario=<name>`` runs it.
"""

from __future__ import annotations

import dataclasses
import functools
from abc import ABC, abstractmethod
from collections.abc import Iterable
from dataclasses import dataclass
from importlib.metadata import EntryPoint, entry_points
from typing import Any, ClassVar, Protocol, TypeVar

from simbench.bounds import check_bounds
from simbench.contract import Scenario
from simbench.entry_points import SOURCE_GROUP, load_plugin
from simbench.errors import SimbenchError
from simbench.typed import check_choices

__all__ = [
    "ENTRY_POINT_GROUP",
    "SIMULATED",
    "SourceConfig",
    "DataConfig",
    "Source",
    "Plugin",
    "scenario_config",
    "discover",
    "plugins",
    "registered",
    "get",
]

#: Entry-point group in which packages (simbench itself too) name their source classes.
ENTRY_POINT_GROUP = SOURCE_GROUP
#: The default source, the simulator: a result row or scenario that names no source was simulated.
SIMULATED = "simulated"


@dataclass
class SourceConfig:
    """The fields every source's ``Config`` has; a subclass sets ``source`` to its source's name."""

    name: str = ""  #: the scenario's name in result tables
    source: str = SIMULATED  #: the source that reads this node (:func:`get`)


class DataConfig(Protocol):
    """What :meth:`Source.load` reads: the data part of a composed config.

    ``scenario`` is the source's ``Config``; ``receiver``, ``imu`` and ``seed``
    are the tracking preset, IMU grade and random seed that a simulating source
    uses (a real log ignores them).
    """

    @property
    def scenario(self) -> SourceConfig: ...

    @property
    def receiver(self) -> Any: ...

    @property
    def imu(self) -> Any: ...

    @property
    def seed(self) -> int: ...


def check_source_config(cfg: DataConfig) -> None:
    """The check every source's config gets (:meth:`Source.check`'s default): the choice fields and the
    bounds of every number (:func:`~simbench.bounds.check_bounds`), in one line each."""
    check_choices(cfg.scenario, "scenario")
    check_bounds(cfg.scenario, "scenario")


class Source(ABC):
    """A scenario source: subclass it, set ``name`` and ``Config``, write :meth:`load`."""

    name: ClassVar[str] = ""
    Config: ClassVar[type[SourceConfig]] = SourceConfig

    def check(self, cfg: DataConfig) -> None:
        """Raise a one-line :class:`~simbench.errors.SimbenchError` for a config :meth:`load` cannot use.

        Runs before any file is read or data generated; the default checks the choice fields and
        the bounds of every number (:func:`~simbench.bounds.check_bounds`).
        """
        check_source_config(cfg)

    def label(self, cfg: DataConfig) -> str:
        """The scenario's name in result tables, known before :meth:`load` (for rows of a job that fails).

        The default is ``scenario.name``; a source that derives the name from its input overrides it.
        """
        return cfg.scenario.name

    def input_files(self, cfg: DataConfig) -> dict[str, tuple[str, ...]]:
        """The files :meth:`load` reads, by the setting that names them (after :meth:`check`).

        Their content enters the scenario's cache key (:func:`simbench.runs.scenarios.scenario_key`),
        so a file edited in place, or a relative path naming another file from another folder, is
        read again. The default: none (a source that reads files lists them).
        """
        return {}

    @abstractmethod
    def load(self, cfg: DataConfig) -> Scenario:
        """The scenario ``cfg.scenario`` describes (after :meth:`check`).

        A source other than the simulator records its name in ``meta['source']`` (the ``source``
        column of the result tables).
        """


C = TypeVar("C", bound=SourceConfig)


def scenario_config(cfg: DataConfig, kind: type[C]) -> C:
    """``cfg.scenario`` as a ``kind``: what :meth:`Source.load` starts with.

    Raises
    ------
    SimbenchError
        When ``cfg.scenario`` is the ``Config`` of another source.
    """
    if not isinstance(cfg.scenario, kind):
        raise SimbenchError(
            "scenario",
            f"is a {type(cfg.scenario).__name__}, not a {kind.__name__}",
            f"choose its source with scenario={kind().source} on the command line, or build a {kind.__name__}",
        )
    return cfg.scenario


@dataclass(frozen=True)
class Plugin:
    """A source class a package registered through :data:`ENTRY_POINT_GROUP`."""

    cls: type[Source]
    package: str  #: the distribution that declares the entry point (``pip install`` name)


def discover(entries: Iterable[EntryPoint]) -> dict[str, Plugin]:
    """Load the source classes the entry points name and check each one.

    Parameters
    ----------
    entries : iterable of importlib.metadata.EntryPoint
        Entry points of :data:`ENTRY_POINT_GROUP`.

    Raises
    ------
    SimbenchError
        In one line naming the package: an entry point that cannot be loaded or
        names no :class:`Source` subclass, a ``Config`` that is not a
        :class:`SourceConfig` dataclass whose ``source`` defaults to the entry
        point's name, a ``name`` other than the entry point's, or a name that
        another package registers.
    """
    found: dict[str, Plugin] = {}
    for entry in entries:
        loaded = load_plugin(entry, Source, "source", "Add a source")
        cls, package, field, fix = loaded.cls, loaded.package, loaded.field, loaded.fix
        config = getattr(cls, "Config", None)
        defaults: dict[str, Any] = {}
        if isinstance(config, type) and issubclass(config, SourceConfig) and dataclasses.is_dataclass(config):
            defaults = {f.name: f.default for f in dataclasses.fields(config)}
        if defaults.get("source") != entry.name:
            raise SimbenchError(
                field,
                f"package '{package}': {cls.__name__}.Config is not a SourceConfig dataclass with "
                f"source: str = '{entry.name}'",
                fix,
            )
        loaded.check_name()
        if entry.name in found and found[entry.name].cls is not cls:
            loaded.refuse_taken(f"package '{found[entry.name].package}'")
        found[entry.name] = Plugin(cls=cls, package=package)
    return found


@functools.cache
def plugins() -> dict[str, Plugin]:
    """The installed sources by name, built-ins included (discovered once per process; see :func:`discover`)."""
    return dict(sorted(discover(entry_points(group=ENTRY_POINT_GROUP)).items()))


def registered() -> dict[str, type[Source]]:
    """The source classes by name."""
    return {name: plugin.cls for name, plugin in plugins().items()}


def get(name: str) -> type[Source]:
    """Look a source class up by name, with a one-line error for an unknown name."""
    known = registered()
    if name not in known:
        raise SimbenchError(
            "scenario.source",
            f"unknown source '{name}'",
            f"choose from {', '.join(known)}" if known else "reinstall simbench (pip install -e .) to register them",
        )
    return known[name]
