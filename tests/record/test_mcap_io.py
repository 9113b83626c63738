import numpy as np
import pytest

from bench.errors import ConfigError, RecordingError
from bench.record.mcap_io import RecordingReader, RecordingWriter, dtype_from_json, dtype_to_json

DT = np.dtype([("t_ns", "<i8"), ("v", "<f8", (3,)), ("flag", "u1")])


def _records(t0, n):
    r = np.zeros(n, DT)
    r["t_ns"] = t0 + np.arange(n) * 1000
    r["v"] = np.arange(3 * n).reshape(n, 3) * 0.5
    r["flag"] = np.arange(n) % 7
    return r


def test_dtype_json_round_trip():
    assert dtype_from_json(dtype_to_json(DT)) == DT


def test_columnar_and_json_round_trip(tmp_path):
    p = tmp_path / "a.mcap"
    with RecordingWriter(p, epoch_ns=1_700_000_000_000_000_000) as w:
        w.columnar_topic("/x", "test.X", DT, description="d", units={"v": "m/s"})
        w.json_topic("/ev", "test.Ev", {"type": "object"})
        w.write_block("/x", _records(0, 10))
        w.write_json("/ev", 5, {"a": 1})
        w.write_block("/x", _records(10_000, 5))
        w.attach("case.toml", b"id = 1\n")
        w.metadata("run_start", {"seed": 3, "name": "x"})
    r = RecordingReader(p)
    assert r.complete
    x = r.read_columnar("/x")
    assert np.array_equal(x, np.concatenate([_records(0, 10), _records(10_000, 5)]))
    assert list(r.iter_json("/ev")) == [(1_700_000_000_000_000_005, {"a": 1})]
    assert r.attachments() == {"case.toml": b"id = 1\n"}
    md = r.metadata()
    assert md["run_start"] == {"seed": "3", "name": "x"} and md["run_end"]["status"] == "complete"
    t = r.topics()
    assert t["/x"].messages == 2 and t["/x"].schema == "test.X"


def test_a_crash_inside_the_writer_still_leaves_a_readable_file(tmp_path):
    p = tmp_path / "b.mcap"
    with pytest.raises(RuntimeError), RecordingWriter(p) as w:
        w.columnar_topic("/x", "test.X", DT)
        w.write_block("/x", _records(0, 3))
        raise RuntimeError("boom")
    r = RecordingReader(p)
    assert r.metadata()["run_end"] == {"status": "error", "reason": "RuntimeError: boom"}
    assert len(r.read_columnar("/x")) == 3


def test_truncated_file_reads_up_to_the_damage(tmp_path):
    p = tmp_path / "c.mcap"
    with RecordingWriter(p, chunk_size=4096) as w:
        w.columnar_topic("/x", "test.X", DT)
        for i in range(200):
            w.write_block("/x", _records(i * 100_000, 50))
    data = p.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    r = RecordingReader(cut)
    assert not r.complete
    x = r.read_columnar("/x")
    assert 0 < len(x) < 200 * 50
    assert np.array_equal(x, np.concatenate([_records(i * 100_000, 50) for i in range(200)])[: len(x)])
    assert r.topics()["/x"].messages == len(x) // 50


def test_missing_file_and_missing_topic(tmp_path):
    with pytest.raises(ConfigError, match="no such file"):
        RecordingReader(tmp_path / "none.mcap")
    p = tmp_path / "d.mcap"
    with RecordingWriter(p) as w:
        w.columnar_topic("/x", "test.X", DT)
    with pytest.raises(RecordingError, match="no messages"):
        RecordingReader(p).read_columnar("/x")
