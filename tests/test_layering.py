"""The layers of simbench, declared here and checked on the source.

An AST scan of every module under ``simbench/`` and ``estimators/`` (and, for
rule (b), ``tests/``, ``benchmarks/`` and ``examples/``):

(a) a module imports only modules of its own unit or of a lower layer
    (:data:`LAYERS`), at the top or inside a function, also through
    ``importlib.import_module``; units of one layer (``sim`` and ``data``) never
    import each other. Importing ``a.b.c`` also runs ``a/__init__`` and ``a/b/__init__``
    (the parent packages that are not the importer's own): such an edge counts by what the
    ``__init__`` loads at import time, every module of which must be one the importer may import
    (:func:`package_init_violations`); ``import_module`` with a name that is not a literal string
    cannot be checked and is refused unless its line says why it is safe (``# dynamic: ...``);
(b) no module imports an underscore name from another module
    (``from x import _y``) or reads ``m._y`` where ``m`` is an imported module;
(c) there is no import cycle between modules (module-level imports and the parent-package
    ``__init__`` each of them runs);
(d) imports sit at the top of a module: one inside a function is allowed only for
    an optional dependency, and says so in a comment on its line (``# optional: ...``),
    or in an entry point (the top layer: ``simbench.cli``, ``simbench.api``) for start-up
    time, marked ``# lazy`` on its line (``python -m simbench --help`` must not wait
    seconds for every estimator and pandas).

Dunder names (``__version__``, ``__file__``) are public. Attributes of
objects (``self._cache``) are not module attributes and are not checked.
"""

from __future__ import annotations

import ast
import importlib.util
from collections.abc import Collection
from pathlib import Path
from typing import NamedTuple

import pytest

import estimators

ROOT = Path(__file__).resolve().parent.parent
SCANNED_PACKAGES = ("simbench", "estimators")
#: Further folders checked for rule (b) only: they may import any layer.
PRIVATE_NAME_SCANNED = ("tests", "benchmarks", "examples")

#: The estimator family packages; every built-in estimator lives in one.
ESTIMATOR_FAMILIES = (
    "estimators.batch",
    "estimators.incremental",
    "estimators.filters",
    "estimators.gnss_ins",
    "estimators.baselines",
)

#: The layers, bottom up. Each is a tuple of units; a unit is a tuple of module prefixes. A module may
#: import its own unit and every unit of a lower layer.
LAYERS: tuple[tuple[tuple[str, ...], ...], ...] = (
    (
        (
            "simbench.errors",
            "simbench.bounds",
            "simbench.typed",
            "simbench.contract",
            "simbench.source_registry",
            "simbench.entry_points",
            "simbench.paths",
        ),
    ),  # the shared base
    (("simbench.core",),),  # physics: frames, time, orbits, atmosphere
    (("simbench.gnss",),),  # measurement model, single point, navigation
    (("simbench.sim",), ("simbench.data",)),  # scenario sources, side by side
    (("estimators", "estimators.base", "estimators.model"),),  # the registry, the interface, the shared GNSS model
    tuple((family,) for family in ESTIMATOR_FAMILIES),  # side by side: each imports the model, never another
    (("simbench.analysis",),),  # statistics, claims, tables on data frames
    (("simbench.runs",),),  # composition, jobs, store, studies
    (("simbench.report",),),
    (("simbench.api", "simbench.cli", "simbench.__main__", "simbench"),),  # entry points; the lazy facade
)


def is_private(name: str) -> bool:
    """True for ``_x`` names; dunders such as ``__version__`` are public."""
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def is_module(dotted: str) -> bool:
    """True when ``dotted`` names a module or package (in this repository or installed)."""
    rel = Path(*dotted.split("."))
    if (ROOT / rel.with_suffix(".py")).is_file() or (ROOT / rel / "__init__.py").is_file():
        return True
    try:
        return importlib.util.find_spec(dotted) is not None
    except (ImportError, ValueError):
        return False


def in_package(module: str, packages: tuple[str, ...]) -> bool:
    return any(module == p or module.startswith(p + ".") for p in packages)


