"""The Table getters: types, finite numbers, bounds, unknown keys, each error naming the
file and the dotted key."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.config.table import Table, check_keys, unknown_key
from bench.errors import ConfigError
from bench.units import quantity

F = "case.toml"


def _err(fn, *args, **kw) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        fn(*args, **kw)
    assert info.value.file == F
    return info.value


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_number_refuses_nan_and_inf(value):
    e = _err(Table({"x": value}, F, "run").number, "x")
    assert e.key == "run.x" and "finite" in e.reason


@pytest.mark.parametrize("value", [math.nan, math.inf, "1e400 m", "1e306 km", 10**400])
def test_quantity_refuses_what_is_not_finite_in_si(value):
    e = _err(Table({"d": value}, F, "t").quantity, "d", "length", "m")
    assert e.key == "t.d" and "finite length" in e.reason
    with pytest.raises(ConfigError, match="finite"):
        quantity(value, "length", "m")


def test_time_ns_is_bounded_by_default():
    e = _err(Table({"at": "1e300 s"}, F, "command[0]").time_ns, "at")
    assert e.key == "command[0].at" and "expected a time <= 2592000 s (30 days), found '1e300 s'" in e.reason
    e = _err(Table({"step": "0 s"}, F, "clock").time_ns, "step", positive=True)
    assert "positive" in e.reason
    assert Table({"at": "2592000 s"}, F).time_ns("at") == 2_592_000 * 10**9


@pytest.mark.parametrize(
    "getter,value,kind,needle",
    [
        ("int", 10_001, "runs", "a number of runs <= 10000, found 10001"),
        ("int", 10**30, "runs", "<= 10000"),
        ("number", 1001.0, "speed_factor", "a speed factor <= 1000"),
        ("number", 0.0, "speed_factor", "a speed factor > 0"),
    ],
)
def test_getters_apply_a_named_bound(getter, value, kind, needle):
    t = Table({"v": value}, F, "k")
    e = _err(getattr(t, getter), "v", bound=kind)
    assert e.key == "k.v" and needle in e.reason


def test_quantity_bound_shows_the_value_as_written():
    t = Table({"rate": "20 kHz"}, F, "dut")
    e = _err(t.quantity, "rate", "frequency", "Hz", bound="rate")
    assert "expected a rate <= 10000 Hz, found '20 kHz'" in e.reason
    assert Table({"rate": "10 kHz"}, F).quantity("rate", "frequency", "Hz", bound="rate") == 10_000.0


def test_int_minimum_and_maximum():
    t = Table({"n": 7}, F)
    assert t.int("n", minimum=1, maximum=7) == 7
    e = _err(Table({"n": 8}, F).int, "n", minimum=1, maximum=7)
    assert "expected an integer >= 1 and <= 7, found 8" in e.reason
    e = _err(Table({"n": 1e3}, F).int, "n", minimum=1)
    assert "expected an integer >= 1, found 1000.0 (a number)" in e.reason


def test_unknown_keys_name_the_key_and_list_the_allowed():
    t = Table({"rate": 1, "rtae": 2}, F, "dut.synthetic")
    t.number("rate")
    e = _err(t.finish)
    assert e.key == "dut.synthetic.rtae" and e.reason == "unknown key 'rtae'; expected one of: rate"
    e = _err(check_keys, {"b": 1, "zz": 2}, {"a", "b"}, file=F, key="segment[2]")
    assert e.key == "segment[2].zz" and e.reason == "unknown key 'zz'; expected one of: a, b"
    e = _err(check_keys, {"reporting": {}}, ("case", "run"), file=F, noun="table")
    assert e.key == "reporting" and e.reason == "unknown table 'reporting'; expected one of: case, run"
    assert unknown_key("x", [], file=F).reason.endswith("expected one of: none")


_UNIT_TOKENS = ["m", "km", "s", "ms", "h", "Hz", "deg", "rad", "g", "ug", "%", "ppm", "^", "/", "*", "(", ")",
                "sqrt(", "2", "-3", "400", "0.5", " "]


@settings(max_examples=400, deadline=None)
@given(
    st.one_of(
        st.floats(allow_nan=True, allow_infinity=True),
        st.integers(),
        st.text(max_size=30),
        st.builds(lambda n, u: f"{n} {''.join(u)}", st.floats(allow_nan=True, allow_infinity=True) | st.integers(),
                  st.lists(st.sampled_from(_UNIT_TOKENS), max_size=8)),
    ),
    st.sampled_from(["length", "time", "frequency", "angular_rate", "dimensionless"]),
)
def test_quantity_is_finite_or_a_config_error(value, dimension):
    """Whatever a file says, a quantity is a finite SI value or a ConfigError, never a crash."""
    try:
        x = quantity(value, dimension, "1" if dimension == "dimensionless" else "s" if dimension == "time" else "m"
                     if dimension == "length" else "Hz" if dimension == "frequency" else "rad/s")
    except ConfigError:
        return
    assert math.isfinite(x)
