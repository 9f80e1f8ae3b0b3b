"""``python -m simbench zero-baseline``: the zero-baseline table of :mod:`simbench.runs.zero_baseline`."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from simbench.cli.text import OneLineParser, plain_text
from simbench.errors import SimbenchError
from simbench.runs.checks import check_seed
from simbench.runs.files import check_output_dir
from simbench.runs.zero_baseline import write_zero_baseline


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m simbench zero-baseline SCENARIO... [KEY=VALUE...] [--seed N] [--out DIR]``."""
    parser = OneLineParser(prog="python -m simbench zero-baseline", description=plain_text(__doc__))
    parser.add_argument(
        "scenarios",
        nargs="+",
        help="presets of conf/scenario, e.g. morgantown1 morgantown2, and "
        "dotted config overrides, e.g. scenario.duration_s=300",
    )
    parser.add_argument("--seed", type=int, default=0, help="environment seed (default 0)")
    parser.add_argument("--out", type=Path, default=Path("results/zero_baseline"), help="folder for zero_baseline.csv")
    args = parser.parse_args(argv)
    names = [a for a in args.scenarios if "=" not in a]
    overrides = dict(a.split("=", 1) for a in args.scenarios if "=" in a)
    try:  # the arguments before the first scenario is generated
        check_seed(args.seed, "--seed", "--seed 0")
        if not names:
            raise SimbenchError("scenarios", "names no scenario preset", "e.g. zero-baseline morgantown1 morgantown2")
        out = check_output_dir("--out", args.out, "--out results/zero_baseline")
        table, path = write_zero_baseline(names, out, args.seed, **overrides)
    except SimbenchError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(table.to_string(index=False))
    print(f"written: {path}")
    return 0
