"""`bench fmu info` and `bench fmu check`."""

from __future__ import annotations

from bench.cli.app import run
from bench.paths import models_dir
from bench.plant.manifest import sha256_file
from tests.plant.conftest import DATA

MAPPINGS = models_dir() / "vehicles" / "mappings"


def test_fmu_info_lists_variables_with_units(fmu_build, capsys):
    assert run(["fmu", "info", str(fmu_build / "TrackedVehicle.fmu")]) == 0
    out = capsys.readouterr().out
    assert "FMI version     3.0 (co-simulation)" in out
    assert "left_lever" in out and "v_odometer" in out and "m/s" in out and "stopTime 20" in out


def test_fmu_check_passes_and_fails(fmu_build, foreign_fmu, tmp_path, capsys):
    wheeled = str(fmu_build / "WheeledVehicle.fmu")
    assert run(["fmu", "check", wheeled, "--mapping", str(MAPPINGS / "bench_wheeled.toml")]) == 0
    out = capsys.readouterr().out
    assert out.count("PASS") == 7 and "FAIL" not in out and "WARN" not in out
    assert "PASS  a short run through the mapping: truth from body velocity and rate, integrated" in out
    # a mapping written for another FMU: the check names the missing variables
    assert run(["fmu", "check", wheeled, "--mapping", str(MAPPINGS / "bench_tracked.toml")]) == 3
    assert "'left_lever' is not a variable of WheeledVehicle" in capsys.readouterr().out
    # the third-party FMU with its own mapping, trusted by the sha256 the user gives
    assert run(["fmu", "check", str(foreign_fmu), "--mapping", str(DATA / "foreign" / "mapping.toml"),
                "--sha256", sha256_file(foreign_fmu)]) == 0
    capsys.readouterr()
    # an FMU the build did not make, without a given sha256, is not simulated
    lone = tmp_path / "TrackedVehicle.fmu"
    data = bytearray((fmu_build / "TrackedVehicle.fmu").read_bytes())
    data[len(data) // 2] ^= 0xFF
    lone.write_bytes(bytes(data))
    assert run(["fmu", "check", str(lone)]) == 3
    assert "SHA-256 mismatch" in capsys.readouterr().out
    # a missing file is a bench error with a clear message
    assert run(["fmu", "info", str(tmp_path / "nothing.fmu")]) == 2
