import numpy as np
import pytest

from bench.frames import CanBatch, SerialBatch
from bench.wire.imu import encode_batch
from bench.wire.imu_stream import ImuStreamDecoder


def test_feed_batch_gives_each_frame_the_arrival_of_its_last_byte():
    n = 1000
    t = (np.arange(1, n + 1) * 5_000_000).astype(np.int64)
    frames = encode_batch(t, np.zeros((n, 3)), np.zeros((n, 3)), 0x3F, 25.0, np.arange(n) % 256)
    buf = frames.tobytes()
    offsets = np.append(np.arange(0, len(buf), 100), len(buf))  # re-cut in 100-byte reads
    arrival = np.arange(len(offsets) - 1) * 1000
    s = ImuStreamDecoder().feed_batch(SerialBatch(arrival, offsets, buf))
    assert np.array_equal(s["t_ns"], t)
    assert np.array_equal(s["rx_ns"], ((np.arange(1, n + 1) * 42 - 1) // 100) * 1000)


def test_feed_batch_across_calls_and_with_garbage():
    n = 20
    t = (np.arange(1, n + 1) * 5_000_000).astype(np.int64)
    frames = encode_batch(t, np.zeros((n, 3)), np.zeros((n, 3)), 0x3F, 25.0, np.arange(n) % 256, at_ns=t + 3)
    d = ImuStreamDecoder()
    first = d.feed_batch(frames.take(np.arange(10)))
    noise = SerialBatch(np.array([t[9] + 5]), np.array([0, 5]), b"\x01\x02\x03\x04\x05")
    mid = d.feed_batch(noise)
    rest = d.feed_batch(frames.take(np.arange(10, n)))
    assert len(first) == 10 and len(mid) == 0 and len(rest) == 10
    assert np.array_equal(np.concatenate([first["rx_ns"], rest["rx_ns"]]), t + 3)
    assert d.tally.as_dict().get("sync") == 1


def test_batches_that_cannot_be_traffic_are_refused_when_built():
    with pytest.raises(ValueError, match="must not decrease"):
        SerialBatch([0, 1, 2], [0, 5, 3, 6], bytes(6))  # a chunk of -2 bytes
    with pytest.raises(ValueError, match="at most 64 bytes"):
        CanBatch([0], [0x120], np.zeros((1, 80), np.uint8), [80])
