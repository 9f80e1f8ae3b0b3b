"""Write ``rinex_corpus_counts.json``: what georinex, an independent reader, reads from each observation file of
``../shared/data/rinex_corpus`` (tests/test_rinex_corpus.py compares simbench's reader with it).

Per file its size; per observation file: the number of epochs and, per observable (georinex's names:
RINEX 3 codes, RINEX 2 types) and satellite, the count of values that are neither blank nor 0.000 (RINEX:
both mean missing). georinex 1.16 needs about a minute per hour of a one-day 30 s multi-GNSS file, so the
six files over 1 MB are read over their first two hours (``tlim``). Per RINEX 2/3 navigation file: per
system, the satellites with a healthy record (health 0; QZSS health bit 0, L1C/B, masked as simbench and
RTKLIB do). Run from the repository root::

    python -W ignore tests/data/make_rinex_corpus_counts.py
"""

from __future__ import annotations

import gzip
import json
import sys
import time
from pathlib import Path

import georinex
import numpy as np

ROOT = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "rinex_corpus"
OUT = Path(__file__).with_name("rinex_corpus_counts.json")
#: Files read over a window only: (first, last) epoch, GPS time as written in the file.
WINDOWS = {
    "CRNX/V3/AJAC00FRA_R_20242090000_01D_30S_MO.crx.gz": ("2024-07-27T00:00:00", "2024-07-27T01:59:59"),
    "CRNX/V3/AJAC00FRA_R_20242100000_01D_30S_MO.crx.gz": ("2024-07-28T00:00:00", "2024-07-28T01:59:59"),
    "CRNX/V3/NYA100NOR_S_20241270000_01D_30S_MO.crx.gz": ("2024-05-06T00:00:00", "2024-05-06T01:59:59"),
    "CRNX/V3/NYA100NOR_S_20241280000_01D_30S_MO.crx.gz": ("2024-05-07T00:00:00", "2024-05-07T01:59:59"),
    "OBS/V3/OB712480.23O.gz": ("2023-09-05T00:00:00", "2023-09-05T01:59:59"),
    "OBS/V3/OB713520.23O.gz": ("2023-12-18T00:00:00", "2023-12-18T01:59:59"),
}


def counts(path: Path, window: tuple[str, str] | None) -> dict:
    """georinex's epochs and per-observable, per-satellite counts of present values of one file."""
    ds = georinex.load(path, fast=False, tlim=window)
    per_var = {}
    for name in ds.data_vars:
        if name.endswith(("lli", "ssi")):
            continue
        a = ds[name].values
        n = (np.isfinite(a) & (a != 0)).sum(axis=0)
        per_var[str(name)] = {str(s): int(k) for s, k in zip(ds.sv.values, n) if k}
    return {"epochs": int(ds.time.size), "window": window, "counts": per_var}


#: Health field of each system's records in georinex.
HEALTH = {"G": "health", "R": "health", "E": "health", "C": "SatH1", "J": "health"}


def healthy_satellites(path: Path) -> dict:
    """Per system, the satellites of a navigation file with at least one healthy record (where georinex parses
    the system's numbers: it leaves every Galileo and BeiDou number of some 3.04/3.05 files NaN), and the
    satellites that have a record at all (from the record lines' ids)."""
    out = {}
    for system, name in HEALTH.items():
        ds = georinex.load(path, use={system})
        if "sv" not in ds.coords or name not in ds or not np.isfinite(ds[name].values).any():
            continue
        health = ds[name].values.astype(float)
        if system == "J":
            health = np.where(np.isfinite(health), health.astype(np.int64, copy=False) & ~1, np.nan)
        ok = (health == 0).any(axis=0)
        # georinex ignores ``use`` in RINEX 2 files: keep the system's own satellites
        sats = sorted({str(s)[:3] for s, k in zip(ds.sv.values, ok) if k and str(s)[0] == system})
        if sats:
            out[system] = sats
    return {"healthy": out, "present": record_ids(path)}


def record_ids(path: Path) -> dict:
    """Per system, the satellite ids that open a record (RINEX 3 'G05 2021 ...'; RINEX 2 GLONASS ' 5 21 ...')."""
    raw = path.read_bytes()
    lines = (gzip.decompress(raw) if raw[:2] == b"\x1f\x8b" else raw).decode(errors="replace").splitlines()
    body = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    rinex2_glonass = lines[0][:1] == " " and lines[0][5:6] == "2" and lines[0][20:21] == "G"
    ids: dict[str, set[str]] = {}
    for ln in lines[body:]:
        if rinex2_glonass and ln[:2].strip().isdigit():
            ids.setdefault("R", set()).add(f"R{int(ln[:2]):02d}")
        elif not rinex2_glonass and ln[:1] in HEALTH and ln[1:3].strip().isdigit():
            ids.setdefault(ln[0], set()).add(ln[0] + f"{int(ln[1:3]):02d}")
    if lines[0][5:6] == "2" and lines[0][20:21] == "N":  # RINEX 2 GPS: ' 5 21  1  1 ...'
        ids = {"G": {f"G{int(ln[:2]):02d}" for ln in lines[body:] if ln[:2].strip().isdigit()}}
    return {k: sorted(v) for k, v in ids.items()}


def main(names: list[str]) -> None:
    out = json.loads(OUT.read_text()) if OUT.exists() else {}
    files = sorted(
        p for d in ("OBS", "CRNX", "NAV/V2", "NAV/V3") for p in (ROOT / d).glob("*/*" if len(d) < 5 else "*")
    )
    for path in files:
        name = path.relative_to(ROOT).as_posix()
        if names and name not in names:
            continue
        start = time.perf_counter()
        out[name] = healthy_satellites(path) if name.startswith("NAV/") else counts(path, WINDOWS.get(name))
        out[name]["bytes"] = path.stat().st_size
        print(f"{name}: {time.perf_counter() - start:.1f} s", flush=True)
        OUT.write_text(json.dumps(out, indent=0, sort_keys=True) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
