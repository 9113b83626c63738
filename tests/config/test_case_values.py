"""Any hostile value at any key of a test case is either accepted or refused with a
ConfigError naming the file: never another exception, never a non-finite number."""

from __future__ import annotations

import contextlib
import copy
import math
import tomllib
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.acceptance.schema import build_case
from bench.errors import ConfigError
from tests.config.conftest import DRIVE, base_case

_EXTRA = """
[[fault]]
layer = "wire"
target = "serial:imu"
kind = "garbage"
start = "10 s"
end = "20 s"
params = { every = "100 ms", length = 8 }

[[fault]]
target = "odometer"
kind = "idling"
start = "30 s"
duration = "5 s"
params = { ratio = 0.3 }

[clock]
step = "10 ms"
speed = 1.0

[scoring]
convergence = "5 s"

[[dut.synthetic.output]]
kind = "bad_frames"
every = 2.0
start = "10 s"
end = "20 s"

[[criterion]]
id = "P"
requirement = "R2"
metric = "accuracy.horizontal.rms"
at_most = "8 m"
monte_carlo = { percentile = 95, confidence = 0.9 }
"""

HOSTILE = [math.nan, math.inf, -math.inf, -1, 0, 0.0, 1e300, 10**18, 2**70, -(2**70), "", "nan", "1e300 s",
           "1e400 m", "1 ns", "-5 s", "20 kHz", "km^400", [], [math.nan], {}, {"x": math.nan}, True, "0 or 1"]


def _doc() -> dict[str, Any]:
    return tomllib.loads(base_case() + _EXTRA)


def _leaves(node: Any, path: tuple = ()) -> list[tuple]:
    if isinstance(node, dict):
        return [p for k, v in node.items() for p in _leaves(v, (*path, k))] + ([path] if path else [])
    if isinstance(node, list):
        return [p for i, v in enumerate(node) for p in _leaves(v, (*path, i))] + [path]
    return [path]


_DOC = _doc()
_PATHS = sorted(_leaves(_DOC), key=repr)


def _set(doc: dict[str, Any], path: tuple, value: Any) -> None:
    node = doc
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value


def test_the_unmodified_case_loads(folder):
    build_case(copy.deepcopy(_DOC), text="", file=str(folder / "case.toml"), base=folder, check_files=True, path=None)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(_PATHS), st.sampled_from(HOSTILE)), min_size=1, max_size=3))
def test_a_hostile_value_anywhere_is_accepted_or_a_config_error(tmp_path_factory, changes):
    folder = tmp_path_factory.mktemp("case")
    (folder / "drive.toml").write_text(DRIVE)
    doc = copy.deepcopy(_DOC)
    for path, value in changes:
        with contextlib.suppress(KeyError, IndexError, TypeError):  # an earlier change replaced the parent
            _set(doc, path, copy.deepcopy(value))
    file = str(folder / "case.toml")
    try:
        case = build_case(doc, text="", file=file, base=folder, check_files=True, path=None)
    except ConfigError as exc:
        assert exc.file == file or file in str(exc)
        return
    for c in case.criteria:  # what was accepted is finite
        for x in (c.limit.low, c.limit.high, c.marginal, c.marginal_relative):
            assert x is None or math.isfinite(x)
    assert 1 <= len(case.run.seeds) <= 10_000
    assert all(0 <= w.start_ns < w.end_ns <= 2_592_000 * 10**9 for w in case.faults)


@pytest.mark.parametrize("value", HOSTILE)
def test_every_hostile_value_at_every_limit(folder, value):
    for key in ("at_most", "marginal"):
        doc = copy.deepcopy(_DOC)
        doc["criterion"][0][key] = copy.deepcopy(value)
        try:
            case = build_case(doc, text="", file="c.toml", base=folder, check_files=True, path=None)
        except ConfigError as exc:
            assert exc.file == "c.toml" and exc.key and exc.key.startswith("criterion[0]")
            continue
        c = case.criteria[0]
        assert math.isfinite(c.limit.high) and (c.marginal is None or math.isfinite(c.marginal))
