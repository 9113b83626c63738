"""The report's per-case figures: decodable, non-blank PNGs drawn with the scoring's numbers,
left out when the recording lacks their data, never a crash."""

from __future__ import annotations

import io
import math

import matplotlib.image as mpimg
import numpy as np
import pytest

from bench.acceptance.case import load_case
from bench.acceptance.synthetic import SyntheticRunner
from bench.report.figdata import decimate, load_figure_run
from bench.report.figures import Figure, case_figures
from bench.scoring.align import nav_errors
from bench.scoring.data import load_run
from bench.scoring.metrics import Scorer
from bench.scoring.windows import WindowSpec
from tests.acceptance.conftest import DRIVE

CASE = """
[case]
id = "FIG"
title = "figures"
requirements = ["R"]

[scenario]
script = "drive.toml"

[[fault]]
start = "20 s"
end = "25 s"
target = "odometer"
kind = "idling"

[[fault]]
start = "150 s"
end = "160 s"
target = "odometer"
kind = "sliding"

[[command]]
at = "100 s"
command = "grid"

[dut]
kind = "synthetic"

[dut.synthetic]
rate = "100 Hz"
latency = "5 ms"
sigma_position = ["1 m", "1 m", "1 m"]
sigma_velocity = ["0.1 m/s", "0.1 m/s", "0.1 m/s"]
sigma_attitude = ["1 arcmin", "1 arcmin", "1 arcmin"]

[[dut.synthetic.error]]
kind = "markov"
quantity = "position"
sigma = ["1 m", "1 m", "0.5 m"]
tau = "10 s"

[[dut.synthetic.error]]
kind = "switch_step"
quantity = "position"
value = ["0 m", "1.5 m", "0 m"]

[[dut.synthetic.detect]]
target = "odometer"
windows = [0]
latency = "0.5 s"
exclude = true
{extra}
[run]
seeds = [3]

[[criterion]]
id = "HMAX"
requirement = "R"
metric = "accuracy.horizontal.max"
at_most = "8 m"
"""

NO_QUALITY = """
[[dut.synthetic.output]]
kind = "no_quality"
start = "0 s"
"""

NO_OUTPUT = """
[[dut.synthetic.output]]
kind = "drop"
start = "0 s"
"""

CRITERIA = [
    {"id": "HMAX", "metric": "accuracy.horizontal.max", "unit": "m", "limit_si": {"low": None, "high": 8.0},
     "comparator": "at_most", "window": "all", "variant": None},
    {"id": "H95", "metric": "accuracy.horizontal.cep95", "unit": "m", "limit_si": {"low": None, "high": 5.0},
     "comparator": "at_most", "window": "converged", "variant": None},
    {"id": "OTHER", "metric": "accuracy.horizontal.max", "unit": "m", "limit_si": {"low": None, "high": 1.0},
     "comparator": "at_most", "window": "all", "variant": "some_other_variant"},
]


def _record(tmp_path_factory, name: str, extra: str = ""):
    d = tmp_path_factory.mktemp(name)
    (d / "drive.toml").write_text(DRIVE)
    (d / "case.toml").write_text(CASE.replace("{extra}", extra))
    return SyntheticRunner().run(load_case(d / "case.toml"), 3, d)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    return _record(tmp_path_factory, "full")


@pytest.fixture(scope="module")
def figures(recording) -> dict[str, Figure]:
    return {f.key: f for f in case_figures(recording, CRITERIA, title="FIG")}


def _pixels(png: bytes) -> np.ndarray:
    return mpimg.imread(io.BytesIO(png), format="png")


def test_every_figure_with_data_is_drawn_as_a_decodable_non_blank_png(figures):
    assert list(figures) == ["trajectory", "errors", "cdf", "nees", "switch-1", "faults"]
    for f in figures.values():
        img = _pixels(f.png)
        assert img.ndim == 3 and img.shape[0] > 300 and img.shape[1] > 500
        assert float(np.var(img[..., :3])) > 1e-3, f.key  # not blank
        assert len(f.png) < 200_000, f.key
        assert f.title and f.alt and f.caption


