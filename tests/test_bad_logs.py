"""Bad logs at the door (issue 25): each damaged copy of a real log either gives a one-line
error naming the file and the line, or a one-line warning and exactly the rows of the intact log.

The RINEX cases cut a one-minute piece out of the Hong Kong log (inside the span of its ground
truth); the libRSF cases damage a synthetic file at a known line.
"""

from __future__ import annotations

import bz2
import gzip
import warnings
from collections.abc import Callable
from pathlib import Path

import hatanaka
import numpy as np
import pandas as pd
import pytest
from conftest import one_line_error

from simbench.data.broadcast import read_navigation
from simbench.data.librsf import read_librsf, write_synthetic_librsf
from simbench.data.reference import read_reference
from simbench.data.rinex import RinexObs, load_rinex, read_rinex_obs
from simbench.errors import SimbenchWarning
from simbench.gnss.navigation import read_gps_navigation

HK = Path(__file__).resolve().parents[2] / "shared" / "data" / "hk_tst_2019"
OBS, NAV, NAV_BDS = HK / "COM3_190428_124409.obs", HK / "hksc1180.19n", HK / "hksc1180.19b"
TRUTH = HK / "groundTruth_TST.csv"
needs_hk = pytest.mark.usefixtures("shared_data")

#: Epoch records of the piece: one minute from 12:58:30 GPS, where the ground truth has begun.
FIRST, N_EPOCHS = "> 2019  4 28 12 58 30", 60
OBS_FIELDS = [
    "epoch_t_int",
    "epoch_t_frac",
    "row_epoch",
    "sat",
    "code",
    "phase_cycles",
    "doppler_hz",
    "cn0_dbhz",
    "lli",
    "code_l2",
    "phase_l2_cycles",
    "lli_l2",
    "approx_position",
]


class Piece:
    """The piece of the Hong Kong log as LF lines: ``head`` (header) and ``epochs`` (one list of lines each)."""

    def __init__(self, lines: list[str]) -> None:
        body = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
        starts = [i for i in range(body, len(lines)) if lines[i].startswith(">")] + [len(lines)]
        first = next(k for k, i in enumerate(starts) if lines[i].startswith(FIRST))
        self.head = lines[:body]
        self.epochs = [lines[a:b] for a, b in zip(starts[first : first + N_EPOCHS], starts[first + 1 :])]

    def lines(self, epochs: list[list[str]] | None = None) -> list[str]:
        return self.head + [ln for e in (self.epochs if epochs is None else epochs) for ln in e]

    def line_of(self, epoch: int, row: int = 0) -> int:
        """1-based line number of line ``row`` of epoch record ``epoch`` in :meth:`lines`."""
        return len(self.head) + sum(len(e) for e in self.epochs[:epoch]) + row + 1


def text(lines: list[str]) -> bytes:
    return ("\n".join(lines) + "\n").encode()


def with_count(header: str, count: int) -> str:
    return header[:32] + f"{count:3d}" + header[35:]


@pytest.fixture(scope="module")
def piece(shared_data: Path) -> Piece:
    return Piece(OBS.read_text().splitlines())


@pytest.fixture(scope="module")
def intact(piece: Piece, tmp_path_factory: pytest.TempPathFactory) -> RinexObs:
    p = tmp_path_factory.mktemp("intact") / "piece.obs"
    p.write_bytes(text(piece.lines()))
    return read_rinex_obs(p, "GC")


def assert_same_obs(a: RinexObs, b: RinexObs) -> None:
    for name in OBS_FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), name
    assert a.interval_s == b.interval_s


def _cut_inside_last_code(p: Piece) -> bytes:
    """The file ends inside the pseudorange of the last satellite line of epoch 20."""
    epochs = p.epochs[:21]
    return text(p.lines(epochs))[:-1][: -(len(epochs[-1][-1]) - 10)]


def _unsorted(p: Piece) -> list[str]:
    e = p.epochs[:]
    e[10], e[11] = e[11], e[10]
    return p.lines(e)


