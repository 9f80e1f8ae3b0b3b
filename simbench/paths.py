"""Where the files a config names are found: the data home of the named logs, and the check that a file exists.

The named presets (``conf/scenario/hk_tst_2019.yaml``, ``nagoya_static.yaml``, ``morgantown1.yaml``, ...)
name their files as ``${simbench_data:hk_tst_2019/COM3_190428_124409.obs}``, a path inside the
data home (:func:`data_home`): the folder :data:`DATA_HOME_ENV` names, else ``shared/data`` beside
the repository. So a preset runs from any working directory, while a path given on the command
line (``scenario.obs=a.obs``) is the user's own and starts at the working directory.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from simbench.contract import file_sha256
from simbench.errors import SimbenchError

__all__ = ["DATA_HOME_ENV", "REPO_ROOT", "data_home", "data_path", "require_file", "file_digest"]

#: Environment variable naming the data home: the folder that holds ``hk_tst_2019/``, ``nagoya_static/``, ...
DATA_HOME_ENV = "SIMBENCH_DATA"
#: The repository root (the parent of the ``simbench`` package and of ``conf/``).
REPO_ROOT = Path(__file__).resolve().parents[1]


def data_home(environ: Mapping[str, str] = os.environ) -> Path:
    """The folder the named presets read their logs from: ``$SIMBENCH_DATA``, else ``<repository>/../shared/data``.

    A relative ``$SIMBENCH_DATA`` starts at the working directory; the result is absolute.
    """
    given = environ.get(DATA_HOME_ENV, "")
    return Path(given).expanduser().resolve() if given else (REPO_ROOT.parent / "shared" / "data").resolve()


def data_path(relative: str) -> str:
    """``relative`` inside :func:`data_home`: the ``${simbench_data:...}`` of the presets (absolute)."""
    return str(data_home() / relative)


def require_file(field: str, path: str) -> None:
    """Raise a one-line :class:`SimbenchError` unless ``path`` is an existing file.

    The message names the setting, the path as given and as tried (absolute), and the fix: for a
    path inside the data home, :data:`DATA_HOME_ENV`; for any other, the working directory a
    relative path starts at.

    Parameters
    ----------
    field : str
        The setting that named the file (``scenario.obs``).
    path : str
        The path as the config holds it.

    Raises
    ------
    SimbenchError
        For a missing file or a folder.
    """
    if os.path.isfile(path):
        return
    tried = Path(path).absolute()
    problem = "is a folder, not a file" if tried.is_dir() else "file does not exist"
    where = f"{field} '{path}'" if str(tried) == path else f"{field} '{path}' (tried {tried})"
    home = data_home()
    if tried.is_relative_to(home):
        now = f"{DATA_HOME_ENV}={os.environ[DATA_HOME_ENV]}" if os.environ.get(DATA_HOME_ENV) else "the default"
        folder = tried.relative_to(home).parts[0]
        fix = (
            f"the named logs are read from the data home {home} ({now}); put {folder}/ there, "
            f"or set {DATA_HOME_ENV} to the folder that holds {folder}/"
        )
    else:
        fix = (
            f"check the path (a relative path starts at the working directory {Path.cwd()}; "
            f"'${{simbench_data:<folder>/<file>}}' names a file of the data home {home}, set by {DATA_HOME_ENV})"
        )
    raise SimbenchError(where, problem, fix)


#: Digests already taken in this process, by (absolute path, size, modification time in ns).
_DIGESTS: dict[tuple[str, int, int], str] = {}


def file_digest(path: str) -> str:
    """SHA-256 of a file's content (hex, 16 digits), for cache keys that follow a file edited in place.

    A file's digest is taken again only when its size or modification time changed since this
    process last read it (a Hong Kong observation file of 3.6 MB hashes in ~2 ms).

    Parameters
    ----------
    path : str
        An existing file (checked before: :func:`require_file`).
    """
    st = os.stat(path)
    stamp = (os.path.abspath(path), st.st_size, st.st_mtime_ns)
    if stamp not in _DIGESTS:
        _DIGESTS[stamp] = file_sha256(Path(path))[:16]
    return _DIGESTS[stamp]
