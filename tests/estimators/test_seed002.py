"""seed002 (bench/estimators/seed002.py): configuration, the lever-position models, and the
S002 case's first 260 s in process (alignment at rest, drive-off at 180 s, the idling fault
at 240-245 s) with the two-layer detection and without detection, on the same seed."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from bench.acceptance.case import load_case
from bench.errors import ConfigError
from bench.estimators.seed002 import Seed002
from bench.estimators.seed002_kernel import (
    M_CURVE,
    M_PARKED,
    M_PIVOT,
    M_SHIFTING,
    M_STRAIGHT_HIGH,
    M_STRAIGHT_LOW,
    M_UNKNOWN,
    lever_model,
)
from bench.run.case_runner import spec_from_case
from bench.run.engine import run
from bench.scoring.align import nav_errors
from bench.scoring.data import load_run

CASE = Path(__file__).parents[2] / "test_cases" / "S002_sins_odometer_faults.toml"
START = [39.84991, 116.17715, 60.0]


@pytest.mark.parametrize(
    ("left", "right", "model"),
    [
        (0, 0, M_STRAIGHT_HIGH),
        (1, 1, M_STRAIGHT_LOW),
        (0, 1, M_CURVE),
        (1, 0, M_CURVE),
        (0, 2, M_PIVOT),
        (2, 1, M_PIVOT),
        (2, 2, M_PARKED),
        (-1, 0, M_UNKNOWN),
    ],
)
def test_the_levers_choose_the_seeds_kinematic_model(left, right, model):
    assert lever_model(float(left), float(right), False, True) == model


def test_while_a_lever_moves_and_without_constraints():
    assert lever_model(0.0, 1.0, True, True) == M_SHIFTING
    for left, right in ((0, 1), (0, 2), (2, 2), (1, 1)):
        assert lever_model(float(left), float(right), False, False) == M_STRAIGHT_HIGH


@pytest.mark.parametrize(
    ("config", "key"),
    [
        ({"detection": "three_layer"}, "dut.config.detection"),
        ({"false_alarm": 1.5}, "dut.config.false_alarm"),
        ({"constraints": "yes"}, "dut.config.constraints"),
        ({"odometer_noise": [0.1, 0.1]}, "dut.config.odometer_noise"),
        ({"alignment": "5 s"}, "dut.config.coarse_alignment"),
        ({"wheel_base": 3.0}, "dut.config"),
    ],
)
def test_bad_configuration_names_the_key(config, key):
    est = Seed002()
    with pytest.raises(ConfigError) as err:
        est.configure({"initial_position": START, **config})
    assert key in str(err.value)


def _run(variant: str, out: Path) -> Path:
    case = load_case(CASE).for_variant(variant)
    spec = spec_from_case(case, 1, out)
    spec = dataclasses.replace(spec, duration_ns=260_000_000_000)
    res = run(spec)
    assert res.status == "complete", res.reason
    return Path(res.path)


@pytest.fixture(scope="module")
def short_runs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("s002")
    return {v: load_run(_run(v, folder / v)) for v in ("with_detection", "without_detection")}


def _flags(d):
    q = d.quality[np.argsort(d.quality["t_ns"])]
    return q["t_ns"] * 1e-9, (q["fault_detected"] & 1) != 0, (q["excluded"] & 1) != 0, q["odo_fault_class"]


@pytest.mark.slow
def test_two_layer_detects_and_isolates_the_idling_fault_as_longitudinal(short_runs):
    t, det, exc, cls = _flags(short_runs["with_detection"])
    inside = (t >= 240.0) & (t < 245.0)
    first = t[det & (t >= 240.0)][0]
    assert 240.0 <= first <= 240.5  # within 0.5 s of the onset
    assert np.mean(exc[inside]) >= 0.9
    assert set(cls[det].tolist()) == {1}  # longitudinal: the second layer (lateral, vertical) passed
    assert not np.any(det & (t >= 180.0) & ((t < 240.0) | (t >= 246.0)))  # no false alarm after drive-off


@pytest.mark.slow
def test_without_detection_nothing_is_flagged_and_the_fault_drags_the_solution(short_runs):
    _, det, _, cls = _flags(short_runs["without_detection"])
    assert not det.any() and not cls.any()
    growth = {}
    for v, d in short_runs.items():
        e = nav_errors(d.truth, d.nav)
        t = e.t_ns * 1e-9
        h = np.hypot(e.pos[:, 0], e.pos[:, 1])
        growth[v] = float(np.max(h[(t >= 240.0) & (t <= 246.0)]) - h[np.searchsorted(t, 240.0) - 1])
    assert growth["with_detection"] < 0.5
    assert growth["without_detection"] > 10.0 * max(growth["with_detection"], 0.05)
