"""A supplier's FMU used as shipped: a planar car packaged by pythonfmu (FMI 2.0, its own
names and units, none declared, no pitch, roll or vertical motion) drives a scenario
through a mapping file alone, and ``bench fmu check`` tells warnings from errors."""

from __future__ import annotations

import math
import zipfile
from pathlib import Path

import numpy as np
import pytest

from bench.cli.app import run as bench
from bench.errors import ConfigError
from bench.plant.manifest import sha256_file, verify_fmu
from bench.plant.pose import geodetic_to_local
from bench.plant.runner import PlantRun, run_plant
from bench.plant.scenario import plant_setup
from bench.plant.trajectory import FmuTrajectory
from tests.plant.conftest import DATA
from tests.plant.helpers import run_fmu

MAPPING = DATA / "planar" / "mapping.toml"
OUTPUTS = ["x", "y", "yaw", "speed_kmh", "yaw_rate_dps"]
DURATION = 30.0
# straight at 10 m/s for 10 s, then a loop of radius 2.7 m / tan(7.7 deg) = 20 m (more than a
# full turn), then straight again, faster
COMMANDS = [
    {"at": "0 s", "throttle": 0.5},
    {"at": "10 s", "steering": {"to": "7.7 deg", "over": "1 s"}},
    {"at": "24 s", "steering": {"to": "0 deg", "over": "1 s"}, "throttle": 0.6},
]


def _scenario(fmu: Path, mapping: Path, heading: str = "30 deg") -> dict:
    return {
        "initial": {"latitude": 39.84991, "longitude": 116.17715, "height": "60 m", "heading": heading,
                    "speed": "10 m/s"},
        "plant": {"fmu": str(fmu), "mapping": str(mapping), "sha256": sha256_file(fmu), "duration": f"{DURATION} s"},
        "command": COMMANDS,
    }


def _drive(fmu: Path, mapping: Path) -> tuple[PlantRun, FmuTrajectory, np.ndarray, np.ndarray]:
    """The scenario through the mapping, and the same FMU stepped directly with the same
    held commands (its start values set by hand: yaw0 = 90 - 30 deg, 36 km/h)."""
    setup = plant_setup(_scenario(fmu, mapping), file="scenario.toml", base=Path.cwd())
    run = run_plant(setup)
    ticks, vals = setup.script.ticks(["throttle", "steering"])
    changes = {float(t): {"pedal": float(a), "steer_deg": math.degrees(float(s))} for t, (a, s) in zip(ticks, vals,
                                                                                                        strict=True)}
    first = changes.pop(0.0)
    t, y = run_fmu(fmu, DURATION, OUTPUTS, inputs=first, params={"yaw0": math.radians(60.0), "v0_kmh": 36.0},
                   changes=changes, trust=verify_fmu(fmu, sha256=sha256_file(fmu)))
    return run, FmuTrajectory(run, setup.script), t[:-1], y[:-1]


def _position_error(traj: FmuTrajectory, t: np.ndarray, y: np.ndarray) -> np.ndarray:
    k = traj.kinematics(t)
    lat0, lon0 = math.radians(39.84991), math.radians(116.17715)
    enu = geodetic_to_local(k.lat, k.lon, k.h, lat0, lon0, 60.0)
    assert np.abs(enu[:, 2]).max() < 1e-6  # a planar model: height stays
    return np.hypot(enu[:, 0] - y[:, 0], enu[:, 1] - y[:, 1])


