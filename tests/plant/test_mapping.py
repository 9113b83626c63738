"""Mapping files: the original format, per-component channels, constants, angle
conventions, the start state's inverse conversions, and errors that name file and key."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.paths import models_dir
from bench.plant.checks import mapping_problems, mapping_warnings
from bench.plant.fmi import FmuDescription, Variable
from bench.plant.mapping import load_mapping
from bench.plant.pose import HeadingUnwrap, PoseSource, geodetic_to_local, local_to_geodetic
from tests.plant.conftest import DATA


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "m.toml"
    p.write_text(text)
    return p


def test_the_original_format_reads_as_before():
    m = load_mapping(DATA / "foreign" / "mapping.toml")
    assert m.output_vars() == ["vx_kmh", "vy_kmh", "vz_kmh", "p_dps", "q_dps", "r_dps", "theta_deg", "phi_deg",
                               "wheel_kmh"]
    raw = np.array([[36.0, 3.6, 0.0, 0.0, 0.0, 90.0, 2.0, 1.0, 72.0]])
    q = m.convert(raw)
    assert np.allclose(q["vel_b"], [[-1.0, 10.0, 0.0]])  # FLU -> RFU: left is minus right
    assert np.allclose(q["omega_nb_b"], [[0.0, 0.0, math.pi / 2]])
    assert q["pitch"][0] == pytest.approx(-math.radians(2.0)) and q["odometer_speed"][0] == pytest.approx(20.0)
    assert m.inputs["throttle"].to_fmu(0.5) == pytest.approx(50.0)
    assert not m.pose_truth and m.heading is None and m.start == {}
    bench = load_mapping(models_dir() / "vehicles" / "mappings" / "bench_tracked.toml")
    assert bench.output_vars()[:3] == ["v_x", "v_y", "v_z"]


def test_components_with_their_own_units_scales_offsets_and_constants(tmp_path):
    m = load_mapping(_write(tmp_path, """
[mapping]
body_frame = "FLU"
[outputs]
velocity = { x = { var = "u", unit = "km/h" }, y = { var = "v", unit = "m/s", sign = -1 }, z = { value = 0 } }
angular_rate = { vars = [{ value = 0 }, { value = 0 }, { var = "r", unit = "deg/s", scale = 0.1 }] }
pitch = { value = 0 }
roll = { var = "bank", unit = "deg", offset = 1.0 }
odometer_speed = { var = "u", unit = "km/h" }
"""))
    assert m.output_vars() == ["u", "v", "r", "bank"]  # each variable read once
    q = m.convert(np.array([[36.0, 1.0, 100.0, 3.0], [72.0, 0.0, 0.0, 1.0]]))
    assert np.allclose(q["vel_b"], [[1.0, 10.0, 0.0], [0.0, 20.0, 0.0]])  # v: right positive after sign -1
    assert np.allclose(q["omega_nb_b"][:, 2], [math.radians(10.0), 0.0])
    assert np.allclose(q["pitch"], 0.0) and np.allclose(q["roll"], [math.radians(2.0), 0.0])
    assert np.allclose(q["odometer_speed"], [10.0, 20.0])


def test_heading_conventions_and_the_start_state_round_trip(tmp_path):
    m = load_mapping(_write(tmp_path, """
