"""The data contract between generator, estimators and metrics.

A :class:`Scenario` holds five tables. Three of them are what a receiver gives an
estimator (:class:`ReceiverData`): the observation, IMU and odometry tables
(the last with zero rows when the vehicle has no odometry).
The other two are truth: the trajectory and the per-observation error labels.
Estimators only ever receive :class:`ReceiverData`; the runner hands labels
only to estimators that require :attr:`Need.labels` (the oracle), and skips an
estimator whose :class:`Need` a scenario does not offer (:func:`available_needs`).

Every column, its unit and its meaning is listed in the ``*_COLUMNS`` dicts
below; docs/contract.md's tables restate them (tests/test_readme.py checks every column is there).
An observation table may also carry the :data:`OPTIONAL_OBSERVATION_COLUMNS`, after the others;
a consumer treats an absent one as all NaN.
"""

from __future__ import annotations

import hashlib
import json
import os
import uuid
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from simbench.errors import SimbenchError

#: Observation table, one row per (epoch, satellite) that the receiver tracks.
OBSERVATION_COLUMNS: dict[str, str] = {
    "epoch": "int, GNSS epoch index (0-based)",
    "t": "s, receive time since scenario start (GPS time scale)",
    "sat": "str, satellite id, e.g. 'G05'",
    "code_l1": "m, L1 C/A pseudorange",
    "phase_l1": "m, L1 carrier phase (cycles times wavelength; contains an integer ambiguity)",
    "doppler_l1": "Hz, L1 Doppler (positive for an approaching satellite)",
    "cn0_l1": "dB-Hz, L1 carrier-to-noise density",
    "lli_l1": "bool, loss-of-lock indicator: the receiver flags a possible slip since the last epoch",
    "code_l2": "m, second-frequency pseudorange: GPS L2 or L5, Galileo E5a or E5b, BeiDou B3I or B2I, "
    "GLONASS G2 (NaN when single-frequency)",
    "phase_l2": "m, second-frequency carrier phase (NaN when single-frequency)",
    "lli_l2": "bool, second-frequency loss-of-lock indicator",
    "f1_f2_ratio": "1, ratio of the carrier frequencies of the *_l1 and *_l2 signals of this row (NaN without "
    "a second frequency): 154/120 GPS L1/L2, 154/115 L1/L5 and E1/E5a, 154/118 E1/E5b, 9/7 GLONASS, "
    "1561.098/1268.52 BeiDou B1I/B3I, 1561.098/1207.14 B1I/B2I",
    "sat_x": "m, satellite ECEF x at transmit time, Earth-fixed frame of transmit time (product)",
    "sat_y": "m, satellite ECEF y (as sat_x)",
    "sat_z": "m, satellite ECEF z (as sat_x)",
    "sat_vx": "m/s, satellite ECEF velocity x",
    "sat_vy": "m/s, satellite ECEF velocity y",
    "sat_vz": "m/s, satellite ECEF velocity z",
    "sat_clock": "m, satellite clock offset times c (product, relativistic term included; add to code)",
    "sat_clock_drift": "m/s, satellite clock drift times c",
    "el": "deg, elevation from the receiver's approximate position",
    "az": "deg, azimuth clockwise from north",
}

#: Observation columns a source writes when it knows them (the RINEX reader does; the simulator and
#: libRSF logs do not): appended after :data:`OBSERVATION_COLUMNS`; NaN or absent counts as 0.
OPTIONAL_OBSERVATION_COLUMNS: dict[str, str] = {
    "sat_dcb": "m, c (T2 - T1): broadcast group delay of the *_l2 signal minus that of the *_l1 signal, clock "
    "reference of the broadcast message (GPS/QZSS L1/L2 (gamma - 1) c TGD, Galileo (gamma - 1) c BGD of the pair, "
    "BeiDou B1I/B3I -c TGD1, B1I/B2I c (TGD2 - TGD1), gamma = f1_f2_ratio^2); the ionosphere-free clock is "
    "sat_clock + sat_dcb / (gamma - 1). NaN where nothing is broadcast (GLONASS, GPS/QZSS L5) or without a second "
    "frequency",
    "sat_dcb_sigma": "m, stated RMS of what sat_dcb misses of the row's two codes' group-delay difference: the "
    "inter-signal biases no broadcast message of the file gives (GPS/QZSS C/A against the P(Y) code TGD refers "
    "to, L2C against P2, L5), 0 where the message gives the pair's (Galileo BGD, BeiDou TGD, GPS P1/P2); NaN "
    "where nothing is stated (GLONASS) or without a second frequency",
}

