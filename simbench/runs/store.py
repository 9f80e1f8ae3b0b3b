"""The results store of a run directory.

Layout of ``RUN_DIR``::

    cache/<scenario_key>/            the generated scenario (Scenario.save), shared by all jobs
    cache/<scenario_key>/manifest.json   sha256 of each of its tables, checked before every load
    jobs/<scenario_key>/<estimator>-<config hash>-<code hash>.summary.parquet   one estimator on one scenario:
                                     1 row; its footer records the sha256 of the two files below
    jobs/<scenario_key>/<...>.epochs.parquet       its per-epoch errors
    jobs/<scenario_key>/<...>.diagnostics.json     its diagnostics (report material)
    summary.parquet, epochs.parquet  the aggregate of the run's job files (rebuilt by every finalize)
    claims.csv, report/               built from the aggregate

Keys hash the resolved config and the code identity of what computes it
(:func:`simbench.runs.provenance.code_identity`): the scenario source's for a
cache key, the estimator's for a result. A rerun into the same directory finds
finished results of unchanged code and skips them; an edited estimator is
recomputed, and its new result replaces the one of the old code. Every job
that needs a scenario reads the same cached tables.

The store checks itself on read: Parquet pages carry CRC checksums (verified),
a summary row names the checksums of its epochs and diagnostics, a cached
scenario those of its tables. A missing or damaged file is named in a one-line
warning (:func:`simbench.errors.warn`) and recomputed by the next run (the
report leaves its job out). Every file is written under a temporary name of
its own and renamed, so a killed run leaves no half-written file behind and
concurrent writers never collide.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, TypeVar

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from simbench.contract import (
    MANIFEST,
    MANIFEST_KEY,
    METADATA_SHA256,
    Scenario,
    config_key,
    decode_metadata,
    file_sha256,
    json_default,
    metadata_sha256,
    read_parquet_metadata,
    temporary_name,
    write_bytes,
    write_parquet,
)
from simbench.errors import SimbenchError, one_line, warn
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS
from simbench.runs.studies import study_dirs

#: The files of a job besides its summary, whose sha256 the summary's footer records (``simbench.files``).
JOB_FILES = (".epochs.parquet", ".diagnostics.json")
#: What a report does with a damaged job file.
LEFT_OUT = "left out of the aggregate; rerun the run to recompute it"


def result_stem(run_dir: Path, scenario_key: str, estimator: str, estimator_config: Any, code: str = "") -> Path:
    """Path stem of one estimator's results on one scenario.

    ``estimator_config`` is the estimator's full composed config (every field,
    choices as their YAML words), so a rerun of the same settings finds its
    result whether a value came from the dataclass default, YAML or the command line.
    ``code`` is the estimator's code identity (:func:`~simbench.runs.provenance.code_identity`);
    ``''`` for rows no estimator of this code base computed (a scored solution file).
    """
    name = f"{estimator}-{config_key(estimator_config)}" + (f"-{code}" if code else "")
    return Path(run_dir) / "jobs" / scenario_key / name


def _verified_table(path: Path, consequence: str) -> pa.Table | None:
    """A stored Parquet file, opened once, with its page checksums and metadata checksum verified; None,
    with a one-line warning naming ``path`` and ``consequence``, when it is missing or damaged."""
    table, problem = _checked_table(path)
    if problem:
        warn(str(path), problem, consequence)
    return table


def _checked_table(path: Path) -> tuple[pa.Table | None, str]:
    """A stored Parquet file with its checksums verified, and ``''``; or None and what is wrong with it."""
    try:
        file = pq.ParquetFile(path, page_checksum_verification=True)
        # the footer's own key-value metadata (pyarrow adds the serialized Arrow schema after the checksum),
        # which must also be what that Arrow schema carries
        kv = {k: v for k, v in (file.metadata.metadata or {}).items() if k != b"ARROW:schema"}
        table = file.read()
        recorded = kv.get(METADATA_SHA256.encode())
        # a file of another writer (no checksum) is taken as it reads
        if recorded is not None and (json.loads(recorded) != metadata_sha256(kv) or table.schema.metadata != kv):
            return None, "has metadata that differs from its sha256 (damaged)"
        return table, ""
    except FileNotFoundError:
        return None, "is missing"
    except Exception as exc:  # pyarrow raises several types (ArrowInvalid, OSError) for a damaged file
        return None, f"cannot be read ({one_line(exc)})"


def load_table(path: Path, fix: str, columns: Sequence[str] = ()) -> tuple[pd.DataFrame, dict[str, Any]]:
    """A stored Parquet file of a run folder (``summary.parquet``) with its checksums verified, and its
    ``simbench.*`` metadata: what a subcommand reads, which has no job to leave out instead.

    Raises
    ------
    SimbenchError
        Naming ``path`` and ``fix`` when it is missing, damaged or lacks one of ``columns``.
    """
    table, problem = _checked_table(Path(path))
    if table is None:
        raise SimbenchError(str(path), problem, fix)
    missing = [c for c in columns if c not in table.column_names]
    if missing:
        raise SimbenchError(str(path), f"has no column {', '.join(missing)} (damaged or not this file)", fix)
    return table.to_pandas(), decode_metadata(table.schema.metadata)


def read_table(path: Path, consequence: str) -> pd.DataFrame | None:
    """A stored Parquet file with its page checksums and metadata checksum verified; None, with a
    one-line warning naming ``path`` and ``consequence``, when it is missing or damaged."""
    table = _verified_table(path, consequence)
    return None if table is None else table.to_pandas()


def read_job(stem: Path, consequence: str) -> pd.DataFrame | None:
    """The summary rows of a stored job whose files are all intact.

    None when the job has no summary (never run, or killed before its summary,
    which is written last), silently; and when its summary cannot be read or
    another of its files is missing or differs from the checksum the summary
    recorded, with a one-line warning naming that file and ``consequence``.
    """
    path = stem.with_suffix(".summary.parquet")
    if not path.is_file():
        if any(stem.with_suffix(suffix).is_file() for suffix in JOB_FILES):
            warn(str(path), "is missing beside its job's other files (a killed or damaged job)", consequence)
        return None
    table = _verified_table(path, consequence)
    if table is None:
        return None
    # a summary written before checksums were recorded names none; its files must still be there
    recorded = decode_metadata(table.schema.metadata).get("simbench.files", {})
    for suffix in JOB_FILES:
        other = stem.with_suffix(suffix)
        if not other.is_file():
            warn(str(other), "is missing", consequence)
            return None
        if suffix in recorded and file_sha256(other) != recorded[suffix]:
            warn(str(other), "differs from the sha256 its summary recorded (damaged or overwritten)", consequence)
            return None
    return table.to_pandas()


def is_finished(stem: Path) -> bool:
    """A result is finished once its files are intact (:func:`read_job`) and its summary row has status ``ok``.

    Failed and diverged results are retried by a rerun: the failure may have
    been fixed in the meantime, and a deterministic failure costs little. So is
    a result written before a column joined :data:`SUMMARY_COLUMNS` (e.g.
    ``overrides``): the aggregate must have every column in every row. A damaged
    result is recomputed after a warning naming the file.
    """
    return _finished_summary(stem, "recomputing the result") is not None


def _finished_summary(stem: Path, consequence: str) -> pd.DataFrame | None:
    """The summary of a finished result (:func:`is_finished`), else None."""
    summary = read_job(stem, consequence)
    if summary is None or set(SUMMARY_COLUMNS) - set(summary.columns) or not (summary["status"] == "ok").all():
        return None
    return summary


def write_result(
    stem: Path, summary: pd.DataFrame, epochs: pd.DataFrame, diagnostics: dict[str, Any], metadata: dict[str, Any]
) -> None:
    """Write one estimator's result files; the summary row last, as the completion marker.

    The summary's footer records the sha256 of the other two files. Results of the
    same estimator and config computed by other code (another code hash in the
    stem) are removed: this result supersedes them.
    """
    write_parquet(epochs, stem.with_suffix(".epochs.parquet"), metadata)
    write_json(stem.with_suffix(".diagnostics.json"), diagnostics)
    files = {suffix: file_sha256(stem.with_suffix(suffix)) for suffix in JOB_FILES}
    write_parquet(summary, stem.with_suffix(".summary.parquet"), {**metadata, "simbench.files": files})
    coded = re.fullmatch(r"(.+-[0-9a-f]{16})-[0-9a-f]{16}", stem.name)
    if coded:
        for old in stem.parent.glob(f"{coded.group(1)}-*.summary.parquet"):
            old_stem = old.with_name(old.name.removesuffix(".summary.parquet"))
            if old_stem != stem:
                for suffix in (*JOB_FILES, ".summary.parquet"):  # the summary last, as it was written
                    old_stem.with_suffix(suffix).unlink(missing_ok=True)


def adopt_result(stem: Path, found: Path, tags: Mapping[str, Any]) -> bool:
    """Copy another run's finished result of the same scenario, estimator, config and code to ``stem``.

    The studies of one world (``+sweep=thesis``) share rows: ``ch5_sensitivity`` at
    scale 1 is ``ch5_bce``'s run, and the studies' L2, DCS and MM runs on the same
    scenario are identical. The copy is written like a computed result (checksums,
    summary last) with this run's ``tags`` (e.g. its sweep name) and the found
    result's provenance plus ``simbench.adopted_from``.

    Parameters
    ----------
    stem : Path
        This run's stem of the result (:func:`result_stem`).
    found : Path
        The other run's stem of the same result.
    tags : mapping of str to Any
        Columns set on every summary and epoch row of the copy.

    Returns
    -------
    bool
        False, writing nothing, when ``found`` is not a finished result (:func:`is_finished`).
    """
    instead = "computing the result instead"
    summary = _finished_summary(found, instead)
    epochs = None if summary is None else read_table(found.with_suffix(".epochs.parquet"), instead)
    if summary is None or epochs is None:
        return False
    diagnostics = json.loads(found.with_suffix(".diagnostics.json").read_text())
    metadata = {k: v for k, v in provenance_of(found.with_suffix(".summary.parquet")).items() if k != "simbench.files"}
    metadata["simbench.adopted_from"] = str(found)
    write_result(stem, summary.assign(**tags), epochs.assign(**tags), diagnostics, metadata)
    return True


def adopt_cache(run_dir: Path, key: str, others: Sequence[Path]) -> bool:
    """Give ``run_dir`` the intact cached scenario ``key`` of one of ``others`` (hard links where possible).

    Returns
    -------
    bool
        True when ``run_dir`` holds the scenario afterwards (already, or adopted).
    """
    target = Path(run_dir) / "cache" / key
    if target.is_dir():
        return True
    for other in others:
        source = Path(other) / "cache" / key
        if not source.is_dir() or cache_problem(source):
            continue
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = temporary_name(target)
        try:
            shutil.copytree(source, tmp, copy_function=_link_or_copy)
            tmp.rename(target)
        except OSError:  # another job adopted or built it first; its copy is identical
            shutil.rmtree(tmp, ignore_errors=True)
        return target.is_dir()
    return False


def _link_or_copy(src: str, dst: str) -> None:
    """A hard link (cached tables are never written in place), or a copy across file systems."""
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def write_json(path: Path, obj: Any) -> None:
    """Atomic JSON write under a temporary name of its own."""
    write_bytes(path, json.dumps(obj, default=json_default).encode())


def cache_problem(directory: Path) -> str:
    """Why the cached scenario in ``directory`` cannot be trusted: ``''`` when its tables match its
    manifest, else the damaged file and what is wrong with it."""
    manifest = directory / MANIFEST
    try:
        recorded = json.loads(manifest.read_text())
    except (OSError, ValueError) as exc:
        return f"{manifest}: cannot be read ({one_line(exc)})"
    if not isinstance(recorded, dict) or "observations.parquet" not in recorded:
        return f"{manifest}: names no observations.parquet"
    saved_as = recorded.pop(MANIFEST_KEY, directory.name)
    if saved_as != directory.name:
        return f"{manifest}: holds scenario {saved_as}, not {directory.name} (a cache folder moved or swapped)"
    for name, digest in recorded.items():
        path = directory / name
        if not path.is_file():
            return f"{path}: is missing"
        if file_sha256(path) != digest:
            return f"{path}: differs from the sha256 in {MANIFEST} (damaged or overwritten)"
    return ""


def cache_damaged(run_dir: Path, key: str) -> bool:
    """True when the run holds the cached scenario ``key`` and it is damaged (:func:`cache_problem`)."""
    target = Path(run_dir) / "cache" / key
    return target.is_dir() and bool(cache_problem(target))


def cached_scenario(run_dir: Path, key: str, build: Callable[[], Scenario]) -> Scenario:
    """Load the scenario ``key`` from the run's cache, or ``build()`` it and cache it.

    A cached scenario is loaded only when its tables match its manifest; a damaged
    one is rebuilt after a one-line warning naming the file. Concurrent jobs may
    both build a missing scenario; each writes into its own temporary directory
    and the first rename wins, so readers always see one complete, identical
    copy (generation is deterministic).
    """
    target = Path(run_dir) / "cache" / key
    if target.is_dir():
        problem = cache_problem(target)
        if not problem:
            return Scenario.load(target)
        field, _, what = problem.partition(": ")
        warn(field, what, "rebuilding the cached scenario")
    scenario = build()
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_name(target)  # not tempfile.mkdtemp: the cache folder gets the run's usual permissions
    scenario.save(tmp, key=key)
    if target.is_dir() and cache_problem(target):  # still damaged (no other job rebuilt it): set it aside
        trash = temporary_name(target)
        try:
            target.rename(trash)
        except OSError:  # another job moved it first
            pass
        shutil.rmtree(trash, ignore_errors=True)
    try:
        tmp.rename(target)
    except OSError:  # another job won the race; its copy is identical
        shutil.rmtree(tmp, ignore_errors=True)
    return scenario


def run_folders(run_dir: Path) -> list[Path]:
    """The folders whose ``jobs/`` and ``cache/`` make up the run ``run_dir``: itself, and for a study
    collection (``+sweep=thesis``) each study's results_dir (:func:`~simbench.runs.studies.study_dirs`).

    Other folders below ``run_dir`` (earlier runs kept inside it) are no part of it.
    """
    run_dir = Path(run_dir)
    return list(dict.fromkeys([run_dir, *study_dirs(run_dir)]))


def job_stems(run_dir: Path) -> list[Path]:
    """The stems of every job of the run ``run_dir`` (:func:`run_folders`) that wrote its summary."""
    return [
        p.with_name(p.name.removesuffix(".summary.parquet"))
        for folder in run_folders(run_dir)
        for p in sorted(folder.glob("jobs/*/*.summary.parquet"))
    ]


#: Threads that read and verify job files: reading and hashing release the GIL for part of each file, so
#: two threads take about 25 % less wall time on a 5-world thesis store (579 jobs) than one.
READ_THREADS = 2

T = TypeVar("T")


def _read_each(read: Callable[[Path], T], stems: Sequence[Path]) -> list[T]:
    """``read`` of every stem, in order, on :data:`READ_THREADS` threads."""
    if len(stems) < 2:
        return [read(stem) for stem in stems]
    with ThreadPoolExecutor(READ_THREADS) as pool:
        return list(pool.map(read, stems))


def intact_jobs(run_dir: Path) -> list[tuple[Path, pd.DataFrame]]:
    """Stem and summary rows of each of the run's jobs whose files are intact (:func:`job_stems`,
    :func:`read_job`); a damaged job is left out with a one-line warning naming the file."""
    stems = job_stems(Path(run_dir))
    summaries = _read_each(lambda stem: read_job(stem, LEFT_OUT), stems)
    return [(stem, summary) for stem, summary in zip(stems, summaries) if summary is not None]


def aggregate(
    run_dir: Path, metadata: dict[str, Any], jobs: list[tuple[Path, pd.DataFrame]] | None = None
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Concatenate the run's intact job files into its summary and epoch tables; a damaged job is
    left out with a one-line warning naming the file.

    ``jobs`` is :func:`intact_jobs` of the run when the caller has it (read here otherwise).
    Written to ``run_dir/summary.parquet`` and ``run_dir/epochs.parquet``.
    """
    run_dir = Path(run_dir)
    summaries, frames = [], []
    jobs = intact_jobs(run_dir) if jobs is None else jobs
    tables = _read_each(lambda stem: read_table(stem.with_suffix(".epochs.parquet"), LEFT_OUT), [j[0] for j in jobs])
    for (_, summary), epochs in zip(jobs, tables):
        if epochs is None:
            continue
        summaries.append(summary)
        if len(epochs):
            frames.append(epochs)
    summary = pd.concat(summaries, ignore_index=True) if summaries else pd.DataFrame(columns=list(SUMMARY_COLUMNS))
    epochs = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=list(EPOCH_COLUMNS))
    write_parquet(summary, run_dir / "summary.parquet", metadata)
    write_parquet(epochs, run_dir / "epochs.parquet", metadata)
    return summary, epochs