def _repeat_satellite(p: Piece) -> list[str]:
    e = [list(x) for x in p.epochs]
    e[5] = [with_count(e[5][0], len(e[5])), *e[5][1:], e[5][1]]
    return p.lines(e)


def _bad_number(p: Piece) -> list[str]:
    e = [list(x) for x in p.epochs]
    e[7][2] = e[7][2][:6] + "x" + e[7][2][7:]
    return p.lines(e)


#: Copies read exactly as the intact piece: (name, file suffix, bytes from the piece, warning or "").
SAME: list[tuple[str, str, Callable[[Piece], bytes], str]] = [
    ("LF", ".obs", lambda p: text(p.lines()), ""),
    ("CR LF", ".obs", lambda p: text(p.lines()).replace(b"\n", b"\r\n"), ""),
    ("CR CR LF", ".obs", lambda p: text(p.lines()).replace(b"\n", b"\r\r\n"), ""),
    ("CR", ".obs", lambda p: text(p.lines()).replace(b"\n", b"\r"), ""),
    ("no final line break", ".obs", lambda p: text(p.lines())[:-1], ""),
    ("blank lines at the end", ".obs", lambda p: text(p.lines()) + b"\n\n", ""),
    ("gzip", ".obs.gz", lambda p: gzip.compress(text(p.lines())), ""),
    ("gzip of CR LF", ".obs.gz", lambda p: gzip.compress(text(p.lines()).replace(b"\n", b"\r\n")), ""),
    ("bzip2", ".obs.bz2", lambda p: bz2.compress(text(p.lines())), ""),
    ("Hatanaka", ".crx", lambda p: hatanaka.compress(text(p.lines()), compression="none"), ""),
    ("Hatanaka gzip", ".crx.gz", lambda p: hatanaka.compress(text(p.lines())), ""),
    ("Hatanaka .19d", ".19d", lambda p: hatanaka.compress(text(p.lines()), compression="none"), ""),
    (
        "every epoch twice",
        ".obs",
        lambda p: text(p.lines([e for e in p.epochs for _ in (0, 1)])),
        "60 epoch records repeat the time tag",
    ),
    ("log appended to itself", ".obs", lambda p: text(p.lines(p.epochs * 2)), "60 epoch records repeat"),
    ("one epoch twice", ".obs", lambda p: text(p.lines(p.epochs[:9] + p.epochs[8:])), "1 epoch records repeat"),
    ("satellite twice in an epoch", ".obs", lambda p: text(_repeat_satellite(p)), "1 satellite lines repeat"),
]

