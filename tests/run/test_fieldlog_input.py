"""Field logs as input, without a source run: NMEA logs without dates or with talkers and
sentences the ICD does not list (every byte is kept), malformed logs of every kind and
files that are no log of the option's kind (directories, devices, FIFOs, text, binary,
another line's log), each refused with an error naming the file and what it holds, and
bad sentences in a log counted and reported."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from bench.cli.app import run as cli
from bench.errors import ConfigError
from bench.run import bytelogs
from bench.run.bytelogs import DAY_NS, read_nmea_log
from bench.run.logreplay import FieldLogs, LogReplay
from bench.wire import imu, nmea


# ---------------------------------------------------------------------------- NMEA logs
def test_nmea_without_dates_across_midnight():
    """GGA and VTG only (no date): the day comes from the epoch and moves on at midnight."""
    fixes = np.zeros(4, nmea.GNSS_FIX_DTYPE)
    midnight = 1_772_409_600_000_000_000  # 2026-03-02T00:00:00Z
    fixes["utc_ns"] = midnight + np.array([-2, -1, 0, 1]) * 1_000_000_000
    fixes["lat"], fixes["lon"], fixes["h"], fixes["quality"], fixes["sats"] = 0.6, 1.9, 380.0, 1, 12
    text = nmea.encode_epochs(fixes, talker="GN").tobytes()
    lines = [ln for ln in text.split(b"\r\n") if ln[3:6] in (b"GGA", b"VTG")]
    data = b"noise" + b"\r\n".join(lines) + b"\r\n"
    log = read_nmea_log(data, file="gga.nmea")
    assert log.info["epochs"] == 4 and log.info["dated_epochs"] == 0 and log.info["untimed"] == 4
    epoch = midnight - 10 * 1_000_000_000
    assert np.array_equal(log.epoch_utc_ns(epoch), fixes["utc_ns"])
    assert np.array_equal(log.epoch_utc_ns(epoch - DAY_NS // 3), fixes["utc_ns"])  # within 12 h either way
    with pytest.raises(ConfigError, match="no date"):
        log.epoch_utc_ns(None)
    batch = log.batch(log.epoch_utc_ns(epoch)[log.epoch_of] - epoch)
    assert batch.tobytes() == data and batch.chunk(0).data.startswith(b"noise$GNGGA")
    assert np.array_equal(batch.t_ns, np.repeat([8, 9, 10, 11], 2) * 1_000_000_000)


def _sentence(body: bytes) -> bytes:
    return b"$" + body + b"*%02X\r\n" % nmea.checksum(body)


def test_nmea_with_other_talkers_and_sentences_keeps_every_byte():
    fixes = np.zeros(2, nmea.GNSS_FIX_DTYPE)
    fixes["utc_ns"] = 1_772_352_000_000_000_000 + np.array([0, 200_000_000])
    fixes["quality"] = 1
    lines = [_sentence(c.data[1:-5].replace(b"GN", b"GP", 1)) for c in nmea.encode_epochs(fixes, talker="GN").chunks()]
    lines.insert(3, _sentence(b"GPGSV,1,1,01,01,40,083,46"))  # a sentence the ICD does not list, in epoch 1
    body = b"$GPGGA,bad*00\r\n" + b"".join(lines)
    log = read_nmea_log(body, file="gp.nmea")
    utc = log.epoch_utc_ns(None)[log.epoch_of]
    assert log.info["bad"] == 1 and log.info["epochs"] == 2
    assert np.array_equal(np.unique(utc), fixes["utc_ns"]) and utc[0] == fixes["utc_ns"][0]
    assert log.batch(utc).tobytes() == body


# ---------------------------------------------------------------------------- malformed input
def _write(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


@pytest.mark.parametrize(
    ("name", "data", "kind", "message"),
    [
        ("bad.asc", b"hello\nnot a log\n", "can", "no CAN data frame"),
        ("bad.blf", bytes(range(256)) * 8, "can", "cannot read CAN log"),
        ("log.xyz", b"0.0 1 120 Rx d 8 00\n", "can", "cannot read CAN log"),
        ("delta.asc", b"date Sun Mar 1 08:00:00.000 am 2026\nbase hex  timestamps relative\n", "can",
         "timestamps relative"),
        ("imu.bin", bytes(np.random.default_rng(1).integers(0, 256, 5000, dtype=np.uint8)), "imu", "no ICD IMU frame"),
        ("empty.bin", b"", "imu", "empty"),
        ("lf.nmea", b"$GPGGA,120000.00,,,,,0,00,,,M,0.0,M,,*5E\n", "gnss", "LF alone"),
        ("vtg.nmea", b"$GBVTG,,T,,M,,N,,K,N*2C\r\n", "gnss", "time field"),
    ],
)
def test_malformed_logs_give_errors_naming_the_file(tmp_path, name, data, kind, message):
    path = _write(tmp_path / name, data)
    with pytest.raises(ConfigError, match=message) as err:
        LogReplay(FieldLogs(**{kind: path}), lockstep=True)
    assert str(path) in str(err.value)


# ---------------------------------------------------------------------------- not what the option expects
def _gga_zda(zda: str) -> bytes:
    gga = "GBGGA,120000.00,3422.64806,N,10851.71886,E,1,12,0.9,380.000,M,0.0,M,,"
    return _sentence(gga.encode()) + _sentence(zda.encode())


def _files(tmp_path: Path) -> dict[str, Path]:
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    (tmp_path / "dir").mkdir()
    fixes = np.zeros(2, nmea.GNSS_FIX_DTYPE)
    fixes["utc_ns"], fixes["quality"] = 1_772_352_000_000_000_000 + np.arange(2) * 10**9, 1
    t = np.array([5_000_000, 10_000_000])
    frames = imu.encode_frames(t, np.zeros((2, 3)), np.zeros((2, 3)), 0x3F, 20.0, [0, 1])
    return {
        "dir": tmp_path / "dir",
        "fifo": fifo,
        "zero": Path("/dev/zero"),
        "text": _write(tmp_path / "notes.txt", b"hello world\nthis is text\n"),
        "binary": _write(tmp_path / "blob.bin", bytes(np.random.default_rng(2).integers(0, 256, 4000, np.uint8))),
        "nmea": _write(tmp_path / "gnss.nmea", nmea.encode_epochs(fixes).tobytes()),
        "imu": _write(tmp_path / "imu.bin", frames.tobytes()),
        "mcap": _write(tmp_path / "run.mcap", b"\x89MCAP0\r\n" + bytes(200)),
    }


@pytest.mark.parametrize(
    ("kind", "name", "found"),
    [
        ("imu", "dir", "is a directory"),
        ("gnss", "dir", "is a directory"),
        ("can", "dir", "is a directory"),
        ("imu", "zero", "is a character device"),
        ("gnss", "zero", "is a character device"),
        ("can", "zero", "is a character device"),
        ("gnss", "fifo", r"is a FIFO \(named pipe\)"),
        ("imu", "fifo", r"is a FIFO \(named pipe\)"),
        ("imu", "text", "found text whose lines end in LF alone, starting 'hello world'"),
        ("imu", "nmea", r"found 10 NMEA sentences .*gnss line"),
        ("gnss", "binary", r"found binary data \(\d+ of its first 4000 bytes not printable"),
        ("gnss", "imu", r"found 2 ICD IMU frames .*imu line"),
        ("gnss", "mcap", "found an MCAP recording"),
        ("imu", "mcap", "found an MCAP recording"),
    ],
)
def test_a_field_log_that_is_not_what_the_option_expects_is_refused_naming_what_it_is(tmp_path, kind, name, found):
    path = _files(tmp_path)[name]
    with pytest.raises(ConfigError, match=found) as err:
        LogReplay(FieldLogs(**{kind: path}), lockstep=True)
    assert str(path) in str(err.value)


def test_the_command_refuses_them_with_exit_2_and_no_traceback(tmp_path, capsys):
    files = _files(tmp_path)
    for option, name in (("--imu-log", "zero"), ("--gnss-log", "fifo"), ("--gnss-log", "binary"), ("--can-log", "dir")):
        argv = ["replay", option, str(files[name]), "--estimator", "dead_reckoning", "-q", "-o"]
        argv.append(str(tmp_path / "o.mcap"))
        assert cli(argv) == 2, (option, name)
        err = capsys.readouterr().err
        assert str(files[name]) in err and "Traceback" not in err
    assert not (tmp_path / "o.mcap").exists()


def test_a_log_bigger_than_the_limit_is_refused_before_it_is_read(tmp_path):
    path = tmp_path / "big.nmea"
    with path.open("wb") as fh:
        fh.truncate(3 << 30)  # 3 GiB, sparse: nothing is written
    for kind in ("gnss", "imu", "can"):
        with pytest.raises(ConfigError, match=r"is 3 GiB, more than the 1 GiB limit") as err:
            LogReplay(FieldLogs(**{kind: path}), lockstep=True)
        assert str(path) in str(err.value)


@pytest.mark.parametrize(
    "zda",
    [
        "GBZDA,120000.00,01,13,2025,00,00",  # month 13: a traceback before
        "GBZDA,120000.00,01,01,9999,00,00",  # beyond int64 ns: a traceback before
        "GBZDA,120000.00,31,02,2025,00,00",  # 31 February: taken as 3 March before
        "GBZDA,120000.00,01,06,2O25,00,00",  # not digits
    ],
)
def test_a_bad_zda_in_a_field_log_is_counted_and_reported(tmp_path, zda, capsys):
    path = _write(tmp_path / "bad.nmea", _gga_zda(zda))
    log = read_nmea_log(path.read_bytes(), file=str(path))
    assert log.info["bad"] == 1 and sum(log.info["bad_kinds"].values()) == 1 and log.info["dated_epochs"] == 0
    with pytest.raises(ConfigError, match=r"no date .*do not decode, by kind: \{'(range|format)': 1\}"):
        log.epoch_utc_ns(None)
    # with the epoch given the log replays; the figures written into the recording say what was bad
    rep = LogReplay(FieldLogs(gnss=path, epoch_ns=1_748_736_000_000_000_000), lockstep=True)
    figures = json.loads(rep.metadata()["log_figures"])["gnss"]
    assert figures["bad"] == 1 and figures["bad_kinds"] == log.info["bad_kinds"]
    assert rep.duration_ns > 0
    argv = ["replay", "--gnss-log", str(path), "--estimator", "dead_reckoning", "-q", "-o", str(tmp_path / "o.mcap")]
    assert cli(argv) == 2
    assert "do not decode" in capsys.readouterr().err


def test_huge_imu_shifts_are_refused_not_overflowed(tmp_path):
    data = _files(tmp_path)["imu"].read_bytes()
    for shift in (10**22, -(10**22), (2**63 // 1000) * 1000):  # an OverflowError before
        with pytest.raises(ConfigError, match="IMU time shift") as err:
            bytelogs.imu_log_chunks(data, file="imu.bin", shift_ns=shift)
        assert "imu.bin" in str(err.value)
