"""`bench imu allan`: the real laser-gyro log (what it can and cannot tell), recordings,
and files that are not IMU logs (exit 2 naming what was found)."""

import os
import re
from pathlib import Path

import pytest

from bench.cli import main

SHORT_DRIVE = Path(__file__).parent.parent / "data" / "short_drive.toml"


def _axis_block(out: str, name: str) -> str:
    return out.split(f"\n{name}  ", 1)[1].split("\n\n", 1)[0]


def test_allan_of_the_real_laser_gyro_log(data_dir, tmp_path, capsys):
    png = tmp_path / "allan.png"
    assert main(["imu", "allan", str(data_dir / "psins_lasergyro_10min.imu"), "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "600 s of data" in out and png.stat().st_size > 10_000
    # the z gyro senses the vertical Earth rate, 15.04 sin(34.25 deg) = 8.46 deg/h
    z = float(re.search(r"\ngyro z  mean (-?[\d.]+) deg/h", out).group(1))
    assert abs(z - 8.46) < 0.5
    # the vibration hump near 0.2 s is named on every gyro, and not fitted as a bias instability
    for ax in "xyz":
        hump = re.search(rf"gyro {ax}: hump at ([\d.]+) s .* no noise term makes: vibration", out)
        assert hump and 0.08 < float(hump.group(1)) < 0.35
        block = _axis_block(out, f"gyro {ax}")
        assert "bias instability B           not resolved" in block
        assert re.search(r"rms log10 misfit \d\.\d{3}", block) and "fit over 0.01-" in block
    assert re.search(r"vibration or periodic motion peaking at 0\.1\d?-0\.2\d? s \(gyro x, gyro y, gyro z\)", out)
    # the vehicle tilted (people aboard): the log is not static, figures become bounds
    assert "gravity direction turn as the gyros say" in out and "the log is not static" in out
    assert "gyro bias instability: not resolvable in 600 s" in out
    assert re.search(r"gyro angle random walk: not resolved on any axis \(< [\d.]+\.\.[\d.]+ deg/sqrt\(h\)\)", out)
    # accelerometers: no 0 figures; bounds instead
    for ax in "xyz":
        block = _axis_block(out, f"accel {ax}")
        assert "0.000 ug" not in block
        assert "velocity random walk N       not resolved (< " in block
        assert "bias instability B           not resolved (no floor or peak" in block


def test_allan_of_a_recording(tmp_path, capsys):
    rec = tmp_path / "s.mcap"
    assert main(["synth", str(SHORT_DRIVE), "-o", str(rec), "-q"]) == 0
    capsys.readouterr()
    assert main(["imu", "allan", str(rec), "--topic", "/imu"]) == 0
    out = capsys.readouterr().out
    assert "90 s of data" in out
    # a drive, not a static log: the rotation is named and the curves do not fit noise terms
    assert "times the Earth rate" in out and "figures withdrawn" in out
    # a topic that is not there, and one that holds something else
    assert main(["imu", "allan", str(rec), "--topic", "/nope"]) == 2
    err = capsys.readouterr().err
    assert "no topic '/nope' in the recording (found /faults, /foxglove/" in err and ", /imu, /imu/ideal, " in err
    assert main(["imu", "allan", str(rec), "--topic", "/truth"]) == 2
    assert "topic /truth holds t_ns, lat, lon" in capsys.readouterr().err


def _file(name, data):
    def make(folder):
        path = folder / name
        path.write_bytes(data if isinstance(data, bytes) else data.encode())
        return path

    return make


def _dir(folder):
    (folder / "d.imu").mkdir()
    return folder / "d.imu"


PSINS_HEAD = "% x\n0 0 0 0 0 0\n34 108 380 0 {ms} 9.78\n0.1 0.1 0.1 125 125 125\n"


def _fifo(tmp_path):
    p = tmp_path / "fifo.imu"
    os.mkfifo(p)
    return p


BAD = {
    "directory": (_dir, "is a directory, not an IMU log (a PSINS .imu text log or an MCAP recording)"),
    "empty": (_file("e.imu", b""), "empty file"),
    "binary": (_file("b.imu", bytes(range(256)) * 4), "binary data (starts 00 01 02 03"),
    "other text": (_file("t.imu", "hello world\n"),
                   "not a PSINS IMU log: expected three parameter lines and samples after the % header, found 1 "
                   "line(s) of other text (first: 'hello world')"),
    "toml": (_file("c.imu", '[case]\nname = "x"\n[dut]\nkind = "a"\n[x]\ny = 1\n'),
             "parameter lines 2 and 3 are not the PSINS layout"),
    "fake mcap": (_file("x.mcap", "not really"), "named .mcap but does not start with the MCAP magic"),
    "fifo": (_fifo, "is a FIFO (named pipe), not an IMU log"),
    "bad header": (_file("h.imu", PSINS_HEAD.format(ms=-10) + "1 2 3 4 5 6\n" * 200),
                   "expected the sampling interval (line 2, field 5) within (0, 1000] ms, found -10"),
    "too short": (_file("s.imu", PSINS_HEAD.format(ms=10) + "1 2 3 4 5 6\n" * 20),
                  "20 samples; an Allan deviation needs at least 100"),
    "nan sample": (_file("n.imu", PSINS_HEAD.format(ms=10) + "1 2 3 4 5 6\n" * 150 + "nan 2 3 4 5 6\n"),
                   "non-finite angle increment in sample 150"),
}


@pytest.mark.parametrize("kind", list(BAD))
def test_a_file_that_is_not_an_imu_log_is_refused_naming_what_it_is(kind, tmp_path, capsys):
    make, message = BAD[kind]
    path = make(tmp_path)
    assert main(["imu", "allan", str(path)]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and message in err, err
    assert "Traceback" not in err
