"""Export then import of a run's own DUT output scores the same as the run.

seed000 runs in process on a one-minute drive (tests/exchange/reference_case.toml); its
solution and quality go out as ``dut.nav`` and ``dut_std.txt`` (``bench export --dut``),
come back as the DUT output of a copy of the run (``bench import-nav``), and every
criterion of the case must have the same value on both recordings. The files carry the
ICD's resolutions (1e-7 deg, 1 mm, 0.1 mm/s; sigmas 0.01 m, 1 mm/s, 0.01 arcmin), so the
re-encoded frames are those the DUT sent and the values agree to rounding of the metric.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from bench.acceptance.judge import score_recording
from bench.cli import main
from bench.record.mcap_io import RecordingReader
from tests.record.views_util import decode_views

HERE = Path(__file__).parent
CASE = HERE / "reference_case.toml"


@pytest.fixture(scope="module")
def reference_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("ref")
    assert main(["run", str(CASE), "-o", str(out), "-q", "--no-plots"]) == 0
    return out / "recordings" / "XCH-REF" / "XCH-REF-s1.mcap"


def test_export_then_import_of_the_dut_output_scores_the_same(reference_run, tmp_path, capsys):
    folder = tmp_path / "x"
    assert main(["export", str(reference_run), "--format", "i2nav", "-o", str(folder), "--dut"]) == 0
    for name in ("imu.txt", "doppler.txt", "truth.nav", "dut.nav", "dut_std.txt", "kf-gins.yaml"):
        assert (folder / name).is_file(), name
    imported = tmp_path / "imported.mcap"
    assert main(["import-nav", str(folder / "dut.nav"), "--run", str(reference_run), "--std",
                 str(folder / "dut_std.txt"), "-o", str(imported)]) == 0
    assert "rejected" not in capsys.readouterr().out
    _, live = score_recording(reference_run)
    _, back = score_recording(imported)
    assert set(live.values) == set(back.values) and len(live.values) >= 15
    for cid, rv in live.values.items():
        other = back.values[cid]
        assert other.verdict == rv.verdict, cid
        assert math.isclose(other.value, rv.value, rel_tol=1e-9, abs_tol=1e-12), (cid, rv.value, other.value)
    assert back.verdict == live.verdict
    # the imported recording is the run with another DUT output: same truth and sensor samples
    with RecordingReader(reference_run) as a, RecordingReader(imported) as b:
        assert b.intact
        for topic in ("/truth", "/imu", "/doppler", "/wire/imu/tx", "/wire/can/tx"):
            assert list(a.iter_raw([topic])) == list(b.iter_raw([topic])), topic
        assert len(b.read_columnar("/dut/nav_solution")) == len(a.read_columnar("/dut/nav_solution"))
        start = b.metadata()["run_start"]
        assert json.loads(start["dut_import"])["nav"].endswith("dut.nav")
        assert b.metadata()["run_end"]["status"] == "complete"


def test_an_imported_output_that_differs_scores_differently(reference_run, tmp_path):
    """The round trip can fail: a result 10 m north of the run's output is judged on its own."""
    folder = tmp_path / "x"
    assert main(["export", str(reference_run), "-o", str(folder), "--dut"]) == 0
    lines = (folder / "dut.nav").read_text().splitlines()
    shifted = []
    for ln in lines:
        c = ln.split()
        c[2] = f"{float(c[2]) + 10.0 / 111_000:.11f}"
        shifted.append(" ".join(c))
    (folder / "moved.nav").write_text("\n".join(shifted) + "\n")
    out = tmp_path / "moved.mcap"
    assert main(["import-nav", str(folder / "moved.nav"), "--run", str(reference_run), "-o", str(out)]) == 0
    _, live = score_recording(reference_run)
    _, moved = score_recording(out)
    assert moved.values["H-RMS"].value > live.values["H-RMS"].value + 5.0
    # without the STD file there is no NAV_QUALITY: the integrity check names it
    assert moved.values["INTEGRITY-quality"].value > 0
    # the Foxglove views are derived again from the imported output, not kept from the run's DUT
    live_views, moved_views = decode_views(reference_run), decode_views(out)
    assert set(moved_views) == set(live_views)
    lat_live = {t: m.latitude for t, m in live_views["/foxglove/dut/location"]}
    lat_moved = {t: m.latitude for t, m in moved_views["/foxglove/dut/location"]}
    both = sorted(set(lat_live) & set(lat_moved))  # the .nav has no validity flag: more epochs come back valid
    assert len(both) >= 10
    assert all(abs(lat_moved[t] - lat_live[t] - 10.0 / 111_000) < 1e-6 for t in both)
    h_moved = [m.horizontal_m for _, m in moved_views["/foxglove/plot/errors"]]
    assert max(h_moved) > 5.0


def test_std_lines_in_any_order_pair_with_their_epochs(reference_run, tmp_path):
    folder = tmp_path / "x"
    assert main(["export", str(reference_run), "-o", str(folder), "--dut"]) == 0
    lines = (folder / "dut_std.txt").read_text().splitlines()
    (folder / "reversed_std.txt").write_text("\n".join(reversed(lines)) + "\n")
    out = tmp_path / "r.mcap"
    assert main(["import-nav", str(folder / "dut.nav"), "--run", str(reference_run), "--std",
                 str(folder / "reversed_std.txt"), "-o", str(out)]) == 0
    _, live = score_recording(reference_run)
    _, back = score_recording(out)
    assert back.values["INTEGRITY-quality"].value == 0
    assert back.values["NEES-POS"].value == pytest.approx(live.values["NEES-POS"].value, rel=1e-12)


@pytest.mark.parametrize(
    ("mutate", "criterion"),
    [
        (lambda lines: lines[::-1], "INTEGRITY-order"),  # epochs in reverse order
        (lambda lines: [ln for ln in lines for _ in (0, 1)], "INTEGRITY-repeated"),  # every epoch twice
        (lambda lines: lines[: len(lines) // 3], "INTEGRITY-missing"),  # output stops a third of the way
    ],
)
def test_an_imported_output_that_misbehaves_fails(reference_run, tmp_path, mutate, criterion):
    """A result the DUT wrote out of order, twice over or cut short is judged FAIL, never PASS."""
    folder = tmp_path / "x"
    assert main(["export", str(reference_run), "-o", str(folder), "--dut"]) == 0
    lines = [ln for ln in (folder / "dut.nav").read_text().splitlines() if ln.strip()]
    (folder / "bad.nav").write_text("\n".join(mutate(lines)) + "\n")
    out = tmp_path / "bad.mcap"
    assert main(["import-nav", str(folder / "bad.nav"), "--run", str(reference_run), "--std",
                 str(folder / "dut_std.txt"), "-o", str(out)]) == 0
    _, judged = score_recording(out)
    assert judged.values[criterion].verdict.name == "FAIL", judged.values[criterion]
    assert judged.verdict.name == "FAIL"
