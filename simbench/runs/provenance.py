"""Provenance stored with every result file: config, git SHA, package versions."""

from __future__ import annotations

import platform
import subprocess
from datetime import datetime, timezone
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