#: IMU table, one row per IMU sample; body axes x forward, y right, z down.
IMU_COLUMNS: dict[str, str] = {
    "t": "s, sample time since scenario start",
    "ax": "m/s^2, specific force along body x",
    "ay": "m/s^2, specific force along body y",
    "az": "m/s^2, specific force along body z",
    "gx": "rad/s, angular rate about body x (w.r.t. inertial space)",
    "gy": "rad/s, angular rate about body y",
    "gz": "rad/s, angular rate about body z",
}

#: Odometry table, one row per odometry sample (wheel speed and yaw rate, and whatever else the vehicle
#: reports, e.g. every component of libRSF ``odom3``); zero rows when the vehicle gives none. Body axes as
#: the IMU table: x forward, y right, z down.
ODOMETRY_COLUMNS: dict[str, str] = {
    "t": "s, sample time since scenario start (GPS time scale; may precede the first epoch)",
    "speed": "m/s, speed over ground along body x (forward; negative when reversing)",
    "yaw_rate": "rad/s, turn rate about body z (down) w.r.t. the Earth: positive turning right "
    "(clockwise seen from above)",
    "var_speed": "m^2/s^2, variance of speed as the vehicle reports it (not the true error)",
    "var_yaw_rate": "rad^2/s^2, variance of yaw_rate as the vehicle reports it",
    "vel_right": "m/s, velocity along body y (right) as the vehicle reports it; NaN when it reports none "
    "(a car's odometry may report 0: its non-holonomic constraint)",
    "vel_down": "m/s, velocity along body z (down) as the vehicle reports it; NaN when it reports none",
    "roll_rate": "rad/s, turn rate about body x (forward); NaN when the vehicle reports none",
    "pitch_rate": "rad/s, turn rate about body y (right); NaN when the vehicle reports none",
    "var_vel_right": "m^2/s^2, variance of vel_right as the vehicle reports it; NaN with vel_right",
    "var_vel_down": "m^2/s^2, variance of vel_down as the vehicle reports it; NaN with vel_down",
    "var_roll_rate": "rad^2/s^2, variance of roll_rate as the vehicle reports it",
    "var_pitch_rate": "rad^2/s^2, variance of pitch_rate as the vehicle reports it",
}

#: The odometry columns a vehicle may leave out (NaN): all but the wheel speed and yaw rate a car always gives.
ODOMETRY_OPTIONAL_COLUMNS: tuple[str, ...] = tuple(list(ODOMETRY_COLUMNS)[5:])

#: Truth trajectory, one row per GNSS epoch.
TRUTH_COLUMNS: dict[str, str] = {
    "epoch": "int, GNSS epoch index",
    "t": "s, time since scenario start",
    "x": "m, antenna ECEF x",
    "y": "m, antenna ECEF y",
    "z": "m, antenna ECEF z",
    "vx": "m/s, ECEF velocity x",
    "vy": "m/s, ECEF velocity y",
    "vz": "m/s, ECEF velocity z",
    "roll": "rad, body roll w.r.t. local NED",
    "pitch": "rad, body pitch",
    "yaw": "rad, heading from north",
    "rx_clock": "m, true receiver clock offset times c",
    "zwd": "m, true zenith wet delay",
    "n_visible": "int, satellites above the elevation mask before any masking",
}

