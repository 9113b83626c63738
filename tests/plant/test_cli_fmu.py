"""`bench fmu info` and `bench fmu check`."""

from __future__ import annotations

import shutil

from bench.cli.app import run
from bench.paths import models_dir
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
    assert out.count("PASS") == 5 and "FAIL" not in out
    # a mapping written for another FMU: the check names the missing variables
    assert run(["fmu", "check", wheeled, "--mapping", str(MAPPINGS / "bench_tracked.toml")]) == 3
    assert "'left_lever' is not a variable of WheeledVehicle" in capsys.readouterr().out
    # the third-party FMU with its own mapping
    assert run(["fmu", "check", str(foreign_fmu), "--mapping", str(DATA / "foreign" / "mapping.toml")]) == 0
    # an FMU without a manifest is not simulated
    lone = tmp_path / "TrackedVehicle.fmu"
    shutil.copy(fmu_build / "TrackedVehicle.fmu", lone)
    assert run(["fmu", "check", str(lone)]) == 3
    assert "no manifest" in capsys.readouterr().out
    # a missing file is a bench error with a clear message
    assert run(["fmu", "info", str(tmp_path / "nothing.fmu")]) == 2
