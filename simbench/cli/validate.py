"""``python -m simbench validate``: sim-vs-real statistics of one or more worlds, side by side.

Each world is a list of Hydra overrides as for ``python -m simbench``; the first
world's come first, each further world starts with ``--against``::

    python -m simbench validate scenario=hk_tst_2019 scenario.systems=G
    python -m simbench validate scenario=urban receiver=low seed=0 --against scenario=hk_tst_2019
    python -m simbench validate scenario=hk_tst_2019 --against scenario=urban receiver=low \\
        --against scenario=urban receiver=high --out results/validation

It prints one row per world (:class:`simbench.analysis.validation.WorldStatistics`) with
the Kolmogorov-Smirnov distances of the |code residual| and C/N0 distributions
against the reference world (``--reference NAME``; default the first real log,
else the first world). ``--out DIR`` also writes ``validation.csv``,
``cn0_by_elevation.csv`` and ``validation.png``. ``--mask DEG`` sets an
elevation mask (default none).
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
from tqdm import tqdm

from simbench.analysis.validation import cn0_by_elevation, comparison_table, residual_sample
from simbench.cli.text import plain_text
from simbench.contract import write_bytes
from simbench.errors import SimbenchError, require_elevation_mask
from simbench.report.figures import validation_figure
from simbench.runs.files import check_output_dir, staged_folder
from simbench.runs.scenarios import scenario_from_overrides

#: Columns the terminal table shows (validation.csv has them all).
SHOWN = [
    "name",
    "n_epochs",
    "sats_median",
    "residual_p50_m",
    "residual_p90_m",
    "residual_p99_m",
    "share_over_10m",
    "share_over_30m",
    "cn0_p10",
    "cn0_p50",
    "cn0_p90",
    "phase_availability",
    "arc_median_s",
    "lli_rate",
    "ks_residual",
    "ks_cn0",
]
_FLAGS = ("--out", "--reference", "--mask")


def parse_args(args: list[str]) -> tuple[list[list[str]], dict[str, str]]:
    """Split the command line into the worlds' override lists and the ``--out/--reference/--mask`` options.

    Raises
    ------
    SimbenchError
        For an unknown flag, a flag without its value, or an empty world.
    """
    worlds: list[list[str]] = [[]]
    options: dict[str, str] = {}
    items = iter(args)
    for item in items:
        if item == "--against":
            worlds.append([])
        elif item.split("=", 1)[0] in _FLAGS:
            flag, _, value = item.partition("=")
            value = value or next(items, "")
            if not value:
                raise SimbenchError(flag, "has no value", f"write {flag} VALUE")
            options[flag.lstrip("-")] = value
        elif item.startswith("-"):
            raise SimbenchError(
                item,
                "unknown option",
                "use --against, --out DIR, --reference NAME or --mask DEG (python -m simbench validate --help)",
            )
        else:
            worlds[-1].append(item)
    if len(worlds) > 1 and not all(worlds[1:]):
        raise SimbenchError("--against", "is followed by no override", "write e.g. --against scenario=hk_tst_2019")
    return worlds, options


def run(args: list[str]) -> pd.DataFrame:
    """Build every world, print the comparison table, write ``--out``; return the table."""
    worlds, options = parse_args(args)
    try:
        mask = float(options.get("mask", 0.0))
    except ValueError:
        raise SimbenchError(
            "--mask", f"is not a number: {options['mask']}", "give the elevation mask in degrees"
        ) from None
    require_elevation_mask("--mask", mask, "give the elevation mask in degrees, e.g. --mask 10")
    out = check_output_dir("--out", options["out"], "--out results/validation") if "out" in options else None
    samples = []
    for overrides in tqdm(worlds, desc="worlds", unit="world", disable=len(worlds) < 2):
        samples.append(residual_sample(scenario_from_overrides(overrides)[1], elevation_mask_deg=mask))
    names = [s.name for s in samples]
    if len(set(names)) < len(names):
        raise SimbenchError("worlds", f"two worlds are the same: {names}", "give each --against a different world")
    table = comparison_table(samples, options.get("reference"))
    print(table[SHOWN].to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    print(f"KS distances against: {table['ks_against'].iloc[0]}")
    if out is not None:
        with staged_folder(out) as staging:  # the three files or none (a full disk)
            write_bytes(staging / "validation.csv", table.to_csv(index=False).encode())
            cn0 = pd.concat([cn0_by_elevation(s) for s in samples])
            write_bytes(staging / "cn0_by_elevation.csv", cn0.to_csv(index=False).encode())
            figure = validation_figure(samples, staging / "validation.png", "Sim vs real: " + ", ".join(names))
        written = [out / "validation.csv", out / "cn0_by_elevation.csv", out / Path(figure.path).name]
        print(f"written: {', '.join(map(str, written))}", file=sys.stderr)
    return table


def main(argv: list[str]) -> int:
    """Run :func:`run` on ``argv``; the exit code (2 with a one-line error on bad input)."""
    if argv and argv[0] in ("-h", "--help"):
        print(plain_text(__doc__))
        return 0
    try:
        run(argv)
    except SimbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0