def test_supplier_car_drives_a_scenario_through_its_mapping_alone(pythonfmu_cars):
    """Truth from the FMU's own east/north and yaw: it matches them at every step, not
    only at the 10 ms samples the splines pass through (measured: 2.5e-8 m straight,
    2.1e-6 m over the loop; heading 4.6e-4 deg; speed 2.7e-5 m/s straight, 1.3e-3 m/s where
    the steering ramps)."""
    run, traj, t, y = _drive(pythonfmu_cars["planar"], MAPPING)
    assert np.unwrap(y[:, 2])[-1] - np.unwrap(y[:, 2])[0] > 2.0 * math.pi  # a whole loop and more
    err = _position_error(traj, t, y)
    straight = t < 10.0
    assert err[straight].max() < 1e-4
    assert err.max() < 1e-4
    k = traj.kinematics(t)
    heading = 0.5 * math.pi - y[:, 2]  # yaw counter-clockwise from east -> heading clockwise from north
    assert np.degrees(np.abs(np.angle(np.exp(1j * (k.euler[:, 0] - heading))))).max() < 5e-3
    assert np.all(k.euler[:, 1] == 0.0) and np.all(k.euler[:, 2] == 0.0)  # the constants: no pitch, no roll
    speed = np.linalg.norm(k.vel_n, axis=1)
    assert np.abs(speed - y[:, 3] / 3.6)[straight].max() < 2e-4
    assert np.abs(speed - y[:, 3] / 3.6).max() < 1e-2
    assert speed[-1] == pytest.approx(12.0 - 2.0 * math.exp(-(DURATION - 24.0) / 2.0), rel=1e-3)  # 0.6 of 72 km/h
    # the odometer reads the FMU's km/h as m/s at the kept samples
    at = t[9::10]
    assert np.allclose(traj.wheel_speed(at), y[9::10, 3] / 3.6, rtol=0, atol=1e-12)
    # the FMU's own rates agree with its pose (exact arcs; the yaw rate is sampled at
    # step ends, so steering ramps held at 100 Hz leave a small heading-rate misfit)
    assert run.consistency["velocity"].rms < 1e-5 and run.consistency["velocity"].samples == 30000
    assert math.degrees(run.consistency["heading_rate"].max) < 0.5
    assert any("'speed_kmh'" in w and "declares no unit" in w and "km/h" in w for w in run.warnings)


def test_the_recording_holds_the_fmus_truth_and_its_checks(pythonfmu_cars, tmp_path):
    """``bench synth`` of the scenario as a file: the recorded truth is the FMU's pose, the
    plant metadata says where the truth came from, the misfits and the missing units."""
    from bench.record.reader import RecordingReader

    fmu = pythonfmu_cars["planar"]
    doc = _scenario(fmu, MAPPING)
    lines = ['[scenario]', 'id = "PLANAR"', 'title = "a supplier\'s planar car"', "[initial]"]
    lines += [f"{k} = {v!r}".replace("'", '"') for k, v in doc["initial"].items()]
    lines += ["[plant]"] + [f'{k} = "{v}"' for k, v in doc["plant"].items()]
    lines += ["[[command]]", 'at = "0 s"', "throttle = 0.5", "[[command]]", 'at = "10 s"',
              'steering = { to = "7.7 deg", over = "1 s" }', "[[command]]", 'at = "24 s"',
              'steering = { to = "0 deg", over = "1 s" }', "throttle = 0.6"]
    scenario = tmp_path / "planar.toml"
    scenario.write_text("\n".join(lines) + "\n")
    out = tmp_path / "planar.mcap"
    assert bench(["synth", str(scenario), "-o", str(out), "-q"]) == 0
    reader = RecordingReader(out)
    plant = reader.metadata()["plant"]
    assert plant["truth_from"] == "the FMU's position and heading" and plant["model"] == "PlanarCar"
    assert plant["misfit_velocity"].startswith("rms ") and "misfit_heading_rate" in plant
    assert "'speed_kmh'" in plant["mapping_warnings"] and "declares no unit" in plant["mapping_warnings"]
    truth = reader.read_columnar("/truth")[1:-1]  # the FMU's outputs after each step, but the last (_drive)
    _, _, t, y = _drive(fmu, MAPPING)
    rows = np.rint(truth["t_ns"] / 1e6).astype(int) - 1  # FMU rows: after step k + 1
    assert np.allclose(t[rows], truth["t_ns"] / 1e9, rtol=0, atol=1e-12)
    lat0, lon0 = math.radians(39.84991), math.radians(116.17715)
    enu = geodetic_to_local(truth["lat"], truth["lon"], truth["h"], lat0, lon0, 60.0)
    assert np.hypot(enu[:, 0] - y[rows, 0], enu[:, 1] - y[rows, 1]).max() < 1e-4
    heading = 0.5 * math.pi - y[rows, 2]
    assert np.degrees(np.abs(np.angle(np.exp(1j * (truth["euler"][:, 0] - heading))))).max() < 5e-3
    assert np.abs(np.linalg.norm(truth["vel_n"], axis=1) - y[rows, 3] / 3.6).max() < 1e-2


