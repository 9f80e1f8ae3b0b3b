"""``python -m simbench zero-baseline``: the zero-baseline table of :mod:`simbench.runs.zero_baseline`."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import pandas as pd
from tqdm.auto import tqdm

from simbench.cli.text import plain_text
from simbench.errors import SimbenchError
from simbench.runs.zero_baseline import TABLE_NAME, zero_baseline


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m simbench zero-baseline SCENARIO... [KEY=VALUE...] [--seed N] [--out DIR]``."""
    parser = argparse.ArgumentParser(prog="python -m simbench zero-baseline", description=plain_text(__doc__))
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
    try:
        table = pd.concat(
            [zero_baseline(s, args.seed, **overrides) for s in tqdm(names, desc="zero baseline")], ignore_index=True
        )
    except SimbenchError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / TABLE_NAME
    tmp = path.with_name(f".{path.name}.tmp")
    table.to_csv(tmp, index=False)
    tmp.replace(path)
    print(table.to_string(index=False))
    print(f"written: {path}")
    return 0
