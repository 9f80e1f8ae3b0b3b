"""A report page that a rebuild has not replaced (yet) says so: never an old page shown as if current.

:func:`mark_stale` puts a banner at the top of ``report/index.html`` and ``report/README.md``
before a rebuild computes anything; the rebuilt page replaces both files whole, banner and all.
A rebuild that is killed, or fails on a full disk or a read-only folder, leaves the banner; a page
that cannot be marked (a full disk) is removed.
:func:`check_report_dir` refuses a report folder that cannot be written before the rebuild starts,
in one line that says whether the old page could be marked.
"""

from __future__ import annotations

from datetime import datetime, timezone
from pathlib import Path

from simbench.contract import write_bytes
from simbench.errors import SimbenchError
from simbench.runs.files import FAULT_FIXES, write_fault

#: The id of the banner's element: a page holding it is stale.
STALE_ID = "simbench-stale"
#: The first line of a stale README.md.
STALE_README = "> **Stale:**"


def mark_stale(out: Path, run_dir: Path) -> str:
    """Mark the page in the report folder ``out`` as stale, or remove it; what became of it.

    The banner is written atomically where the folder allows, else in place (a folder that is
    read-only while its files are not); where neither can be done (a full disk) the page is removed.

    Returns
    -------
    str
        ``''`` when there is no page; else ``marked stale``, ``removed``, or ``could not be marked
        stale or removed`` (an immutable folder or a read-only mount).
    """
    page = out / "index.html"
    if not page.is_file():
        return ""
    when = datetime.now(timezone.utc).isoformat(timespec="seconds")
    say = (
        f"a rebuild of this report began {when} and did not finish: what follows is from an earlier build "
        f"and may not match the results. Rebuild it: python -m simbench report {run_dir}"
    )
    banner = (
        f"<p id='{STALE_ID}' style='background:#f8d4d0;border:2px solid #c00;padding:0.5em'><b>Stale:</b> {say}</p>"
    )
    done = "marked stale"
    for path, mark in (
        (page, lambda text: text.replace("<body>", "<body>" + banner, 1)),
        (out / "README.md", lambda text: f"{STALE_README} {say}\n\n{text}"),
    ):
        if not path.is_file():
            continue
        try:
            text = path.read_text(errors="replace")
        except OSError:
            text = ""
        if STALE_ID in text or text.startswith(STALE_README):
            continue
        if not (text and _write(path, mark(text))):
            done = _remove(path) if path == page else done
    return done


def _write(path: Path, text: str) -> bool:
    """``text`` into ``path``: atomically, else in place; False when neither can be done."""
    try:
        write_bytes(path, text.encode())
        return True
    except OSError:
        pass
    try:
        path.write_text(text)
        return True
    except OSError:
        return False


def _remove(page: Path) -> str:
    """Remove a page that cannot be marked stale: what became of it."""
    try:
        page.unlink()
        return "removed"
    except OSError:
        return "could not be marked stale or removed"


def check_report_dir(out: Path, run_dir: Path) -> None:
    """Raise a one-line :class:`SimbenchError` unless ``run_dir`` and the report folder ``out`` can be written.

    Checked before a rebuild computes anything; an old page that cannot be rebuilt is marked stale
    (:func:`mark_stale`) where that is possible, and the message says whether it is.
    """
    if out.exists() and not out.is_dir():
        fix = f"move it away and rebuild: python -m simbench report {run_dir}"
        raise SimbenchError(str(out), "is a file, not the report folder", fix)
    for folder in (run_dir, out):
        fault = write_fault(folder) if folder.is_dir() else None
        if fault is not None:
            raise SimbenchError(
                str(folder),
                f"cannot be written ({fault.strerror}){old_page(out, run_dir)}",
                f"{FAULT_FIXES.get(fault.errno or 0, 'make it writable')}, then: python -m simbench report {run_dir}",
            )


def old_page(out: Path, run_dir: Path) -> str:
    """What became of the page in ``out`` that a failed rebuild did not replace (:func:`mark_stale`), for
    the end of its error line; ``''`` when there is none."""
    done = mark_stale(out, run_dir)
    return f"; the page of an earlier build, {out / 'index.html'}, {done}" if done else ""
