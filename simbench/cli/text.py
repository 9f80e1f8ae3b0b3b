"""Lines for the terminal that need no result table, so the command line's fast paths (``--help``, a
misspelt name) do not import pandas: "did you mean" suggestions, simbench's warnings as one line each,
and docstrings as plain text for a subcommand's ``--help``."""

from __future__ import annotations

import argparse
import re
import sys
import warnings
from collections.abc import Callable
from typing import NoReturn, TextIO

from simbench.errors import SimbenchWarning

#: Sphinx cross-references (``:func:`~a.b``` and the like) and inline literals (````x````).
SPHINX_ROLE = re.compile(r":[a-z]+:`~?([^`]+)`")
LITERAL = re.compile(r"``([^`]+)``")


def plain_text(doc: str) -> str:
    """A docstring as a terminal shows it: ``x`` as x, :func:`~a.b` as b, :mod:`a.b` as a.b, ``::`` as ``:``.

    Parameters
    ----------
    doc : str
        reStructuredText of a module docstring (a subcommand's description).
    """

    def role(match: re.Match[str]) -> str:
        target = match.group(1)
        return target.rpartition(".")[2] if match.group(0).split("`")[1].startswith("~") else target

    text = LITERAL.sub(r"\1", SPHINX_ROLE.sub(role, doc))
    return re.sub(r"(\S)::$", r"\1:", re.sub(r"\s::$", ":", text, flags=re.M), flags=re.M)


def one_line_warnings(emit: Callable[[str], object] | None = None) -> None:
    """Print every :class:`~simbench.errors.SimbenchWarning` as ``warning: <message>`` on stderr.

    Python's default format adds the file, line and source line of the ``warn`` call, which
    points into simbench rather than at the user's input. Other warnings keep that format.
    ``emit`` takes the line instead, e.g. to print it above a progress bar (:mod:`simbench.cli.progress`).
    """
    default = warnings.showwarning

    def show(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        if issubclass(category, SimbenchWarning) and emit is not None and file is None:
            emit(f"warning: {message}")
        elif issubclass(category, SimbenchWarning):
            print(f"warning: {message}", file=file or sys.stderr)
        else:
            default(message, category, filename, lineno, file, line)

    warnings.showwarning = show


class OneLineParser(argparse.ArgumentParser):
    """A subcommand's argument parser whose refusal is one line naming the argument (exit code 2), as
    every other refusal: argparse's own prints the whole usage first."""

    def error(self, message: str) -> NoReturn:
        print(f"error: {message} -- see {self.prog} --help", file=sys.stderr)
        sys.exit(2)
