"""``bench export`` and ``bench import-nav`` on the command line: the files, the KF-GINS
configuration, and the exit codes of what cannot be done (docs/exchange.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.cli import main

DRIVE = Path(__file__).parent.parent / "exchange" / "short_drive.toml"


@pytest.fixture(scope="module")
def synth_run(tmp_path_factory) -> Path:
    """The short drive with a BDS receiver (lever arm right 0.5, forward 1.2, up 1.8 m) and
    an odometer, a tactical-grade IMU."""
    d = tmp_path_factory.mktemp("synth")
    text = DRIVE.read_text() + (
        '\n[bds]\nmodel = "seed001"\nlever_arm = ["0.5 m", "1.2 m", "1.8 m"]\n'
        '\n[odometer]\nmodel = "typical_wheeled"\n'
        '\n[imu]\ngrade = "tactical"\nrate = "100 Hz"\n'
    )
    scenario = d / "drive.toml"
    scenario.write_text(text)
    rec = d / "drive.mcap"
    assert main(["synth", str(scenario), "-o", str(rec), "-q", "--seed", "4"]) == 0
    return rec


def test_export_writes_every_stream_in_the_i2nav_formats(synth_run, tmp_path, capsys):
    out = tmp_path / "x"
    assert main(["export", str(synth_run), "--format", "i2nav", "-o", str(out)]) == 0
    assert "GPS week 2369 (GPS - UTC 18 s)" in capsys.readouterr().out
    imu = np.loadtxt(out / "imu.txt")
    assert imu.shape[1] == 7 and np.allclose(np.diff(imu[:, 0]), 0.01)
    assert imu[0, 0] == pytest.approx(18.01)  # GPS seconds of week of the first interval's end
    # at rest, forward-right-down: the down accelerometer senses about -g dt
    assert np.mean(imu[:100, 6]) == pytest.approx(-9.797 * 0.01, rel=2e-3)
    pos = np.loadtxt(out / "gnss.pos")
    assert pos.shape[1] == 7 and np.allclose(np.diff(pos[:, 0]), 1.0)
    assert np.all(pos[:, 4:7] > 0) and abs(pos[0, 1] - 34.24605) < 1e-3 and abs(pos[0, 2] - 108.90965) < 1e-3
    odo = np.loadtxt(out / "odo.txt")
    assert odo.shape[1] == 2 and odo[:, 1].max() > 11.0
    nav = np.loadtxt(out / "truth.nav")
    assert nav.shape[1] == 11 and np.all(nav[:, 0] == 2369)
    assert nav[0, 10] == pytest.approx(30.0) and nav[-1, 10] == pytest.approx(120.0, abs=0.5)  # after the right turn
    moving = nav[nav[:, 1] > 40.0]
    course = np.degrees(np.arctan2(moving[:, 6], moving[:, 5])) % 360.0  # from north and east velocity
    assert np.allclose(course, moving[:, 10], atol=0.2)
    yaml = (out / "kf-gins.yaml").read_text()
    assert f'imupath: "{(out / "imu.txt").resolve()}"' in yaml and "imudatarate: 100\n" in yaml
    assert "antlever: [ 1.2, 0.5, -1.8 ]" in yaml  # forward, right, down
    assert "arw: [ 0.05, 0.05, 0.05 ]" in yaml  # tactical: 0.05 deg/sqrt(h)
    assert "vrw: [ 0.0294" in yaml  # 50 ug/sqrt(Hz) = 0.0294 m/s/sqrt(h)
    assert "gsstd: [ 100, 100, 100 ]" in yaml and "asstd: [ 300, 300, 300 ]" in yaml
    assert "corrtime: 0.08333333333" in yaml  # 300 s
    start = float(yaml.split("starttime: ")[1].split()[0])
    assert start == pytest.approx(18.01)
    init = yaml.split("initatt: [ ")[1].split(" ]")[0].split(", ")
    assert float(init[2]) == pytest.approx(30.0)


def test_import_nav_exit_codes(synth_run, tmp_path, capsys):
    out = tmp_path / "x"
    assert main(["export", str(synth_run), "-o", str(out)]) == 0
    # bench synth's recording has no DUT output to export
    assert main(["export", str(synth_run), "-o", str(out), "--dut"]) == 2
    assert "holds no DUT output (/dut/nav_solution)" in capsys.readouterr().err
    # the truth itself as a result: imported, scored by nobody (no case), but readable
    result = out / "truth.nav"
    target = tmp_path / "imported.mcap"
    assert main(["import-nav", str(result), "--run", str(synth_run), "-o", str(target)]) == 0
    assert main(["import-nav", str(result), "--run", str(synth_run), "-o", str(target)]) == 2
    assert "exists" in capsys.readouterr().err
    assert main(["import-nav", str(result), "--run", str(synth_run), "-o", str(target), "--force"]) == 0
    bad = tmp_path / "bad.nav"
    bad.write_text("2369 18.01 34.2 108.9 380 1 2 3 0 0\n")
    assert main(["import-nav", str(bad), "--run", str(synth_run), "-o", str(tmp_path / "b.mcap")]) == 2
    assert "bad.nav: line 1: expected 11 columns" in capsys.readouterr().err
    assert main(["import-nav", str(result), "--run", str(tmp_path / "none.mcap")]) == 2
    file_out = tmp_path / "afile"
    file_out.write_text("")
    assert main(["export", str(synth_run), "-o", str(file_out)]) == 2
