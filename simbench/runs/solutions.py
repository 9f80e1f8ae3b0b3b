"""Every ``ok`` result's positions as files other tools read: RTKLIB ``.pos`` (rtkplot, pos2kml,
``simbench score``) and TUM (evo), beside the truth in the same two formats.

Layout of ``RUN_DIR/solutions/``::

    <scenario>[_<receiver>]/<seed>/<estimator>.pos   RTKLIB .pos, GPST week/tow, lat/lon/height
    <scenario>[_<receiver>]/<seed>/<estimator>.tum   TUM: GPS seconds, local east/north/up
    <scenario>[_<receiver>]/<seed>/truth.pos, truth.tum   the reference trajectory alike

``<estimator>`` is the variant's display name (:func:`simbench.analysis.variants.display_names`:
``dcs``, ``dcs[prior_scale=10]``); the receiver preset is named for simulated data only; a
folder that would hold two scenarios (a sweep over ``scenario.duration_s``) ends in ``-<key>``,
the first 8 characters of the scenario key. The local frame of the TUM files is the east-north-up
frame at the scenario's first reference point (that of ``epochs.parquet``), so
``evo_ape tum truth.tum dcs.tum`` compares them as they are. ``ns`` is the number of satellites
observed at the epoch (estimators do not report how many they used); ``Q`` is 5 (single).

Written by every finalize (:func:`simbench.report.build.finalize`), each file atomically; files
of results no longer in the run are removed.
"""

from __future__ import annotations

import functools
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd

from estimators.base import COVARIANCE_COLUMNS, COVARIANCE_INDEX
from simbench.analysis.metrics import local_enu
from simbench.analysis.tables import data_source, with_variant_columns
from simbench.analysis.variants import display_names
from simbench.contract import read_parquet_metadata, write_bytes
from simbench.core.constants import SECONDS_PER_WEEK
from simbench.data.export.solution import rtklib_pos_text, tum_text
from simbench.runs.provenance import code_identity
from simbench.runs.store import run_folders
from simbench.source_registry import SIMULATED

__all__ = ["SOLUTIONS_DIR", "TRUTH_NAME", "write_solutions"]

#: Folder of the run's solution files.
SOLUTIONS_DIR = "solutions"
#: Stem of the reference trajectory's files in each scenario folder.
TRUTH_NAME = "truth"
#: What a file name keeps of a display name; other characters become '_' (no brackets: shells glob them).
UNSAFE = re.compile(r"[^A-Za-z0-9_.,=+-]")
KEYS = ["scenario_key", "estimator", "gnss_model", "overrides"]
#: The two files of a trajectory.
SUFFIXES = (".pos", ".tum")
#: What each solution file was written from (``<folder>/<name>`` -> digest of the writer's code, the scenario
#: key and the result's rows), so a finalize rewrites only what changed.
DIGESTS = ".digests.json"
#: The columns of a result a file is written from.
HASHED = ["epoch", "t", "x", "y", "z", *COVARIANCE_COLUMNS]


def file_name(name: str) -> str:
    """A display name as a file stem: ``dcs[prior_scale=10]`` is ``dcs__prior_scale=10``."""
    return UNSAFE.sub("_", name.replace("[", "__").replace("]", ""))


def _cache_dir(run_dir: Path, key: str) -> Path | None:
    found = (folder / "cache" / key for folder in run_folders(run_dir))
    return next((p for p in found if (p / "observations.parquet").is_file()), None)


def _folders(summary: pd.DataFrame) -> dict[str, str]:
    """scenario_key -> ``<scenario>[_<receiver>]/<seed>`` (module docstring), unique per key."""
    rows = summary.drop_duplicates("scenario_key")
    names = {}
    for row in rows.itertuples(index=False):
        receiver = str(row.receiver) if isinstance(row.receiver, str) and row.receiver else ""
        simulated = data_source(row.source) == SIMULATED
        label = str(row.scenario) + (f"_{receiver}" if receiver and simulated else "")
        names[str(row.scenario_key)] = (UNSAFE.sub("_", label), str(row.seed))
    counts = pd.Series([v for v in names.values()]).value_counts()
    return {
        key: f"{label}-{key[:8]}/{seed}" if counts[(label, seed)] > 1 else f"{label}/{seed}"
        for key, (label, seed) in names.items()
    }


def _scenario_files(cache: Path) -> tuple[float, pd.Series, pd.DataFrame]:
    """GPS time of the scenario start [s], satellites observed per epoch, and the truth ``t, x, y, z``."""
    nav = read_parquet_metadata(cache / "observations.parquet")["simbench.scenario"]["nav"]
    start = int(nav["gps_week"]) * SECONDS_PER_WEEK + float(nav["start_sow_s"])
    obs = pd.read_parquet(cache / "observations.parquet", columns=["epoch", "sat"])
    truth = pd.read_parquet(cache / "truth.parquet", columns=["t", "x", "y", "z"]).dropna()
    return start, obs.groupby("epoch")["sat"].nunique(), truth


