"""Driver-command scripts: steps, ramps, holds at the command rate, segments, errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.plant.driver import parse_commands
from bench.scenario.loader import load_scenario


def test_steps_ramps_and_held_values():
    s = parse_commands(
        [
            {"at": "0 s", "left_lever": "II", "right_lever": "II", "label": "parked"},
            {"at": "10 s", "left_lever": "former", "right_lever": 0, "throttle": {"to": 0.5, "over": "5 s"}},
            {"at": "20 s", "right_lever": "I", "grade": "3 deg", "surface": "dirt"},
        ],
        30.0, file="t", surface="cement",
    )
    t = np.array([5.0, 12.5, 12.505, 16.0, 25.0])
    assert s.value("throttle", t) == pytest.approx([0.0, 0.25, 0.2505, 0.5, 0.5])
    assert s.held("throttle", t) == pytest.approx([0.0, 0.25, 0.25, 0.5, 0.5])  # 100 Hz ticks
    assert s.value("grade", np.array([19.99, 20.0]))[1] == pytest.approx(math.radians(3.0))
    assert [seg.kind for seg in s.segments()] == ["parked", "straight", "turning_in_curve"]
    assert [seg.surface for seg in s.segments()] == ["cement", "cement", "dirt"]
    assert s.surface_changes() == [(0.0, "cement"), (20.0, "dirt")]
    ticks, vals = s.ticks(["throttle", "right_lever"])
    # t = 0, the levers at 10 s, the 5 s ramp at 100 Hz after them, the right lever at 20 s
    assert ticks[0] == 0.0 and len(ticks) == 1 + 1 + 500 + 1
    assert vals[-1] == pytest.approx([0.5, 1.0])


@pytest.mark.parametrize(
    ("commands", "match"),
    [
        ([{"at": "1 s", "throttle": 0.1}], "start at 0 s"),
        ([{"at": "0 s"}, {"at": "0 s", "throttle": 0.2}], "increase in time"),
        ([{"at": "0 s", "throttle": 1.5}], "within 0..1"),
        ([{"at": "0 s", "left_lever": 3}], "lever position"),
        ([{"at": "0 s", "left_lever": {"to": 1, "over": "1 s"}}], "levers only step"),
        ([{"at": "0 s", "throttle": {"to": 1, "over": "5 s"}}, {"at": "2 s", "throttle": 0.0}], "before the ramp"),
        ([{"at": "0 s", "speed": 3}], "unknown key 'speed'"),
        ([{"at": "0 s", "surface": "lava"}], "expected one of"),
        ([{"at": "0 s"}, {"at": "40 s"}], "not before the end"),
    ],
)
def test_script_errors_name_the_field(commands, match):
    with pytest.raises(ConfigError, match=match):
        parse_commands(commands, 30.0, file="t")


def test_a_scenario_has_one_motion_source(tmp_path):
    p = tmp_path / "x.toml"
    p.write_text('[scenario]\nid = "X"\n[plant]\nvehicle = "tracked_seed002"\nduration = "1 s"\n'
                 '[[segment]]\nkind = "static"\nduration = "1 s"\n')
    with pytest.raises(ConfigError, match="exactly one of"):
        load_scenario(p)
