"""Where the seconds of a job go: cProfile of the generator and of one job per estimator.

A job is the scenario's generation and one estimator's run on it, as the runner
does it (:func:`simbench.runs.runner.run_estimators`, without scoring). For each
estimator this prints the top functions by cumulative and by own (self) time and
the generator's share of the job; ``--generator`` profiles the generator alone at
the ``generator_throughput`` setting (urban, dual frequency, 10 Hz, one hour).
Times are CPU seconds of this process (the profiler's clock is
:func:`time.process_time`, so other processes on a shared machine do not count);
cProfile adds a per-call overhead, so shares of Python-heavy functions are
inflated; compare runs of this script with each other, not with the timing
benchmarks.

    python benchmarks/profile_job.py --world morgantown1 --estimators ekf_ins crt_lss
    python benchmarks/profile_job.py --world urban --duration 300 --seed 1000 --imu-rate 100 \\
        --estimators ekf_ins crt_lss --set crt_lss.window=20
    python benchmarks/profile_job.py --generator --duration 3600
"""

from __future__ import annotations

import argparse
import cProfile
import io
import os
import pstats
import time
from collections.abc import Callable
from functools import partial
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core, as the timing targets say
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import estimators
from simbench.contract import Scenario
from simbench.runs.compose import compose_config
from simbench.sim.config import SimConfig
from simbench.sim.generator import generate
from simbench.typed import to_typed


def profiled(fn: Callable[[], Any]) -> tuple[Any, pstats.Stats, float]:
    """Run ``fn`` under cProfile; return its result, the statistics and the CPU time [s] it took.

    The profiler's clock is this process's CPU time: on a shared machine the wall clock
    also counts the other processes' turns.
    """
    prof = cProfile.Profile(time.process_time)
    start = time.process_time()
    prof.enable()
    out = fn()
    prof.disable()
    cpu = time.process_time() - start
    return out, pstats.Stats(prof), cpu


def cumulative_of(stats: pstats.Stats, function: str, module: str) -> float:
    """Cumulative profiled time [s] of ``module``'s ``function`` (0 when it did not run)."""
    # pstats keeps its table in a documented-by-example but untyped attribute
    table: dict[tuple[str, int, str], tuple[Any, ...]] = stats.stats  # type: ignore[attr-defined]
    return sum(v[3] for (path, _, name), v in table.items() if name == function and path.endswith(module))


def top(stats: pstats.Stats, key: str, n: int) -> str:
    """The ``n`` first rows of the statistics sorted by ``key`` (``cumulative`` or ``tottime``)."""
    out = io.StringIO()
    stats.stream = out  # type: ignore[attr-defined]
    stats.sort_stats(key).print_stats(n)
    lines = out.getvalue().splitlines()
    start = next(i for i, line in enumerate(lines) if line.lstrip().startswith("ncalls"))
    return "\n".join(lines[start : start + n + 1])


def sim_config(args: argparse.Namespace) -> SimConfig:
    """The typed generator config of the chosen world and overrides."""
    overrides = [f"scenario={args.world}", f"receiver={args.receiver}", f"imu={args.imu}", f"seed={args.seed}"]
    if args.duration is not None:
        overrides.append(f"scenario.duration_s={args.duration}")
    if args.rate is not None:
        overrides.append(f"scenario.rate_hz={args.rate}")
    if args.imu_rate is not None:
        overrides.append(f"imu.rate_hz={args.imu_rate}")
    overrides += args.scenario_override
    cfg = compose_config(overrides)
    return to_typed({k: cfg[k] for k in ("scenario", "receiver", "imu", "seed")}, SimConfig)


def estimator_settings(pairs: list[str]) -> dict[str, dict[str, Any]]:
    """``name.field=value`` pairs as per-estimator config dicts (values parsed as int, float or kept)."""
    out: dict[str, dict[str, Any]] = {}
    for pair in pairs:
        key, value = pair.split("=", 1)
        name, field = key.split(".", 1)
        parsed: Any = value
        for kind in (int, float):
            try:
                parsed = kind(value)
                break
            except ValueError:
                continue
        out.setdefault(name, {})[field] = parsed
    return out


def job(sim: SimConfig, name: str, settings: dict[str, Any]) -> Scenario:
    """Generate the scenario and run one estimator on it (the job the profile covers)."""
    scenario = generate(sim)
    cls = estimators.get(name)
    est = cls(to_typed(settings, cls.Config, f"estimator.{name}"))
    if est.uses_labels:
        est.attach_labels(scenario.labels)
    est.estimate(scenario.receiver_view())
    return scenario


def report(title: str, stats: pstats.Stats, cpu: float, n: int) -> None:
    """Print the CPU time, the generator's share and the top functions of one profile."""
    total = max(stats.total_tt, 1e-12)  # type: ignore[attr-defined]
    gen = cumulative_of(stats, "generate", "simbench/sim/generator.py")
    print(f"\n=== {title}: {cpu:.2f} s CPU (profiled {total:.2f} s), generator {100 * gen / total:.1f} %")
    print(f"--- top {n} by cumulative time")
    print(top(stats, "cumulative", n))
    print(f"--- top {n} by self time")
    print(top(stats, "tottime", n))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="morgantown1", help="scenario preset in conf/scenario/")
    ap.add_argument("--receiver", default="low")
    ap.add_argument("--imu", default="consumer")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--duration", type=float, default=None, help="scenario length [s] (preset's by default)")
    ap.add_argument("--rate", type=float, default=None, help="GNSS rate [Hz] (preset's by default)")
    ap.add_argument("--imu-rate", type=float, default=None, help="IMU rate [Hz] (preset's by default)")
    ap.add_argument("--scenario-override", nargs="*", default=[], help="further config overrides, key=value")
    ap.add_argument("--estimators", nargs="*", default=["ekf_ins", "crt_lss"], help="one job each")
    ap.add_argument("--set", nargs="*", default=[], help="estimator settings, e.g. crt_lss.window=20")
    ap.add_argument(
        "--generator",
        action="store_true",
        help="profile the generator alone at the generator_throughput setting (urban, dual frequency, 10 Hz)",
    )
    ap.add_argument("--top", type=int, default=10, help="functions listed per table")
    args = ap.parse_args()
    if args.generator:
        args.world, args.seed, args.estimators = "urban", 0, []
        args.rate = 10.0 if args.rate is None else args.rate
        args.duration = 3600.0 if args.duration is None else args.duration
        args.scenario_override = [
            "scenario.dual_frequency=true",
            "scenario.errors.multipath.elevation_dependent=true",
            *args.scenario_override,
        ]
    sim = sim_config(args)
    print(
        f"world {sim.scenario.name}, receiver {args.receiver}, seed {sim.seed}, {sim.scenario.duration_s:g} s at "
        f"{sim.scenario.rate_hz:g} Hz, IMU {sim.imu.rate_hz:g} Hz"
    )
    if args.generator:
        scenario, stats, cpu = profiled(lambda: generate(sim))
        print(f"{scenario.n_epochs} epochs, {len(scenario.observations)} observations")
        report("generator", stats, cpu, args.top)
    settings = estimator_settings(args.set)
    for name in args.estimators:
        _, stats, cpu = profiled(partial(job, sim, name, settings.get(name, {})))
        report(name, stats, cpu, args.top)


if __name__ == "__main__":
    main()
