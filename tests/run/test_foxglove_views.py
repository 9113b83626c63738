"""The Foxglove views of real runs: the engine with an in-process estimator on the virtual
bus. Every view of the recording decodes with mcap_protobuf; the DUT's map shows its valid
epochs only, with the NAV_QUALITY covariance; the pose arrows of a northward and an
eastward drive point north and east; the plotted horizontal error is scoring's; `bench
views` copies a recording (also one with the old JSON views) into one that scores the same.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from bench.cli import main
from bench.faults.schedule import FaultSchedule
from bench.record.copy import copy_records
from bench.record.foxglove import COVARIANCE_DIAGONAL_KNOWN, COVARIANCE_KNOWN
from bench.record.mcap_io import RecordingReader, RecordingWriter
from bench.run.engine import run
from bench.run.spec import ClockSpec, DutSpec, RunSpec
from bench.scenario.loader import load_scenario
from bench.scoring.accuracy import QUANTITIES
from bench.scoring.data import load_run
from bench.scoring.metrics import Scorer
from bench.scoring.viewwrite import is_view
from tests.record.views_util import bench_ns, decode_views, rotate_x

DATA = Path(__file__).parent / "data"
ROOT = Path(__file__).resolve().parents[2]
CASE_REC = Path("recordings") / "SHORT-DR" / "SHORT-DR-s3.mcap"


def _short_case(folder: Path, duration_s: float) -> Path:
    """tests/run/data/short_dr.toml cut to ``duration_s`` of its drive."""
    text = (DATA / "short_dr.toml").read_text()
    text = text.replace('script = "../../data/short_drive.toml"',
                        f'script = "{ROOT / "tests" / "data" / "short_drive.toml"}"\nduration = "{duration_s:g} s"')
    text = text.replace("[case]\n", '[case]\nshortened = "a test of the Foxglove views"\n', 1)
    out = folder / "short_dr.toml"
    out.write_text(text)
    return out


@pytest.fixture(scope="module")
def case_run(tmp_path_factory):
    """A 40 s run of the SHORT-DR case (dead reckoning in process, virtual CAN bus)."""
    folder = tmp_path_factory.mktemp("case")
    case = _short_case(folder, 40.0)
    assert main(["run", str(case), "-o", str(folder / "out"), "-q", "--no-plots"]) == 0
    path = folder / "out" / CASE_REC
    return path, decode_views(path)


def test_every_view_of_a_run_decodes(case_run):
    path, views = case_run
    assert {"/foxglove/truth/location", "/foxglove/truth/pose", "/foxglove/tf/truth", "/foxglove/dut/location",
            "/foxglove/dut/pose", "/foxglove/tf/dut", "/foxglove/plot/truth", "/foxglove/plot/dut",
            "/foxglove/plot/errors", "/foxglove/plot/bench"} <= set(views)
    assert len(views["/foxglove/truth/location"]) == 40 * 5 + 1  # 40 s at 5 Hz
    assert len(views["/foxglove/plot/truth"]) == 40 * 10 + 1  # 40 s at 10 Hz
    r = RecordingReader(path)
    epoch = r.epoch_ns()
    nav, quality = r.read_columnar("/dut/nav_solution"), r.read_columnar("/dut/nav_quality")
    assert (nav["valid"] == 0).sum() > 100  # the estimator aligns for 4 s: invalid epochs
    valid_t = set(nav["t_ns"][nav["valid"] != 0].tolist())
    sigma = {int(t): s for t, s in zip(quality["t_ns"], quality["sigma_pos"], strict=True)}
    fixes = views["/foxglove/dut/location"]
    assert len(fixes) > 30 * 5  # over 30 s valid at 5 Hz
    for _, fix in fixes:
        t = bench_ns(epoch, fix.timestamp)
        assert t in valid_t and abs(fix.latitude) > 1 and abs(fix.longitude) > 1
        assert fix.position_covariance_type == COVARIANCE_DIAGONAL_KNOWN
        cov = np.array(fix.position_covariance).reshape(3, 3)
        assert np.array_equal(cov, np.diag(sigma[t] ** 2)) and np.all(np.diag(cov) > 0)
    for _, fix in views["/foxglove/truth/location"]:
        assert fix.position_covariance_type == COVARIANCE_KNOWN and not any(fix.position_covariance)
    assert r.metadata()["run_end"]["status"] == "complete"


def test_plotted_horizontal_error_is_the_scorings(case_run):
    path, views = case_run
    err = Scorer(load_run(path)).errors
    h = dict(zip(err.t_ns.tolist(), QUANTITIES["horizontal"][2](err).tolist(), strict=True))
    epoch = RecordingReader(path).epoch_ns()
    plotted = views["/foxglove/plot/errors"]
    assert len(plotted) > 30 * 10  # over 30 s at 10 Hz
    for log_time, m in plotted:
        assert m.horizontal_m == h[log_time - epoch]


def _drive(folder: Path, heading_deg: float) -> Path:
    scenario = folder / "drive.toml"
    scenario.write_text(f"""[scenario]
