"""GLONASS and Galileo: broadcast orbits and clocks, RINEX 3 navigation records, observation rows.

Fixtures are written by the tests: two real broadcast records (GLONASS R13 of
2023-01-08 11:45 UTC, Galileo E01 of 2017-01-01 00:10 GST) and self-consistent
records of satellites placed over Hong Kong for the end-to-end ingest. The
expected values come from independent computations in this file (scipy
``solve_ivp`` on the ICD equations, a textbook Kepler solution, the clock
formulas, UTC + 18 s), never from the code under test.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pymap3d
import pytest
from conftest import one_line_error
from scipy.integrate import solve_ivp

from simbench.core.constants import C_LIGHT, SECONDS_PER_WEEK
from simbench.core.galileo_orbits import GalileoEphemeris
from simbench.core.glonass_orbits import GlonassEphemeris
from simbench.core.gpstime import datetime64_to_gps
from simbench.core.orbits import BroadcastEphemeris
from simbench.data.broadcast import read_navigation
from simbench.data.log_sources import RinexConfig
from simbench.data.rinex import load_rinex
from simbench.errors import SimbenchError
from simbench.gnss.geometry import sagnac_range
from simbench.gnss.navigation import KEPLER_CLOCK_FIELDS
from simbench.runs.scenarios import ScenarioSettings, check_scenario

MU, AE, J2, WE = 3.986004418e14, 6_378_136.0, 1_082_625.75e-9, 7.2921151467e-5
GPS_MINUS_UTC_2019 = 18.0


# --------------------------------------------------------------------------- independent references


def _glonass_rhs(_t: float, y: np.ndarray, acc: np.ndarray) -> np.ndarray:
    """GLONASS ICD 2008 A.3.1.2 equations of motion in PZ-90 (scalar, for scipy)."""
    x, yy, z, vx, vy, vz = y
    r = math.sqrt(x * x + yy * yy + z * z)
    k = 1.5 * J2 * MU * AE**2 / r**5
    q = 5.0 * z * z / r**2
    return np.array(
        [
            vx,
            vy,
            vz,
            -MU / r**3 * x - k * x * (1 - q) + WE**2 * x + 2 * WE * vy + acc[0],
            -MU / r**3 * yy - k * yy * (1 - q) + WE**2 * yy - 2 * WE * vx + acc[1],
            -MU / r**3 * z - k * z * (3 - q) + acc[2],
        ]
    )


def _glonass_truth(pos: np.ndarray, vel: np.ndarray, acc: np.ndarray, dt: float) -> np.ndarray:
    sol = solve_ivp(_glonass_rhs, (0.0, dt), np.r_[pos, vel], method="DOP853", rtol=1e-13, atol=1e-9, args=(acc,))
    return sol.y[:, -1]


def _eccentric_anomaly(el: dict[str, float], tk: float, mu: float) -> tuple[float, float]:
    """Semi-major axis [m] and eccentric anomaly [rad] at ``tk`` [s] after Toe (Kepler's equation, fixed point)."""
    a = el["sqrta"] ** 2
    m = el["m0"] + (math.sqrt(mu / a**3) + el["dn"]) * tk
    e_anom = m
    for _ in range(30):
        e_anom = m + el["e"] * math.sin(e_anom)
    return a, e_anom


def _kepler(el: dict[str, float], tk: float, mu: float, we: float) -> np.ndarray:
    """Textbook broadcast Kepler position (IS-GPS-200 Table 20-IV) with the given constants."""
    a, e_anom = _eccentric_anomaly(el, tk, mu)
    nu = math.atan2(math.sqrt(1 - el["e"] ** 2) * math.sin(e_anom), math.cos(e_anom) - el["e"])
    phi = nu + el["w"]
    u = phi + el["cus"] * math.sin(2 * phi) + el["cuc"] * math.cos(2 * phi)
    r = a * (1 - el["e"] * math.cos(e_anom)) + el["crs"] * math.sin(2 * phi) + el["crc"] * math.cos(2 * phi)
    i = el["i0"] + el["idot"] * tk + el["cis"] * math.sin(2 * phi) + el["cic"] * math.cos(2 * phi)
    om = el["omega0"] + (el["omegadot"] - we) * tk - we * el["toe_sow"]
    xp, yp = r * math.cos(u), r * math.sin(u)
    return np.array(
        [
            xp * math.cos(om) - yp * math.cos(i) * math.sin(om),
            xp * math.sin(om) + yp * math.cos(i) * math.cos(om),
            yp * math.sin(i),
        ]
    )


def _kepler_clock(el: dict[str, float], tk: float) -> float:
    _, e_anom = _eccentric_anomaly(el, tk, MU)
    f_rel = -2 * math.sqrt(MU) / C_LIGHT**2
    return el["af0"] + el["af1"] * tk + el["af2"] * tk * tk + f_rel * el["e"] * el["sqrta"] * math.sin(e_anom)


# --------------------------------------------------------------------------- RINEX 3 writers


def _num(x: float) -> str:
    return f"{x:19.12E}"


def _rounded(x: float) -> float:
    return float(_num(x))


def _record(sv: str, stamp: str, values: list[float]) -> str:
    lines = [f"{sv} {stamp}" + "".join(_num(v) for v in values[:3])]
    rest = values[3:]
    for k in range(0, len(rest), 4):
        lines.append("    " + "".join(_num(v) for v in rest[k : k + 4]))
    return "\n".join(lines)


NAV_HEADER = (
    "     3.04           N: GNSS NAV DATA    M: MIXED            RINEX VERSION / TYPE\n"
    "simbench test                           20190428 000000 UTC PGM / RUN BY / DATE\n"
    "    18                                                      LEAP SECONDS\n"
    "                                                            END OF HEADER\n"
)


def _glonass_values(g: dict) -> list[float]:
    p, v, a = g["pos"] / 1e3, g["vel"] / 1e3, g["acc"] / 1e3
    return [g["clock"], g["gamma"], 45_000.0, p[0], v[0], a[0], 0.0, p[1], v[1], a[1], g["k"], p[2], v[2], a[2], 0.0]


def _galileo_values(el: dict) -> list[float]:
    return [
        el["af0"],
        el["af1"],
        el["af2"],
        77.0,
        el["crs"],
        el["dn"],
        el["m0"],
        el["cuc"],
        el["e"],
        el["cus"],
        el["sqrta"],
        el["toe_sow"],
        el["cic"],
        el["omega0"],
        el["cis"],
        el["i0"],
        el["crc"],
        el["w"],
        el["omegadot"],
        el["idot"],
        el["sources"],
        el["week"],
        0.0,
        3.12,
        0.0,
        el["bgd_a"],
        el["bgd_b"],
        el["toe_sow"] - 30.0,
    ]


# Real GLONASS R13 record, 2023-01-08 11:45:00 UTC (IGS BRDC; also an INSTINCT test case).
R13 = dict(
    clock=-3.075692802668e-05,
    gamma=0.0,
    k=-2,
    pos=np.array([-3.571277832031e03, 1.760026269531e04, 1.809717138672e04]) * 1e3,
    vel=np.array([-1.539720535278e00, 1.948561668396e00, -2.195667266846e00]) * 1e3,
    acc=np.array([-9.313225746155e-10, -1.862645149231e-09, -9.313225746155e-10]) * 1e3,
)
# Real Galileo E01 I/NAV record, 2017-01-01 00:10:00 GST (GPS week 1930).
E01 = dict(
    af0=4.448782419786e-05,
    af1=-9.890754881781e-12,
    af2=0.0,
    crs=1.307187500000e02,
    dn=2.340811789921e-09,
    m0=-1.487659137077e00,
    cuc=6.083399057388e-06,
    e=1.966624986380e-04,
    cus=1.164712011814e-05,
    sqrta=5.440626512527e03,
    toe_sow=600.0,
    cic=-1.676380634308e-08,
    omega0=-2.519894616571e00,
    cis=5.587935447693e-09,
    i0=9.998032176571e-01,
    crc=1.096562500000e02,
    w=-1.421596871170e00,
    omegadot=-5.110212860878e-09,
    idot=6.428839215530e-12,
    sources=513.0,
    week=1930.0,
    bgd_a=-6.286427378654e-09,
    bgd_b=-7.217749953270e-09,
)


# --------------------------------------------------------------------------- GLONASS


def _single(g: dict, tb: float, **kw) -> GlonassEphemeris:
    rec = {
        "sat": np.array([0]),
        "tb": np.array([tb]),
        "pos": g["pos"][None],
        "vel": g["vel"][None],
        "acc": g["acc"][None],
        "clock": np.array([g["clock"]]),
        "gamma": np.array([g["gamma"]]),
        "freq": np.array([g["k"]]),
    }
    return GlonassEphemeris(np.array(["R01"]), rec, **kw)


def test_glonass_icd_example() -> None:
    """The worked example of the GLONASS ICD (tb = 11700 s, ti = 12300 s; also in gnsstk and INSTINCT tests)."""
    ex = dict(
        clock=0.0,
        gamma=0.0,
        k=1,
        pos=np.array([7003.008789, -12206.626953, 21280.765625]) * 1e3,
        vel=np.array([0.7835417, 2.8042530, 1.3525150]) * 1e3,
        acc=np.array([0.0, 1.7e-6, -5.41e-6]),
    )
    ref_pos = np.array([7523174.853, -10506962.176, 21999239.866])
    ref_vel = np.array([950.12609, 2855.68710, 1040.68137])
    # the published result is that of the equations without the lunisolar term: we match it to 1 cm
    st0 = _single({**ex, "acc": np.zeros(3)}, 11_700.0).states(np.array([12_300.0]))
    assert np.linalg.norm(st0.pos[0, 0] - ref_pos) < 0.01
    assert np.linalg.norm(st0.vel[0, 0] - ref_vel) < 1e-4
    # with the broadcast acceleration the state moves by a t^2 / 2 (0.97 m in z after 600 s)
    st = _single(ex, 11_700.0).states(np.array([12_300.0]))
    np.testing.assert_allclose(st.pos[0, 0] - st0.pos[0, 0], 0.5 * ex["acc"] * 600.0**2, atol=0.01)
    np.testing.assert_allclose(st.vel[0, 0] - st0.vel[0, 0], ex["acc"] * 600.0, atol=5e-5)


def test_glonass_rk4_matches_tight_integration_and_physics() -> None:
    tb = 1e9
    eph = _single(R13, tb)
    dts = np.array([-900.0, -421.7, 0.0, 333.3, 900.0, 1500.0])
    st = eph.states(np.full(dts.size, tb), dts[:, None])
    for k, dt in enumerate(dts):
        ref = _glonass_truth(R13["pos"], R13["vel"], R13["acc"], dt) if dt else np.r_[R13["pos"], R13["vel"]]
        assert np.linalg.norm(st.pos[k, 0] - ref[:3]) < 2e-3, (dt, st.pos[k, 0] - ref[:3])
        assert np.linalg.norm(st.vel[k, 0] - ref[3:]) < 1e-5
    radius = np.linalg.norm(st.pos[:, 0], axis=1)
    assert np.all(np.abs(radius - 25_510e3) < 100e3)
    inertial = st.vel[:, 0] + np.cross([0.0, 0.0, WE], st.pos[:, 0])
    assert np.all(np.abs(np.linalg.norm(inertial, axis=1) - 3_953.0) < 20.0)
    # clock: -TauN + GammaN (t - tb), the RINEX fields as they stand
    g = _single({**R13, "gamma": 1.8e-12}, tb).states(np.array([tb]), np.array([[600.0]]))
    assert g.clock[0, 0] == pytest.approx(R13["clock"] + 1.8e-12 * 600.0, abs=1e-15)
    assert g.clock_drift[0, 0] == pytest.approx(1.8e-12)
    # nothing beyond 30 min from tb
    with pytest.raises(SimbenchError, match="no valid GLONASS ephemeris"):
        eph.states(np.array([tb + 1801.0]))


def test_glonass_reader_time_scale_and_bad_records(tmp_path: Path) -> None:
    nav = tmp_path / "r13.rnx"
    rec = _record("R13", "2023 01 08 11 45 00", _glonass_values(R13))
    nav.write_text(NAV_HEADER + rec + "\n")
    eph = read_navigation("R", nav)
    assert eph.sats.tolist() == ["R13"] and eph.freq_number.tolist() == [-2]
    # the RINEX epoch is UTC: the record's own state holds at UTC + 18 s in GPS time
    tb_gps = float(datetime64_to_gps(np.datetime64("2023-01-08T11:45:00"))) + GPS_MINUS_UTC_2019
    st = eph.states(np.array([tb_gps]))
    np.testing.assert_allclose(st.pos[0, 0], R13["pos"], atol=1e-4)
    assert st.clock[0, 0] == pytest.approx(-3.075692802668e-05, abs=1e-17)
    # a malformed number and an impossible channel give one line each
    bad = tmp_path / "bad.rnx"
    bad.write_text(NAV_HEADER + rec.replace("1.948561668396E+00", "1.948561668396X+00") + "\n")
    assert "malformed R13 record" in one_line_error(read_navigation, "R", bad)
    chan = tmp_path / "chan.rnx"
    chan.write_text(NAV_HEADER + _record("R13", "2023 01 08 11 45 00", _glonass_values({**R13, "k": 20})) + "\n")
    assert "frequency number 20" in one_line_error(read_navigation, "R", chan)
    only_e = tmp_path / "e.rnx"
    only_e.write_text(NAV_HEADER + _record("E01", "2017 01 01 00 10 00", _galileo_values(E01)) + "\n")
    msg = one_line_error(read_navigation, "R", only_e)
    assert "scenario.nav_glo" in msg and "no GLONASS records" in msg


# --------------------------------------------------------------------------- Galileo


def test_galileo_kepler_uses_galileo_constants(tmp_path: Path) -> None:
    nav = tmp_path / "e01.rnx"
    fnav = {**E01, "af0": E01["af0"] + 1e-6, "sources": 258.0}  # the F/NAV record: another clock pair
    nav.write_text(
        NAV_HEADER
        + _record("E01", "2017 01 01 00 10 00", _galileo_values(E01))
        + "\n"
        + _record("E01", "2017 01 01 00 10 00", _galileo_values(fnav))
        + "\n"
    )
    eph = read_navigation("E", nav)
    assert isinstance(eph, GalileoEphemeris) and eph.tgd.tolist() == [E01["bgd_b"]]
    toe = 1930 * SECONDS_PER_WEEK + 600.0
    tks = np.array([-3000.0, 0.0, 3600.0])
    st = eph.states(toe + tks)
    for k, tk in enumerate(tks):
        np.testing.assert_allclose(st.pos[k, 0], _kepler(E01, tk, MU, WE), atol=1e-3)
        assert st.clock[k, 0] == pytest.approx(_kepler_clock(E01, tk), abs=1e-15)  # I/NAV af0, not F/NAV
    assert abs(np.linalg.norm(st.pos[1, 0]) - 29_600e3) < 50e3
    # the same records with the GPS constants (mu 3.986005e14) are ~1 m away after an hour (measured 0.96 m)
    records = {k: np.array([E01[k]]) for k in KEPLER_CLOCK_FIELDS}
    records.update(sat=np.array([0]), toe=np.array([toe]), toc=np.array([toe]), tgd=np.array([0.0]))
    gps = BroadcastEphemeris(np.array(["E01"]), records).states(toe + tks)
    gps_ref = _kepler(E01, 3600.0, 3.986005e14, WE)
    np.testing.assert_allclose(gps.pos[2, 0], gps_ref, atol=1e-3)
    assert 0.5 < np.linalg.norm(gps.pos[2, 0] - st.pos[2, 0]) < 2.0


# --------------------------------------------------------------------------- end to end


RX_LLH = (22.3012, 114.1790, 8.0)
T0 = np.datetime64("2019-04-28T12:45:10")  # GPS
OFFSETS = [(15, 0), (-15, 20), (5, -25), (30, 30)]


def _over(lat0: float, lon0: float, dlat: float, dlon: float, radius: float) -> np.ndarray:
    la, lo = np.radians(lat0 + dlat), np.radians(lon0 + dlon)
    return radius * np.array([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)])