#: Copies refused: (name, bytes from the piece, expected part of the message given the piece).
REFUSED: list[tuple[str, Callable[[Piece], bytes], Callable[[Piece], str]]] = [
    ("empty file", lambda p: b"", lambda p: "is empty"),
    ("header only", lambda p: text(p.head), lambda p: "contains no observations"),
    ("header cut", lambda p: text(p.head[:10]), lambda p: "has no END OF HEADER line"),
    ("binary", lambda p: bytes(range(256)) * 4, lambda p: "has no RINEX header"),
    (
        "cut mid-epoch",
        lambda p: text(p.lines(p.epochs[:30] + [p.epochs[30][:4]])),
        lambda p: (
            f"epoch at line {p.line_of(30)} announces {len(p.epochs[30]) - 1} satellites but the file "
            "ends after 3 (cut file)"
        ),
    ),
    (
        "cut mid-line inside an epoch",
        lambda p: text(p.lines(p.epochs[:30] + [p.epochs[30][:4]]))[:-20],
        lambda p: f"epoch at line {p.line_of(30)} announces",
    ),
    ("cut mid-line in the last line", _cut_inside_last_code, lambda p: f"line {p.line_of(21) - 1} ends inside"),
    ("cut at 60 % of the bytes", lambda p: text(p.lines())[: len(text(p.lines())) * 3 // 5], lambda p: "cut"),
    (
        "satellite count too small",
        lambda p: text(
            p.lines(
                p.epochs[:12]
                + [[with_count(p.epochs[12][0], len(p.epochs[12]) - 2), *p.epochs[12][1:]]]
                + p.epochs[13:]
            )
        ),
        lambda p: (
            f"line {p.line_of(12, len(p.epochs[12]) - 1)} is outside any epoch record (the epoch at line "
            f"{p.line_of(12)} announces fewer satellites)"
        ),
    ),
    (
        "satellite count too large",
        lambda p: text(
            p.lines(
                p.epochs[:12] + [[with_count(p.epochs[12][0], len(p.epochs[12])), *p.epochs[12][1:]]] + p.epochs[13:]
            )
        ),
        lambda p: (
            f"epoch at line {p.line_of(12)} announces {len(p.epochs[12])} satellites but the next epoch "
            f"header follows after {len(p.epochs[12]) - 1} (line {p.line_of(13)})"
        ),
    ),
    (
        "a satellite line lost",
        lambda p: text(p.lines(p.epochs[:12] + [p.epochs[12][:-1]] + p.epochs[13:])),
        lambda p: f"epoch at line {p.line_of(12)} announces",
    ),
    (
        "epochs out of order",
        lambda p: text(_unsorted(p)),
        lambda p: f"epoch at line {p.line_of(11)} is earlier than the epoch at line {p.line_of(10)}",
    ),
    (
        "malformed epoch line",
        lambda p: text(p.lines(p.epochs[:3] + [["> 2019  x 28", *p.epochs[3][1:]]] + p.epochs[4:])),
        lambda p: f"malformed epoch line {p.line_of(3)}",
    ),
    (
        "malformed number",
        lambda p: text(_bad_number(p)),
        lambda p: f"line {p.line_of(7, 2)} has a malformed observation",
    ),
    (
        "RINEX 3 labelled 2.11",
        lambda p: text(["     2.11" + p.head[0][9:], *p.lines()[1:]]),
        lambda p: "is RINEX 2.11 without a '# / TYPES OF OBSERV' header line",
    ),
    ("navigation file", lambda p: NAV.read_bytes(), lambda p: "not RINEX 2/3/4 observation data"),
    ("gzip cut", lambda p: gzip.compress(text(p.lines()))[:5000], lambda p: "cannot be unpacked"),
]


@needs_hk
@pytest.mark.parametrize(("name", "suffix", "make", "warning"), SAME, ids=[c[0] for c in SAME])
def test_copy_reads_as_the_intact_log(
    piece: Piece,
    intact: RinexObs,
    tmp_path: Path,
    name: str,
    suffix: str,
    make: Callable[[Piece], bytes],
    warning: str,
) -> None:
    p = tmp_path / f"piece{suffix}"
    p.write_bytes(make(piece))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        got = read_rinex_obs(p, "GC")
    messages = [str(w.message) for w in caught if issubclass(w.category, SimbenchWarning)]
    if warning:
        assert len(messages) == 1 and warning in messages[0] and "\n" not in messages[0], messages
        assert messages[0].startswith(f"scenario.obs '{p}': ")
    else:
        assert not messages, messages
    assert_same_obs(intact, got)


@needs_hk
@pytest.mark.parametrize(("name", "make", "expected"), REFUSED, ids=[c[0] for c in REFUSED])
def test_damaged_copy_is_refused_in_one_line(
    piece: Piece,
    tmp_path: Path,
    name: str,
    make: Callable[[Piece], bytes],
    expected: Callable[[Piece], str],
) -> None:
    p = tmp_path / "piece.obs"
    p.write_bytes(make(piece))
    msg = one_line_error(read_rinex_obs, p, "GC")
    assert msg.startswith(f"scenario.obs '{p}'") and expected(piece) in msg, msg


@needs_hk
def test_crlf_hong_kong_log_gives_the_same_scenario(tmp_path: Path) -> None:
    """THE key case: the whole Hong Kong log with other line endings (the file itself is CR LF) and
    its truth file with CR LF give the same observation table, truth table and metadata."""
    original = load_rinex(OBS, NAV, TRUTH, systems="GC", nav_bds_path=NAV_BDS, name="hk")
    raw = OBS.read_bytes()
    lf = raw.replace(b"\r\n", b"\n")
    truth = tmp_path / "truth.csv"
    truth.write_bytes(TRUTH.read_bytes().replace(b"\n", b"\r\n"))
    for ending, data in (("lf", lf), ("crcrlf", raw.replace(b"\n", b"\r\n"))):
        obs = tmp_path / f"{ending}.obs"
        obs.write_bytes(data)
        copy = load_rinex(obs, NAV, truth, systems="GC", nav_bds_path=NAV_BDS, name="hk")
        pd.testing.assert_frame_equal(original.observations, copy.observations)
        pd.testing.assert_frame_equal(original.truth, copy.truth)
        assert original.nav == copy.nav
        skip = {"files"}
        assert {k: v for k, v in original.meta.items() if k not in skip} == {
            k: v for k, v in copy.meta.items() if k not in skip
        }
    assert len(original.truth) == 485


@needs_hk
@pytest.mark.parametrize(
    "make",
    [
        lambda b: b.replace(b"\r\n", b"\n"),
        lambda b: b.replace(b"\n", b"\r\n"),
        lambda b: b.replace(b"\r\n", b"\r"),
        gzip.compress,
    ],
    ids=["LF", "CR CR LF", "CR", "gzip"],
)
def test_navigation_files_read_the_same(tmp_path: Path, make: Callable[[bytes], bytes]) -> None:
    gps, bds = tmp_path / "nav.19n", tmp_path / "nav.19b"
    gps.write_bytes(make(NAV.read_bytes()))
    bds.write_bytes(make(NAV_BDS.read_bytes()))
    for a, b in (
        (read_gps_navigation(NAV), read_gps_navigation(gps)),
        (read_navigation("C", NAV_BDS, setting="scenario.nav_bds"), read_navigation("C", bds, setting="x")),
    ):
        assert np.array_equal(a.sats, b.sats)
        assert np.array_equal(a.tgd, b.tgd, equal_nan=True)
        assert a.t_coverage == b.t_coverage


# ---------------------------------------------------------------------------- truth files

TRUTH_HEAD = "week,TOW,lat,lon,h"


@pytest.fixture(scope="module")
def truth_rows(shared_data: Path) -> list[str]:
    return TRUTH.read_text().splitlines()


@pytest.fixture(scope="module")
def piece_files(piece: Piece, tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("piece")
    (d / "piece.obs").write_bytes(text(piece.lines()))
    return d


def _swap_columns(rows: list[str], i: int, j: int) -> list[str]:
    out = []
    for r in rows:
        f = r.split(",")
        f[i], f[j] = f[j], f[i]
        out.append(",".join(f))
    return out


def _set_field(rows: list[str], row: int, col: int, value: str) -> list[str]:
    out = rows[:]
    f = out[row].split(",")
    f[col] = value
    out[row] = ",".join(f)
    return out


TRUTH_REFUSED: list[tuple[str, Callable[[list[str]], list[str]], str]] = [
    ("lat and lon swapped", lambda r: _swap_columns(r, 2, 3), "line 1: column 3 (lat) is 114.179"),
    ("latitude 95", lambda r: _set_field(r, 40, 2, "95.0"), "line 41: column 3 (lat) is 95"),
    ("longitude -181", lambda r: _set_field(r, 7, 3, "-181"), "line 8: column 4 (lon) is -181"),
    ("lat 95 after a header and comments", lambda r: ["# x", TRUTH_HEAD, *_set_field(r, 2, 2, "95")], "line 5:"),
    (
        "unsorted",
        lambda r: r[:20] + [r[21], r[20]] + r[22:],
        "line 22: time 2019-04-28 12:58:41 GPS is earlier than line 21",
    ),
    ("empty", lambda r: [], "cannot be parsed"),
    ("text only", lambda r: [TRUTH_HEAD], "contains no numeric rows"),
    ("six columns", lambda r: [x + ",0" for x in r], "has 6 columns"),
]


@needs_hk
@pytest.mark.parametrize(("name", "make", "expected"), TRUTH_REFUSED, ids=[c[0] for c in TRUTH_REFUSED])
def test_bad_truth_file_is_refused_in_one_line(
    truth_rows: list[str], tmp_path: Path, name: str, make: Callable[[list[str]], list[str]], expected: str
) -> None:
    p = tmp_path / "truth.csv"
    p.write_text("\n".join(make(truth_rows)) + "\n")
    msg = one_line_error(read_reference, p)
    assert msg.startswith(f"scenario.truth '{p}'") and expected in msg, msg


@needs_hk
@pytest.mark.parametrize(
    ("name", "make", "warning"),
    [
        ("CR LF", lambda r: r, ""),
        ("header and comments", lambda r: ["# reference", TRUTH_HEAD, *r], ""),
        ("every row twice", lambda r: [x for x in r for _ in (0, 1)], "485 rows repeat the time of the row before"),
        ("one row twice", lambda r: r[:9] + r[8:], "1 rows repeat the time of the row before (first at line 10)"),
    ],
    ids=["CR LF", "header and comments", "every row twice", "one row twice"],
)
def test_repaired_truth_file_reads_as_the_original(
    truth_rows: list[str], tmp_path: Path, name: str, make: Callable[[list[str]], list[str]], warning: str
) -> None:
    p = tmp_path / "truth.csv"
    p.write_bytes(("\r\n".join(make(truth_rows)) + "\r\n").encode())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        got = read_reference(p)
    messages = [str(w.message) for w in caught if issubclass(w.category, SimbenchWarning)]
    assert (messages == []) if not warning else (len(messages) == 1 and warning in messages[0]), messages
    ref = read_reference(TRUTH)
    assert np.array_equal(ref.t_gps, got.t_gps) and np.array_equal(ref.xyz, got.xyz)


def _xyz_rows(swap: bool) -> list[str]:
    """The Hong Kong truth as ``SOW X Y Z`` (continuous GPS seconds, ECEF), X and Y swapped if ``swap``."""
    ref = read_reference(TRUTH)
    xyz = ref.xyz[:, [1, 0, 2]] if swap else ref.xyz
    return [f"{t:.3f} {x:.4f} {y:.4f} {z:.4f}" for t, (x, y, z) in zip(ref.t_gps, xyz)]


@needs_hk
@pytest.mark.parametrize(
    ("name", "make", "expected"),
    [
        (
            "2 degrees north",
            lambda r: [_set_field([x], 0, 2, f"{float(x.split(',')[2]) + 2:.8f}")[0] for x in r],
            "positions are 221 km from",
        ),
        (
            "western longitude",
            lambda r: [_set_field([x], 0, 3, "-" + x.split(",")[3])[0] for x in r],
            "km from the log's single-point fixes",
        ),
        ("X and Y swapped", lambda r: _xyz_rows(swap=True), "km from the log's single-point fixes"),
    ],
    ids=["2 degrees north", "western longitude", "X and Y swapped"],
)
def test_truth_far_from_the_log_is_refused(
    truth_rows: list[str],
    piece_files: Path,
    tmp_path: Path,
    name: str,
    make: Callable[[list[str]], list[str]],
    expected: str,
) -> None:
    """A reference that is valid on its own but not where the log is: refused with the truth file named,
    instead of a ``diverged`` estimator with errors of thousands of kilometres."""
    p = tmp_path / "truth.txt"
    p.write_text("\n".join(make(truth_rows)) + "\n")
    msg = one_line_error(load_rinex, piece_files / "piece.obs", NAV, p, systems="GC", nav_bds_path=NAV_BDS)
    assert msg.startswith(f"scenario.truth '{p}'") and expected in msg, msg


@needs_hk
def test_piece_with_its_truth_loads(piece_files: Path, tmp_path: Path) -> None:
    """The intact piece and the truth in ECEF (SOW X Y Z) pass the distance check: every epoch scored."""
    p = tmp_path / "truth.xyz"
    p.write_text("\n".join(_xyz_rows(swap=False)) + "\n")
    sc = load_rinex(piece_files / "piece.obs", NAV, p, systems="GC", nav_bds_path=NAV_BDS)
    assert len(sc.truth) == N_EPOCHS


# ---------------------------------------------------------------------------- libRSF


@pytest.fixture(scope="module")
def rsf_lines(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    path = write_synthetic_librsf(tmp_path_factory.mktemp("rsf") / "log.txt", 5.0, systems="GR")
    return path.read_text().splitlines()


def _rsf_field(lines: list[str], kind: str, k: int, field: int, value: str) -> tuple[list[str], int]:
    """``lines`` with field ``field`` (1-based, the keyword is field 1) of the ``k``-th ``kind`` line set."""
    i = [j for j, ln in enumerate(lines) if ln.startswith(kind)][k]
    out = lines[:]
    f = out[i].split()
    f[field - 1] = value
    out[i] = " ".join(f)
    return out, i + 1


RSF_REFUSED: list[tuple[str, str, int, int, str, str]] = [
    ("negative pseudorange variance", "pseudorange3", 17, 4, "-4", "field 4 (pseudorange variance) is -4"),
    ("zero pseudorange variance", "pseudorange3", 3, 4, "0", "field 4 (pseudorange variance) is 0"),
    ("NaN pseudorange", "pseudorange3", 25, 3, "nan", "field 3 ('nan') is not a finite number"),
    ("NaN pseudorange on line 1", "pseudorange3", 0, 3, "NaN", "field 3 ('NaN') is not a finite number"),
    ("NaN C/N0 (last field)", "pseudorange3", 9, 11, "nan", "field 11 ('nan') is not a finite number"),
    ("inf satellite X", "pseudorange3", 30, 5, "inf", "field 5 ('inf') is not a finite number"),
    ("negative odometry variance", "odom3", 4, 10, "-1", "odom3 variance field 10 is -1"),
    ("zero speed variance", "odom3", 6, 9, "0", "odom3 variance field 9 is 0"),
    ("zero yaw-rate variance", "odom3", 2, 14, "0", "odom3 variance field 14 is 0"),
    ("NaN odometry speed", "odom3", 11, 3, "nan", "field 3 ('nan') is not a finite number"),
]


@pytest.mark.parametrize(
    ("name", "kind", "k", "field", "value", "expected"), RSF_REFUSED, ids=[c[0] for c in RSF_REFUSED]
)
def test_bad_librsf_value_names_its_line(
    rsf_lines: list[str], tmp_path: Path, name: str, kind: str, k: int, field: int, value: str, expected: str
) -> None:
    lines, line = _rsf_field(rsf_lines, kind, k, field, value)
    lines = ["# smartLoc-style comment", "", *lines]  # comments and blank lines count as lines
    p = tmp_path / "log.txt"
    p.write_text("\n".join(lines) + "\n")
    msg = one_line_error(read_librsf, p)
    assert msg.startswith(f"scenario.obs '{p}' line {line + 2}: ") and expected in msg, msg


@pytest.mark.parametrize("ending", [b"\r\n", b"\n\n"], ids=["CR LF", "blank line after each"])
def test_librsf_line_endings_read_the_same(rsf_lines: list[str], tmp_path: Path, ending: bytes) -> None:
    a, b = tmp_path / "lf.txt", tmp_path / "other.txt"
    a.write_text("\n".join(rsf_lines) + "\n")
    b.write_bytes(ending.join(ln.encode() for ln in rsf_lines) + ending)
    x, y = read_librsf(a), read_librsf(b)
    pd.testing.assert_frame_equal(x.ranges, y.ranges)
    pd.testing.assert_frame_equal(x.odometry, y.odometry)
    pd.testing.assert_frame_equal(x.reference, y.reference)
