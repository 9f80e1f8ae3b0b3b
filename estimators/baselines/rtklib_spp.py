"""RTKLIB single-point positioning: the external reference baseline on real logs and simulated scenarios.

``rtklib_spp`` hands RINEX files (``Need.rinex_files``) to RTKLIB's ``rnx2rtkp``
(Debian package ``rtklib``, 2.4.3) and scores its solutions like any other
estimator's: on a log read from RINEX the raw files it was read from
(:class:`~simbench.contract.RinexFiles`); on a simulated scenario the files
:func:`simbench.data.export.write_receiver_rinex` writes from the receiver's view
into a temporary directory (observations as simulated, the broadcast orbits the
signals came from; see :mod:`simbench.data.export.rinex`). RTKLIB's single mode (``pntpos``) is an independent
implementation of what a receiver does: per epoch, weighted least squares on
the L1 code (GPS C/A, BeiDou B1I) with broadcast orbits and clocks, the
Klobuchar ionosphere and the Saastamoinen troposphere, one clock offset per
system; it then rejects an epoch whose residuals fail its chi-square test or
whose GDOP exceeds 30, so on an urban log it leaves many epochs unsolved
(the runner counts them against availability).

Settings, written per run to an options file (``rnx2rtkp -k``): ``pos1-posmode
= single``, ``pos1-sateph = brdc``, ``pos1-elmask`` = ``elevation_mask_deg``
(10 deg), ``pos1-ionoopt`` from ``ionosphere`` (the ``gnss_model`` choice:
``brdc`` with ``pos1-frequency = l1``, or ``dual-freq`` with ``l1+l2`` where the
other estimators form the ionosphere-free combination), ``pos1-tropopt = saas``
(``troposphere``), ``pos1-posopt5`` (RAIM FDE) =
``raim_fde`` (off, RTKLIB's default), ``pos1-navsys`` from the systems the
scenario ingested; output ECEF, GPS time as week and seconds.

Each solution is matched to the scenario epoch nearest in GPS time. RTKLIB
stamps a solution with the receiver time tag minus its estimated receiver clock
offset, so the two differ by that offset (milliseconds); a solution further
than half the epoch interval from every epoch is dropped.

The pieces (:func:`rnx2rtkp_options`, :func:`run_rnx2rtkp`,
:func:`simbench.data.rtklib_pos.parse_rtklib_pos`, :func:`match_to_epochs`) take
files and times, not scenarios, so other RINEX sources can reuse them.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from estimators import register
from estimators.base import Estimator, solution_frame
from estimators.baselines.configs import IonosphereModel, RtklibSppConfig, TroposphereModel
from estimators.model.measurement import ionosphere_free
from estimators.model.ppp_config import IonosphereMode
from simbench.contract import Need, ReceiverData
from simbench.data.export import write_receiver_rinex
from simbench.data.rtklib_pos import parse_rtklib_pos
from simbench.data.solution_times import match_receiver_epochs
from simbench.errors import SimbenchError

__all__ = ["EXECUTABLE", "RtklibSpp", "rnx2rtkp_options", "run_rnx2rtkp"]

#: The RTKLIB post-processing program.
EXECUTABLE = "rnx2rtkp"
#: RTKLIB ``pos1-navsys`` bit of each RINEX system letter.
NAVSYS_BITS: dict[str, int] = {"G": 1, "S": 2, "R": 4, "E": 8, "J": 16, "C": 32, "I": 64}


_IONO_WORD = {IonosphereModel.broadcast: "brdc", IonosphereModel.free: "dual-freq", IonosphereModel.none: "off"}
_TROPO_WORD = {TroposphereModel.saastamoinen: "saas", TroposphereModel.none: "off"}


def rnx2rtkp_options(config: RtklibSppConfig, systems: str, dual_frequency: bool = False) -> dict[str, str]:
    """The ``rnx2rtkp -k`` options of a single-point run.

    Parameters
    ----------
    config : RtklibSppConfig
    systems : str
        RINEX system letters to use, e.g. ``'GC'``.
    dual_frequency : bool
        What ``ionosphere = auto`` resolves to on the rows (:func:`estimators.model.measurement.ionosphere_free`);
        ignored for the other choices.

    Returns
    -------
    dict of str to str
        RTKLIB option name to value.
    """
    unknown = sorted(set(systems) - set(NAVSYS_BITS))
    if not systems or unknown:
        raise SimbenchError(
            "scenario.systems",
            f"RTKLIB knows no system {unknown or repr(systems)}",
            f"use letters of '{''.join(NAVSYS_BITS)}'",
        )
    iono = config.ionosphere
    if iono == IonosphereModel.auto:
        iono = IonosphereModel.free if dual_frequency else IonosphereModel.broadcast
    return {
        "pos1-posmode": "single",
        "pos1-frequency": "l1+l2" if iono == IonosphereModel.free else "l1",
        "pos1-soltype": "forward",
        "pos1-elmask": f"{config.elevation_mask_deg:g}",
        "pos1-snrmask_r": "off",
        "pos1-dynamics": "off",
        "pos1-tidecorr": "off",
        "pos1-sateph": "brdc",
        "pos1-ionoopt": _IONO_WORD[iono],
        "pos1-tropopt": _TROPO_WORD[config.troposphere],
        "pos1-posopt5": "on" if config.raim_fde else "off",
        "pos1-exclsats": "",
        "pos1-navsys": str(sum(NAVSYS_BITS[s] for s in set(systems))),
        "out-solformat": "xyz",
        "out-outhead": "on",
        "out-timesys": "gpst",
        "out-timeform": "tow",
        "out-timendec": "3",
        "out-outstat": "off",
    }


def _last_line(text: str) -> str:
    """Last non-blank line of a tool's stderr (its progress lines end in carriage returns)."""
    lines = [ln.strip() for ln in text.replace("\r", "\n").splitlines() if ln.strip()]
    return lines[-1] if lines else "(no message)"


