"""Example scenario source: a static receiver under the nominal GPS constellation.

Registered as the source ``static_receiver`` (entry point in ``pyproject.toml``):
``python -m simbench scenario=static_receiver scenario.duration_s=120``. Code
pseudoranges are geometry, a constant receiver clock, the modelled hydrostatic
delay (which the shared model removes again) and white noise; no ionosphere,
no carrier phase.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simbench.contract import NavInfo, Scenario
from simbench.core.constants import DEG, SECONDS_PER_WEEK
from simbench.core.frames import ecef_from_geodetic
from simbench.core.gpstime import day_of_year
from simbench.core.orbits import NominalConstellation
from simbench.data.logs import epoch_grid_of, log_scenario, log_truth, observation_table
from simbench.data.reference import Reference
from simbench.gnss.geometry import elevation_azimuth, sagnac_range
from simbench.gnss.troposphere import troposphere_terms
from simbench.source_registry import DataConfig, Source, SourceConfig, scenario_config


@dataclass
class StaticReceiverConfig(SourceConfig):
    name: str = "static_receiver"
    source: str = "static_receiver"  #: must be the entry point's name
    lat_deg: float = 50.8  #: receiver latitude [deg]
    lon_deg: float = 12.9  #: receiver longitude [deg]
    h_m: float = 300.0  #: ellipsoidal height [m]
    duration_s: float = 60.0
    rate_hz: float = 1.0
    code_sigma_m: float = 1.0  #: white code noise [m]
    clock_m: float = 100.0  #: receiver clock offset times c [m]
    elevation_mask_deg: float = 10.0
    gps_week: int = 2032
    start_sow_s: float = 475_200.0


class StaticReceiver(Source):
    """A receiver standing still for ``duration_s`` under the 24-slot GPS constellation."""

    name = "static_receiver"
    Config = StaticReceiverConfig

    def load(self, cfg: DataConfig) -> Scenario:
        c = scenario_config(cfg, StaticReceiverConfig)
        t = np.arange(int(c.duration_s * c.rate_hz)) / c.rate_hz
        rx = ecef_from_geodetic(c.lat_deg * DEG, c.lon_deg * DEG, c.h_m)
        t0_gps = c.gps_week * SECONDS_PER_WEEK + c.start_sow_s
        sats = NominalConstellation()
        pos = sats.states(t0_gps + t).pos  # (epochs, 24, 3)
        el, az = elevation_azimuth(np.tile(rx, (t.size, 1)), pos)
        k, j = np.nonzero(el > c.elevation_mask_deg * DEG)
        noise = np.random.default_rng(cfg.seed).normal(0.0, c.code_sigma_m, k.size)
        delay = troposphere_terms(el[k, j], c.lat_deg * DEG, c.h_m, day_of_year(c.gps_week, c.start_sow_s))[0]
        code = sagnac_range(pos[k, j], rx) + c.clock_m + delay + noise
        nan, zero = np.full(k.size, np.nan), np.zeros(k.size)
        columns = {"epoch": k, "t": t[k], "sat": sats.sats[j], "code_l1": code, "cn0_l1": np.full(k.size, 45.0)}
        columns |= {f"sat_{a}": pos[k, j, i] for i, a in enumerate("xyz")}
        columns |= {"el": np.degrees(el[k, j]), "az": np.degrees(az[k, j]), "sat_clock": zero}
        columns |= {
            col: nan
            for col in ("phase_l1", "doppler_l1", "code_l2", "phase_l2", "f1_f2_ratio", "sat_vx", "sat_vy", "sat_vz")
        }
        columns |= {"lli_l1": zero.astype(bool), "lli_l2": zero.astype(bool), "sat_clock_drift": zero}
        observations = observation_table(columns)
        reference = Reference(t_gps=t0_gps + t, xyz=np.tile(rx, (t.size, 1)), path="static receiver")
        grid = epoch_grid_of(t, 1.0 / c.rate_hz)
        truth = log_truth(grid, t0_gps, reference, 2.0 / c.rate_hz, observations["epoch"].to_numpy())
        nav = NavInfo(c.gps_week, c.start_sow_s, (0.0,) * 4, (0.0,) * 4, dual_frequency=False, iono_corrected=True)
        return log_scenario(observations, truth, nav, {"name": c.name, "seed": cfg.seed, "source": self.name})
