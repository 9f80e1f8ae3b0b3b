"""Speed-ups change no output: generated tables bit for bit, CRT-LSS and batch positions within 1 mm (issue 27).

The stored values were computed with the code before the speed-ups of issue 27
(commit e660b31; the batch positions: before the sequential-Cholesky L2 solve and the
max-mixtures factor replacement, commit 6d2995e). A digest is the sha256 of each table's canonical bytes: per
column its name, dtype and raw values (strings joined), so a flipped bit, a
changed dtype or a reordered column fails. When a change is *meant* to alter the
generator's output, regenerate them with ``python tests/test_speed_identity.py``
and say why in the commit.
"""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np
import pandas as pd
import pytest

import estimators
import simbench
from estimators.crt_lss import CrtLss, CrtLssConfig

#: label -> (scenario preset, receiver preset, seed, overrides); short, so that the test is fast.
CASES: dict[str, tuple[str, str, int, dict[str, Any]]] = {
    "urban": ("urban", "low", 3, {"scenario.duration_s": 60}),
    "urban_dual_10hz": (
        "urban",
        "high",
        1,
        {
            "scenario.duration_s": 20,
            "scenario.rate_hz": 10,
            "scenario.dual_frequency": True,
            "scenario.errors.multipath.elevation_dependent": True,
        },
    ),
    "urban_deep": ("urban_deep", "low", 0, {"scenario.duration_s": 60}),
    "open_sky": ("open_sky", "geodetic", 5, {"scenario.duration_s": 60}),
    "flight": ("flight", "low", 2, {"scenario.duration_s": 60}),
    "morgantown1": ("morgantown1", "low", 1000, {"scenario.duration_s": 60}),
}

TABLES = ("observations", "imu", "truth", "labels", "odometry")

#: sha256 of :func:`table_digest` per case and table, from the code before issue 27's speed-ups.
DIGESTS: dict[str, dict[str, str]] = {
    "urban": {
        "observations": "8c043714046c9a9dfea8a56757aef91331baaf16356b225bd934535446edd691",
        "imu": "e3d17a4cbbabe1bcc84788090555861bb3ca55c399913d4db5bae229fd454fca",
        "truth": "fc59d200bc89db17d8e506b5c2f81c2dc4d9ec30ab1d8573c90d07b68e17c62d",
        "labels": "bf2d89202083cc222e757ab95f9b176d1c7361d5682de0057d9f29ddced98b83",
        "odometry": "8686373653210e91a3d1b6d616fc99d179a4355e8c749a6c96cc84cc98096456",
    },
    "urban_dual_10hz": {
        "observations": "56feaeac85e534812840bf52e210f478edfe6aae5abfe969ca77ec1d696b52d7",
        "imu": "1df440fa752bbfa70aba1394c3508b267d9aedc3f0598e97baa805785b0e5002",
        "truth": "4e6fe345fcd309f5f82816136cb0ff43466671c7874dee1087f0c41785c34676",
        "labels": "ecbb2bf8aecf272415a46dd944cb9aa4e39f49c0e63be82ac07f933df0eef455",
        "odometry": "7d996ca32a47d435b96b53ddeb36b77a1f10bc2a5e651bfd88cc0afba388fb6c",
    },
    "urban_deep": {
        "observations": "f94542266f98b6a4017be3842369eea282fe503f553660612b15ae60630d762f",
        "imu": "3f93c0603b49a74004b8d973988cedd8daadd7da8c089588d295211fc00bb56c",
        "truth": "b0d6ef473a9c970ba56f2f7949663ebd7e12ead4d3ef014f201b8fc1588185ca",
        "labels": "60731808ab9fac9f7304ba20657e2a0181a6111824a53886d1375fd41e84dc86",
        "odometry": "84ddaed449287af4f9f016b7f2dbefe77a9b6f3f9eb703bd598308eb6b43bf8b",
    },
    "open_sky": {
        "observations": "2528242110e82fd5cdf2141667ad4d09d819da53cefec324193b44baa4e34fd5",
        "imu": "c1ca0b719f0ddef2ca2ccf772502a9949ee7f57fefeb102244fc096f406b3aea",
        "truth": "9430430f797e7e58f0ec950e88aec89e34669159f26425d6127a9a9944d76401",
        "labels": "f10b38ecaa4eb9acb9ab15f97513ef1192b3ddd0b7d254acd2b15ec5bef8722d",
        "odometry": "0f3778229a15dd4f150971d1c9cfd32f4065a2e93029efd713803358446b961a",
    },
    "flight": {
        "observations": "f76e835ab1b3018fff5acc72bb547f7c30dd8334eb37f66847ec15b808232562",
        "imu": "1f577a95f7700ae5c2d2a0fa695aa81a7d4d39f5cc2638128f7d6749903d68b0",
        "truth": "080d8110fb9e315775bb11a2f0410a7cf9c1af150a3fd83f4b4f661dc750fc82",
        "labels": "b6a0defee472349432a56e3ced356afa8dc610b38f9117f13f9cfb04636e42f2",
        "odometry": "b322c98394080a834495ca34f0b2eb4a5f83351e2cabfb1347494a3c6edbd0fc",
    },
    "morgantown1": {
        "observations": "8c0edb18d697a0f42b4be7a2b853d3087f8bb6ba5ab95f8c6ef584ffe9fff1c4",
        "imu": "59e2faf9b88e815437d29c12bfc999e550f2eecc8619ac9e30d2bd27630f70b0",
        "truth": "5a13af84d8eb3c96a4abdaedf88c18a3464f0245213e0554cd1957f2cea5d4f2",
        "labels": "59b0f65eb88c39b9b370ff70516432414ec1d522da4096402554d11e0b29c941",
        "odometry": "422c2fac8d2682b8d89fc1df79cd1a8478322057e26e7bdfc5a3fed26be7393e",
    },
}

