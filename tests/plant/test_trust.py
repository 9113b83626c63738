"""FMU trust: the expected SHA-256 comes from the build's manifest or the case, never from
a SHA256SUMS beside the FMU; untrusted native code is never loaded (a library whose
constructor leaves a mark proves it); an explicit opt-in is recorded."""

from __future__ import annotations

import math
import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest

from bench.cli.app import run as bench
from bench.errors import ConfigError
from bench.paths import models_dir
from bench.plant.driver import parse_commands
from bench.plant.fmi import FmuInstance, read_description, simulate
from bench.plant.manifest import sha256_file, verify_fmu
from bench.plant.mapping import load_mapping
from bench.plant.runner import PlantSetup, run_plant
from bench.record.mcap_io import RecordingReader
from tests.plant.conftest import DATA

MAPPING = models_dir() / "vehicles" / "mappings" / "bench_tracked.toml"


def _setup(fmu: Path, **kw) -> PlantSetup:
    script = parse_commands([{"at": "0 s", "throttle": 0.3}], 1.0, file="test", surface="cement")
    return PlantSetup(fmu=fmu, mapping=load_mapping(MAPPING), script=script, lat0=math.radians(39.8),
                      lon0=math.radians(116.2), h0=60.0, **kw)


def _evil_copy(fmu_build: Path, folder: Path) -> tuple[Path, Path]:
    """TrackedVehicle.fmu with its Linux binary replaced by a library whose constructor
    writes a marker file when loaded, and a matching SHA256SUMS beside it."""
    if shutil.which("gcc") is None:
        pytest.skip("gcc is needed to build the marker library")
    marker = folder / "native-code-ran"
    src = folder / "evil.c"
    src.write_text('#include <stdio.h>\n__attribute__((constructor)) static void mark(void) {\n'
                   f'  FILE *f = fopen("{marker}", "w"); if (f) {{ fputs("loaded", f); fclose(f); }}\n}}\n')
    lib = folder / "evil.so"
    subprocess.run(["gcc", "-shared", "-fPIC", "-o", str(lib), str(src)], check=True, capture_output=True)
    fmu = folder / "TrackedVehicle.fmu"
    with zipfile.ZipFile(fmu_build / "TrackedVehicle.fmu") as zin, zipfile.ZipFile(fmu, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename.startswith("binaries/") and item.filename.endswith(".so"):
                data = lib.read_bytes()
            zout.writestr(item, data)
    (folder / "SHA256SUMS").write_text(f"{sha256_file(fmu)}  {fmu.name}\n")
    return fmu, marker


def test_a_sha256sums_beside_a_tampered_fmu_is_not_trusted_and_its_code_never_loads(fmu_build, tmp_path, capsys):
    fmu, marker = _evil_copy(fmu_build, tmp_path)
    listed = verify_fmu(fmu_build / "TrackedVehicle.fmu").sha256
    found = sha256_file(fmu)
    with pytest.raises(ConfigError) as exc:
        run_plant(_setup(fmu))
    msg = str(exc.value)
    assert str(fmu) in msg and listed in msg and found in msg and "SHA-256 mismatch" in msg
    assert "SHA256SUMS beside it is not trusted" in msg
    with pytest.raises(ConfigError, match="SHA-256 mismatch"):
        FmuInstance(read_description(fmu)).open()
    with pytest.raises(ConfigError, match="SHA-256 mismatch"):
        simulate(fmu, stop_time=0.1, step=0.01)
    assert bench(["fmu", "check", str(fmu)]) == 3
    out = capsys.readouterr().out
    assert "FAIL  SHA-256 trusted" in out and "short simulation with fmpy" not in out
    assert bench(["fmu", "info", str(fmu)]) == 0
    assert "trust           NOT trusted: SHA-256 mismatch" in capsys.readouterr().out
    assert not marker.exists()  # not a byte of its native code ran
    # the same library is loaded once the user opts in (the test's control: the marker works)
    setup = _setup(fmu, unverified=True)
    with pytest.raises(Exception):  # noqa: B017 - the marker library is no FMU
        run_plant(setup)
    assert marker.read_text() == "loaded"


def test_an_untampered_copy_of_a_build_fmu_is_trusted_by_its_content(fmu_build, tmp_path):
    copy = tmp_path / "renamed.fmu"
    shutil.copy(fmu_build / "TrackedVehicle.fmu", copy)
    trust = verify_fmu(copy)
    assert trust.verified and "build manifest" in trust.source
    assert run_plant(_setup(copy)).steps == 1000


def test_an_fmu_unknown_to_the_build_needs_the_case_sha256(foreign_fmu):
    # the foreign FMU has a SHA256SUMS of its own beside it: not enough
    with pytest.raises(ConfigError, match="no trusted SHA-256 for this FMU") as exc:
        verify_fmu(foreign_fmu)
    assert "SHA256SUMS beside it is not trusted" in str(exc.value) and 'sha256 = "<hex>"' in str(exc.value)
    digest = sha256_file(foreign_fmu)
    trust = verify_fmu(foreign_fmu, sha256=digest.upper(), where="case.toml [plant]")
    assert trust.verified and trust.source == "sha256 given in case.toml [plant]"
    with pytest.raises(ConfigError, match=f"expects {'0' * 64}, the file has {digest}"):
        verify_fmu(foreign_fmu, sha256="0" * 64, where="case.toml [plant]")
    with pytest.raises(ConfigError, match="64 hex digits"):
        verify_fmu(foreign_fmu, sha256="abc")
    # a given hash that does not match is refused even with the opt-in
    with pytest.raises(ConfigError, match="SHA-256 mismatch"):
        verify_fmu(foreign_fmu, sha256="0" * 64, unverified=True)


def test_fmu_check_names_its_trust_source(fmu_build, foreign_fmu, capsys):
    assert bench(["fmu", "check", str(fmu_build / "WheeledVehicle.fmu")]) == 0
    assert f"SHA-256 trusted: {sha256_file(fmu_build / 'WheeledVehicle.fmu')[:16]}... matches the build manifest" in (
        capsys.readouterr().out)
    assert bench(["fmu", "check", str(foreign_fmu)]) == 3
    assert "no trusted SHA-256 for this FMU" in capsys.readouterr().out
    assert bench(["fmu", "check", str(foreign_fmu), "--sha256", sha256_file(foreign_fmu)]) == 0
    assert "matches sha256 given in --sha256" in capsys.readouterr().out
    assert bench(["fmu", "check", str(foreign_fmu), "--trust-fmu"]) == 0
    assert "NOT verified: loading its native code because of --trust-fmu" in capsys.readouterr().out
    assert bench(["fmu", "info", str(fmu_build / "TrackedVehicle.fmu")]) == 0
    assert "trust           trusted: listed in the build manifest" in capsys.readouterr().out


def _scenario(tmp_path: Path, fmu: Path, plant_extra: str) -> Path:
    path = tmp_path / "foreign_drive.toml"
    path.write_text(f"""[scenario]
id = "FOREIGN"
title = "the third-party FMU, 4 s"
[initial]
latitude = 39.8
longitude = 116.2
height = "60 m"
[plant]
fmu = "{fmu}"
mapping = "{DATA / 'foreign' / 'mapping.toml'}"
duration = "4 s"
{plant_extra}
[[command]]
at = "0 s"
throttle = 0.5
""")
    return path


def test_the_scenario_trust_is_checked_and_written_into_the_recording(foreign_fmu, tmp_path, capsys):
    refused = _scenario(tmp_path, foreign_fmu, "")
    assert bench(["synth", str(refused), "-o", str(tmp_path / "no.mcap"), "-q"]) == 2
    assert "no trusted SHA-256 for this FMU" in capsys.readouterr().err
    bad = _scenario(tmp_path, foreign_fmu, 'sha256 = "not a hash"')
    assert bench(["synth", str(bad), "-o", str(tmp_path / "no.mcap"), "-q"]) == 2
    assert "plant.sha256: expected the FMU's SHA-256 as 64 hex digits" in capsys.readouterr().err
    old = _scenario(tmp_path, foreign_fmu, 'manifest = "SHA256SUMS"')
    assert bench(["synth", str(old), "-o", str(tmp_path / "no.mcap"), "-q"]) == 2
    assert "plant.manifest: a manifest file is not trusted" in capsys.readouterr().err
    for extra, verified, source in (
        (f'sha256 = "{sha256_file(foreign_fmu)}"', "true", f"sha256 given in {tmp_path / 'foreign_drive.toml'}"),
        ('trust = "unverified"', "false", "unverified: no trusted SHA-256, loaded by the user's explicit opt-in"),
    ):
        scenario = _scenario(tmp_path, foreign_fmu, extra)
        out = tmp_path / f"{verified}.mcap"
        assert bench(["synth", str(scenario), "-o", str(out), "-q"]) == 0
        plant = RecordingReader(out).metadata()["plant"]
        assert plant["fmu_verified"] == verified and plant["fmu_trust"].startswith(source)
        assert plant["fmu_sha256"] == sha256_file(foreign_fmu)