def run_rnx2rtkp(obs: str, navs: Sequence[str], options: Mapping[str, str], timeout_s: float) -> str:
    """Run ``rnx2rtkp`` in a temporary directory and return the text of its ``.pos`` output.

    Parameters
    ----------
    obs : str
        RINEX observation file.
    navs : sequence of str
        Navigation files.
    options : mapping of str to str
        Options file content (:func:`rnx2rtkp_options`).
    timeout_s : float
        Wall-time limit [s].

    Returns
    -------
    str
        The ``.pos`` file (header and at least one solution row).

    Raises
    ------
    SimbenchError
        A missing input file or executable, a timeout, a non-zero exit or an
        output without solutions; the message carries the tool's last stderr line.
    """
    for key, path in (("obs", obs), *(("nav", n) for n in navs)):
        if not Path(path).is_file():
            raise SimbenchError(
                f"scenario.rinex.{key}",
                f"'{path}' does not exist",
                "rerun from the RINEX files (the cached scenario points to moved files)",
            )
    with tempfile.TemporaryDirectory(prefix="rtklib_spp-") as tmp:
        conf, out = Path(tmp) / "spp.conf", Path(tmp) / "out.pos"
        conf.write_text("".join(f"{k}={v}\n" for k, v in options.items()))
        cmd = [EXECUTABLE, "-k", str(conf), "-o", str(out), obs, *navs]
        try:
            # check=False: a failed run is reported below with the tool's own last line
            proc = subprocess.run(
                cmd, cwd=tmp, capture_output=True, text=True, errors="replace", timeout=timeout_s, check=False
            )
        except FileNotFoundError:
            raise SimbenchError(
                "rtklib_spp", f"{EXECUTABLE} is not on PATH", "install RTKLIB (apt-get install rtklib)"
            ) from None
        except subprocess.TimeoutExpired:
            raise SimbenchError(
                "estimator.rtklib_spp.timeout_s",
                f"{EXECUTABLE} ran longer than {timeout_s:g} s",
                "raise timeout_s or shorten the log",
            ) from None
        text = out.read_text(errors="replace") if out.is_file() else ""
    if proc.returncode != 0:
        raise SimbenchError(
            "rtklib_spp",
            f"{EXECUTABLE} exited with code {proc.returncode}: {_last_line(proc.stderr)}",
            "check the RINEX files with rnx2rtkp by hand",
        )
    if not any(ln.strip() and not ln.startswith("%") for ln in text.splitlines()):
        raise SimbenchError(
            "rtklib_spp",
            f"{EXECUTABLE} wrote no solution: {_last_line(proc.stderr)}",
            "check that the navigation files cover the observations and the systems match",
        )
    return text


@register
class RtklibSpp(Estimator):
    """RTKLIB ``rnx2rtkp`` single-point solutions on the scenario's RINEX files (raw or exported)."""

    name = "rtklib_spp"
    Config = RtklibSppConfig
    requires = frozenset({Need.rinex_files})

    @classmethod
    def unavailable_reason(cls) -> str:
        if shutil.which(EXECUTABLE) is None:
            return f"{EXECUTABLE} (RTKLIB) is not on PATH; install it with apt-get install rtklib"
        return ""

    def _estimate(self, data: ReceiverData) -> tuple[pd.DataFrame, dict[str, Any]]:
        start = time.perf_counter()
        cfg: RtklibSppConfig = self.config
        with tempfile.TemporaryDirectory(prefix="rtklib_spp-export-") as tmp:
            files = data.rinex if data.rinex is not None else write_receiver_rinex(data, tmp, "receiver")
            auto_free = cfg.ionosphere == IonosphereModel.auto and ionosphere_free(
                data.observations, IonosphereMode.auto, cfg.elevation_mask_deg
            )
            options = rnx2rtkp_options(cfg, files.systems, auto_free)
            text = run_rnx2rtkp(files.obs, files.nav, options, cfg.timeout_s)
        pos = parse_rtklib_pos(text, f"{EXECUTABLE} output")
        si, ei, _ = match_receiver_epochs(data, pos["t_gps"].to_numpy())
        matched = pos.iloc[si]
        update_s = (time.perf_counter() - start) / max(si.size, 1)
        epochs = solution_frame(
            ei, data.epoch_times[ei], matched[["x", "y", "z"]].to_numpy(), np.full(si.size, update_s)
        )
        program = next((ln.split(":", 1)[1].strip() for ln in text.splitlines() if ln.startswith("% program")), "")
        diagnostics = {
            "program": program,
            "options": options,
            "files": "raw" if data.rinex is not None else "exported",
            "n_solutions": len(pos),
            "n_matched": int(si.size),
            "quality_counts": {str(k): int(v) for k, v in matched["q"].value_counts().sort_index().items()},
            "median_satellites": float(matched["ns"].median()) if len(matched) else float("nan"),
        }
        return epochs, diagnostics
