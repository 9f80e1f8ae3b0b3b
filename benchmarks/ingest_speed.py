"""Ingest speed: a one-hour libRSF file and the Hong Kong RINEX log (target: each under 10 s).

Usage: ``python benchmarks/ingest_speed.py [--repeat 3]``. The one-hour libRSF
file (1 Hz pseudoranges, 10 Hz odometry, 1 Hz reference) is generated into a
temporary directory, not committed. Times are wall-clock on a shared machine:
take the minimum over repeats and expect noise.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from simbench.data.librsf import load_librsf, write_synthetic_librsf
from simbench.data.rinex import load_rinex

HK = Path(__file__).resolve().parents[2] / "shared" / "data" / "hk_tst_2019"
TARGET_S = 10.0


def _best(fn, repeat: int) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(repeat):
        tic = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - tic)
    return best, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = write_synthetic_librsf(Path(tmp) / "hour.txt", 3600.0, odometry_rate_hz=10.0)
        size_mb = path.stat().st_size / 1e6
        t_rsf, sc = _best(lambda: load_librsf(path, gps_week=2032, start_sow_s=475_200.0), args.repeat)
        print(
            f"libRSF one hour ({size_mb:.1f} MB, {len(sc.observations)} pseudoranges, "
            f"{sc.meta['odometry_rows']} odometry lines): {t_rsf:.2f} s "
            f"({t_rsf / TARGET_S:.2f} of the {TARGET_S:.0f} s target)"
        )
    if (HK / "COM3_190428_124409.obs").is_file():
        for systems in ("G", "GC"):
            t_hk, sc = _best(
                lambda systems=systems: load_rinex(
                    HK / "COM3_190428_124409.obs",
                    HK / "hksc1180.19n",
                    HK / "groundTruth_TST.csv",
                    systems=systems,
                    nav_bds_path=HK / "hksc1180.19b",
                ),
                args.repeat,
            )
            print(
                f"RINEX Hong Kong ({sc.meta['epochs']} epochs, {len(sc.observations)} rows, "
                f"systems {sc.meta['systems']}): {t_hk:.2f} s ({t_hk / TARGET_S:.2f} of the target)"
            )
    else:
        print(f"RINEX Hong Kong: data not found under {HK}")


if __name__ == "__main__":
    main()
