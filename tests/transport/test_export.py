"""ASC and BLF export: python-can's LogReader reads every frame back, frame for frame."""

from __future__ import annotations

import can
import numpy as np
import pytest

from bench.errors import RecordingError
from bench.frames import CanBatch
from bench.transport.export import export_can_log, read_can_log
from bench.wire.can import CanEncoder

EPOCH = 1_748_736_000_000_000_000  # UTC of bench time zero, ns


def _bus() -> tuple[CanBatch, CanBatch]:
    rng = np.random.default_rng(11)
    enc = CanEncoder()
    t = np.arange(1, 301) * 10_000_000
    tx = CanBatch.concat(
        [
            enc.encode("BENCH_TIME", t, time_ns=t, lockstep=1),
            enc.encode(
                "ODOMETER",
                t + 123_000,
                pulse_count=np.arange(300) * 9,
                speed=rng.uniform(0, 20, 300),
                reverse=0,
                valid=1,
            ),
        ]
    ).sorted()
    rx = CanBatch(t + 2_345_000, 0x300, rng.integers(0, 256, (300, 48), np.uint8), 48, True)
    return tx, rx


@pytest.mark.parametrize("suffix", [".asc", ".blf"])
def test_log_reader_reads_every_frame_back(tmp_path, suffix):
    tx, rx = _bus()
    path = tmp_path / f"bus{suffix}"
    assert export_can_log(path, tx, rx, start_utc_ns=EPOCH) == 900
    merged = CanBatch.concat([tx, rx])
    is_rx = np.r_[np.zeros(len(tx), bool), np.ones(len(rx), bool)]
    order = np.argsort(merged.t_ns, kind="stable")
    merged, is_rx = merged.take(order), is_rx[order]
    kw = {"relative_timestamp": False} if suffix == ".asc" else {}
    msgs = [m for m in can.LogReader(str(path), **kw) if not m.is_error_frame]
    assert len(msgs) == len(merged)
    t_first = None
    for i, m in enumerate(msgs):
        f = merged.frame(i)
        assert m.arbitration_id == f.can_id and bytes(m.data) == f.data
        assert m.is_fd == f.fd and m.bitrate_switch == f.fd and m.dlc == len(f.data)
        assert m.is_rx == bool(is_rx[i]) and not m.is_extended_id
        if suffix == ".blf":  # absolute UTC, to the microsecond
            assert round(m.timestamp * 1e6) == (EPOCH + f.t_ns) // 1000
        else:  # the ASC header keeps the start to the millisecond; intervals are exact to the microsecond
            t_first = m.timestamp if t_first is None else t_first
            assert round((m.timestamp - t_first) * 1e6) == (f.t_ns - merged.t_ns[0]) // 1000
    back, flags = read_can_log(path, start_utc_ns=EPOCH)
    np.testing.assert_array_equal(back.t_ns, merged.t_ns)
    np.testing.assert_array_equal(back.can_id, merged.can_id)
    np.testing.assert_array_equal(flags, is_rx)
    for i in range(len(back)):
        assert back.frame(i).data == merged.frame(i).data


def test_asc_relative_times_are_bench_time(tmp_path):
    tx, _ = _bus()
    path = tmp_path / "tx.asc"
    export_can_log(path, tx, start_utc_ns=EPOCH + 123_456_789)  # not a whole millisecond
    first = next(m for m in can.LogReader(str(path)) if not m.is_error_frame)
    assert round(first.timestamp * 1e6) == tx.t_ns[0] // 1000
    text = path.read_text()
    assert "Begin Triggerblock" in text and "bench time zero" in text


def test_unknown_suffix_is_a_recording_error(tmp_path):
    with pytest.raises(RecordingError):
        export_can_log(tmp_path / "bus.xyz", *_bus())
