"""Recordings read past damage: a bad chunk is skipped, counted and named; the rest is read.

Every test damages a real file the writer produced (many small chunks) the way a disk, a
copy or a killed writer does, and checks what the reader returns against what was written.
"""

import json
import os
import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.errors import ConfigError
from bench.record.mcap_io import RecordingReader, RecordingWriter
from bench.record.scan import scan

DT = np.dtype([("t_ns", "<i8"), ("v", "<f8", (3,))])
EPOCH = 1_700_000_000_000_000_000
BLOCKS = 60  # one block of 100 records per 0.1 s of bench time
RNG = np.random.default_rng(7)
VALUES = RNG.normal(size=(BLOCKS * 100, 3))  # incompressible: one chunk per few blocks


def _block(i: int) -> np.ndarray:
    r = np.zeros(100, DT)
    r["t_ns"] = i * 100_000_000 + np.arange(100) * 1_000_000
    r["v"] = VALUES[i * 100 : (i + 1) * 100]
    return r


def _write(path) -> None:
    w = RecordingWriter(path, epoch_ns=EPOCH, chunk_size=8 << 10)
    w.metadata("run_start", {"kind": "test", "epoch_utc_ns": str(EPOCH)})
    w.columnar_topic("/x", "test.X", DT)
    w.json_topic("/ev", "test.Ev", {"type": "object"})
    w.attach("case/c.toml", b"id = 1\n")
    for i in range(BLOCKS):
        w.write_block("/x", _block(i))
        w.write_json("/ev", i * 100_000_000, {"i": i})
    w.close()


@pytest.fixture
def rec(tmp_path):
    p = tmp_path / "r.mcap"
    _write(p)
    return p


def _chunks(path):
    idx = scan(path)
    out = [(c.offset, c.length, c.start_ns, c.end_ns) for c in idx.chunks]
    idx.close()
    return out


def _flip(path, at: int, n: int = 64) -> None:
    data = bytearray(path.read_bytes())
    for k in range(at, at + n):
        data[k] ^= 0xFF
    path.write_bytes(bytes(data))


