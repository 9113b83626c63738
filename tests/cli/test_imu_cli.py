from bench.cli import main


def test_allan_of_the_real_laser_gyro_log(data_dir, tmp_path, capsys):
    png = tmp_path / "allan.png"
    assert main(["imu", "allan", str(data_dir / "psins_lasergyro_10min.imu"), "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "600 s of data" in out and "gyro ARW" in out
    # the z gyro senses the vertical Earth rate, 15.04 sin(34.25 deg) = 8.46 deg/h
    z = next(ln for ln in out.splitlines() if ln.strip().startswith("z"))
    assert abs(float(z.split()[-1]) - 8.46) < 0.5
    assert png.stat().st_size > 10_000


def test_allan_of_a_recording(tmp_path, capsys):
    from pathlib import Path

    short = Path(__file__).parent.parent / "data" / "short_drive.toml"
    rec = tmp_path / "s.mcap"
    assert main(["synth", str(short), "-o", str(rec), "-q"]) == 0
    assert main(["imu", "allan", str(rec), "--topic", "/imu"]) == 0
    assert "90 s of data" in capsys.readouterr().out
