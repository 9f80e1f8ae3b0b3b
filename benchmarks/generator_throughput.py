"""Generator throughput: one hour at 10 Hz, ~10 satellites, every error source on.

Target: under 5 s on one core (foundation issue), 1.0 s (issue 27). Prints the
wall and CPU time of an end-to-end generation (best of ``--repeat``; on a
shared machine the CPU time of this process is the steadier of the two),
observation rows per second and the ratio to the target.
Run: ``python benchmarks/generator_throughput.py [--repeat N]``.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core, as the target says
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from simbench.runs.compose import compose_config
from simbench.sim.config import SimConfig
from simbench.sim.generator import generate
from simbench.typed import to_typed

TARGET_S = 1.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--duration", type=float, default=3600.0)
    parser.add_argument(
        "--broadcast",
        action="store_true",
        help="31-satellite broadcast constellation (brdc.18n) instead of the nominal 24",
    )
    args = parser.parse_args()
    cfg = compose_config(
        [
            "scenario=urban",
            "receiver=low",
            "seed=0",
            f"scenario.duration_s={args.duration}",
            "scenario.rate_hz=10",
            "scenario.dual_frequency=true",
            "scenario.errors.multipath.elevation_dependent=true",
            *(
                [
                    "scenario.constellation.kind=broadcast",
                    "scenario.constellation.nav_path=${simbench_data:wvu_drives/brdc.18n}",
                ]
                if args.broadcast
                else []
            ),
        ]
    )
    sim = to_typed({k: cfg[k] for k in ("scenario", "receiver", "imu", "seed")}, SimConfig)
    times, cpu = [], []
    for _ in range(args.repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        sc = generate(sim)
        times.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    best = min(times)
    n_obs, n_ep = len(sc.observations), sc.n_epochs
    print(
        f"scenario: {args.duration:.0f} s at 10 Hz, {n_ep} epochs, {n_obs} observations "
        f"({n_obs / n_ep:.1f} satellites/epoch), {len(sc.imu)} IMU samples"
    )
    print(f"generation wall time: best {best:.2f} s, all {', '.join(f'{t:.2f}' for t in times)}")
    print(f"generation CPU time: best {min(cpu):.2f} s, all {', '.join(f'{t:.2f}' for t in cpu)}")
    print(f"throughput: {n_obs / best:,.0f} observations/s, {n_ep / best:,.0f} epochs/s")
    print(f"ratio to the {TARGET_S:.0f} s target: {best / TARGET_S:.2f} ({'met' if best < TARGET_S else 'MISSED'})")


if __name__ == "__main__":
    main()
