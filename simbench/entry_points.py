"""Plug-in classes named by entry points: the loading and the checks every plug-in group shares.

Estimators (``simbench.estimators``) and scenario sources (``simbench.sources``)
are discovered alike; each group adds its own checks on the loaded class.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib.metadata import EntryPoint, entry_points
from typing import Generic, NoReturn, TypeVar

from simbench.errors import SimbenchError, one_line

__all__ = ["ALL_ESTIMATORS", "ESTIMATOR_GROUP", "SOURCE_GROUP", "LoadedPlugin", "entry_point_names", "load_plugin"]

#: Entry-point group in which installed packages name their estimator classes (:mod:`estimators`).
ESTIMATOR_GROUP = "simbench.estimators"
#: Entry-point group in which packages (simbench itself too) name their source classes
#: (:mod:`simbench.source_registry`).
SOURCE_GROUP = "simbench.sources"
#: The ``estimator`` option that selects every registered estimator (the default run); no
#: estimator may take this name.
ALL_ESTIMATORS = "all"

T = TypeVar("T")


@dataclass(frozen=True)
class LoadedPlugin(Generic[T]):
    """A class an entry point names, with what an error about it must say."""

    cls: type[T]
    package: str  #: the distribution that declares the entry point (``pip install`` name)
    field: str  #: the ``field`` of an error about this plug-in, e.g. ``source plug-in 'x'``
    fix: str  #: the generic fix: mend the package or uninstall it
    name: str = ""  #: the entry point's name
    kind: str = ""  #: the group's noun in messages, e.g. ``estimator``

    def check_name(self) -> None:
        """One line naming the package when the class's ``name`` is not the entry point's."""
        name = getattr(self.cls, "name", None)
        if name != self.name:
            raise SimbenchError(
                self.field,
                f"package '{self.package}': {self.cls.__name__}.name is {name!r}, not the entry point's name",
                self.fix,
            )

    def refuse_taken(self, owner: str) -> NoReturn:
        """One line: ``owner`` (``package 'x'``, ``a built-in estimator``) already has the entry point's name."""
        raise SimbenchError(
            self.field,
            f"package '{self.package}' registers the name '{self.name}' of {owner}",
            f"rename the {self.kind} in package '{self.package}' or pip uninstall one of them",
        )


def load_plugin(entry: EntryPoint, base: type[T], kind: str, readme_section: str) -> LoadedPlugin[T]:
    """Load the class ``entry`` names and check that it subclasses ``base``.

    Parameters
    ----------
    entry : importlib.metadata.EntryPoint
        One entry point of a simbench plug-in group.
    base : type
        The class every plug-in of the group subclasses (``Estimator``, ``Source``).
    kind : str
        The group's noun in messages, e.g. ``estimator``.
    readme_section : str
        README section that explains writing such a plug-in, named in the fix.

    Raises
    ------
    SimbenchError
        In one line naming the package: the entry point cannot be loaded, or names
        no subclass of ``base``.
    """
    dist = getattr(entry, "dist", None)  # None for an entry point not read from an installed package
    package = dist.name if dist is not None else entry.value.split(":")[0]
    field = f"{kind} plug-in '{entry.name}'"
    fix = f"fix package '{package}' (README, {readme_section}) or pip uninstall {package}"
    try:
        cls = entry.load()
    except Exception as exc:
        raise SimbenchError(field, f"package '{package}' cannot load {entry.value}: {one_line(exc)}", fix) from None
    if not (isinstance(cls, type) and issubclass(cls, base)):
        article = "an" if base.__name__[0] in "AEIOU" else "a"
        raise SimbenchError(
            field, f"package '{package}' names {entry.value}, not {article} {base.__name__} subclass", fix
        )
    return LoadedPlugin(cls=cls, package=package, field=field, fix=fix, name=entry.name, kind=kind)


def entry_point_names(group: str) -> list[str]:
    """The names the installed packages declare in an entry-point group, without loading one.

    What ``--help`` and the name checks of a command line need: loading the estimators takes
    seconds. A plug-in that cannot load is refused when the run composes its config.
    """
    return sorted({entry.name for entry in entry_points(group=group)})