#: Error labels, one row per observation row (same order, same epoch and sat).
LABEL_COLUMNS: dict[str, str] = {
    "epoch": "int, GNSS epoch index",
    "sat": "str, satellite id",
    "sigma_code_l1": "m, true DLL tracking jitter std of this observation",
    "sigma_phase_l1": "m, true PLL tracking jitter std",
    "multipath_code_l1": "m, true code multipath error (diffuse process + the DLL's error on the canyon rays)",
    "sigma_multipath_code_l1": "m, std of the code multipath of this observation (process std and canyon-ray RMS)",
    "multipath_phase_l1": "m, true carrier multipath error",
    "nlos": "bool, non-line-of-sight: the direct ray is masked and the loops lock to a reflection",
    "nlos_delay": "m, extra path of the ray the loops lock to (a reflection; cm for a ray diffracted over a roof)",
    "iono_l1": "m, true slant ionospheric delay on L1 (code +, phase -)",
    "tropo": "m, true slant tropospheric delay",
    "orbit_clock_error": "m, line-of-sight projection of (true - product) orbit plus clock error",
    "ambiguity_l1": "cycles, true integer L1 ambiguity",
    "ambiguity_l2": "cycles, true integer L2 ambiguity (0 when single-frequency)",
    "slip": "bool, a true cycle slip happened at this epoch",
    "noise_code_l1": "m, the thermal noise sample added to the code",
    "noise_phase_l1": "m, the thermal noise sample added to the phase",
    "sample_grid_code_l1": "m, code error of the DLL seeing the code phase on the sample grid",
}

RECEIVER_COLUMNS = (
    frozenset(OBSERVATION_COLUMNS)
    | frozenset(OPTIONAL_OBSERVATION_COLUMNS)
    | frozenset(IMU_COLUMNS)
    | frozenset(ODOMETRY_COLUMNS)
)
TRUTH_ONLY_COLUMNS = (frozenset(TRUTH_COLUMNS) | frozenset(LABEL_COLUMNS)) - frozenset(OBSERVATION_COLUMNS)


def empty_odometry() -> pd.DataFrame:
    """The odometry table of a vehicle without odometry: zero rows, :data:`ODOMETRY_COLUMNS`."""
    return pd.DataFrame({c: np.zeros(0) for c in ODOMETRY_COLUMNS})


@dataclass(frozen=True)
class NavInfo:
    """Broadcast information a receiver decodes besides the observables.

    Attributes
    ----------
    gps_week : int
        GPS week of the scenario start.
    start_sow_s : float
        GPS seconds of week at ``t = 0`` [s].
    iono_alpha, iono_beta : tuple of 4 float
        Klobuchar coefficients (IS-GPS-200 units).
    dual_frequency : bool
        Whether L2 observables are present.
    iono_corrected : bool
        The code and phase already have the ionospheric delay removed (e.g.
        libRSF files); the broadcast Klobuchar delay must not be removed again.
    ephemeris : str
        The broadcast orbits the satellite states come from, for tools that need
        a navigation file (:mod:`simbench.data.export`): ``'nominal'`` (the simulator's
        nominal constellation), the path of a RINEX GPS navigation file, or
        ``''`` when unknown (libRSF logs, whose files carry satellite positions only).
    """

    gps_week: int
    start_sow_s: float
    iono_alpha: tuple[float, ...]
    iono_beta: tuple[float, ...]
    dual_frequency: bool
    iono_corrected: bool = False
    ephemeris: str = ""


@dataclass(frozen=True)
class RinexFiles:
    """The raw RINEX files a real-log scenario was read from, for estimators that run external
    tools on them (``rtklib_spp``); absolute paths, so a cached scenario still finds them.

    Attributes
    ----------
    obs : str
        RINEX observation file.
    nav : tuple of str
        Navigation files of the ingested systems (GPS first).
    systems : str
        System letters the scenario ingested, e.g. ``'GC'``.
    """

    obs: str
    nav: tuple[str, ...]
    systems: str


