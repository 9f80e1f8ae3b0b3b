"""``python -m simbench``: simulate, run estimators, write results and a report.

The Hydra app composes ``conf/config.yaml``; every result lands in
``results_dir``: ``summary.parquet``, ``epochs.parquet`` (provenance in the
file metadata), ``scenario/`` (the generated tables) and ``report/``.
"""
from __future__ import annotations

import sys
from pathlib import Path

import hydra
from omegaconf import DictConfig, OmegaConf

from simbench.compose import CONF_DIR, compose_config
from simbench.errors import SimbenchError


def run(cfg: DictConfig) -> Path:
    """Simulate the configured scenario, run the configured estimators, write the store and report."""
    from simbench.config import SimConfig, to_typed
    from simbench.contract import write_parquet
    from simbench.provenance import provenance
    from simbench.report.build import build_report
    from simbench.runner import run_estimators
    from simbench.scenarios import build_scenario

    sim = to_typed({k: cfg[k] for k in ("scenario", "receiver", "imu", "seed")}, SimConfig, "config")
    out = Path(cfg.results_dir)
    out.mkdir(parents=True, exist_ok=True)
    if cfg.progress:
        print(f"simulating {sim.scenario.name} ({sim.scenario.duration_s:.0f} s at {sim.scenario.rate_hz:g} Hz), "
              f"receiver {sim.receiver.name}, seed {sim.seed}", file=sys.stderr)
    scenario = build_scenario(sim)
    scenario.save(out / "scenario")
    result = run_estimators(scenario, OmegaConf.to_container(cfg.estimator, resolve=True),
                            receiver=sim.receiver.name, progress=bool(cfg.progress))
    meta = provenance(OmegaConf.to_container(cfg, resolve=True))
    write_parquet(result.summary, out / "summary.parquet", meta)
    write_parquet(result.epochs, out / "epochs.parquet", meta)
    report = build_report(out)
    shown = ["estimator", "status", "availability", "horizontal_median", "horizontal_mean", "horizontal_p95",
             "horizontal_max", "error_3d_median", "update_median_s", "message"]
    print(result.summary[shown].to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print(f"results: {out.resolve()}  report: {report.resolve() / 'README.md'}")
    return out


@hydra.main(config_path=str(CONF_DIR), config_name="config", version_base="1.3")
def _app(cfg: DictConfig) -> None:
    try:
        run(cfg)
    except SimbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)


def main() -> None:
    """Entry point: compose once up front so a bad override gets one line, not Hydra's error page."""
    args = sys.argv[1:]
    if not any(a in ("-m", "--multirun") or a.startswith("-") for a in args):
        try:
            compose_config(args)
        except SimbenchError as exc:
            print(f"error: {exc}", file=sys.stderr)
            sys.exit(2)
    _app()
