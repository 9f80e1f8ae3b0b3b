"""Layering rules, checked on the source: sim/data/gnss never import estimators, nobody borrows private names.

An AST scan of every module under ``simbench/`` and ``estimators/``:

(a) a module in ``simbench/sim/``, ``simbench/data/`` or ``simbench/gnss/``
    imports ``estimators`` (at the top or inside a function, also through
    ``importlib.import_module``);
(b) a module imports an underscore name from another module
    (``from x import _y``) or reads ``m._y`` where ``m`` is an imported module.

Dunder names (``__version__``, ``__file__``) are public. Attributes of
objects (``self._cache``) are not module attributes and are not checked.
"""
from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCANNED_PACKAGES = ("simbench", "estimators")
#: Packages that sit below the estimators and must not depend on them.
LOWER_LAYERS = ("simbench.sim", "simbench.data", "simbench.gnss")


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


def layering_violations(source: str, module: str, path: str, is_package: bool = False) -> list[str]:
    """Every breach of rules (a) and (b) in one module's source, as ``path:line: message``.

    Parameters
    ----------
    source : str
        Python source text.
    module : str
        Its dotted module name (``simbench.sim.orbits``); decides whether rule (a) applies.
    path : str
        Shown in the messages.
    is_package : bool
        The source is a package ``__init__`` (resolves relative imports).
    """
    tree = ast.parse(source, filename=path)
    lower = in_package(module, LOWER_LAYERS)
    found: list[str] = []
    module_names: set[str] = set()  # local names bound to module objects
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if lower and in_package(alias.name, ("estimators",)):
                    found.append(f"{path}:{node.lineno}: imports {alias.name}")
                module_names.add(alias.asname or alias.name.split(".")[0])
        elif isinstance(node, ast.ImportFrom):
            target = absolute_target(node, module, is_package)
            if lower and in_package(target, ("estimators",)):
                found.append(f"{path}:{node.lineno}: imports from {target}")
            for alias in node.names:
                if is_private(alias.name):
                    found.append(f"{path}:{node.lineno}: imports private name {alias.name} from {target}")
                elif alias.name != "*" and is_module(f"{target}.{alias.name}"):
                    module_names.add(alias.asname or alias.name)
        elif isinstance(node, ast.Call) and lower and dotted_name(node.func) in ("importlib.import_module",
                                                                                 "import_module", "__import__"):
            arg = node.args[0] if node.args else None
            if isinstance(arg, ast.Constant) and isinstance(arg.value, str) and in_package(arg.value,
                                                                                           ("estimators",)):
                found.append(f"{path}:{node.lineno}: imports {arg.value} dynamically")
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and is_private(node.attr):
            owner = dotted_name(node.value)
            if owner is not None and owner.split(".")[0] in module_names:
                found.append(f"{path}:{node.lineno}: reads private name {node.attr} of module {owner}")
    return sorted(set(found), key=lambda s: (s.split(":")[0], int(s.split(":")[1]), s))


def scan(package: str) -> list[str]:
    """Violations in every module of one top-level package of the repository."""
    found = []
    for file in sorted((ROOT / package).rglob("*.py")):
        rel = file.relative_to(ROOT)
        is_package = file.name == "__init__.py"
        parts = rel.parent.parts if is_package else rel.with_suffix("").parts
        found += layering_violations(file.read_text(), ".".join(parts), str(rel), is_package)
    return found


# --------------------------------------------------------------------------- the checker can fail

SYNTHETIC = """\
import estimators
import numpy as np
import simbench.sim.orbits as orbits_mod
from simbench.sim import orbits
from simbench.sim.orbits import _fmt_gps, FIT_HALF_WINDOW_S
from simbench import __version__
from ._private_sibling import thing
from . import _helper


def f(self):
    from estimators.measurement import troposphere_terms
    import importlib
    importlib.import_module("estimators.bce")
    x = orbits._CHUNK_EPOCHS + orbits_mod._CHUNK_EPOCHS
    y = self._cache + np.pi + orbits.__name__ + orbits.FIT_HALF_WINDOW_S
    return x, y
"""


def test_checker_finds_every_kind_of_violation() -> None:
    found = layering_violations(SYNTHETIC, "simbench.sim.fake", "fake.py")
    assert found == [
        "fake.py:1: imports estimators",
        "fake.py:5: imports private name _fmt_gps from simbench.sim.orbits",
        "fake.py:8: imports private name _helper from simbench.sim",
        "fake.py:12: imports from estimators.measurement",
        "fake.py:14: imports estimators.bce dynamically",
        "fake.py:15: reads private name _CHUNK_EPOCHS of module orbits",
        "fake.py:15: reads private name _CHUNK_EPOCHS of module orbits_mod",
    ]


def test_estimators_may_import_estimators() -> None:
    found = layering_violations(SYNTHETIC, "estimators.fake", "fake.py")
    assert found == [
        "fake.py:5: imports private name _fmt_gps from simbench.sim.orbits",
        "fake.py:8: imports private name _helper from estimators",
        "fake.py:15: reads private name _CHUNK_EPOCHS of module orbits",
        "fake.py:15: reads private name _CHUNK_EPOCHS of module orbits_mod",
    ]


def test_relative_imports_resolve_against_the_package() -> None:
    src = "from .orbits import _fmt_gps\nfrom ..errors import SimbenchError\n"
    assert layering_violations(src, "simbench.data.rinex", "r.py") == [
        "r.py:1: imports private name _fmt_gps from simbench.data.orbits"
    ]
    assert layering_violations(src, "simbench.data", "i.py", is_package=True) == [
        "i.py:1: imports private name _fmt_gps from simbench.data.orbits"
    ]


def test_scan_covers_the_whole_tree() -> None:
    # Guards against a scan that silently reads nothing (e.g. a wrong ROOT).
    files = [f for p in SCANNED_PACKAGES for f in (ROOT / p).rglob("*.py")]
    assert len(files) > 30
    assert (ROOT / "simbench" / "sim" / "orbits.py") in files


# --------------------------------------------------------------------------- the tree obeys

@pytest.mark.parametrize("package", SCANNED_PACKAGES)
def test_layering(package: str) -> None:
    found = scan(package)
    assert not found, "layering violations:\n" + "\n".join(found)
