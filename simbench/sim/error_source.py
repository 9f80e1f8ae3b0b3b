"""The generator's error sources: what each one reads (:class:`SimState`), adds (:class:`Contribution`) and is.

:func:`simbench.sim.generator.generate` runs the sources of
:mod:`simbench.sim.error_sources` in order, in two stages:

1. *signal* sources, before the receiver locks: antenna, C/N0 fading, clocks,
   atmosphere, street canyon. They add delays common to code and phase
   (:attr:`Contribution.delay_m`), the dispersive ionospheric delay, pseudorange
   rate and C/N0, and may mask satellites;
2. the receiver's lock (from the final C/N0), then *tracking* sources: phase arcs,
   multipath, sample grid, thermal noise. They add errors per observable.

Each source draws from its own named random stream
(:func:`simbench.sim.processes.stream`), so switching one off or reordering
does not change the others' random numbers. The order of the list is the order
of the floating-point sums, so moving a source changes outputs in the last bits.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import pymap3d

from simbench.core.constants import CHIP_LENGTH_CA, IONO_L2_SCALE, LAMBDA_L1
from simbench.core.orbits import Constellation
from simbench.sim import tracking
from simbench.sim.config import ErrorsConfig, ReceiverConfig, SimConfig
from simbench.sim.geometry import LineOfSight
from simbench.sim.processes import Columns, gauss_markov, stream
from simbench.sim.trajectory import Trajectory

#: L2 signals are weaker than L1 C/A (IS-GPS-200 minimum powers differ by 1.5-3 dB).
L2_CN0_LOSS_DB = 3.0
#: The observables tracking sources add to: fields of :class:`Contribution` and :class:`SimState`.
TRACKING_TERMS = ("code_l1_m", "phase_l1_m", "code_l2_m", "phase_l2_m", "doppler_l1_hz")


@dataclass
class Contribution:
    """What one error source adds. ``None`` adds nothing; arrays broadcast to (n, m) = (epochs, satellites).

    Signal sources fill the first group, tracking sources the second.
    """

    delay_m: np.ndarray | None = None  #: non-dispersive delay on code and phase, L1 and L2 [m]
    iono_l1_m: np.ndarray | None = None  #: dispersive L1 delay: code +, phase -, times (f1/f2)^2 on L2 [m]
    range_rate_mps: np.ndarray | None = None  #: rate of the pseudorange, into the Doppler [m/s]
    cn0_dbhz: np.ndarray | None = None  #: C/N0 change [dB]
    visible: np.ndarray | None = None  #: bool: False where this source hides the satellite from the antenna

    code_l1_m: np.ndarray | None = None  #: L1 code tracking error [m]
    phase_l1_m: np.ndarray | None = None  #: L1 carrier error [m]
    code_l2_m: np.ndarray | None = None  #: L2 code tracking error [m] (dual frequency only)
    phase_l2_m: np.ndarray | None = None  #: L2 carrier error [m] (dual frequency only)
    doppler_l1_hz: np.ndarray | None = None  #: L1 Doppler error [Hz]

    #: (n, m) label columns (:data:`simbench.contract.LABEL_COLUMNS` or the source's own)
    labels: dict[str, np.ndarray] = field(default_factory=dict)
    #: (n, m) receiver-view columns the source owns (e.g. ``sat_x`` of an orbit product, ``lli_l1``)
    observations: dict[str, np.ndarray] = field(default_factory=dict)
    #: (n,) truth columns (e.g. ``rx_clock`` [m])
    truth: dict[str, np.ndarray] = field(default_factory=dict)
    #: (n, m) intermediate arrays later sources read from :attr:`SimState.shared`
    shared: dict[str, np.ndarray] = field(default_factory=dict)


@dataclass
class Lock:
    """The receiver's tracking state, from the final C/N0; arrays (n, m)."""

    tracked: np.ndarray  #: bool: the channel delivers an observation
    carrier_locked: np.ndarray  #: bool: tracked, and the PLL holds lock: the observation has a phase
    sigma_code_m: np.ndarray  #: DLL thermal jitter std [m]
    pll_jitter_rad: np.ndarray  #: PLL thermal jitter std [rad]
    pll_stress_rad: np.ndarray  #: PLL jitter plus a third of the dynamic stress error [rad]


