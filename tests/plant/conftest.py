"""Fixtures: the bench's FMUs (built by `make install`, or here into a temporary folder)."""

from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path

import pytest

from bench.paths import fmu_dir

DATA = Path(__file__).parent / "data"
NAMES = ("TrackedVehicle", "TrackedVehicle_fmi2", "WheeledVehicle", "WheeledVehicle_fmi2")


def fmu_build_module():
    """fmu/build.py as a module (it is a script beside the package, not part of it)."""
    spec = importlib.util.spec_from_file_location("bench_fmu_build", fmu_dir() / "build.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="session")
def fmu_build() -> Path:
    """fmu/build: the four bench FMUs and the build's SHA256SUMS (built here, as 'make
    fmus' does, when missing: only the build's own manifest is trusted)."""
    built = fmu_dir() / "build"
    if all((built / f"{n}.fmu").is_file() for n in NAMES) and (built / "SHA256SUMS").is_file():
        return built
    if shutil.which("cmake") is None:
        pytest.skip("cmake is needed to build the FMUs from source")
    assert fmu_build_module().main(["--out", str(built)]) == 0
    return built


@pytest.fixture(scope="session")
def foreign_fmu(tmp_path_factory) -> Path:
    """The third-party-style FMI 2.0 FMU of tests/plant/data/foreign, with a SHA256SUMS
    beside it (which the bench must not trust: tests give its sha256 explicitly)."""
    if shutil.which("cmake") is None:
        pytest.skip("cmake is needed to build the test FMU")
    out = tmp_path_factory.mktemp("foreign")
    mod = fmu_build_module()
    (fmu,) = mod.build_model(DATA / "foreign", out, ["2"])
    mod.write_manifest(out, [fmu])
    return fmu


def build_pythonfmu(source: Path, out: Path) -> Path:
    """An FMI 2.0 co-simulation FMU built by pythonfmu from one Python source file (the
    module name is the file's: give each model its own, the FMUs share the interpreter)."""
    pytest.importorskip("pythonfmu")
    from pythonfmu.builder import FmuBuilder

    return Path(FmuBuilder.build_FMU(source, dest=out))


@pytest.fixture(scope="session")
def pythonfmu_cars(tmp_path_factory) -> dict[str, Path]:
    """The supplier-style pythonfmu FMUs of tests/plant/data/planar, built once per session:
    ``planar`` (a planar car that runs) and ``broken`` (its step raises). They run inside
    this Python process: pythonfmu's binary takes the interpreter's symbols from the host
    process (no libpython is loaded or needed beside it)."""
    out = tmp_path_factory.mktemp("pythonfmu")
    return {"planar": build_pythonfmu(DATA / "planar" / "planar_car.py", out),
            "broken": build_pythonfmu(DATA / "planar" / "broken_car.py", out)}
