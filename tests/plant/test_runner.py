"""The plant runner: trust checks, mapping, failures, a third-party FMU, S002 through the FMU."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bench.errors import ConfigError, PlantError
from bench.nav import earth
from bench.paths import models_dir
from bench.plant.driver import parse_commands
from bench.plant.fmi import read_description
from bench.plant.manifest import sha256_file
from bench.plant.mapping import load_mapping
from bench.plant.runner import PlantSetup, run_plant
from bench.plant.trajectory import FmuTrajectory
from tests.plant.conftest import DATA

LAT0, LON0 = math.radians(39.84991), math.radians(116.17715)


def _setup(fmu: Path, commands: list[dict], duration: float, mapping: Path | None = None, **kw) -> PlantSetup:
    mapping = mapping or models_dir() / "vehicles" / "mappings" / "bench_tracked.toml"
    script = parse_commands(commands, duration, file="test", surface="cement")
    return PlantSetup(fmu=fmu, mapping=load_mapping(mapping), script=script, lat0=LAT0, lon0=LON0, h0=60.0, **kw)


DRIVE = [
    {"at": "0 s", "throttle": {"to": 0.6, "over": "5 s"}},
    {"at": "12 s", "right_lever": 1},
    {"at": "16 s", "right_lever": 0, "grade": {"to": "3 deg", "over": "4 s"}},
]


def test_build_fmu_runs_trusted_by_the_build_manifest(fmu_build):
    run = run_plant(_setup(fmu_build / "TrackedVehicle.fmu", DRIVE[:1], 2.0))
    assert run.steps == 2000
    assert run.trust.verified and run.trust.source == f"the build manifest {fmu_build / 'SHA256SUMS'}"
    assert run.trust.sha256 == run.sha256 == sha256_file(fmu_build / "TrackedVehicle.fmu")


def test_mapping_that_does_not_fit_the_fmu_is_a_config_error(fmu_build, tmp_path):
    text = (models_dir() / "vehicles" / "mappings" / "bench_tracked.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('"v_odometer", unit = "m/s"', '"v_odo", unit = "km/h"'))
    with pytest.raises(ConfigError, match="'v_odo' is not a variable"):
        run_plant(_setup(fmu_build / "TrackedVehicle.fmu", DRIVE[:1], 1.0, mapping=bad))
    bad.write_text(text.replace('"v_odometer", unit = "m/s"', '"v_drive", unit = "km/h"'))
    with pytest.raises(ConfigError, match="reads it in 'km/h' but the FMU declares 'm/s'"):
        run_plant(_setup(fmu_build / "TrackedVehicle.fmu", DRIVE[:1], 1.0, mapping=bad))


def test_failing_fmu_ends_the_run_with_its_reason(fmu_build):
    # a yaw time constant far below the solver step makes the RK4 solver blow up in the turn
    setup = _setup(fmu_build / "TrackedVehicle.fmu", DRIVE, 20.0, parameters={"tau_yaw": 1e-6})
    with pytest.raises(PlantError, match=r"doStep at t = 1[2-9]\.\d+ s returned Error.*state \w+ became -?nan"):
        run_plant(setup)
    with pytest.raises(PlantError, match="i_pivot must be within"):
        run_plant(_setup(fmu_build / "TrackedVehicle.fmu", DRIVE[:1], 1.0, parameters={"i_pivot": 1.5}))


def test_fmi2_and_fmi3_runs_give_the_same_truth(fmu_build):
    a = run_plant(_setup(fmu_build / "TrackedVehicle.fmu", DRIVE, 22.0))
    b = run_plant(_setup(fmu_build / "TrackedVehicle_fmi2.fmu", DRIVE, 22.0))
    for k in ("lat", "lon", "h", "psi", "odometer_speed"):
        assert np.array_equal(a.samples[k], b.samples[k])
    assert a.samples["h"][-1] > 60.0  # climbed the 3 deg grade
    assert np.degrees(a.samples["psi"][-1]) > 30.0  # the right turn raised the heading


def test_third_party_fmu_runs_through_a_mapping_file(foreign_fmu):
    """An FMI 2.0 FMU with other names, ISO axes, km/h, deg/s and nose-down pitch."""
    desc = read_description(foreign_fmu)
    assert desc.fmi_version == "2.0" and "v_y" not in desc.variables
    commands = [
        {"at": "0 s", "throttle": 0.5},  # 50 % pedal of 72 km/h: 10 m/s
        {"at": "20 s", "steering": "5 deg"},  # left
        {"at": "30 s", "steering": "0 deg", "grade": "3 deg"},
    ]
    setup = _setup(foreign_fmu, commands, 40.0, mapping=DATA / "foreign" / "mapping.toml",
                   sha256=sha256_file(foreign_fmu))  # a third-party FMU: its hash comes from the case
    run = run_plant(setup)
    traj = FmuTrajectory(run, setup.script)
    k = traj.kinematics(np.array([19.9, 29.9, 39.9]))
    speed = np.linalg.norm(k.vel_n, axis=1)
    v_expected = 10.0 * (1.0 - math.exp(-19.9 / 2.0))
    assert speed[0] == pytest.approx(v_expected, rel=1e-3)
    # the body moves forward (RFU y), not sideways: heading equals the course
    course = np.arctan2(k.vel_n[:, 0], k.vel_n[:, 1])
    assert np.allclose(np.angle(np.exp(1j * (course - k.euler[:, 0]))), 0.0, atol=1e-3)
    # left steering turns the heading anticlockwise by integral(v tan(delta) / wheelbase)
    t = np.linspace(20.0, 29.9, 9901)
    v = 10.0 * (1.0 - np.exp(-t / 2.0))
    dpsi = np.trapezoid(v * math.tan(math.radians(5.0)) / 3.0, t)
    assert k.euler[1, 0] - k.euler[0, 0] == pytest.approx(-dpsi, rel=1e-3)
    # uphill: the FMU's nose-down-positive pitch arrives as +3 deg nose up, and height grows
    assert math.degrees(k.euler[2, 1]) == pytest.approx(3.0, abs=1e-3)
    assert k.vel_n[2, 2] == pytest.approx(speed[2] * math.sin(math.radians(3.0)), rel=1e-3)
    # odometer in km/h mapped to m/s
    assert traj.wheel_speed(np.array([19.9]))[0] == pytest.approx(v_expected, rel=1e-3)
    lat, lon, _ = earth.ecef_to_geodetic(earth.geodetic_to_ecef(k.lat, k.lon, k.h))
    assert np.all(np.isfinite(lat)) and np.all(np.isfinite(lon))


@pytest.mark.parametrize("name", ["TrackedVehicle.fmu", "TrackedVehicle_fmi2.fmu"])
def test_compiled_stepping_equals_fmpys_own_calls(fmu_build, name):
    """FmuInstance.advance (DoStep and the bulk getter from compiled code) against the
    same FMU stepped through fmpy's bound functions one call at a time: the same bits."""
    from bench.plant.fmi import FmuInstance
    from bench.plant.manifest import verify_fmu

    path = fmu_build / name
    desc = read_description(path)
    trust = verify_fmu(path, sha256=None, where="test", unverified=False)
    outs = [n for n, v in desc.variables.items() if v.causality == "output"]
    h, n = 1e-3, 1500
    results = []
    for compiled in (True, False):
        buf = np.zeros((n, len(outs)))
        with FmuInstance(desc, trust=trust) as inst:
            inst.set({"throttle": 0.7})
            inst.exit_initialization()
            if compiled:
                inst.bind_outputs(outs, buf)
                inst.advance(0, 700, h)  # two calls, the second at a row offset
                inst.advance(700, n - 700, h, row0=700)
            else:
                fmu, vrs = inst._fmu, [desc.variables[o].vr for o in outs]
                for k in range(n):
                    fmu.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
                    buf[k] = fmu.getFloat64(vrs) if desc.fmi_version == "3.0" else fmu.getReal(vrs)
        results.append(buf)
    assert np.array_equal(results[0], results[1])
    assert results[0][-1, outs.index("v_odometer")] > 0.1  # the vehicle drove off: the rows are not all alike
    with FmuInstance(desc, trust=trust) as inst:
        inst.exit_initialization()
        inst.bind_outputs(outs, np.zeros((10, len(outs))))
        with pytest.raises(ValueError, match="outside the bound buffer"):
            inst.advance(0, 5, h, row0=8)
