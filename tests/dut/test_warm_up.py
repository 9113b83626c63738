"""The estimator's ``warm_up`` hook: called once, after configuration and before the first
step; through the harness before it opens its links, so before its first DUT_READY (a
kernel compiled inside a step left the bench without an answer for as long as it took)."""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import numpy as np

import bench.dut.harness as harness_module
from bench.dut.estimator import Estimator, EstimatorOutput, register_estimator
from bench.faults.schedule import FaultSchedule
from bench.run.engine import run
from bench.run.spec import DutSpec, RunSpec
from bench.scenario.loader import load_scenario
from bench.topics import NAV_SOLUTION_DTYPE
from bench.wire.can import codec
from tests.dut.harness_util import drive_harness

SHORT = Path(__file__).parent.parent / "data" / "short_drive.toml"
READY_ID = codec("DUT_READY").frame_id


class _Records(Estimator):
    """Notes every call, in order, in the class's ``events``."""

    name = "records_warm_up"
    events: ClassVar[list[str]] = []

    def configure(self, config):
        type(self).events.append("configure")

    def warm_up(self):
        type(self).events.append("warm_up")

    def step(self, inputs):
        type(self).events.append("step")
        sol = np.zeros(1, NAV_SOLUTION_DTYPE)
        sol["t_ns"] = inputs.t_ns
        return EstimatorOutput(sol)


def _first(events: list[str], what: str) -> int:
    assert what in events, events[:10]
    return events.index(what)


def test_the_harness_warms_the_estimator_up_before_its_links_and_its_first_dut_ready(monkeypatch):
    _Records.events = []
    events = _Records.events
    opened = harness_module.open_can_link

    def open_can_link(*args, **kwargs):  # the harness's CAN link, noting what it sends
        events.append("links")
        link = opened(*args, **kwargs)
        send_many = link.send_many

        def noted(batch):
            if np.any(batch.can_id == READY_ID):
                events.append("DUT_READY")
            return send_many(batch)

        link.send_many = noted
        return link

    monkeypatch.setattr(harness_module, "open_can_link", open_can_link)
    register_estimator(_Records.name, _Records)
    done = drive_harness(_Records.name, {}, 4)
    assert done.error is None, done.error
    assert len(done.nav.ready_ns) == 4  # answered every step
    assert events.count("warm_up") == 1
    assert _first(events, "configure") < _first(events, "warm_up") < _first(events, "links") \
        < _first(events, "step") < _first(events, "DUT_READY"), events


def test_an_in_process_run_warms_the_estimator_up_once_before_its_first_step(tmp_path):
    _Records.events = []
    register_estimator(_Records.name, _Records)
    spec = RunSpec(scenario=load_scenario(SHORT), tables={"imu": {"grade": "navigation", "rate": "200 Hz"}},
                   schedule=FaultSchedule(), dut=DutSpec("in_process", name=_Records.name), out=tmp_path / "r.mcap",
                   duration_ns=1_000_000_000)
    res = run(spec)
    assert res.status == "complete", res.reason
    events = _Records.events
    assert events[:2] == ["configure", "warm_up"] and events.count("warm_up") == 1
    assert events.count("step") >= 100  # 10 ms steps over 1 s: every step after the warm-up
