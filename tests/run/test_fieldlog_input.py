"""Field logs as input, without a source run: NMEA logs without dates or with talkers and
sentences the ICD does not list (every byte is kept), and malformed logs of every kind,
each refused with an error naming the file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.run.bytelogs import DAY_NS, read_nmea_log
from bench.run.logreplay import FieldLogs, LogReplay
from bench.wire import nmea


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