def _constellations() -> tuple[dict[str, dict], dict[str, dict]]:
    glo, gal = {}, {}
    for j, (dlat, dlon) in enumerate(OFFSETS):
        pos = _over(RX_LLH[0], RX_LLH[1], dlat, dlon, 25_510e3)
        up = pos / np.linalg.norm(pos)
        east = np.cross([0.0, 0.0, 1.0], up)
        east /= np.linalg.norm(east)
        north = np.cross(up, east)
        v_in = math.sqrt(MU / 25_510e3) * (0.5 * east + math.sqrt(0.75) * north)
        g = dict(
            pos=pos,
            vel=v_in - np.cross([0.0, 0.0, WE], pos),
            acc=np.array([1.1e-6, -2.3e-6, 1.7e-6]),
            clock=[-3.075692802668e-05, 1.2e-4, -8.0e-6, 4.4e-5][j],
            gamma=[0.0, 9.1e-13, -1.8e-12, 2.7e-12][j],
            k=[-2, 1, 4, 6][j],
        )
        glo[f"R{j + 5:02d}"] = {
            k: (np.array([_rounded(x) for x in v]) if isinstance(v, np.ndarray) else (_rounded(v) if k != "k" else v))
            for k, v in g.items()
        }
    toe_sow = 45_900.0
    for j, (dlat, dlon) in enumerate([(10, 10), (-20, -10), (25, -20), (0, 35)]):
        d = _over(RX_LLH[0], RX_LLH[1], dlat, dlon, 1.0)
        i0, w = 0.9774, 0.3
        u = math.asin(d[2] / math.sin(i0))
        lam = math.atan2(d[1], d[0]) - math.atan2(math.cos(i0) * math.sin(u), math.cos(u))
        el = {
            **E01,
            "m0": u - w,
            "w": w,
            "i0": i0,
            "omega0": lam + WE * toe_sow,
            "toe_sow": toe_sow,
            "week": 2051.0,
            "sources": 517.0,
            "af0": [4.45e-5, -2.1e-4, 6.0e-4, 1.3e-5][j],
            "bgd_b": [-7.2e-9, -3.1e-9, 2.4e-9, -5.0e-9][j],
            "bgd_a": -6.3e-9,
        }
        gal[f"E{j + 11:02d}"] = {k: _rounded(v) for k, v in el.items()}
    return glo, gal