def _blocks_read(r: RecordingReader) -> set[int]:
    x = r.read_columnar("/x")
    starts = x["t_ns"][::100] // 100_000_000
    for i in starts:  # every block read back is exactly the one written
        assert np.array_equal(x[x["t_ns"] // 100_000_000 == i], _block(int(i)))
    return {int(i) for i in starts}


def test_an_intact_recording_has_no_damage(rec):
    r = RecordingReader(rec)
    assert r.finished and r.intact and not r.damage and r.tail is None
    assert _blocks_read(r) == set(range(BLOCKS))
    assert r.topics()["/x"].messages == BLOCKS and r.topics()["/ev"].messages == BLOCKS


def test_64_flipped_bytes_in_a_chunk_skip_that_chunk_only(rec):
    chunks = _chunks(rec)
    assert len(chunks) >= 8
    off, length, t0, t1 = chunks[len(chunks) // 2]
    _flip(rec, off + length // 2)
    r = RecordingReader(rec)
    assert r.finished and not r.intact
    (d,) = r.damage
    assert d.what == f"chunk {len(chunks) // 2}" and (d.offset, d.length) == (off, length)
    assert (d.start_ns, d.end_ns) == (t0, t1) and d.exact
    assert "CRC" in d.reason and set(d.topics) == {"/x", "/ev"}
    lost_x = set(range(BLOCKS)) - _blocks_read(r)
    lost_ev = set(range(BLOCKS)) - {doc["i"] for _, doc in r.iter_json("/ev")}
    for lost in (lost_x, lost_ev):  # one stretch of messages, inside the chunk's span
        assert lost == set(range(min(lost), max(lost) + 1))
        assert all(t0 <= EPOCH + i * 100_000_000 <= t1 for i in lost)
    assert len(lost_x) + len(lost_ev) == d.messages
    assert r.topics()["/x"].messages == BLOCKS - len(lost_x)
    assert r.metadata()["run_end"]["status"] == "complete" and r.attachments() == {"case/c.toml": b"id = 1\n"}
    text = r.damage_lines()[0]
    assert text.startswith(f"chunk {len(chunks) // 2} at byte {off} ({length} B), messages logged at bench time")


def test_a_damaged_record_length_is_skipped_by_resynchronising(rec):
    chunks = _chunks(rec)
    off, length, _, _ = chunks[3]
    data = bytearray(rec.read_bytes())
    data[off + 1 : off + 9] = struct.pack("<Q", 1 << 50)  # the chunk's length: past the end of the file
    rec.write_bytes(bytes(data))
    r = RecordingReader(rec)
    assert r.finished
    (d,) = r.damage
    assert d.what == "bytes" and d.offset == off and d.length >= length
    assert d.start_ns is not None and set(d.topics) == {"/x", "/ev"}  # named from the summary's chunk index
    got = _blocks_read(r)
    assert 0 in got and BLOCKS - 1 in got and len(got) < BLOCKS


def test_an_unfinished_file_with_a_bad_chunk_is_read_around_it(tmp_path):
    p = tmp_path / "killed.mcap"
    _write(p)
    data = p.read_bytes()
    p.write_bytes(data[: len(data) * 7 // 10])  # what a writer killed inside a chunk leaves
    chunks = _chunks(p)
    off, length, _, _ = chunks[2]
    _flip(p, off + length // 2, 64)
    r = RecordingReader(p)
    assert not r.finished and r.tail is not None and r.tail[0] + r.tail[1] == p.stat().st_size
    (d,) = r.damage
    assert d.what == "chunk 2" and "CRC" in d.reason and "/x" in d.topics
    got = _blocks_read(r)
    assert 0 in got and max(got) > 10 and len(got) < BLOCKS
    assert "run_end" not in r.metadata() and r.metadata()["run_start"]["kind"] == "test"


@pytest.mark.parametrize("cut", ["footer", "summary"])
def test_a_damaged_or_missing_footer_is_damage_of_a_finished_file(rec, cut):
    data = bytearray(rec.read_bytes())
    if cut == "footer":
        data[-37:-29] = b"\0" * 8  # the footer record's opcode and length
    else:
        data = data[: data.rfind(b"\x0f\x04\x00\x00\x00\x00\x00\x00\x00") + 13]  # up to the data end
    rec.write_bytes(bytes(data))
    r = RecordingReader(rec)
    assert r.finished and not r.intact
    assert [d.what for d in r.damage] == ["footer"]
    assert _blocks_read(r) == set(range(BLOCKS))


def test_a_changed_metadata_record_is_caught_by_the_data_section_crc(rec):
    data = rec.read_bytes()
    at = data.rindex(b"complete")
    rec.write_bytes(data[:at] + b"COMPLETE" + data[at + 8 :])
    r = RecordingReader(rec)
    assert [d.what for d in r.damage] == ["data section"] and "CRC" in r.damage[0].reason


def test_a_damaged_attachment_is_named(rec):
    data = rec.read_bytes()
    at = data.index(b"id = 1")
    rec.write_bytes(data[:at] + b"id = 9" + data[at + 6 :])
    r = RecordingReader(rec)
    assert r.attachments() == {}
    assert [d.what for d in r.damage] == ["attachment"] and "case/c.toml" in r.damage[0].reason


@pytest.mark.parametrize(
    ("make", "found"),
    [
        (lambda p: p.write_text("hello world\n"), "starts with 'hello wo', not the MCAP magic"),
        (lambda p: p.write_bytes(b""), "is empty"),
        (lambda p: p.mkdir(), "is a directory"),
        (lambda p: os.mkfifo(p), "is a FIFO"),
        (lambda p: p.write_bytes(b"\x89MCAP0\r\n\x01"), "without a header record"),
        (lambda p: p.write_bytes(b"\0" * 4096), "starts with bytes 00 00"),
    ],
)
def test_what_is_not_a_recording_is_refused_naming_what_it_is(tmp_path, make, found):
    p = tmp_path / "x.mcap"
    make(p)
    with pytest.raises(ConfigError, match=found.replace("(", r"\(")):
        RecordingReader(p)


def test_dev_zero_and_another_programs_mcap_are_refused(tmp_path):
    with pytest.raises(ConfigError, match="is a device"):
        RecordingReader("/dev/zero")
    from mcap.writer import Writer

    p = tmp_path / "other.mcap"
    with p.open("wb") as fh:
        w = Writer(fh)
        w.start(profile="ros2", library="someone-else")
        w.finish()
    with pytest.raises(ConfigError, match="profile 'ros2' written by 'someone-else', not a bench recording"):
        RecordingReader(p)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(st.floats(0.02, 1.0), st.integers(1, 255), st.integers(1, 64)), min_size=1, max_size=4),
       st.booleans())
def test_any_damage_reads_only_what_was_written(tmp_path_factory, flips, truncate):
    """Whatever is flipped (past the header) or cut, reading never raises and never returns a
    byte that was not written: every block and JSON document read is one of the originals."""
    p = tmp_path_factory.mktemp("fuzz") / "f.mcap"
    _write(p)
    data = bytearray(p.read_bytes())
    for where, mask, n in flips:
        at = max(200, int(where * (len(data) - n)))
        for k in range(at, min(at + n, len(data))):
            data[k] ^= mask
    if truncate:
        data = data[: int(len(data) * flips[0][0]) + 200]
    p.write_bytes(bytes(data))
    r = RecordingReader(p)
    _blocks_read(r) if r.topics().get("/x") and r.topics()["/x"].messages else None
    if "/ev" in r.topics():
        for _, doc in r.iter_json("/ev"):
            assert doc in [{"i": i} for i in range(BLOCKS)]
    r.metadata(), r.attachments()
    json.dumps([d.text() for d in r.damage])


def test_a_file_overwritten_under_an_open_reader_is_a_recording_error(rec):
    from bench.errors import RecordingError

    r = RecordingReader(rec)
    rec.write_bytes(rec.read_bytes()[:60])  # another program truncates it while it is open
    with pytest.raises(RecordingError, match="changed since"):
        r.read_columnar("/x")
    with pytest.raises(RecordingError, match="changed since"):
        r.attachments()
