"""Provenance stored with every result file: config, git SHA, package versions, code identity.

The code identity of a module (:func:`code_identity`) is a hash of its source
and of every module it imports, transitively, from the packages that make up
the code path of a result (``simbench``, ``estimators`` and the module's own
top-level package, e.g. a plug-in's). Result and cache keys include it, so an
edited estimator or scenario source is recomputed, and an untouched one is not.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import platform
import subprocess
from datetime import datetime, timezone
from functools import cache
from importlib import metadata
from pathlib import Path
from typing import Any

PACKAGES = (
    "simbench",
    "numpy",
    "scipy",
    "pandas",
    "pyarrow",
    "gtsam",
    "filterpy",
    "scikit-learn",
    "hydra-core",
    "omegaconf",
    "pymap3d",
    "georinex",
    "matplotlib",
)


#: Top-level packages whose modules are part of every code identity (besides the module's own package).
CODE_PACKAGES = ("simbench", "estimators")


def code_identity(module: str) -> str:
    """16-hex-digit hash of ``module``'s source and of the sources it imports, transitively,
    from :data:`CODE_PACKAGES` and its own top-level package.

    Third-party imports are left out (their versions are in :func:`versions`). Each
    file is read and parsed once per process while its size and modification time
    stay the same, so a key costs a few stat calls.

    Parameters
    ----------
    module : str
        A dotted module name, e.g. ``type(estimator).__module__``.

    Returns
    -------
    str
        The hash.
    """
    roots = (*CODE_PACKAGES, module.split(".")[0])
    seen: dict[str, str] = {}
    todo = [module]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        path = module_file(name)
        try:
            stat = path.stat() if path is not None else None
        except OSError:  # a module file removed since it was found
            stat = None
        if path is None or stat is None:  # a class or function of ``from a import b``, or a module that is gone
            continue
        digest, imports = file_facts(path, name, stat.st_size, stat.st_mtime_ns)
        seen[name] = digest
        todo.extend(m for m in imports if m.split(".")[0] in roots and m not in seen)
    text = "\n".join(f"{name} {digest}" for name, digest in sorted(seen.items()))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@cache
def module_file(name: str) -> Path | None:
    """The source (or extension) file of module ``name``; None for a name that is no module."""
    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, ValueError):  # a parent that is no package (``a.b`` of ``from a import b``)
        return None
    origin = spec.origin if spec is not None else None
    return Path(origin) if origin and Path(origin).is_file() else None


@cache
def file_facts(path: Path, name: str, size: int, mtime_ns: int) -> tuple[str, tuple[str, ...]]:
    """sha256 of the module file ``path`` (module ``name``) and the absolute names its imports give.

    ``size`` and ``mtime_ns`` are part of the cache key only: an edited file is read again.
    ``from a import b`` gives both ``a`` and ``a.b`` (:func:`code_identity` keeps the modules).
    """
    data = path.read_bytes()
    digest = hashlib.sha256(data).hexdigest()
    if path.suffix != ".py":
        return digest, ()
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    imports: list[str] = []
    for node in ast.walk(ast.parse(data, filename=str(path))):
        if isinstance(node, ast.Import):
            imports.extend(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            # a relative import counts its dots from the module's package
            parent = package[: len(package) - node.level + 1] if node.level else []
            base = ".".join([*parent, *([node.module] if node.module else [])])
            imports.extend([base, *(f"{base}.{alias.name}" for alias in node.names)])
    return digest, tuple(imports)


def git_sha(repo: Path | None = None) -> str:
    """SHA of HEAD (with ``-dirty`` if the tree has changes), or ``unknown`` outside git."""
    repo = repo or Path(__file__).resolve().parents[2]
    try:
        sha = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=repo, capture_output=True, text=True, check=True, timeout=10
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=repo,
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
        return sha + ("-dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def provenance(config: dict[str, Any]) -> dict[str, Any]:
    """The metadata dict written into result Parquet files."""
    return {
        "simbench.config": config,
        "simbench.git_sha": git_sha(),
        "simbench.versions": versions(),
        "simbench.created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