def test_mixed_navigation_and_observations_round_trip(tmp_path: Path) -> None:
    """R and E rows through load_rinex: positions, clock sign, time scale and FDMA wavelength all checked."""
    glo, gal = _constellations()
    nav = tmp_path / "mixed.rnx"
    text = NAV_HEADER
    for sv, g in glo.items():  # tb = 12:45:00 UTC
        text += _record(sv, "2019 04 28 12 45 00", _glonass_values(g)) + "\n"
    for sv, el in gal.items():  # Toc = Toe = 12:45:00 GST
        text += _record(sv, "2019 04 28 12 45 00", _galileo_values(el)) + "\n"
        # an F/NAV record with another clock: must not be used by an E1 user
        text += (
            _record(sv, "2019 04 28 12 45 00", _galileo_values({**el, "af0": el["af0"] + 2e-6, "sources": 258.0}))
            + "\n"
        )
    nav.write_text(text)

    rx = np.array(pymap3d.geodetic2ecef(*RX_LLH))
    bias = {"R": 31.0, "E": 47.0}  # per-system receiver delays [m]
    ambiguity = 1000  # cycles
    t0 = float(datetime64_to_gps(T0))
    tb_glo = float(datetime64_to_gps(np.datetime64("2019-04-28T12:45:00"))) + GPS_MINUS_UTC_2019
    toe_gal = 2051 * SECONDS_PER_WEEK + 45_900.0
    n_ep = 4
    rows: dict[tuple[int, str], tuple[float, float, np.ndarray, float]] = {}
    for e in range(n_ep):
        t_rx = t0 + e
        for sv in [*glo, *gal]:
            tau = 0.07
            for _ in range(4):  # transmit time of the signal received at t_rx (exact Sagnac rotation)
                t_tx = t_rx - tau
                if sv[0] == "R":
                    g = glo[sv]
                    st = _glonass_truth(g["pos"], g["vel"], g["acc"], t_tx - tb_glo)[:3]
                    clk = g["clock"] + g["gamma"] * (t_tx - tb_glo)
                    f = 1602e6 + g["k"] * 0.5625e6
                else:
                    el = gal[sv]
                    st = _kepler(el, t_tx - toe_gal, MU, WE)
                    clk = _kepler_clock(el, t_tx - toe_gal) - el["bgd_b"]
                    f = 1575.42e6
                th = WE * tau
                rot = np.array(
                    [st[0] * math.cos(th) + st[1] * math.sin(th), -st[0] * math.sin(th) + st[1] * math.cos(th), st[2]]
                )
                tau = np.linalg.norm(rot - rx) / C_LIGHT
            code = C_LIGHT * tau + bias[sv[0]] - C_LIGHT * clk
            rows[(e, sv)] = (code, code / (C_LIGHT / f) + ambiguity, st, clk)

    head = [
        "     3.04           OBSERVATION DATA    M: MIXED            RINEX VERSION / TYPE",
        "R    4 C1C L1C D1C S1C                                      SYS / # / OBS TYPES",
        "E    4 C1C L1C D1C S1C                                      SYS / # / OBS TYPES",
        "  2019     4    28    12    45   10.0000000     GPS         TIME OF FIRST OBS",
        "     1.000                                                  INTERVAL",
        "                                                            END OF HEADER",
    ]
    body = []
    for e in range(n_ep):
        body.append(f"> 2019 04 28 12 45 {10 + e:2d}.0000000  0{len(glo) + len(gal):3d}")
        for sv in [*glo, *gal]:
            code, cyc, _, _ = rows[(e, sv)]
            body.append(f"{sv}{code:14.3f}  {cyc:14.3f}  {-500.0:14.3f}  {42.0:14.3f}  ")
    obs_file = tmp_path / "mixed.obs"
    obs_file.write_text("\n".join(head + body) + "\n")

    sc = load_rinex(obs_file, nav, None, systems="RE")
    obs = sc.observations
    assert len(obs) == n_ep * 8 and set(obs["sat"].str[0]) == {"R", "E"}
    for (e, sv), (_code, _cyc, st, clk) in rows.items():
        row = obs[(obs["epoch"] == e) & (obs["sat"] == sv)].iloc[0]
        # satellite at transmit time: the time scale (UTC + 18 s for GLONASS) and the orbit
        np.testing.assert_allclose(row[["sat_x", "sat_y", "sat_z"]].to_numpy(float), st, atol=0.01)
        # clock sign and BGD: the E1 / L1 user's clock times c
        assert row["sat_clock"] == pytest.approx(C_LIGHT * clk, abs=1e-3)
        # FDMA wavelength: phase in metres equals the code plus the ambiguity in that wavelength
        f = 1602e6 + glo[sv]["k"] * 0.5625e6 if sv[0] == "R" else 1575.42e6
        assert row["phase_l1"] - row["code_l1"] == pytest.approx(ambiguity * C_LIGHT / f, abs=2e-3)
    # the model closes: code + sat_clock - range = the system's receiver delay, to the millimetre
    resid = obs["code_l1"] + obs["sat_clock"] - sagnac_range(obs[["sat_x", "sat_y", "sat_z"]].to_numpy(), rx)
    for s, b in bias.items():
        np.testing.assert_allclose(resid[obs["sat"].str[0] == s], b, atol=0.01)
    # elevation and azimuth of every row from the per-system-clock single-point solution
    sat = obs[["sat_x", "sat_y", "sat_z"]].to_numpy()
    lat, lon, _ = pymap3d.ecef2geodetic(*rx)
    az, el, _ = pymap3d.ecef2aer(sat[:, 0], sat[:, 1], sat[:, 2], lat, lon, RX_LLH[2])
    np.testing.assert_allclose(obs["el"], el, atol=0.01)
    np.testing.assert_allclose(obs["az"], az, atol=0.01)
    assert (obs["el"] > 20).all()
    assert sc.meta["files"]["nav_glo"] == sc.meta["files"]["nav_gal"] == str(nav)