@dataclass(frozen=True)
class ReceiverData:
    """Everything an estimator may see: observations, IMU, navigation info and, for a log read
    from RINEX, the raw files (``rinex``; None otherwise); ``odometry`` (:data:`ODOMETRY_COLUMNS`)
    has zero rows when the vehicle gives none, so ``if len(data.odometry):`` tells."""

    observations: pd.DataFrame
    imu: pd.DataFrame
    nav: NavInfo
    rinex: RinexFiles | None = None
    odometry: pd.DataFrame = field(default_factory=empty_odometry)

    def __post_init__(self) -> None:
        leaked = (
            set(self.observations.columns) | set(self.imu.columns) | set(self.odometry.columns)
        ) - RECEIVER_COLUMNS
        if leaked:
            raise ValueError(f"receiver data carries non-receiver columns {sorted(leaked)}")

    @property
    def epoch_times(self) -> np.ndarray:
        """Receive time of each epoch index 0..n-1 [s]; NaN for epochs with no observation."""
        obs = self.observations
        n = int(obs["epoch"].max()) + 1 if len(obs) else 0
        out = np.full(n, np.nan)
        out[obs["epoch"].to_numpy()] = obs["t"].to_numpy()
        return out


@dataclass(frozen=True)
class Scenario:
    """A generated (or ingested) scenario: receiver view plus truth.

    Attributes
    ----------
    observations, imu : pandas.DataFrame
        Receiver view, columns :data:`OBSERVATION_COLUMNS`, :data:`IMU_COLUMNS`.
    truth : pandas.DataFrame
        Per-epoch truth, :data:`TRUTH_COLUMNS`.
    labels : pandas.DataFrame or None
        Per-observation error labels, :data:`LABEL_COLUMNS`, row-aligned with
        ``observations``; None for real data.
    nav : NavInfo
    meta : dict
        ``name``, ``seed``, ``config`` (the resolved simulation config as a
        plain dict) and anything else worth keeping with the data.
    rinex : RinexFiles or None
        The raw RINEX files of a log read from RINEX (:func:`simbench.data.rinex.load_rinex`).
    odometry : pandas.DataFrame
        Receiver view, :data:`ODOMETRY_COLUMNS`; zero rows when there is no odometry.
    """

    observations: pd.DataFrame
    imu: pd.DataFrame
    truth: pd.DataFrame
    labels: pd.DataFrame | None
    nav: NavInfo
    meta: dict[str, Any] = field(default_factory=dict)
    rinex: RinexFiles | None = None
    odometry: pd.DataFrame = field(default_factory=empty_odometry)

    def receiver_view(self) -> ReceiverData:
        """What an estimator receives: no truth and no labels."""
        return ReceiverData(self.observations, self.imu, self.nav, rinex=self.rinex, odometry=self.odometry)

    @property
    def n_epochs(self) -> int:
        return len(self.truth)

    # ------------------------------------------------------------------ Parquet I/O

    def save(self, directory: str | Path, key: str = "") -> Path:
        """Write the five tables as Parquet files into ``directory`` (atomic per file).

        The nav info and ``meta`` go into each file's key-value metadata under
        ``simbench.scenario``; :data:`MANIFEST` names the sha256 of each table and, when given,
        the cache ``key`` the folder is saved under (:data:`MANIFEST_KEY`), so a moved folder is told.
        """
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        meta = {
            "nav": self.nav.__dict__,
            "meta": self.meta,
            "rinex": None if self.rinex is None else self.rinex.__dict__,
        }
        for name in ("observations", "imu", "truth", "labels", "odometry"):
            table = getattr(self, name)
            if table is not None:
                write_parquet(table, out / f"{name}.parquet", {"simbench.scenario": meta})
        # written last, so a folder with a manifest is complete; readers check its tables against it
        tables = {p.name: file_sha256(p) for p in sorted(out.glob("*.parquet"))}
        write_bytes(out / MANIFEST, json.dumps(({MANIFEST_KEY: key} if key else {}) | tables).encode())
        return out

    @classmethod
    def load(cls, directory: str | Path) -> Scenario:
        """Read a scenario written by :meth:`save`."""
        src = Path(directory)
        if not (src / "observations.parquet").is_file():
            raise SimbenchError(
                "scenario", f"no observations.parquet in {src}", "point to a directory written by Scenario.save"
            )
        tables = {
            n: pd.read_parquet(src / f"{n}.parquet") if (src / f"{n}.parquet").is_file() else None
            for n in ("observations", "imu", "truth", "labels", "odometry")
        }
        meta = read_parquet_metadata(src / "observations.parquet")["simbench.scenario"]
        nav = meta["nav"]
        nav = NavInfo(**{**nav, "iono_alpha": tuple(nav["iono_alpha"]), "iono_beta": tuple(nav["iono_beta"])})
        rinex = meta.get("rinex")
        rinex = None if rinex is None else RinexFiles(**{**rinex, "nav": tuple(rinex["nav"])})
        odometry = tables["odometry"] if tables["odometry"] is not None else empty_odometry()
        return cls(
            tables["observations"],
            tables["imu"],
            tables["truth"],
            tables["labels"],
            nav,
            meta["meta"],
            rinex=rinex,
            odometry=odometry,
        )


