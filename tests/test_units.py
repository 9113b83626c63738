import math

import pytest

from bench.errors import ConfigError
from bench.units import G0, parse_unit, quantity, to_unit, vector


@pytest.mark.parametrize(
    "text,dim,si",
    [
        ("0.01 deg/h", "angular_rate", math.radians(0.01) / 3600),
        ("0.001 deg/sqrt(h)", "angle_random_walk", math.radians(0.001) / 60),
        ("100 ug", "acceleration", 100e-6 * G0),
        ("10 ug/sqrt(Hz)", "velocity_random_walk", 10e-6 * G0),
        ("1e-4 g", "acceleration", 1e-4 * G0),
        ("50 ppm", "dimensionless", 5e-5),
        ("0.1 %", "dimensionless", 1e-3),
        ("3 arcsec", "angle", math.radians(3 / 3600)),
        ("2.1 arcmin", "angle", math.radians(2.1 / 60)),
        ("36 km/h", "velocity", 10.0),
        ("125 ug*s", "velocity", 125e-6 * G0),
        ("0.5 deg/h/g", "g_sensitivity", math.radians(0.5) / 3600 / G0),
        ("3 deg/h/sqrt(h)", "rate_random_walk", math.radians(3) / 3600 / 60),
        ("1 m/s^2", "acceleration", 1.0),
        ("-20 m", "length", -20.0),
        ("460800 Hz", "frequency", 460800.0),
    ],
)
def test_quantities_to_si(text, dim, si):
    assert quantity(text, dim, "1") == pytest.approx(si, rel=1e-12)


def test_bare_numbers_take_the_default_unit():
    assert quantity(0.01, "angular_rate", "deg/h") == pytest.approx(math.radians(0.01) / 3600)
    assert quantity("7", "time", "min") == 420.0


def test_dimension_mismatch_and_garbage_are_refused():
    with pytest.raises(ConfigError) as exc:
        quantity("0.01 m/s", "angular_rate", "deg/h", file="f.toml", key="gyro.bias")
    assert exc.value.file == "f.toml" and exc.value.key == "gyro.bias"
    assert "angular_rate" in str(exc.value) and "velocity" in str(exc.value)
    for bad in ("fast", "1 furlong", True, None, [1]):
        with pytest.raises(ConfigError):
            quantity(bad, "velocity", "m/s")


def test_vectors_and_to_unit():
    assert list(vector(["1 deg", "2 deg", 3], "angle", "deg")) == pytest.approx([math.radians(v) for v in (1, 2, 3)])
    assert list(vector("1 m", "length", "m")) == [1.0, 1.0, 1.0]
    assert to_unit(math.radians(1) / 3600, "deg/h") == pytest.approx(1.0)
    assert parse_unit("deg/h")[1] == parse_unit("rad/s")[1]
