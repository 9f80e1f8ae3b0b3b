"""The generator's error sources, one module each, in the order :func:`simbench.sim.generator.generate` runs them.

The order is that of the floating-point sums (code: range, receiver clock,
satellite clock, troposphere, NLOS delay, ionosphere, then multipath, sample
grid, noise), so outputs stay bit for bit what they were; random numbers do not
depend on it (each source has its own stream). A source reads what the sources
before it added (:class:`~simbench.sim.error_source.SimState`): the canyon needs
the antenna's visibility, multipath the canyon's ray errors.
"""

from __future__ import annotations

from simbench.sim.error_source import ErrorSource
from simbench.sim.error_sources.antenna import Antenna
from simbench.sim.error_sources.clocks import ReceiverClock, SatelliteClock
from simbench.sim.error_sources.cn0 import Cn0Fade, Cn0Noise
from simbench.sim.error_sources.cycle_slips import CycleSlips
from simbench.sim.error_sources.ionosphere import Ionosphere
from simbench.sim.error_sources.multipath import Multipath
from simbench.sim.error_sources.nlos import Nlos
from simbench.sim.error_sources.orbit_clock import OrbitClockError
from simbench.sim.error_sources.sample_grid import SampleGrid
from simbench.sim.error_sources.scintillation import Scintillation
from simbench.sim.error_sources.tracking_noise import TrackingNoise, TrackingNoiseL2
from simbench.sim.error_sources.troposphere import Troposphere

#: Before the receiver locks: what reaches the antenna (delays, pseudorange rate, C/N0, visibility).
SIGNAL_SOURCES: tuple[ErrorSource, ...] = (
    Antenna(),
    Cn0Fade(),
    Cn0Noise(),
    ReceiverClock(),
    SatelliteClock(),
    OrbitClockError(),
    Troposphere(),
    Nlos(),
    Ionosphere(),
    Scintillation(),
)
#: After the lock, on the locked channels: errors of the tracking loops per observable.
TRACKING_SOURCES: tuple[ErrorSource, ...] = (
    CycleSlips(),
    Multipath(),
    SampleGrid(),
    TrackingNoise(),
    TrackingNoiseL2(),
)