[outputs]
velocity = { vars = ["u", "v", "w"] }
heading = { var = "yaw", unit = "deg", convention = "ccw_from_east" }
pitch = { value = 0 }
roll = { value = 0 }
[start]
heading = { var = "yaw0", unit = "deg", convention = "ccw_from_east", wrap = "positive" }
speed = { var = "v0", unit = "km/h" }
latitude = { var = "lat0", unit = "deg" }
east = { var = "x0", unit = "cm", offset = 500.0 }
"""))
    h = m.heading
    assert h is not None and float(h.to_bench(90.0)) == pytest.approx(0.0)  # north
    assert float(h.to_bench(0.0)) == pytest.approx(math.pi / 2)  # east
    assert float(h.to_bench(180.0)) == pytest.approx(-math.pi / 2)  # west
    for psi in (0.0, 0.3, 2.0, -2.5):
        assert float(h.to_bench(h.to_fmu(psi))) == pytest.approx(psi)
    start = m.start_values(heading=math.radians(135.0), speed=10.0, lat=math.radians(40.0), lon=0.0, h=0.0)
    # 135 deg from north clockwise = -45 deg from east counter-clockwise, wrapped to [0, 360)
    assert start == pytest.approx({"yaw0": 315.0, "v0": 36.0, "lat0": 40.0, "x0": 500.0})
    sym = load_mapping(_write(tmp_path, (tmp_path / "m.toml").read_text().replace('"positive"', '"symmetric"')))
    assert sym.start_values(heading=math.radians(135.0), speed=0, lat=0, lon=0, h=0)["yaw0"] == pytest.approx(-45.0)


def test_mapping_errors_name_the_file_and_key(tmp_path):
    base = '[outputs]\npitch = { value = 0 }\nroll = { value = 0 }\n'
    cases = {
        'position = { east = "x", north = "y" }\nvelocity = { vars = ["u", "v", "w"] }\n': "outputs.heading",
        'velocity = { vars = ["u", "v", "w"] }\n': "outputs.angular_rate",
        'heading = "yaw"\nvelocity = { x = "u", y = { var = "v", unit = "deg" }, z = { value = 0 } }\n':
            "outputs.velocity.y.unit",
        'heading = "yaw"\nvelocity = { x = "u", y = "v" }\n': "outputs.velocity",
        'heading = { value = 0 }\nvelocity = { vars = ["u", "v", "w"] }\n': "outputs.heading.value",
        'heading = "yaw"\nvelocity = { vars = ["u", "v", "w"] }\nodometer_speed = { var = "u", convention = '
        '"ccw_from_east" }\n': "outputs.odometer_speed.convention",
        'heading = { var = "yaw", convention = "ccw_from_south" }\nvelocity = { vars = ["u", "v", "w"] }\n':
            "outputs.heading.convention",
        'heading = "yaw"\nposition = { east = "x", latitude = "lat" }\n': "outputs.position",
        'heading = "yaw"\nposition = { east = "x", north = "y" }\n[start]\nspeed = { value = 3 }\n':
            "start.speed.value",
        'heading = "yaw"\nvelocity = { vars = ["u", "v", "w"] }\nroll = { var = "r", scale = 0 }\n':
            "outputs.roll.scale",
    }
    for body, key in cases.items():
        text = base + body if "roll =" not in body else base.replace("roll = { value = 0 }\n", "") + body
        path = _write(tmp_path, text)
        with pytest.raises(ConfigError) as exc:
            load_mapping(path)
        assert exc.value.file == str(path) and exc.value.key == key, (body, exc.value)


def _desc(units: dict[str, str | None]) -> FmuDescription:
    variables = {n: Variable(n, i, "Float64", "output", "continuous", u, None, "") for i, (n, u) in
                 enumerate(units.items())}
    return FmuDescription(Path("x.fmu"), "2.0", "Car", "Car", "", "tool", True, variables)


def test_units_checked_against_the_fmu(tmp_path):
    m = load_mapping(_write(tmp_path, """
[outputs]
velocity = { x = { var = "u", unit = "km/h" }, y = { value = 0 }, z = { value = 0 } }
heading = { var = "yaw", unit = "rad" }
pitch = { value = 0 }
roll = { value = 0 }
"""))
    assert mapping_problems(_desc({"u": "km/h", "yaw": "rad"}), m) == []
    assert mapping_warnings(_desc({"u": "km/h", "yaw": "rad"}), m) == []
    (w,) = mapping_warnings(_desc({"u": None, "yaw": "rad"}), m)
    assert "'u'" in w and "outputs.velocity.x" in w and "declares no unit; trusting the mapping's 'km/h'" in w
    (p,) = mapping_problems(_desc({"u": "m/s", "yaw": "rad"}), m)
    assert "reads it in 'km/h' but the FMU declares 'm/s'" in p
    bare = load_mapping(_write(tmp_path, (tmp_path / "m.toml").read_text().replace(', unit = "rad"', "")))
    (p,) = mapping_problems(_desc({"u": "km/h", "yaw": "deg"}), bare)
    assert "'yaw'" in p and "declares 'deg' but the mapping gives no unit" in p
    (w,) = mapping_warnings(_desc({"u": "km/h", "yaw": None}), bare)
    assert "neither the FMU nor the mapping gives a unit; read as rad" in w


def test_pose_streams():
    lat0, lon0, h0 = math.radians(39.8), math.radians(116.2), 60.0
    enu = np.array([[0.0, 0.0, 0.0], [100.0, -50.0, 2.0], [-3000.0, 4000.0, 0.0]])
    lat, lon, h = local_to_geodetic(enu, lat0, lon0, h0)
    assert np.allclose(geodetic_to_local(lat, lon, h, lat0, lon0, h0), enu, rtol=0, atol=1e-6)
    un = HeadingUnwrap()
    a = un.push(np.array([3.0, -3.1, -3.0]))
    b = un.push(np.array([3.1, 2.9]))
    assert np.allclose(np.concatenate([a, b]), [3.0, 2 * math.pi - 3.1, 2 * math.pi - 3.0, 3.1, 2.9])
    # a geodetic position is kept as the FMU gives it
    src = PoseSource(lat0, lon0, h0, 0.01, 1)
    q = {"lat": lat, "lon": lon, "psi": np.zeros(3), "pitch": np.zeros(3), "roll": np.zeros(3)}
    src.push(np.array([0.0, 0.01, 0.02]), q)
    kept = src.kept.arrays()
    assert np.allclose(kept["lat"], lat, rtol=0, atol=1e-15) and np.allclose(kept["h"], h0)
