"""The command line of a run or sweep before and around Hydra: what Hydra would refuse on a page, one line.

``python -m simbench`` (:func:`simbench.cli.main.main`) refuses here, with exit code 2, a first word that
is no subcommand, a sweep without ``-m``, and any error Hydra or OmegaConf raise about the command line
(a malformed override, an unknown ``--config-name``, a bad ``hydra.*`` value), which Hydra prints over
several lines with exit code 1, the code of failed rows.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Collection
from typing import Any, cast

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from simbench.errors import SimbenchError, did_you_mean

__all__ = ["check_subcommand", "check_no_sweep", "run_hydra", "hydra_error", "unresolved"]


def unresolved(cfg: DictConfig, key: str) -> Any:
    """The value of a root key as written, its interpolations (``${now:...}``) unresolved."""
    return cast(dict[str, Any], OmegaConf.to_container(OmegaConf.masked_copy(cfg, [key]), resolve=False))[key]


def check_subcommand(args: list[str], subcommands: Collection[str]) -> None:
    """Refuse a first argument that is neither one of ``subcommands``, a flag nor an override (``reprot``, a path).

    Hydra would only say ``Error parsing override 'reprot' missing EQUAL``.

    Raises
    ------
    SimbenchError
        Naming the word, the closest subcommand and the known ones.
    """
    if not args or args[0].startswith(("-", "~", "+")) or "=" in args[0]:
        return
    word = args[0]
    raise SimbenchError(
        "command",
        f"unknown subcommand '{word}'{did_you_mean(word, subcommands)}",
        f"the subcommands are {', '.join(subcommands)}; a run takes key=value overrides (python -m simbench --help)",
    )


def check_no_sweep(args: list[str]) -> None:
    """Refuse a sweep (``seed=0,1``, ``range(...)``) on the command line of a single run, without ``-m``.

    Hydra would stop with a page about an ambiguous value after the checks passed.

    Raises
    ------
    SimbenchError
        Naming the swept key, with the ``-m`` command and the list spelling.
    """
    given = [a for a in args if not a.startswith("-")]
    try:
        parsed = OverridesParser.create().parse_overrides(given)
    except HydraException:
        return  # Hydra's parser says what is wrong (run_hydra: one line)
    for arg, override in zip(given, parsed):
        if override.is_sweep_override() and not override.key_or_group.startswith("hydra."):
            key = override.get_key_element()
            raise SimbenchError(
                key,
                f"'{arg}' is a sweep, and sweeps need -m",
                f"run python -m simbench -m {' '.join(args)}, or write a list as {key}=[a,b]",
            )


def run_hydra(app: Callable[[], None]) -> None:
    """Hand the command line to Hydra (``app``, the ``hydra.main`` function); an error Hydra itself raises
    is one line and exit 2.

    Hydra prints its own errors over several lines (a parse error, an unknown config name, a
    bad ``hydra.*`` value) and exits 1, the code of failed rows. With ``HYDRA_FULL_ERROR`` set
    by the user its full report is kept.
    """
    if os.environ.get("HYDRA_FULL_ERROR"):
        app()
        return
    os.environ["HYDRA_FULL_ERROR"] = "1"  # Hydra raises instead of printing and exiting 1
    try:
        app()
    except (HydraException, OmegaConfBaseException) as exc:
        print(f"error: {hydra_error(exc)}", file=sys.stderr)
        sys.exit(2)
    finally:
        del os.environ["HYDRA_FULL_ERROR"]


def hydra_error(exc: BaseException) -> SimbenchError:
    """An exception of Hydra or OmegaConf as one line naming the command line and the override grammar."""
    lines = [" ".join(ln.split()) for ln in f"{exc}\n{exc.__cause__ or ''}".splitlines()]
    lines = [ln for ln in lines if ln and not ln.startswith(("See https", "Set the environment"))]
    problem = ": ".join(lines[:2]) + (" (" + ", ".join(lines[2:12]) + ")" if lines[2:] else "")
    override = getattr(exc, "override", None)  # a parse error names the override apart from its message
    return SimbenchError(
        f"override '{override}'" if override else "command line",
        problem or type(exc).__name__,
        "see python -m simbench --help; overrides are key=value (https://hydra.cc/docs/1.2/advanced/override_grammar/basic)",
    )