def diagnostics(run_dir: Path, jobs: list[tuple[Path, pd.DataFrame]] | None = None) -> dict[str, list[dict[str, Any]]]:
    """All diagnostics of a run's intact jobs, grouped by estimator name, each with its job's summary row.

    ``jobs`` is :func:`intact_jobs` of the run when the caller has it (read here otherwise).
    """
    out: dict[str, list[dict[str, Any]]] = {}
    for stem, summary in intact_jobs(run_dir) if jobs is None else jobs:
        estimator = stem.name.split("-")[0]
        path = stem.with_suffix(".diagnostics.json")
        try:
            diag = json.loads(path.read_text())
        except ValueError as exc:  # a job written before checksums: its summary could not vouch for the file
            warn(str(path), f"cannot be read ({one_line(exc)})", LEFT_OUT)
            continue
        out.setdefault(estimator, []).append({"job": summary.iloc[0].to_dict(), "diagnostics": diag})
    return out


def cached_scenarios(run_dir: Path) -> list[Path]:
    """The folders of the run's cached scenarios (:func:`run_folders`) whose tables match their manifests;
    a damaged one is left out with a one-line warning naming the file."""
    out = []
    for folder in run_folders(run_dir):
        for directory in sorted(p for p in folder.glob("cache/*") if p.is_dir() and not p.name.startswith(".")):
            problem = cache_problem(directory)
            if problem:
                field, _, what = problem.partition(": ")
                warn(field, what, "left out of the report; rerun the run to rebuild it")
            else:
                out.append(directory)
    return out


def provenance_of(path: Path) -> dict[str, Any]:
    """The provenance metadata of a result file."""
    return read_parquet_metadata(path)