def absolute_target(node: ast.ImportFrom, module: str, is_package: bool) -> str:
    """The absolute module name of ``from <target> import ...`` written in ``module``."""
    if node.level == 0:
        return node.module or ""
    parts = module.split(".")
    base = parts if is_package else parts[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def dotted_name(node: ast.expr) -> str | None:
    """``a.b.c`` for a chain of attribute reads on a plain name, else None."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    return ".".join([node.id, *reversed(parts)])


def unit_of(module: str) -> tuple[int, int] | None:
    """(layer, unit) of a module of this repository by its longest matching prefix; None for third parties."""
    best: tuple[int, int, int] | None = None
    for li, layer in enumerate(LAYERS):
        for ui, unit in enumerate(layer):
            for prefix in unit:
                if module == prefix or module.startswith(prefix + "."):
                    if best is None or len(prefix) > best[2]:
                        best = (li, ui, len(prefix))
    return None if best is None else best[:2]


def allowed(importer: str, target: str) -> bool:
    """Rule (a): ``importer`` may import ``target``."""
    src, dst = unit_of(importer), unit_of(target)
    if src is None or dst is None:
        return True
    return dst == src or dst[0] < src[0]


def imported_modules(
    node: ast.Import | ast.ImportFrom, module: str, is_package: bool, names: Collection[str] = ()
) -> list[str]:
    """The modules an import statement loads: ``from a import b`` gives ``a.b`` where that is a module, else ``a``.

    ``names`` are further module names to count as modules (those of a synthetic tree).
    """
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    target = absolute_target(node, module, is_package)
    return [
        f"{target}.{a.name}"
        if a.name != "*" and (f"{target}.{a.name}" in names or is_module(f"{target}.{a.name}"))
        else target
        for a in node.names
    ]


def parent_packages(target: str, importer: str) -> list[str]:
    """The packages whose ``__init__`` importing ``target`` from ``importer`` runs first, outermost first.

    Importing ``a.b.c`` runs ``a/__init__`` and ``a/b/__init__``; those of the importer's own
    packages are running already (a module's packages start before it), so they are no new edge.
    """
    parts = target.split(".")
    ancestors = (".".join(parts[:i]) for i in range(1, len(parts)))
    return [p for p in ancestors if not (importer == p or importer.startswith(p + "."))]


def layering_violations(
    source: str, module: str, path: str, is_package: bool = False, layers: bool = True
) -> list[str]:
    """Every breach of rules (a), (b) and (d) in one module's source, as ``path:line: message``.

    Parameters
    ----------
    source : str
        Python source text.
    module : str
        Its dotted module name (``simbench.core.orbits``); places it in :data:`LAYERS`.
    path : str
        Shown in the messages.
    is_package : bool
        The source is a package ``__init__`` (resolves relative imports).
    layers : bool
        Check rules (a) and (d) too; False for tests, benchmarks and examples (rule (b) only).
    """
    tree = ast.parse(source, filename=path)
    lines = source.splitlines()
    found: list[str] = []
    module_names: set[str] = set()  # local names bound to module objects
    top_level = {id(n) for n in tree.body}
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            targets = imported_modules(node, module, is_package)
            if layers:
                found += [
                    f"{path}:{node.lineno}: imports {target} from a higher layer or a sibling unit"
                    for target in targets
                    if not allowed(module, target)
                ]
                nested = id(node) not in top_level and not _in_type_checking_block(tree, node)
                line = lines[node.lineno - 1]
                lazy = "# lazy" in line and unit_of(module) == (len(LAYERS) - 1, 0)
                if nested and "# optional" not in line and not lazy:
                    found.append(
                        f"{path}:{node.lineno}: imports inside a function (only an optional "
                        "dependency may, with '# optional: ...' on its line, or an entry point, with '# lazy')"
                    )
            if isinstance(node, ast.Import):
                module_names.update(alias.asname or alias.name.split(".")[0] for alias in node.names)
            else:
                target = absolute_target(node, module, is_package)
                for alias in node.names:
                    if is_private(alias.name):
                        found.append(f"{path}:{node.lineno}: imports private name {alias.name} from {target}")
                    elif alias.name != "*" and is_module(f"{target}.{alias.name}"):
                        module_names.add(alias.asname or alias.name)
        elif (
            isinstance(node, ast.Call)
            and layers
            and dotted_name(node.func) in ("importlib.import_module", "import_module", "__import__")
        ):
            arg = node.args[0] if node.args else next((k.value for k in node.keywords if k.arg == "name"), None)
            if not (isinstance(arg, ast.Constant) and isinstance(arg.value, str)):
                if "# dynamic:" not in lines[node.lineno - 1]:
                    found.append(
                        f"{path}:{node.lineno}: imports a module by a computed name (no check can see which; "
                        "say why it is safe with '# dynamic: ...' on its line)"
                    )
            elif not allowed(module, arg.value):
                found.append(f"{path}:{node.lineno}: imports {arg.value} dynamically from a higher layer")
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and is_private(node.attr):
            owner = dotted_name(node.value)
            if owner is not None and owner.split(".")[0] in module_names:
                found.append(f"{path}:{node.lineno}: reads private name {node.attr} of module {owner}")
    return sorted(set(found), key=lambda s: (s.split(":")[0], int(s.split(":")[1]), s))


def _in_type_checking_block(tree: ast.Module, node: ast.stmt) -> bool:
    """True for an import under a module-level ``if TYPE_CHECKING:`` (never executed)."""
    return any(
        isinstance(top, ast.If)
        and dotted_name(top.test) in ("TYPE_CHECKING", "typing.TYPE_CHECKING")
        and any(node is n for n in ast.walk(top))
        for top in tree.body
    )


class ModuleSource(NamedTuple):
    """One module of a tree: its dotted name, the path shown in messages, its text, whether it is a package."""

    name: str
    path: str
    text: str
    is_package: bool


def module_files(package: str) -> list[tuple[str, Path, bool]]:
    """(dotted name, file, is_package) of every module of one top-level folder of the repository."""
    out = []
    for file in sorted((ROOT / package).rglob("*.py")):
        rel = file.relative_to(ROOT)
        is_package = file.name == "__init__.py"
        parts = rel.parent.parts if is_package else rel.with_suffix("").parts
        out.append((".".join(parts), file, is_package))
    return out


def tree_sources(packages: tuple[str, ...] = SCANNED_PACKAGES) -> list[ModuleSource]:
    """Every module of the repository's ``packages``."""
    return [
        ModuleSource(name, str(file.relative_to(ROOT)), file.read_text(), is_package)
        for p in packages
        for name, file, is_package in module_files(p)
    ]


def scan(package: str, layers: bool = True) -> list[str]:
    """Violations in every module of one top-level folder of the repository."""
    return [
        v for m in tree_sources((package,)) for v in layering_violations(m.text, m.name, m.path, m.is_package, layers)
    ]


def in_tree(target: str, names: Collection[str]) -> str:
    """The module of ``names`` an import of ``target`` loads (the package whose ``__init__`` defines a name); ''
    for a third party."""
    while target and target not in names:
        target = target.rpartition(".")[0]
    return target


Graph = dict[str, set[str]]


def import_graphs(sources: list[ModuleSource] | None = None) -> tuple[Graph, Graph]:
    """Module-level import edges between the modules of ``sources`` (default: :data:`SCANNED_PACKAGES`).

    Returns the named edges (an import of ``a.b.c`` is one to ``a.b.c``; a name defined in a
    package ``__init__``, one to that package) and the parent-package edges (to the packages
    the import runs first, :func:`parent_packages`).
    """
    sources = tree_sources() if sources is None else sources
    names = {m.name for m in sources}
    named: Graph = {m.name: set() for m in sources}
    parents: Graph = {m.name: set() for m in sources}
    for m in sources:
        for node in ast.parse(m.text).body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                for target in imported_modules(node, m.name, m.is_package, names):
                    target = in_tree(target, names)
                    named[m.name].update({target} & names - {m.name})
                    parents[m.name].update(p for p in parent_packages(target, m.name) if p in names)
    return named, parents


def import_graph(sources: list[ModuleSource] | None = None) -> Graph:
    """Every module-level import edge, named and parent-package (what :func:`cycles` walks)."""
    named, parents = import_graphs(sources)
    return {m: named[m] | parents[m] for m in named}


def loaded_code(named: Graph, parents: Graph, package: str) -> set[str]:
    """The modules whose code running ``package/__init__`` loads by name, directly or through what it loads.

    A package reached as a parent is run but not named: it adds what it names, not itself.
    """
    found: set[str] = set()
    seen = {package}
    todo = [(m, True) for m in named.get(package, ())] + [(m, False) for m in parents.get(package, ())]
    while todo:
        m, by_name = todo.pop()
        if by_name:
            found.add(m)
        if m not in seen:
            seen.add(m)
            todo += [(n, True) for n in named.get(m, ())] + [(n, False) for n in parents.get(m, ())]
    return found


def package_init_violations(sources: list[ModuleSource] | None = None) -> list[str]:
    """Rule (a) for the parent packages an import runs, as ``path:line: message``.

    A parent package's ``__init__`` is not named by the importer, so it counts by what it
    runs: every module its imports load by name (transitively, :func:`loaded_code`) must be
    one the importer may import. (The lazy facade ``simbench/__init__`` loads nothing of ours.)
    """
    sources = tree_sources() if sources is None else sources
    names = {m.name for m in sources}
    named, parents = import_graphs(sources)
    found = []
    for m in sources:
        for node in ast.walk(ast.parse(m.text)):
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            for target in imported_modules(node, m.name, m.is_package, names):
                for package in parent_packages(in_tree(target, names), m.name):
                    bad = sorted(r for r in loaded_code(named, parents, package) if not allowed(m.name, r))
                    if package in names and bad:
                        found.append(
                            f"{m.path}:{node.lineno}: importing {target} runs {package}/__init__, which loads "
                            f"{', '.join(bad)} from a higher layer or a sibling unit"
                        )
    return sorted(set(found))


def cycles(graph: Graph) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


# --------------------------------------------------------------------------- the checker can fail

SYNTHETIC = """\
import estimators
import numpy as np
import simbench.core.orbits as orbits_mod
from simbench.core import orbits
from simbench.core.orbits import _fmt_gps, FIT_HALF_WINDOW_S
from simbench import __version__
from ._private_sibling import thing
from . import _helper
from simbench.data.rinex import load_rinex
from simbench.runs import jobs


def f(self):
    from estimators.model.measurement import troposphere_terms
    import importlib  # lazy: only an entry point may say so
    importlib.import_module("estimators.batch.bce")
    import matplotlib  # optional: plotting
    x = orbits._CHUNK_EPOCHS + orbits_mod._CHUNK_EPOCHS
    y = self._cache + np.pi + orbits.__name__ + orbits.FIT_HALF_WINDOW_S
    return x, y
"""


def test_checker_finds_every_kind_of_violation() -> None:
    found = layering_violations(SYNTHETIC, "simbench.sim.fake", "fake.py")
    assert found == [
        "fake.py:1: imports estimators from a higher layer or a sibling unit",
        "fake.py:5: imports private name _fmt_gps from simbench.core.orbits",
        "fake.py:6: imports simbench from a higher layer or a sibling unit",
        "fake.py:8: imports private name _helper from simbench.sim",
        "fake.py:9: imports simbench.data.rinex from a higher layer or a sibling unit",
        "fake.py:10: imports simbench.runs.jobs from a higher layer or a sibling unit",
        "fake.py:14: imports estimators.model.measurement from a higher layer or a sibling unit",
        "fake.py:14: imports inside a function (only an optional dependency may, with '# optional: ...' on its line, "
        "or an entry point, with '# lazy')",
        "fake.py:15: imports inside a function (only an optional dependency may, with '# optional: ...' on its line, "
        "or an entry point, with '# lazy')",
        "fake.py:16: imports estimators.batch.bce dynamically from a higher layer",
        "fake.py:18: reads private name _CHUNK_EPOCHS of module orbits",
        "fake.py:18: reads private name _CHUNK_EPOCHS of module orbits_mod",
    ]


def test_higher_layers_may_import_lower_ones() -> None:
    found = layering_violations(SYNTHETIC, "simbench.cli.fake", "fake.py")  # line 15 is an entry point's lazy import
    assert found == [
        "fake.py:5: imports private name _fmt_gps from simbench.core.orbits",
        "fake.py:8: imports private name _helper from simbench.cli",
        "fake.py:14: imports inside a function (only an optional dependency may, with '# optional: ...' on its line, "
        "or an entry point, with '# lazy')",
        "fake.py:18: reads private name _CHUNK_EPOCHS of module orbits",
        "fake.py:18: reads private name _CHUNK_EPOCHS of module orbits_mod",
    ]


def test_tests_are_checked_for_private_names_only() -> None:
    found = layering_violations(SYNTHETIC, "tests.test_fake", "fake.py", layers=False)
    assert found == [
        "fake.py:5: imports private name _fmt_gps from simbench.core.orbits",
        "fake.py:8: imports private name _helper from tests",
        "fake.py:18: reads private name _CHUNK_EPOCHS of module orbits",
        "fake.py:18: reads private name _CHUNK_EPOCHS of module orbits_mod",
    ]


def test_layer_order() -> None:
    assert allowed("simbench.sim.generator", "simbench.gnss.spp")
    assert allowed("simbench.sim.generator", "simbench.sim.tracking")
    assert not allowed("simbench.sim.generator", "simbench.data.rinex")  # side by side
    assert not allowed("simbench.data.rinex", "simbench.sim.config")
    assert not allowed("simbench.core.orbits", "simbench.gnss.geometry")
    assert allowed("simbench.runs.runner", "simbench.analysis.metrics")
    assert not allowed("simbench.report.build", "simbench.cli.main")
    assert allowed("simbench.cli.main", "simbench.report.build")
    assert not allowed("simbench.core.frames", "simbench")  # the facade is on top
    assert allowed("simbench.core.frames", "numpy")
    # estimator families import the shared model and the registry, never each other
    assert allowed("estimators.batch.bce", "estimators.model.measurement")
    assert allowed("estimators.batch.oracle", "estimators.batch.robust")
    assert allowed("estimators.incremental.ice", "estimators")
    assert not allowed("estimators.incremental.isam2", "estimators.batch.robust")
    assert not allowed("estimators.gnss_ins.crt_lss", "estimators.filters.ekf_ppp")
    assert not allowed("estimators.model.ppp_graph", "estimators.batch.robust")


def test_every_estimator_lives_in_a_family_package() -> None:
    """No estimator module outside ``estimators/<family>/`` (issue 47): the registry, the interface and
    the model register none, and every family package is declared in :data:`LAYERS`."""
    families = set(ESTIMATOR_FAMILIES)
    folders = {f"estimators.{p.name}" for p in (ROOT / "estimators").iterdir() if (p / "__init__.py").is_file()}
    assert folders == families | {"estimators.model"}
    homes = {name: cls.__module__.rpartition(".")[0] for name, cls in estimators.built_in().items()}
    assert len(homes) >= 15
    assert {name: home for name, home in homes.items() if home not in families} == {}


def test_relative_imports_resolve_against_the_package() -> None:
    src = "from .orbits import _fmt_gps\nfrom ..errors import SimbenchError\n"
    assert layering_violations(src, "simbench.data.rinex", "r.py") == [
        "r.py:1: imports private name _fmt_gps from simbench.data.orbits"
    ]
    assert layering_violations(src, "simbench.data", "i.py", is_package=True) == [
        "i.py:1: imports private name _fmt_gps from simbench.data.orbits"
    ]


def test_cycle_finder() -> None:
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


DYNAMIC = """\
import importlib
from importlib import import_module


def load(name):
    importlib.import_module(name)
    import_module(f"simbench.cli.{name}")
    __import__(name)  # dynamic: the plug-in modules found at run time
    importlib.import_module("simbench.core.orbits")
    importlib.import_module("simbench.runs.jobs")
    return importlib.import_module(name="x." + name)
"""


def test_computed_dynamic_imports_are_refused_unless_marked() -> None:
    computed = (
        "imports a module by a computed name (no check can see which; say why it is safe with "
        "'# dynamic: ...' on its line)"
    )
    assert layering_violations(DYNAMIC, "simbench.sim.fake", "d.py") == [
        f"d.py:6: {computed}",
        f"d.py:7: {computed}",
        "d.py:10: imports simbench.runs.jobs dynamically from a higher layer",
        f"d.py:11: {computed}",
    ]


def test_parent_packages_are_those_not_running_already() -> None:
    assert parent_packages("a.b.c", "x.y") == ["a", "a.b"]
    assert parent_packages("a.b.c", "a.z") == ["a.b"]
    assert parent_packages("a.b.c", "a.b") == []  # the importer is the package a.b itself
    assert parent_packages("a", "x") == []


def facade_tree(facade: str) -> list[ModuleSource]:
    """A synthetic tree: the ``simbench`` facade, two base modules, the top layer and an estimator module."""
    return [
        ModuleSource("simbench", "simbench/__init__.py", facade, True),
        ModuleSource("simbench.errors", "simbench/errors.py", "", False),
        ModuleSource("simbench.api", "simbench/api.py", "from simbench.errors import SimbenchError\n", False),
        ModuleSource("estimators", "estimators/__init__.py", "", True),
        ModuleSource("estimators.fake", "estimators/fake.py", "\nfrom simbench.errors import SimbenchError\n", False),
    ]


def test_a_parent_package_counts_by_what_its_init_loads() -> None:
    eager = facade_tree("from simbench.api import run\n")
    # the estimator names only simbench.errors (rule (a) per module sees nothing) ...
    assert layering_violations(eager[-1].text, "estimators.fake", "estimators/fake.py") == []
    # ... but importing it runs simbench/__init__, which loads the top layer
    assert package_init_violations(eager) == [
        "estimators/fake.py:2: importing simbench.errors runs simbench/__init__, which loads simbench.api from a "
        "higher layer or a sibling unit"
    ]
    assert package_init_violations(facade_tree("import lazy_loader\n")) == []  # a lazy facade loads nothing


def test_a_cycle_through_a_parent_package_is_found() -> None:
    tree = [
        ModuleSource("a", "a/__init__.py", "from c import f\n", True),
        ModuleSource("a.b", "a/b.py", "", False),
        ModuleSource("c", "c.py", "from a.b import g\n", False),
    ]
    assert import_graph(tree) == {"a": {"c"}, "a.b": set(), "c": {"a", "a.b"}}
    assert cycles(import_graph(tree)) == [["a", "c"]]  # c names only a.b, but importing it runs a/__init__


def test_scan_covers_the_whole_tree() -> None:
    # Guards against a scan that silently reads nothing (e.g. a wrong ROOT).
    files = [f for p in SCANNED_PACKAGES for f in (ROOT / p).rglob("*.py")]
    assert len(files) > 30
    assert (ROOT / "simbench" / "core" / "orbits.py") in files
    graph = import_graph()
    assert "simbench.core.constants" in graph["simbench.core.frames"]


def test_every_module_has_a_layer() -> None:
    missing = [name for p in SCANNED_PACKAGES for name, _, _ in module_files(p) if unit_of(name) is None]
    assert not missing, f"modules outside LAYERS: {missing}"


# --------------------------------------------------------------------------- the tree obeys


@pytest.mark.parametrize("package", SCANNED_PACKAGES)
def test_layering(package: str) -> None:
    found = scan(package)
    assert not found, "layering violations:\n" + "\n".join(found)


@pytest.mark.parametrize("folder", PRIVATE_NAME_SCANNED)
def test_no_private_names_borrowed(folder: str) -> None:
    found = scan(folder, layers=False)
    assert not found, "private names imported:\n" + "\n".join(found)


def test_no_import_cycles() -> None:
    found = cycles(import_graph())
    assert not found, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_parent_packages_load_only_lower_layers() -> None:
    found = package_init_violations()
    assert not found, "parent-package __init__ edges to higher layers:\n" + "\n".join(found)
