"""Run folders: one of its own for each run of the default name, and every earlier run's Hydra config kept.

The default ``results_dir`` is named by the second a run starts in (``results/run-20261129-061502``);
two runs started in one second would share it, their rows and ``.hydra`` mixed. A run into a folder
that already holds a run (a fixed ``results_dir``, resumed or extended) keeps the earlier run's
``.hydra`` config (and a sweep's ``multirun.yaml``) under a numbered name instead of overwriting it.
"""

from __future__ import annotations

import itertools
import re
from pathlib import Path

from simbench.errors import SimbenchError, warn

__all__ = ["unique_run_dir", "keep_earlier_configs"]


def unique_run_dir(path: Path) -> Path:
    """Create and return ``path``, or ``path-2``, ``path-3``, ... when it exists (the first free one).

    Creating the folder claims it: of two runs started at once, each gets its own.

    Parameters
    ----------
    path : Path
        The folder wanted, e.g. ``results/run-20261129-061502``.

    Raises
    ------
    SimbenchError
        When no folder can be created there, naming ``results_dir``.
    """
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        for n in itertools.count(1):
            candidate = path if n == 1 else path.with_name(f"{path.name}-{n}")
            try:
                candidate.mkdir()
            except FileExistsError:
                continue
            return candidate
    except OSError as exc:
        raise SimbenchError(
            "results_dir", f"cannot create a run folder at {path} ({exc.strerror})", "give results_dir=DIR"
        ) from None
    raise AssertionError("unreachable")  # pragma: no cover; itertools.count never ends


#: The Hydra files of one run or sweep: its ``.hydra`` folders (the run's, or each job's) and a sweep's list.
_NUMBERED = re.compile(r"(?:\.hydra|multirun)\.(\d+)(?:\.yaml)?$")


def keep_earlier_configs(run_dir: Path) -> int | None:
    """Rename an earlier run's Hydra config in ``run_dir`` before a new run writes its own.

    ``.hydra`` (a run's, or each ``job*/.hydra`` of a sweep) becomes ``.hydra.N`` and ``multirun.yaml``
    becomes ``multirun.N.yaml``, N one more than the highest number already kept, so the runs into
    one folder are numbered in order; one warning says so.

    Parameters
    ----------
    run_dir : Path
        The folder the run or sweep is about to write (``hydra.run.dir`` or ``hydra.sweep.dir``).

    Returns
    -------
    int or None
        N, or None when the folder held no earlier config.
    """
    jobs = sorted(run_dir.glob("job[0-9]*/"))  # a sweep's job folders (hydra.sweep.subdir)
    found = [p for p in (run_dir / ".hydra", run_dir / "multirun.yaml", *(j / ".hydra" for j in jobs)) if p.exists()]
    if not found:
        return None
    names = [p.name for folder in (run_dir, *jobs) for p in folder.iterdir()]
    kept = [int(m.group(1)) for name in names if (m := _NUMBERED.fullmatch(name))]
    n = max(kept, default=0) + 1
    for path in found:
        path.rename(path.with_name(f"multirun.{n}.yaml" if path.name == "multirun.yaml" else f".hydra.{n}"))
    warn(
        "results_dir",
        f"'{run_dir}' holds an earlier run's Hydra config",
        f"kept as .hydra.{n}" + (f" and multirun.{n}.yaml" if (run_dir / f"multirun.{n}.yaml").exists() else ""),
    )
    return n