#: CRT-LSS (L = 20) position minus truth [m] per epoch on :data:`CRT_CASE`, before the speed-ups.
CRT_CASE = ("urban", "low", 1000, {"scenario.duration_s": 40, "imu.rate_hz": 100.0})
CRT_ERRORS: list[tuple[float, float, float]] = [
    (1.49920, 10.76191, -17.83125),
    (1.48806, 6.43666, -17.84690),
    (-0.61230, 0.02954, -8.89918),
    (-5.52622, -12.86898, 6.56905),
    (-3.54367, -12.53958, 6.04659),
    (-3.45687, -12.66191, 5.10149),
    (-3.31291, -10.97815, 4.26982),
    (-3.57010, -10.31438, 5.11526),
    (-2.37988, -8.69274, 5.38223),
    (-2.97994, -10.58372, 5.31310),
    (-3.80096, -12.47225, 5.65129),
    (-4.87326, -14.65428, 7.13774),
    (-5.20413, -15.57755, 7.97029),
    (-4.59466, -14.38065, 6.92741),
    (-4.33951, -12.84127, 5.69346),
    (-4.29987, -12.15616, 6.23099),
    (-3.60153, -10.78881, 6.29208),
    (-2.94717, -9.95712, 5.54596),
    (-2.88512, -10.09643, 5.24329),
    (-3.33929, -10.90431, 5.05652),
    (-3.26787, -11.59225, 5.78878),
    (-3.03711, -11.26639, 6.52635),
    (-2.67934, -10.05432, 5.65916),
    (-2.27166, -8.68994, 4.85148),
    (-1.78230, -7.17233, 4.70476),
    (-1.30155, -5.83937, 4.79677),
    (-1.21591, -5.99863, 4.90878),
    (-1.46916, -6.39009, 4.77944),
    (-2.06234, -8.00078, 5.45280),
    (-1.87922, -7.95030, 5.94417),
    (-1.61714, -7.82094, 5.76565),
    (-1.43075, -6.71267, 4.78040),
    (-1.41402, -5.93239, 4.62570),
    (-1.04966, -5.64451, 5.23576),
    (-0.40874, -4.90212, 4.86725),
    (-0.23930, -4.67334, 4.55433),
    (-0.62696, -5.37235, 5.09099),
    (-0.77010, -5.87172, 5.92037),
    (-0.41599, -4.96030, 5.55065),
]

#: Batch graph estimators' position minus truth [m] at every 20th epoch of :data:`BATCH_CASE`.
BATCH_CASE = ("urban", "low", 1000, {"scenario.duration_s": 120})
BATCH_EPOCHS = slice(None, None, 20)
BATCH_ERRORS: dict[str, list[tuple[float, float, float]]] = {
    "l2": [
        (-3.84324, -9.19806, 13.05317),
        (-3.07691, -7.57388, 12.31185),
        (-2.36906, -5.81185, 11.67435),
        (-2.16432, -5.46214, 11.67341),
        (-2.08249, -5.45717, 11.53511),
        (-1.87728, -5.27530, 11.23652),
    ],
    "dcs": [
        (-4.53480, -8.60444, 13.55421),
        (-4.05164, -7.49881, 13.00931),
        (-3.43352, -6.18625, 12.45408),
        (-3.23880, -5.93124, 12.43709),
        (-3.24082, -6.09518, 12.54034),
        (-2.97465, -6.52236, 12.77814),
    ],
    "mm": [
        (-4.09295, -8.62646, 13.53653),
        (-3.57939, -7.54929, 12.98303),
        (-3.08565, -6.48109, 12.46648),
        (-2.88733, -6.26285, 12.35993),
        (-2.81665, -6.41766, 12.29475),
        (-2.48105, -6.88757, 12.33066),
    ],
    "bce": [
        (-4.10252, -8.85228, 13.28758),
        (-3.56848, -7.80993, 12.72881),
        (-3.11483, -6.88100, 12.28151),
        (-2.88662, -6.64465, 12.21393),
        (-2.85413, -6.85585, 12.25416),
        (-2.51400, -7.25437, 12.37600),
    ],
}


