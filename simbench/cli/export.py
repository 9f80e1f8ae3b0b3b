"""``python -m simbench export [overrides] format=rinex|librsf|gnsslogger out=DIR``: write a scenario for other tools.

The overrides are those of ``python -m simbench`` (``scenario=urban receiver=low
seed=3 scenario.duration_s=60``); the scenario is built exactly as a run builds
it (:func:`simbench.runs.scenarios.build_scenario`). ``format`` (default ``rinex``)
and ``out`` (required) belong to this command. Files are named
``<scenario>_<receiver>_<seed>.*``; the command prints them and the command
line that reads them back.
"""

from __future__ import annotations

import sys

from simbench.cli.text import plain_text
from simbench.data.export import ExportFormat, export_scenario
from simbench.errors import SimbenchError
from simbench.runs.checks import check_seed
from simbench.runs.compose import compose_config
from simbench.runs.files import check_output_dir, staged_folder
from simbench.runs.scenarios import build_scenario, check_scenario, scenario_settings

_USAGE = "python -m simbench export scenario=urban receiver=low seed=0 format=rinex|librsf|gnsslogger out=DIR"


def main(argv: list[str]) -> int:
    """Run the export; return the process exit code (2 with a one-line error on bad input)."""
    args = list(argv)
    if any(a in ("-h", "--help") for a in args):
        print(plain_text(__doc__).strip().splitlines()[0] + f"\nusage: {_USAGE}")
        return 0
    own = {a.partition("=")[0]: a.partition("=")[2] for a in args if a.startswith(("format=", "out="))}
    overrides = [a for a in args if not a.startswith(("format=", "out="))]
    try:
        if not own.get("out"):
            raise SimbenchError("out", "no output directory given", f"add out=DIR: {_USAGE}")
        fmt = own.get("format", ExportFormat.rinex.value)
        if fmt not in {f.value for f in ExportFormat}:
            raise SimbenchError(
                "format", f"unknown export format '{fmt}'", f"choose from {', '.join(f.value for f in ExportFormat)}"
            )
        cfg = compose_config(overrides)
        sim = scenario_settings(cfg)
        check_seed(sim.seed)
        inputs = [p for paths in check_scenario(sim).input_files(sim).values() for p in paths]
        out = check_output_dir("out", own["out"], "out=results/export", inputs)  # before the scenario is built
        scenario = build_scenario(sim)
        # a RINEX log without scenario.name is named after its observation file (in meta)
        stem = f"{scenario.meta.get('name') or sim.scenario.name}_{sim.receiver.name}_{sim.seed}"
        with staged_folder(out) as staging:  # every file or none: a full disk leaves no half export
            staged = export_scenario(scenario, fmt, staging, stem, receiver=sim.receiver.name)
        files = [out / f.name for f in staged]
    except SimbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for f in files:
        print(f)
    if fmt in (ExportFormat.rinex.value, ExportFormat.gnsslogger.value):
        navs = [str(f) for f in files[1:] if not f.name.endswith("_truth.csv")]
        nav = navs[0] if len(navs) == 1 else f"[{','.join(navs)}]"  # several files: records merged
        truth = next((f" scenario.truth={f}" for f in files if f.name.endswith("_truth.csv")), "")
        print(
            f"read back: python -m simbench scenario={fmt} scenario.obs={files[0]} scenario.nav={nav}{truth}",
            file=sys.stderr,
        )
    else:
        print(
            f"read back: python -m simbench scenario=librsf scenario.obs={files[0]} "
            f"scenario.gps_week={scenario.nav.gps_week} scenario.start_sow_s={scenario.nav.start_sow_s!r}",
            file=sys.stderr,
        )
    return 0