id = "STRAIGHT"
title = "straight drive"
start_utc = "2026-03-01T08:00:00Z"

[initial]
latitude = 34.246
longitude = 108.909
height = "380 m"
heading = "{heading_deg:g} deg"

[[segment]]
kind = "static"
duration = "5 s"

[[segment]]
kind = "accelerate"
speed = "10 m/s"
duration = "14 s"

[[segment]]
kind = "uniform"
duration = "10 s"
""")
    spec = RunSpec(scenario=load_scenario(scenario), tables={"imu": {"grade": "navigation", "rate": "200 Hz"},
                                                             "doppler": {"model": "seed000"}},
                   schedule=FaultSchedule(), out=folder / "run.mcap", seed=1, clock=ClockSpec(),
                   dut=DutSpec("in_process", name="dead_reckoning",
                               config={"initial_position": [34.246, 108.909, 380.0], "alignment": "4 s"}))
    res = run(spec)
    assert res.ok, res.reason
    return res.path


@pytest.mark.parametrize(("heading_deg", "axis"), [(0.0, (0.0, 1.0, 0.0)), (90.0, (1.0, 0.0, 0.0))])
def test_pose_arrow_of_a_straight_drive_points_along_it(tmp_path, heading_deg, axis):
    views = decode_views(_drive(tmp_path, heading_deg))
    want = np.array(axis)
    for topic, tol_deg in (("/foxglove/truth/pose", 0.01), ("/foxglove/dut/pose", 1.0)):
        poses = views[topic]
        assert len(poses) > 100
        for _, m in poses:
            assert m.frame_id == "enu_start"
            angle = math.degrees(math.acos(min(1.0, float(rotate_x(m.pose.orientation) @ want))))
            assert angle < tol_deg, (topic, angle)
    for topic in ("/foxglove/tf/truth", "/foxglove/tf/dut"):
        for _, m in views[topic]:
            assert math.degrees(math.acos(min(1.0, float(rotate_x(m.rotation) @ want)))) < 1.0
    _, last = views["/foxglove/truth/pose"][-1]
    p = np.array([last.pose.position.x, last.pose.position.y])
    assert float(p @ want[:2]) > 100 and abs(float(p[0] * want[1] - p[1] * want[0])) < 0.5  # moved along the axis


def _results(path: Path, out: Path, capsys) -> list:
    assert main(["score", str(path), "--json", str(out)]) == 0
    capsys.readouterr()
    doc = json.loads(out.read_text())
    out = [(c["id"], c["verdict"], c["value_si"], c["reason"], [(r["value"], r["verdict"]) for r in c["runs"]])
           for case in doc["cases"] for c in case["criteria"]]
    return [doc["verdict"], *out]


def test_bench_views_copy_scores_identically(case_run, tmp_path, capsys):
    path, _ = case_run
    # an older recording: no protobuf views, the JSON LocationFix of before
    old = tmp_path / "old.mcap"
    with RecordingReader(path) as src, RecordingWriter(old, epoch_ns=src.epoch_ns()) as rec:
        end = copy_records(src, rec, keep=lambda t, n, e: not is_view(t, n, e))
        rec.json_topic("/truth/location", "foxglove.LocationFix", {"type": "object"})
        rec.write_json("/truth/location", 0, {"latitude": 34.246, "longitude": 108.909})
        rec.close(end["status"], end["reason"])
    new = tmp_path / "new.mcap"
    assert main(["views", str(old), "-o", str(new)]) == 0
    assert main(["views", str(old), "-o", str(new)]) == 2  # not overwritten without --force
    capsys.readouterr()
    a, b, c = RecordingReader(path), RecordingReader(old), RecordingReader(new)
    assert "/truth/location" not in c.topics() and "/truth/location" in b.topics()
    views_of = {x: {t for t in x.topics() if t.startswith("/foxglove/")} for x in (a, c)}
    assert views_of[a] and views_of[c] == views_of[a]
    sources = [t for t in a.topics() if not t.startswith("/foxglove/")]
    assert sources and list(c.iter_raw(sources)) == list(a.iter_raw(sources))
    assert c.metadata() == a.metadata() and c.attachments() == a.attachments() and c.intact
    ra = _results(path, tmp_path / "a.json", capsys)
    assert ra and ra == _results(new, tmp_path / "c.json", capsys)
    assert main(["info", str(new)]) == 0
    decode_views(new)
