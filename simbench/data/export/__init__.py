"""Export any scenario for other tools: RINEX 3.04 (observations, navigation, reference CSV), libRSF text,
or an Android GnssLogger Raw log (with the RINEX navigation file and the reference CSV).

``python -m simbench export scenario=urban receiver=low seed=0 format=rinex out=DIR``
(:mod:`simbench.cli.export`). The writers of the receiver's files take
:class:`~simbench.contract.ReceiverData` only (:func:`write_receiver_rinex`,
:func:`simbench.data.export.librsf.write_librsf`), so an estimator may call them
(``rtklib_spp``); the truth goes through separate functions
(:func:`simbench.data.export.truth.write_truth_csv`,
:func:`simbench.data.export.librsf.append_librsf_truth`).
Formats: :mod:`simbench.data.export.rinex`, :mod:`simbench.data.export.librsf`,
:mod:`simbench.data.export.gnsslogger`, :mod:`simbench.data.export.truth`.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from simbench.contract import ReceiverData, RinexFiles, Scenario
from simbench.core.constants import SECONDS_PER_WEEK
from simbench.data.export.gnsslogger import write_gnsslogger
from simbench.data.export.librsf import append_librsf_truth, write_librsf
from simbench.data.export.rinex import write_broadcast_navigation, write_nominal_navigation, write_rinex_obs
from simbench.data.export.truth import write_truth_csv
from simbench.errors import SimbenchError
from simbench.typed import Choice

__all__ = ["ExportFormat", "export_scenario", "write_receiver_rinex", "write_receiver_navigation"]


class ExportFormat(Choice):
    """File format of an export (member names are the command-line words)."""

    rinex = "rinex"  #: RINEX 3.04 observation + navigation files and the reference CSV
    librsf = "librsf"  #: libRSF text: pseudorange3, odom3, point3
    gnsslogger = "gnsslogger"  #: Android GnssLogger Raw log, RINEX 3.04 navigation file(s), reference CSV


def write_receiver_rinex(
    data: ReceiverData, out_dir: str | os.PathLike[str], stem: str = "simbench", *, receiver: str = "simbench"
) -> RinexFiles:
    """Write the RINEX observation and navigation files of a receiver's view.

    Parameters
    ----------
    data : ReceiverData
    out_dir : str or PathLike
        Directory (created if needed).
    stem : str
        File name stem: ``<stem>.obs``, ``<stem>.nav``.
    receiver : str
        Receiver type for the observation header.

    Returns
    -------
    RinexFiles
        Absolute paths; navigation files of a log read from RINEX are copied as they are.

    Raises
    ------
    SimbenchError
        When the scenario names no broadcast orbits (``NavInfo.ephemeris``, e.g. libRSF logs).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    obs_path = write_rinex_obs(out / f"{stem}.obs", data, marker=stem, receiver=receiver)
    systems = "".join(sorted(set(data.observations["sat"].str[0])))
    navs = write_receiver_navigation(data, out, stem)
    return RinexFiles(obs=os.path.abspath(obs_path), nav=tuple(os.path.abspath(n) for n in navs), systems=systems)


def write_receiver_navigation(data: ReceiverData, out_dir: str | os.PathLike[str], stem: str) -> tuple[Path, ...]:
    """The navigation file(s) of a receiver's view: those of a log read from RINEX copied as they are, else
    ``<stem>.nav`` with the nominal constellation or the scenario's broadcast records.

    Raises
    ------
    SimbenchError
        When the scenario names no broadcast orbits (``NavInfo.ephemeris``, e.g. libRSF logs).
    """
    out = Path(out_dir)
    if data.rinex is not None:
        return tuple(Path(shutil.copyfile(n, out / Path(n).name)) for n in data.rinex.nav)
    if data.nav.ephemeris == "nominal":
        t = data.observations["t"].to_numpy(float)
        t0 = data.nav.gps_week * SECONDS_PER_WEEK + data.nav.start_sow_s
        return (write_nominal_navigation(out / f"{stem}.nav", data.nav, t0 + t.min(), t0 + t.max()),)
    if data.nav.ephemeris:
        return (write_broadcast_navigation(out / f"{stem}.nav", data.nav, data.nav.ephemeris),)
    raise SimbenchError(
        "export",
        "the scenario names no broadcast orbits for a navigation file (a libRSF log carries satellite positions only)",
        "export it with format=librsf",
    )


def export_scenario(
    scenario: Scenario,
    fmt: ExportFormat | str,
    out_dir: str | os.PathLike[str],
    stem: str = "simbench",
    *,
    receiver: str = "simbench",
) -> list[Path]:
    """Write a scenario's receiver files and its reference trajectory.

    Parameters
    ----------
    scenario : Scenario
    fmt : ExportFormat or str
        ``rinex``: ``<stem>.obs``, ``<stem>.nav`` and ``<stem>_truth.csv``;
        ``librsf``: ``<stem>.txt`` with pseudorange3, odom3 and point3 lines;
        ``gnsslogger``: ``<stem>_gnss_log.txt`` (Raw lines, :mod:`simbench.data.export.gnsslogger`), the
        navigation file(s) as for ``rinex`` and ``<stem>_truth.csv``.
    out_dir : str or PathLike
    stem : str
        File name stem.
    receiver : str
        Receiver type for the RINEX header.

    Returns
    -------
    list of Path
        The files written.
    """
    try:
        fmt = ExportFormat(fmt)
    except ValueError:
        raise SimbenchError(
            "format", f"unknown export format '{fmt}'", f"choose from {', '.join(f.value for f in ExportFormat)}"
        ) from None
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    data = scenario.receiver_view()
    if fmt in (ExportFormat.rinex, ExportFormat.gnsslogger):
        if fmt == ExportFormat.rinex:
            files = write_receiver_rinex(data, out, stem, receiver=receiver)
            written = [Path(files.obs), *map(Path, files.nav)]
        else:
            written = [
                write_gnsslogger(out / f"{stem}_gnss_log.txt", data),
                *write_receiver_navigation(data, out, stem),
            ]
        if len(scenario.truth):
            written.append(write_truth_csv(out / f"{stem}_truth.csv", scenario.truth, scenario.nav))
        return written
    path = write_librsf(out / f"{stem}.txt", data)
    if len(scenario.truth):
        append_librsf_truth(path, scenario.truth)
    return [path]