def table_digest(table: pd.DataFrame) -> str:
    """sha256 of a table's canonical bytes: row count, then per column its name, dtype and values."""
    h = hashlib.sha256(str(len(table)).encode())
    for name in table.columns:
        values = table[name].to_numpy()
        h.update(f"|{name}|{table[name].dtype}|".encode())
        if values.dtype == object:
            h.update("\x1f".join(map(str, values)).encode())
        else:
            h.update(np.ascontiguousarray(values).tobytes())
    return h.hexdigest()


def scenario_digests(label: str) -> dict[str, str]:
    """Digest of each table of a case's scenario."""
    name, receiver, seed, overrides = CASES[label]
    sc = simbench.simulate(name, receiver, seed=seed, **overrides)
    return {table: table_digest(getattr(sc, table)) for table in TABLES}


def position_errors(scenario: simbench.Scenario, epochs: pd.DataFrame) -> np.ndarray:
    """ECEF position of each solution row minus the truth at its epoch [m], shape (rows, 3)."""
    truth = scenario.truth.set_index("epoch").loc[epochs["epoch"], ["x", "y", "z"]].to_numpy()
    return epochs[["x", "y", "z"]].to_numpy() - truth


def crt_lss_errors() -> np.ndarray:
    """CRT-LSS (L = 20) ECEF position minus truth [m], shape (epochs, 3), on :data:`CRT_CASE`."""
    name, receiver, seed, overrides = CRT_CASE
    sc = simbench.simulate(name, receiver, seed=seed, **overrides)
    return position_errors(sc, CrtLss(CrtLssConfig(window=20)).estimate(sc.receiver_view()).epochs)


def batch_errors() -> dict[str, np.ndarray]:
    """Each batch graph estimator's ECEF position minus truth [m] at :data:`BATCH_EPOCHS` of :data:`BATCH_CASE`."""
    name, receiver, seed, overrides = BATCH_CASE
    sc = simbench.simulate(name, receiver, seed=seed, **overrides)
    data = sc.receiver_view()
    return {
        est: position_errors(sc, estimators.get(est)().estimate(data).epochs.iloc[BATCH_EPOCHS])
        for est in ("l2", "dcs", "mm", "bce")
    }


@pytest.mark.parametrize("label", sorted(CASES))
def test_generator_output_is_bit_identical(label: str) -> None:
    assert scenario_digests(label) == DIGESTS[label]


def test_crt_lss_positions_within_a_millimetre() -> None:
    errors = crt_lss_errors()
    assert errors.shape == (len(CRT_ERRORS), 3)
    assert np.abs(errors - np.array(CRT_ERRORS)).max() <= 1e-3


def test_batch_positions_within_a_millimetre() -> None:
    errors = batch_errors()
    assert set(errors) == set(BATCH_ERRORS)
    for name, reference in BATCH_ERRORS.items():
        assert errors[name].shape == (len(reference), 3), name
        assert np.abs(errors[name] - np.array(reference)).max() <= 1e-3, name


def _print_rows(rows: np.ndarray, indent: str) -> None:
    """Rows of position errors as the tuple literals of :data:`CRT_ERRORS` and :data:`BATCH_ERRORS`."""
    for row in rows:
        print(f"{indent}({row[0]:.5f}, {row[1]:.5f}, {row[2]:.5f}),")


if __name__ == "__main__":
    print("DIGESTS: dict[str, dict[str, str]] = {")
    for case in CASES:
        print(f"    {case!r}: {scenario_digests(case)!r},")
    print("}")
    print("CRT_ERRORS: list[tuple[float, float, float]] = [")
    _print_rows(crt_lss_errors(), "    ")
    print("]")
    print("BATCH_ERRORS: dict[str, list[tuple[float, float, float]]] = {")
    for name, rows in batch_errors().items():
        print(f"    {name!r}: [")
        _print_rows(rows, "        ")
        print("    ],")
    print("}")