def test_the_loader_reads_what_load_run_reads(recording):
    fast, full = load_figure_run(recording), load_run(recording)
    for name in ("truth", "nav", "quality"):
        assert np.array_equal(getattr(fast, name), getattr(full, name))
    assert fast.faults == full.faults and fast.segments == full.segments and fast.commands == full.commands
    assert fast.case_attachment() == full.case_attachment()


def test_cep_marks_are_the_percentiles_of_the_horizontal_error(recording, figures):
    run = load_run(recording)
    e = nav_errors(run.truth, run.nav)
    h = np.hypot(e.pos[e.usable, 0], e.pos[e.usable, 1])  # window: 'converged', no convergence time set: all
    v = figures["cdf"].values
    assert v["cep50"] == np.percentile(h, 50)
    assert v["cep95"] == np.percentile(h, 95)
    assert v["epochs"] == len(h)
    assert f"CEP95 {v['cep95']:.3g} m" in figures["cdf"].alt


def test_limits_of_this_variant_are_drawn_and_named_in_the_caption(figures):
    cap = figures["errors"].caption
    assert "HMAX" in cap and "accuracy.horizontal.max" in cap
    assert "OTHER" not in cap  # another variant's criterion


def test_nees_statistics_are_the_scorings(recording, figures):
    s = Scorer(load_run(recording))
    v = figures["nees"].values
    for q, dof in (("position", 3), ("velocity", 3), ("heading", 1)):
        assert v[f"{q}_within"] == s.metric(f"consistency.{q}.within", WindowSpec("all")).value
        assert v[f"{q}_nees"] == s.metric(f"consistency.{q}.nees", WindowSpec("all")).value
        assert v[f"{q}_lower"] < dof < v[f"{q}_upper"]


def test_fault_timeline_shows_the_scorings_latency(recording, figures):
    s = Scorer(load_run(recording))
    details = s.metric("faults.latency_max", WindowSpec("all")).details["windows"]
    v = figures["faults"].values
    for w in details:
        lat = w["latency_s"]
        assert v[f"latency_{w['id']}"] == (math.inf if lat is None else lat)
    assert v["latency_0"] == pytest.approx(0.5, abs=0.011)
    assert math.isinf(v["latency_1"])  # the second window is not detected
    assert "1 of 2 fault windows detected" in figures["faults"].alt


def test_the_switch_close_up_is_centred_on_the_commanded_switch(figures):
    v = figures["switch-1"].values
    assert 100.0 <= v["t_s"] < 101.0
    assert v["position_jump"] == pytest.approx(1.5, abs=0.3)


def test_a_dut_without_sigmas_gets_no_nees_figure(tmp_path_factory):
    rec = _record(tmp_path_factory, "noq", NO_QUALITY)
    keys = [f.key for f in case_figures(rec, CRITERIA)]
    assert "nees" not in keys and "faults" not in keys
    assert keys[:3] == ["trajectory", "errors", "cdf"]


def test_a_recording_without_dut_output_gives_the_truth_trajectory_only(tmp_path_factory):
    rec = _record(tmp_path_factory, "noout", NO_OUTPUT)
    figs = case_figures(rec, CRITERIA)
    assert [f.key for f in figs] == ["trajectory"]
    assert "truth only" in figs[0].caption
    assert float(np.var(_pixels(figs[0].png)[..., :3])) > 1e-3


def test_decimation_keeps_every_extreme():
    t = np.arange(100_000) * 0.01
    y = np.sin(t) + np.where(np.arange(100_000) == 54_321, 50.0, 0.0)
    td, yd = decimate(t, y, n=1000)
    assert len(td) <= 2100 and np.all(np.diff(td) > 0)
    assert yd.max() == y.max() and yd.min() == y.min()
    _, short_y = decimate(t[:100], y[:100], n=1000)
    assert np.array_equal(short_y, y[:100])
