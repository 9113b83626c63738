"""Any hostile value at any key of a motion script is either built into a bounded, finite
trajectory or refused with a ConfigError naming the file: never another exception."""

from __future__ import annotations

import contextlib
import copy
import math
import tomllib
from typing import Any

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.errors import ConfigError
from bench.scenario.motion import build_profile
from bench.scenario.script_values import check_script_size

SCRIPT = """
[scenario]
id = "H"

[initial]
latitude = 30.0
longitude = 110.0
height = "50 m"
heading = "10 deg"

[limits]
accel = "1 m/s^2"

[[segment]]
kind = "accelerate"
speed = "10 m/s"
duration = "20 s"

[[segment]]
kind = "turn"
direction = "left"
angle = "90 deg"
rate = "5 deg/s"
duration = "30 s"
repeat = 2

[[segment]]
kind = "climb"
angle = "2 deg"
duration = "20 s"

[[segment]]
kind = "stop"
"""

HOSTILE = [math.nan, math.inf, -math.inf, -1, 0, 1e300, 10**18, 2**70, "", "1e300 s", "1e400 m", "1e306 km",
           "1 ns", "-5 s", "1e9 deg", "1e300 m/s", [], {}, True, 100_000_000, "34°14.763'Q"]
DOC = tomllib.loads(SCRIPT)


def _leaves(node: Any, path: tuple = ()) -> list[tuple]:
    if isinstance(node, dict):
        return [p for k, v in node.items() for p in _leaves(v, (*path, k))] + ([path] if path else [])
    if isinstance(node, list):
        return [p for i, v in enumerate(node) for p in _leaves(v, (*path, i))] + [path]
    return [path]


PATHS = sorted(_leaves(DOC), key=repr)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.sampled_from(PATHS), st.sampled_from(HOSTILE)), min_size=1, max_size=2))
def test_a_hostile_value_anywhere_in_a_script_builds_bounded_or_is_refused(changes):
    doc = copy.deepcopy(DOC)
    for path, value in changes:
        with contextlib.suppress(KeyError, IndexError, TypeError):
            node = doc
            for k in path[:-1]:
                node = node[k]
            node[path[-1]] = copy.deepcopy(value)
    try:
        check_script_size(doc.get("segment"), file="s.toml")
        traj = build_profile(doc, file="s.toml")
    except ConfigError as exc:
        assert exc.file == "s.toml"
        return
    assert 0 < traj.duration_s <= 2_592_000
    k = traj.kinematics(np.linspace(0.0, traj.duration_s, 7))
    arrays = [v for v in vars(k).values() if isinstance(v, np.ndarray)]
    assert arrays and all(np.all(np.isfinite(v)) for v in arrays)
