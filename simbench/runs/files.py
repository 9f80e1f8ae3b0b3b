"""The files of a run folder and of the subcommands' outputs, with one line for every problem.

Every subcommand checks its output folder before it computes anything
(:func:`check_output_dir`), reads the CSV files of a run folder through
:func:`read_csv_table` (a damaged ``study_times.csv`` or ``claims.csv`` is one line
naming the file, not a pandas traceback), writes a folder of several files through
:func:`staged_folder` (all of them or none), and turns a fault of the machine (a full
disk, a read-only or immutable folder) into one line naming the path (:func:`os_fault`).
"""

from __future__ import annotations

import errno
import os
import re
import shutil
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import pandas as pd

from simbench.contract import temporary_name
from simbench.errors import SimbenchError

__all__ = ["check_output_dir", "os_fault", "read_csv_table", "staged_folder", "write_fault"]

#: What to do about a fault of the machine, by errno; others get :data:`OTHER_FAULT_FIX`.
FAULT_FIXES = {
    errno.ENOSPC: "free space on its file system and run the command again",
    errno.EDQUOT: "free space within your disk quota and run the command again",
    errno.EROFS: "its file system is mounted read-only: write on a writable one",
    errno.EACCES: "make it writable (chmod u+w) or write elsewhere",
    errno.EPERM: "it may be immutable (lsattr; chattr -i) or another user's: make it writable or write elsewhere",
}
OTHER_FAULT_FIX = "check the folder and the disk, and run the command again"


def os_fault(
    exc: OSError, path: str | os.PathLike[str] | None = None, what: str = "cannot be written", note: str = ""
) -> SimbenchError:
    """A fault of the machine (``exc``) as one line naming the path (``exc.filename``, else ``path``).

    Parameters
    ----------
    exc : OSError
        A full disk (``ENOSPC``), a read-only (``EROFS``) or forbidden (``EACCES``, ``EPERM``:
        e.g. an immutable folder) path, or another ``OSError``.
    path : path-like, optional
        The file or folder being written when ``exc`` names none (pyarrow's errors do not).
    what : str
        What went wrong with it, e.g. ``cannot be written``.
    note : str
        Appended to the problem, e.g. what became of an old report page.
    """
    where = exc.filename if exc.filename is not None else path
    if where is not None:  # a temporary file is named as the file it was to become (contract.temporary_name)
        where = re.sub(r"(^|/)\.([^/]+)\.[0-9a-f]{32}\.tmp$", r"\1\2", os.fspath(where))
    # pyarrow's strerror is a paragraph naming the temporary file; the errno says it in a word
    reason = os.strerror(exc.errno) if exc.errno else exc.strerror or (str(exc).splitlines() or [type(exc).__name__])[0]
    fix = FAULT_FIXES.get(exc.errno or 0, OTHER_FAULT_FIX)
    return SimbenchError(str(where or "(unknown path)"), f"{what} ({reason}){note}", fix)


def write_fault(folder: Path) -> OSError | None:
    """Why nothing can be written in the existing folder ``folder``: None when a file can be.

    A temporary file is made and removed: ``os.access`` says yes to root on a read-only mount or
    an immutable folder.
    """
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        return exc
    return None


def check_output_dir(
    field: str, path: str | os.PathLike[str], example: str, inputs: Iterable[str | os.PathLike[str]] = ()
) -> Path:
    """``path`` as a folder a command may write into, checked before it computes anything.

    Parameters
    ----------
    field : str
        The argument naming the folder, e.g. ``out`` or ``--out``.
    path : path-like
        The folder; a missing one (and its missing parents) is created later by the writer.
    example : str
        A correct argument for the fix, e.g. ``out=results/export``.
    inputs : iterable of path-like
        Files the command reads: the folder must hold none of them (an export into the log's own
        folder would write over the log's navigation file: ``SameFileError``, half an export left).

    Raises
    ------
    SimbenchError
        Naming ``field``: an empty path, a file, a path under a file, a folder the process cannot
        write in, or the folder of an input file.
    """
    text = os.fspath(path)
    if not text.strip():
        raise SimbenchError(field, "is empty", f"give a folder, e.g. {example}")
    target = Path(text)
    if target.exists() and not target.is_dir():
        raise SimbenchError(field, f"{text} is a file, not a folder", f"give a folder, e.g. {example}")
    parent = target
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise SimbenchError(field, f"{parent} is a file, not a folder", f"give a path of folders, e.g. {example}")
    fault = write_fault(parent)
    if fault is not None:
        raise SimbenchError(
            field, f"cannot write in {parent} ({fault.strerror})", f"give a folder you can write, e.g. {example}"
        )
    resolved = target.resolve()
    for file in inputs:
        if Path(file).resolve().parent == resolved:
            raise SimbenchError(
                field,
                f"{text} is the folder of the input {file}; writing there would replace input files",
                f"give another folder, e.g. {example}",
            )
    return target


def read_csv_table(
    path: Path, columns: Sequence[str], fix: str, numbers: Sequence[str] = (), **read_csv: object
) -> pd.DataFrame:
    """A CSV file of a run folder with the ``columns`` its readers use.

    Parameters
    ----------
    path : Path
    columns : sequence of str
        Columns the file must have.
    fix : str
        How to repair the file, for the error.
    numbers : sequence of str
        Columns whose every non-blank cell must be a number; returned as floats (a blank is NaN).
    **read_csv
        Passed to :func:`pandas.read_csv`.

    Raises
    ------
    SimbenchError
        Naming ``path``: missing, unreadable (empty, binary, a bad line), a missing column or a
        cell that is not a number.
    """
    try:
        table = pd.read_csv(path, **read_csv)
    except FileNotFoundError:
        raise SimbenchError(str(path), "is missing", fix) from None
    except OSError as exc:
        raise os_fault(exc, path, "cannot be read") from None
    except (ValueError, pd.errors.ParserError, UnicodeDecodeError) as exc:  # EmptyDataError is a ValueError
        raise SimbenchError(str(path), f"cannot be read ({str(exc).splitlines()[0]})", fix) from None
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise SimbenchError(str(path), f"has no column {', '.join(missing)} (damaged or not this file)", fix)
    for column in numbers:
        cells = table[column].replace("", None)
        values = pd.to_numeric(cells, errors="coerce")
        bad = cells[values.isna() & cells.notna()]
        if len(bad):
            raise SimbenchError(str(path), f"column {column} holds '{bad.iloc[0]}', not a number", fix)
        table[column] = values.astype(float)  # a blank cell is NaN, also where blanks are kept as text
    return table


@contextmanager
def staged_folder(out: Path) -> Iterator[Path]:
    """A temporary folder beside ``out`` to write into; its files move into ``out`` when the block ends.

    All or nothing: a fault while writing (a full disk) or an exception in the block removes the
    temporary folder and leaves ``out`` as it was; the files are moved in only once every one of
    them is written (renames within one file system, which do not fill a disk).

    Raises
    ------
    SimbenchError
        For a fault of the machine while making the folder or moving the files, naming the path.
    """
    out = Path(out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        staging = temporary_name(out)
        staging.mkdir()
    except OSError as exc:
        raise os_fault(exc, out) from None
    try:
        yield staging
        if not out.exists():
            staging.rename(out)
            return
        for file in sorted(staging.iterdir()):
            os.replace(file, out / file.name)
    except OSError as exc:
        name = Path(os.fspath(exc.filename)) if exc.filename is not None else None
        # named as the file it was to become, not by its temporary name
        if name is not None and name.is_relative_to(staging):
            exc.filename = str(out / name.relative_to(staging))
        raise os_fault(exc, out) from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