# --------------------------------------------------------------------------- configuration


def test_systems_setting_and_missing_navigation(tmp_path: Path) -> None:
    for name in ("a.obs", "a.csv", "e.rnx"):  # the door checks that every named file exists
        (tmp_path / name).touch()
    sc = RinexConfig(obs=str(tmp_path / "a.obs"), truth=str(tmp_path / "a.csv"))
    cfg = ScenarioSettings(scenario=sc)
    sc.nav = str(tmp_path / "gps.rnx")
    (tmp_path / "gps.rnx").write_text(
        "     3.04           N: GNSS NAV DATA    G: GPS              RINEX VERSION / TYPE\n"
    )
    sc.systems = "GX"
    msg = one_line_error(check_scenario, cfg)
    assert "scenario.systems" in msg and "X" in msg and "GREC" in msg
    sc.systems = "GE"  # a GPS-only nav file cannot serve Galileo
    assert "scenario.nav_gal" in one_line_error(check_scenario, cfg)
    sc.nav_gal = str(tmp_path / "e.rnx")
    check_scenario(cfg)
    sc.systems = "GR"
    assert "scenario.nav_glo" in one_line_error(check_scenario, cfg)
    # a mixed file serves every system
    (tmp_path / "gps.rnx").write_text(
        "     3.04           N: GNSS NAV DATA    M: MIXED            RINEX VERSION / TYPE\n"
    )
    sc.systems = "GREC"
    check_scenario(cfg)
    sc.nav = ""
    assert "scenario.nav" in one_line_error(check_scenario, cfg)