@dataclass
class SimState:
    """What the error sources read: configuration, trajectory, geometry, and the sums so far.

    Geometry arrays have shape (n, m) (epochs, satellites), per-epoch arrays (n,). The m
    satellites are those of the constellation that rise above the elevation mask at some epoch
    (:attr:`columns`); random draws span the whole constellation (:meth:`draw`,
    :meth:`gauss_markov`), so that no satellite's numbers depend on which others are kept.
    """

    cfg: SimConfig
    traj: Trajectory  #: at the IMU rate
    idx: np.ndarray  #: IMU sample of each GNSS epoch
    start_sow_s: float  #: GPS seconds of week at t = 0 [s]
    #: the antenna's geodetic latitude, longitude [rad] and height [m] at each epoch (from ``traj``)
    lat_rad: np.ndarray = field(init=False)
    lon_rad: np.ndarray = field(init=False)
    h_m: np.ndarray = field(init=False)
    los: LineOfSight
    constellation: Constellation
    iono_alpha: tuple[float, ...]  #: Klobuchar coefficients handed to the receiver
    iono_beta: tuple[float, ...]
    above: np.ndarray  #: bool: above the elevation mask
    #: the constellation's satellites the grids keep (those ever above the mask) and the width random draws span
    columns: Columns
    # ---- sums of the signal sources
    in_view: np.ndarray = field(init=False)  #: bool: above the mask and seen by the antenna
    delay_m: np.ndarray = field(init=False)  #: geometric range plus the non-dispersive delays [m]
    iono_l1_m: np.ndarray = field(init=False)  #: dispersive L1 delay [m]
    range_rate_mps: np.ndarray = field(init=False)  #: pseudorange rate [m/s]
    cn0_dbhz: np.ndarray = field(init=False)  #: L1 C/N0 [dB-Hz]
    # ---- the receiver's lock, then the observables the tracking sources add to
    lock_state: Lock | None = None
    code_l1_m: np.ndarray = field(init=False)
    phase_l1_m: np.ndarray = field(init=False)
    code_l2_m: np.ndarray = field(init=False)
    phase_l2_m: np.ndarray = field(init=False)
    doppler_l1_hz: np.ndarray = field(init=False)
    # ---- columns and intermediate arrays of the sources
    labels: dict[str, np.ndarray] = field(default_factory=dict)
    observations: dict[str, np.ndarray] = field(default_factory=dict)
    truth: dict[str, np.ndarray] = field(default_factory=dict)
    shared: dict[str, np.ndarray] = field(default_factory=dict)
    _sky_cells: tuple[np.ndarray, np.ndarray] | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        pos = self.traj.pos[self.idx]
        self.lat_rad, self.lon_rad, self.h_m = pymap3d.ecef2geodetic(pos[:, 0], pos[:, 1], pos[:, 2], deg=False)
        self.in_view = self.above.copy()
        self.delay_m = self.los.range_m
        self.iono_l1_m = np.zeros(self.shape)
        self.range_rate_mps = self.los.range_rate_mps
        self.cn0_dbhz = np.zeros(self.shape)

    # ---- what sources read
    @property
    def shape(self) -> tuple[int, int]:
        """(n, m): epochs, satellites."""
        return self.los.range_m.shape

    @property
    def t(self) -> np.ndarray:
        """Epoch times since the scenario start, (n,) [s]."""
        return self.traj.t[self.idx]

    @property
    def dt_s(self) -> float:
        """GNSS epoch interval [s]."""
        return 1.0 / self.cfg.scenario.rate_hz

    @property
    def errors(self) -> ErrorsConfig:
        return self.cfg.scenario.errors

    @property
    def receiver(self) -> ReceiverConfig:
        return self.cfg.receiver

    @property
    def dual_frequency(self) -> bool:
        return self.cfg.scenario.dual_frequency

    @property
    def spacing_chips(self) -> float:
        """Early-late spacing the sampled correlator realises [chips]."""
        rx = self.cfg.receiver
        return tracking.effective_spacing_chips(rx.correlator_spacing_chips, rx.sampling_mhz * 1e6)

    @property
    def front_end_bw_hz(self) -> float:
        """Double-sided front-end bandwidth [Hz]."""
        return self.cfg.receiver.front_end_bw_mhz * 1e6

    def code_jitter_m(self, cn0_dbhz: np.ndarray) -> np.ndarray:
        """The receiver's thermal-noise code jitter at ``cn0_dbhz`` [dB-Hz] (1-sigma, [m]):
        :func:`~simbench.sim.tracking.dll_jitter_chips` with its loop settings, times the C/A chip length."""
        rx = self.cfg.receiver
        bw, t = rx.dll_bw_hz, rx.integration_s
        return CHIP_LENGTH_CA * tracking.dll_jitter_chips(cn0_dbhz, bw, self.spacing_chips, self.front_end_bw_hz, t)

    @property
    def cn0_l2_dbhz(self) -> np.ndarray:
        """L2 C/N0 [dB-Hz]."""
        return self.cn0_dbhz - L2_CN0_LOSS_DB

    @property
    def signal_code_l1_m(self) -> np.ndarray:
        """L1 pseudorange of the signal as it reaches the antenna, before tracking errors [m]."""
        return self.delay_m + self.iono_l1_m

    @property
    def signal_code_l2_m(self) -> np.ndarray:
        """L2 pseudorange of the signal as it reaches the antenna [m]."""
        return self.delay_m + IONO_L2_SCALE * self.iono_l1_m

    @property
    def sky_cells(self) -> tuple[np.ndarray, np.ndarray]:
        """Epoch and satellite indices of the (epoch, satellite) cells above the elevation mask, epoch-major.

        Deterministic per-cell physics (atmosphere, antenna gain) runs on these only: the grid's
        satellites each rise above the mask at some epoch, not at every one, and no later stage
        reads a cell below the mask (it is never in view, so never tracked).
        """
        if self._sky_cells is None:
            ei, si = np.nonzero(self.above)
            self._sky_cells = (ei, si)
        return self._sky_cells

    def draw(self, sample: Callable[..., np.ndarray], *args: Any) -> np.ndarray:
        """An (n, m) draw ``sample(*args, size=...)`` taken across the whole constellation, cut to the grid's
        satellites (:class:`~simbench.sim.processes.Columns`), e.g. ``state.draw(rng.standard_normal)``."""
        return self.columns.draw(sample, self.shape[0], *args)

    def gauss_markov(self, sigma: float, tau_s: float, rng: np.random.Generator) -> np.ndarray:
        """One Gauss-Markov process per satellite at the epochs (:func:`~simbench.sim.processes.gauss_markov`),
        (n, m): drawn across the whole constellation, filtered for the grid's satellites."""
        c = self.columns
        return gauss_markov(self.shape[0], c.width, sigma, tau_s, self.dt_s, rng, c.keep)

    def on_sky(self, values: np.ndarray) -> np.ndarray:
        """An (n, m) grid holding ``values`` at :attr:`sky_cells`, 0 (False) below the mask."""
        grid = np.zeros(self.shape, np.asarray(values).dtype)
        grid[self.above] = values
        return grid

    def stream(self, name: str) -> np.random.Generator:
        """The scenario seed's random stream ``name``."""
        return stream(self.cfg.seed, name)

    # ---- what the generator does with contributions
    def add(self, c: Contribution) -> None:
        """Add a source's contribution to the sums, its columns to the tables."""
        tracking_terms = {name: getattr(c, name) for name in TRACKING_TERMS}
        changes_signal = any(x is not None for x in (c.visible, c.delay_m, c.iono_l1_m, c.range_rate_mps, c.cn0_dbhz))
        if changes_signal and self.lock_state is not None:
            raise ValueError("a source changed the signal after the receiver locked: list it in SIGNAL_SOURCES")
        if self.lock_state is None and any(x is not None for x in tracking_terms.values()):
            raise ValueError("a source added a tracking error before the receiver locked: list it in TRACKING_SOURCES")
        if c.visible is not None:
            self.in_view = self.in_view & c.visible
        if c.delay_m is not None:
            self.delay_m = self.delay_m + c.delay_m
        if c.iono_l1_m is not None:
            self.iono_l1_m = self.iono_l1_m + c.iono_l1_m
        if c.range_rate_mps is not None:
            self.range_rate_mps = self.range_rate_mps + c.range_rate_mps
        if c.cn0_dbhz is not None:
            self.cn0_dbhz = self.cn0_dbhz + c.cn0_dbhz
        for name, term in tracking_terms.items():
            if term is not None:
                setattr(self, name, getattr(self, name) + term)
        self.labels.update(c.labels)
        self.observations.update(c.observations)
        self.truth.update(c.truth)
        self.shared.update(c.shared)

    def start_tracking(self, lock: Lock) -> None:
        """Hand the signal to the locked loops: the observables start as the signal's code, phase and Doppler."""
        self.lock_state = lock
        self.code_l1_m = self.signal_code_l1_m
        self.phase_l1_m = self.delay_m - self.iono_l1_m
        self.doppler_l1_hz = -self.range_rate_mps / LAMBDA_L1
        if self.dual_frequency:
            self.code_l2_m = self.signal_code_l2_m
            self.phase_l2_m = self.delay_m - IONO_L2_SCALE * self.iono_l1_m
        else:
            self.code_l2_m = self.phase_l2_m = np.full(self.shape, np.nan)

    @property
    def lock(self) -> Lock:
        """The receiver's lock state, for tracking sources (set by :meth:`start_tracking`)."""
        if self.lock_state is None:
            raise RuntimeError("the receiver has not locked yet: only tracking sources read the lock")
        return self.lock_state


class ErrorSource(Protocol):
    """One error source of the generator (a module of :mod:`simbench.sim.error_sources`).

    Attributes
    ----------
    name : str
        Name of its random stream, ``stream(seed, name)``: unique, and stable (changing it changes outputs).
    labels : Mapping[str, type]
        Label columns it fills, with their dtype. Columns of
        :data:`simbench.contract.LABEL_COLUMNS` are zero when the source is off;
        other columns appear only in scenarios where it runs.
    """

    name: str
    labels: Mapping[str, type]

    def enabled(self, state: SimState) -> bool:
        """Whether it runs in this scenario (usually ``scenario.errors.<name>.enabled``)."""
        ...

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        """Its contribution, drawing random numbers from ``rng`` (its own stream) only."""
        ...


class AlwaysOn:
    """Base of an error source that runs in every scenario (:class:`ErrorSource`): a subclass sets ``name``
    and ``apply``, and ``labels`` when it fills label columns."""

    labels: Mapping[str, type] = {}

    def enabled(self, state: SimState) -> bool:
        return True