def test_supplier_car_integrated_from_its_rates_alone(pythonfmu_cars, tmp_path):
    """The same car mapped by speed (km/h forward, constants sideways and up) and yaw rate
    (deg/s) only: the bench integrates them (measured: 0.28 mm straight, 9.9 mm at most over
    the loop, 2.9 mm at the end; heading within 0.015 deg)."""
    text = MAPPING.read_text()
    rates = tmp_path / "rates.toml"
    rates.write_text("\n".join(line for line in text.splitlines()
                               if not line.startswith(("position =", "heading ="))))
    run, traj, t, y = _drive(pythonfmu_cars["planar"], rates)
    assert run.consistency == {}
    err = _position_error(traj, t, y)
    assert err[t < 10.0].max() < 1e-3
    assert err.max() < 0.05
    heading = 0.5 * math.pi - y[:, 2]
    assert np.degrees(np.abs(np.angle(np.exp(1j * (traj.kinematics(t).euler[:, 0] - heading))))).max() < 0.05


def test_start_heading_the_fmu_cannot_take_is_refused(pythonfmu_cars, tmp_path):
    text = MAPPING.read_text()
    bad = tmp_path / "mapping.toml"
    bad.write_text(text.replace('heading = { var = "yaw0"', 'heading_unused = { var = "yaw0"'))
    with pytest.raises(ConfigError, match=r"mapping.toml: start.heading_unused: unknown key"):
        plant_setup(_scenario(pythonfmu_cars["planar"], bad), file="s.toml", base=tmp_path)
    bad.write_text("\n".join(line for line in text.splitlines() if not line.startswith('heading = { var = "yaw0"')))
    setup = plant_setup(_scenario(pythonfmu_cars["planar"], bad), file="s.toml", base=tmp_path)
    with pytest.raises(ConfigError, match=r"mapping.toml: start.heading: the FMU starts at heading 90\.0+ deg"):
        run_plant(setup)
    # the FMU's own start heading is the scenario's: no parameter needed
    run = run_plant(plant_setup(_scenario(pythonfmu_cars["planar"], bad, "90 deg"), file="s.toml", base=tmp_path))
    assert run.samples["psi"][0] == pytest.approx(0.5 * math.pi)


def test_fmu_check_of_a_pythonfmu_car_passes_with_warnings(pythonfmu_cars, capsys):
    fmu = pythonfmu_cars["planar"]
    assert bench(["fmu", "check", str(fmu), "--mapping", str(MAPPING), "--sha256", sha256_file(fmu)]) == 0
    out = capsys.readouterr().out
    assert "FAIL" not in out
    assert "WARN  fmpy's validator objects to the model description (generated by PythonFMU 0.7.0)" in out
    assert "ModelStructure/InitialUnknowns" in out  # what the validator said
    assert "WARN  missing unit: 'speed_kmh'" in out and "the FMU declares no unit; trusting the mapping's 'km/h'" in out
    assert "PASS  the FMU runs" in out
    assert "truth from the FMU's position and heading" in out and "misfit of the FMU's velocity" in out
    assert "PASS  check passed with" in out


def test_fmu_check_of_an_fmu_that_cannot_run_is_an_error(pythonfmu_cars, tmp_path, capsys):
    broken = pythonfmu_cars["broken"]
    assert bench(["fmu", "check", str(broken), "--sha256", sha256_file(broken)]) == 3
    out = capsys.readouterr().out
    assert "WARN  fmpy's validator objects" in out and "FAIL  the FMU runs" in out
    # a corrupted binary: the archive and its model description are intact, the library is not
    bad = tmp_path / "PlanarCar.fmu"
    with zipfile.ZipFile(pythonfmu_cars["planar"]) as zin, zipfile.ZipFile(bad, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            zout.writestr(item, b"\x7fELF garbage" if item.filename.endswith(".so") else data)
    assert bench(["fmu", "check", str(bad), "--sha256", sha256_file(bad)]) == 3
    out = capsys.readouterr().out
    assert "FAIL  the FMU runs" in out and "FAIL  check failed" in out