class Need(str, Enum):
    """An input an estimator may require and a scenario may or may not offer.

    Estimators declare theirs (``Estimator.requires``); the runner compares
    them with :func:`available_needs` and skips an estimator whose needs the
    scenario cannot meet. Defined here, not in ``estimators/``, because
    ``simbench/`` never imports ``estimators/``.
    """

    #: L1 carrier-phase rows (any finite ``phase_l1``).
    phase = "phase"
    #: An IMU table with at least two samples.
    imu = "imu"
    #: The per-observation error labels (only the oracle).
    labels = "labels"
    #: L2 code and phase (``nav.dual_frequency`` and any finite ``code_l2``).
    dual_frequency = "dual_frequency"
    #: RINEX files for external tools: those a log was read from (``Scenario.rinex``), or written by
    #: :mod:`simbench.data.export` from the observations and the broadcast orbits (``NavInfo.ephemeris``).
    rinex_files = "rinex_files"


#: Why a scenario lacks each need, phrased for the ``message`` column of a skipped row.
MISSING_NEED_REASONS: dict[Need, str] = {
    Need.phase: "needs carrier phase; the observations have none (a code-only log)",
    Need.imu: "needs an IMU table; the scenario has fewer than 2 IMU samples (a GNSS-only log)",
    Need.labels: "needs error labels; the scenario (real data) has none",
    Need.dual_frequency: "needs L2 code and phase; the observations are single-frequency",
    Need.rinex_files: "needs RINEX files; the scenario was not read from RINEX and has no broadcast orbits to "
    "export (a libRSF log)",
}


def available_needs(scenario: Scenario) -> frozenset[Need]:
    """The :class:`Need` members ``scenario`` can satisfy.

    Parameters
    ----------
    scenario : Scenario

    Returns
    -------
    frozenset of Need
    """
    obs = scenario.observations
    offered = set()
    if "phase_l1" in obs and np.isfinite(obs["phase_l1"].to_numpy(dtype=float)).any():
        offered.add(Need.phase)
    if scenario.imu is not None and len(scenario.imu) >= 2:
        offered.add(Need.imu)
    if scenario.labels is not None:
        offered.add(Need.labels)
    if scenario.nav.dual_frequency and "code_l2" in obs and np.isfinite(obs["code_l2"].to_numpy(dtype=float)).any():
        offered.add(Need.dual_frequency)
    if scenario.rinex is not None or scenario.nav.ephemeris:
        offered.add(Need.rinex_files)
    return frozenset(offered)


