"""``python -m simbench zero-baseline``: the zero-baseline table of :mod:`simbench.runs.zero_baseline`."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

import pandas as pd
from tqdm.auto import tqdm

from simbench.cli.text import OneLineParser, plain_text
from simbench.contract import write_bytes
from simbench.errors import SimbenchError
from simbench.runs.checks import check_seed
from simbench.runs.files import check_output_dir, os_fault
from simbench.runs.zero_baseline import TABLE_NAME, check_zero_baseline, zero_baseline


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
    try:  # the seed and the output folder before the first scenario is generated
        check_seed(args.seed, "--seed", "--seed 0")
        if not names:
            raise SimbenchError("scenarios", "names no scenario preset", "e.g. zero-baseline morgantown1 morgantown2")
        out = check_output_dir("--out", args.out, "--out results/zero_baseline")
        for name in names:  # every scenario's config before the first is generated
            check_zero_baseline(name, args.seed, **overrides)
        table = pd.concat(
            [zero_baseline(s, args.seed, **overrides) for s in tqdm(names, desc="zero baseline")], ignore_index=True
        )
        path = out / TABLE_NAME
        try:
            write_bytes(path, table.to_csv(index=False).encode())
        except OSError as exc:  # a full disk: one line, and no half-written table (written under another name)
            raise os_fault(exc, path) from None
    except SimbenchError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(table.to_string(index=False))
    print(f"written: {path}")
    return 0