def write_solutions(run_dir: str | Path, summary: pd.DataFrame, epochs: pd.DataFrame) -> list[Path]:
    """Write the ``.pos`` and TUM file of every ``ok`` result and of each scenario's truth (module docstring).

    A file whose result, name and writer are those of the previous finalize (:data:`DIGESTS`) is kept:
    formatting is about 10 us a row, and a thesis run has millions.

    Parameters
    ----------
    run_dir : str or Path
        The run folder; its cached scenarios give the GPS time, satellites and truth.
    summary : pandas.DataFrame
        The run's ``summary.parquet`` rows.
    epochs : pandas.DataFrame
        Its ``epochs.parquet`` rows (those of ``ok`` results are written).

    Returns
    -------
    list of Path
        The run's solution files (written now, or kept).
    """
    run_dir = Path(run_dir)
    root = run_dir / SOLUTIONS_DIR
    named = with_variant_columns(summary)
    named = named.assign(name=display_names(named).map(file_name))  # the report's names: over every row
    ok = named[named["status"] == "ok"].drop_duplicates(KEYS)
    rows = with_variant_columns(epochs)
    # one pass over the epoch table (millions of rows in a thesis run), not one selection per result
    solutions = {tuple(map(str, k)): g for k, g in rows.groupby(KEYS, sort=False, observed=True)}
    try:
        before = json.loads((root / DIGESTS).read_text())
    except (OSError, ValueError):
        before = {}
    code = code_identity(__name__)  # an edited writer rewrites every file
    digests: dict[str, str] = {}
    for key, folder in _folders(ok).items():
        cache = _cache_dir(run_dir, key)
        if cache is None:  # a result without its scenario (the store warned): nothing to time it by
            continue
        scenario = functools.cache(lambda cache=cache: _scenario_files(cache))  # read only to write
        stem = f"{folder}/{TRUTH_NAME}"
        digests[stem] = f"{code}-{key}"
        if before.get(stem) != digests[stem] or not _written(root / stem):
            _write_truth(root / stem, key, *scenario())
        for result in ok[ok["scenario_key"] == key].itertuples(index=False):
            sol = solutions.get((key, *(str(getattr(result, c)) for c in KEYS[1:])))
            if sol is None:
                continue
            stem = f"{folder}/{result.name}"
            content = pd.util.hash_pandas_object(sol[[c for c in HASHED if c in sol]], index=False)
            digests[stem] = f"{code}-{key}-{int(content.sum()) & (2**64 - 1):016x}"
            if before.get(stem) != digests[stem] or not _written(root / stem):
                _write_result(root / stem, key, sol, *scenario())
    kept = {root / f"{stem}{suffix}" for stem in digests for suffix in SUFFIXES}
    for stale in {*root.glob("*/*/*.pos"), *root.glob("*/*/*.tum")} - kept:
        stale.unlink(missing_ok=True)
    write_bytes(root / DIGESTS, json.dumps(digests, sort_keys=True).encode())
    return sorted(kept)


def _written(stem: Path) -> bool:
    return all(stem.with_name(stem.name + suffix).is_file() for suffix in SUFFIXES)


def _write_truth(stem: Path, key: str, start: float, satellites: pd.Series, truth: pd.DataFrame) -> None:
    xyz = truth[["x", "y", "z"]].to_numpy(float)
    comments = [f"simbench {TRUTH_NAME} of scenario {stem.parent.relative_to(stem.parents[2])} (key {key})"]
    _write(stem, start + truth["t"].to_numpy(float), xyz, None, None, xyz[0], comments)


def _write_result(
    stem: Path, key: str, sol: pd.DataFrame, start: float, satellites: pd.Series, truth: pd.DataFrame
) -> None:
    covariance = np.full((len(sol), 3, 3), np.nan)
    if set(COVARIANCE_COLUMNS) <= set(sol.columns):
        for column, (i, j) in COVARIANCE_INDEX.items():
            covariance[:, i, j] = covariance[:, j, i] = sol[column].to_numpy(float)
    ns = satellites.reindex(sol["epoch"].to_numpy()).fillna(0).to_numpy(np.int64)
    comments = [f"simbench {stem.name} on scenario {stem.parent.relative_to(stem.parents[2])} (key {key})"]
    origin = truth[["x", "y", "z"]].to_numpy(float)[0]
    t_gps = start + sol["t"].to_numpy(float)
    _write(stem, t_gps, sol[["x", "y", "z"]].to_numpy(float), ns, covariance, origin, comments)


def _write(
    stem: Path,
    t_gps: np.ndarray,
    xyz: np.ndarray,
    ns: np.ndarray | None,
    covariance: np.ndarray | None,
    origin: np.ndarray,
    comments: list[str],
) -> None:
    """``stem.pos`` and ``stem.tum`` of one trajectory."""
    pos, tum = (stem.with_name(stem.name + suffix) for suffix in SUFFIXES)
    ns = np.zeros(len(xyz), np.int64) if ns is None else ns
    write_bytes(pos, rtklib_pos_text(t_gps, xyz, ns, covariance, comments).encode())
    frame = f"x y z: east, north, up [m] of the local frame at ECEF {' '.join(f'{c:.4f}' for c in origin)}"
    tum_comments = [*comments, "timestamp: GPS seconds since 1980-01-06 [s]", frame, "orientation unknown: identity"]
    write_bytes(tum, tum_text(t_gps, local_enu(xyz, origin), tum_comments).encode())