def unmet_needs_reason(needs: frozenset[Need], offered: frozenset[Need]) -> str:
    """One line saying which of ``needs`` a scenario offering ``offered`` (:func:`available_needs`)
    cannot meet and why; ``""`` when all are met."""
    missing = needs - offered
    return "; ".join(MISSING_NEED_REASONS[n] for n in Need if n in missing)


def write_parquet(df: pd.DataFrame, path: str | Path, metadata: dict[str, Any] | None = None) -> Path:
    """Write ``df`` to Parquet atomically, with JSON ``metadata`` in the file's key-value metadata.

    The file is written under a temporary name of its own next to ``path`` and
    renamed, so readers never see a half-written file and concurrent writers of
    one path never share a temporary file (the last rename wins). Every data page
    carries a CRC checksum, which readers may verify (``page_checksum_verification``),
    and the key-value metadata its sha256 (:data:`METADATA_SHA256`, :func:`metadata_sha256`).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    table = pa.Table.from_pandas(df, preserve_index=False)
    extra = {k.encode(): json.dumps(v, default=json_default).encode() for k, v in (metadata or {}).items()}
    kv = {**(table.schema.metadata or {}), **extra}
    table = table.replace_schema_metadata({**kv, METADATA_SHA256.encode(): json.dumps(metadata_sha256(kv)).encode()})
    tmp = temporary_name(path)
    try:
        pq.write_table(table, tmp, write_page_checksum=True)
        os.replace(tmp, path)
    except OSError as exc:
        if exc.filename is None:  # pyarrow's errors (a full disk) name no file: name the one being written
            exc.filename = str(path)
        raise
    finally:
        tmp.unlink(missing_ok=True)
    return path


def temporary_name(path: Path) -> Path:
    """A name beside ``path`` that no other writer uses (hidden; ends in ``.tmp``).

    Not :func:`tempfile.mkstemp`: its files are private (mode 0600), and the renamed file must
    get the permissions any other file of the run gets.
    """
    return path.with_name(f".{path.name}.{uuid.uuid4().hex}.tmp")


#: The file of a saved scenario (:meth:`Scenario.save`) naming the sha256 of each of its tables.
MANIFEST = "manifest.json"
#: The manifest's entry naming the cache key its folder was saved under (not a file).
MANIFEST_KEY = "scenario_key"


def file_sha256(path: Path) -> str:
    """sha256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def write_bytes(path: Path, data: bytes) -> None:
    """Atomic write: a temporary file of its own in the same folder, renamed over ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_name(path)
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


#: Key-value metadata entry of a file :func:`write_parquet` wrote: the sha256 of the other entries.
METADATA_SHA256 = "simbench.metadata_sha256"


def metadata_sha256(kv: dict[bytes, bytes]) -> str:
    """sha256 of a Parquet file's key-value metadata, in key order, without :data:`METADATA_SHA256`."""
    digest = hashlib.sha256()
    for key in sorted(k for k in kv if k != METADATA_SHA256.encode()):
        digest.update(len(key).to_bytes(8, "little") + key + len(kv[key]).to_bytes(8, "little") + kv[key])
    return digest.hexdigest()


def read_parquet_metadata(path: str | Path) -> dict[str, Any]:
    """Return the JSON key-value metadata written by :func:`write_parquet`."""
    return decode_metadata(pq.read_schema(path).metadata)


def decode_metadata(raw: Mapping[bytes, bytes] | None) -> dict[str, Any]:
    """The ``simbench.*`` entries of an Arrow schema's key-value metadata, JSON-decoded."""
    out = {}
    for k, v in (raw or {}).items():
        key = k.decode()
        if key.startswith("simbench."):
            out[key] = json.loads(v)
    return out


def config_key(config: Any) -> str:
    """Stable 16-hex-digit hash of a JSON-serialisable config (key order does not matter)."""
    text = json.dumps(config, sort_keys=True, default=json_default, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def json_default(obj: Any) -> Any:
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.floating,)):
        return float(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")
