"""The results store of a run directory.

Layout of ``RUN_DIR``::

    cache/<scenario_key>/            the generated scenario (Scenario.save), shared by all jobs
    jobs/<scenario_key>/<result_key>.summary.parquet   one estimator on one scenario: 1 row
    jobs/<scenario_key>/<result_key>.epochs.parquet    its per-epoch errors
    jobs/<scenario_key>/<result_key>.diagnostics.json  its diagnostics (report material)
    summary.parquet, epochs.parquet  the aggregate of every job file (rebuilt at any time)
    claims.csv, report/               built from the aggregate

Keys are hashes of resolved configs, so a rerun into the same directory finds
finished results and skips them, and every job that needs a scenario reads
the same cached tables. Every file is written under a temporary name and
renamed, so a killed run leaves no half-written file behind.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow.parquet as pq

from simbench.contract import Scenario, json_default, read_parquet_metadata, write_parquet
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS


def config_key(config: Any) -> str:
    """Stable 16-hex-digit hash of a JSON-serialisable config (key order does not matter)."""
    text = json.dumps(config, sort_keys=True, default=json_default, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def result_stem(run_dir: Path, scenario_key: str, estimator: str, estimator_config: Any) -> Path:
    """Path stem of one estimator's results on one scenario.

    ``estimator_config`` is the estimator's full composed config (every field,
    choices as their YAML words), so a rerun of the same settings finds its
    result whether a value came from the dataclass default, YAML or the command line.
    """
    return Path(run_dir) / "jobs" / scenario_key / f"{estimator}-{config_key(estimator_config)}"


def is_finished(stem: Path) -> bool:
    """A result is finished once its summary row (written last) exists with status ``ok``.

    Failed and diverged results are retried by a rerun: the failure may have
    been fixed in the meantime, and a deterministic failure costs little. So is
    a result written before a column joined :data:`SUMMARY_COLUMNS` (e.g.
    ``overrides``): the aggregate must have every column in every row.
    """
    path = stem.with_suffix(".summary.parquet")
    if not path.is_file() or set(SUMMARY_COLUMNS) - set(pq.read_schema(path).names):
        return False
    return bool((pd.read_parquet(path, columns=["status"])["status"] == "ok").all())


def write_result(
    stem: Path, summary: pd.DataFrame, epochs: pd.DataFrame, diagnostics: dict[str, Any], metadata: dict[str, Any]
) -> None:
    """Write one estimator's result files; the summary row last, as the completion marker."""
    write_parquet(epochs, stem.with_suffix(".epochs.parquet"), metadata)
    write_json(stem.with_suffix(".diagnostics.json"), diagnostics)
    write_parquet(summary, stem.with_suffix(".summary.parquet"), metadata)


def write_json(path: Path, obj: Any) -> None:
    """Atomic JSON write."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(json.dumps(obj, default=json_default))
    tmp.replace(path)


def cached_scenario(run_dir: Path, key: str, build: Any) -> Scenario:
    """Load the scenario ``key`` from the run's cache, or ``build()`` it and cache it.

    Concurrent jobs may both build a missing scenario; each writes into its own
    temporary directory and the first rename wins, so readers always see one
    complete, identical copy (generation is deterministic).
    """
    target = Path(run_dir) / "cache" / key
    if (target / "observations.parquet").is_file():
        return Scenario.load(target)
    scenario = build()
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{key}.", dir=target.parent))
    scenario.save(tmp)
    try:
        tmp.rename(target)
    except OSError:  # another job won the race; its copy is identical
        shutil.rmtree(tmp, ignore_errors=True)
    return scenario


def aggregate(run_dir: Path, metadata: dict[str, Any]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Concatenate every job file below ``run_dir`` into the run's summary and epoch tables.

    Written to ``run_dir/summary.parquet`` and ``run_dir/epochs.parquet``.
    """
    run_dir = Path(run_dir)
    summaries = sorted(run_dir.glob("**/jobs/*/*.summary.parquet"))
    summary = (
        pd.concat([pd.read_parquet(p) for p in summaries], ignore_index=True)
        if summaries
        else pd.DataFrame(columns=list(SUMMARY_COLUMNS))
    )
    frames = [pd.read_parquet(p) for p in sorted(run_dir.glob("**/jobs/*/*.epochs.parquet"))]
    frames = [f for f in frames if len(f)]
    epochs = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=list(EPOCH_COLUMNS))
    write_parquet(summary, run_dir / "summary.parquet", metadata)
    write_parquet(epochs, run_dir / "epochs.parquet", metadata)
    return summary, epochs


def diagnostics(run_dir: Path) -> dict[str, list[dict[str, Any]]]:
    """All diagnostics of a run, grouped by estimator name, each with its job's summary key."""
    out: dict[str, list[dict[str, Any]]] = {}
    for path in sorted(Path(run_dir).glob("**/jobs/*/*.diagnostics.json")):
        estimator = path.name.split("-")[0]
        summary = path.with_name(path.name.replace(".diagnostics.json", ".summary.parquet"))
        row = pd.read_parquet(summary).iloc[0].to_dict() if summary.is_file() else {}
        out.setdefault(estimator, []).append({"job": row, "diagnostics": json.loads(path.read_text())})
    return out


def provenance_of(path: Path) -> dict[str, Any]:
    """The provenance metadata of a result file."""
    return read_parquet_metadata(path)
